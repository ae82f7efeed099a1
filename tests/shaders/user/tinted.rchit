#version 460
// A closest-hit whose shading a specialization constant sets: an engine's quality or debug
// switch compiled in per pipeline (`--spec 1=…`).
#extension GL_EXT_ray_tracing : require
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(constant_id = 1) const uint TINT = 0u;
layout(constant_id = 2) const float GAIN = 1.0;

layout(location = 0) rayPayloadInEXT Shade shade;
hitAttributeEXT vec2 bary;

void main() {
    vec3 tint = vec3(float(TINT & 3u), float((TINT >> 2) & 3u), 1.0) / 3.0;
    shade.color = vec3(bary, 1.0 - bary.x - bary.y) * tint * GAIN;
    shade.dist = gl_HitTEXT;
    shade.instance = uint(gl_InstanceCustomIndexEXT);
}
