#version 460
#extension GL_EXT_ray_tracing : require
layout(location = 0) rayPayloadInEXT vec4 p;
void main() {
    p = vec4(undeclared_thing, 1.0);
}
