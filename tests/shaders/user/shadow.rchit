#version 460
// A closest-hit that shades with a shadow ray, the way the RT tutorials do: the shadow ray has
// its own payload (location 1, a bool), miss index 1, and skips closest-hits and any-hits. The
// harness supplies a miss shader for each index, each receiving its ray's payload. With
// SHADOW_RUNS_CLOSEST_HIT the shadow ray would run this closest-hit with its bool payload.
#extension GL_EXT_ray_tracing : require
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(set = 0, binding = 0) uniform accelerationStructureEXT sceneTlas;
layout(set = 0, binding = 1) buffer Lit { uint shadowedHits; uint litHits; } lit;

layout(location = 0) rayPayloadInEXT Shade shade;
layout(location = 1) rayPayloadEXT bool shadowed;
hitAttributeEXT vec2 bary;

const vec3 TO_LIGHT = normalize(vec3(0.3, 0.8, -0.5));

void main() {
    vec3 at = gl_WorldRayOriginEXT + gl_WorldRayDirectionEXT * gl_HitTEXT;
    shadowed = true;
#ifdef SHADOW_RUNS_CLOSEST_HIT
    const uint skip = 0u;
#else
    const uint skip = gl_RayFlagsSkipClosestHitShaderEXT;
#endif
    uint flags = gl_RayFlagsTerminateOnFirstHitEXT | gl_RayFlagsOpaqueEXT | skip;
    traceRayEXT(sceneTlas, flags, 0xFF, 0, 0, 1, at + TO_LIGHT * 0.01, T_MIN, TO_LIGHT, T_MAX, 1);
    if (shadowed) atomicAdd(lit.shadowedHits, 1u); else atomicAdd(lit.litHits, 1u);
    shade.color = (shadowed ? 0.2 : 1.0) * vec3(bary, 1.0 - bary.x - bary.y);
    shade.dist = gl_HitTEXT;
    shade.instance = uint(gl_InstanceCustomIndexEXT);
}
