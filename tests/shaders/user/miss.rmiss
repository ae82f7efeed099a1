#version 460
#extension GL_EXT_ray_tracing : require
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(location = 0) rayPayloadInEXT Shade shade;

void main() {
    float up = 0.5 + 0.5 * gl_WorldRayOriginEXT.y / 6.0;
    shade.color = mix(vec3(0.9, 0.8, 0.7), vec3(0.3, 0.5, 0.9), up);
    shade.dist = -1.0;
}
