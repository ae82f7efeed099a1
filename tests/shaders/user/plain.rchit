#version 460
// A closest-hit shading by the barycentrics and the instance.
#extension GL_EXT_ray_tracing : require
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(location = 0) rayPayloadInEXT Shade shade;
hitAttributeEXT vec2 bary;

void main() {
    shade.color = vec3(bary, 1.0 - bary.x - bary.y) * (1.0 + float(gl_InstanceID & 3));
    shade.dist = gl_HitTEXT;
    shade.instance = uint(gl_InstanceCustomIndexEXT);
}
