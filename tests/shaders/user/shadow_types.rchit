#version 460
// A closest-hit that shades and casts a shadow ray of its own ray type, as DXR / nvpro engines
// do: sbtRecordOffset 1, sbtRecordStride 2, miss index 1, terminate-on-first-hit, skip the
// closest-hit, opaque (with ALPHA_SHADOW not opaque, so the shadow any-hit alpha-tests). Its hit
// group is ray type 1's: empty, or the alpha-test any-hit.
#extension GL_EXT_ray_tracing : require
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"
#include "shadow_types.glsl"

layout(set = 0, binding = 0) uniform accelerationStructureEXT sceneTlas;

layout(location = 0) rayPayloadInEXT Shade shade;
layout(location = 1) rayPayloadEXT bool shadowed;
hitAttributeEXT vec2 bary;

const vec3 TO_LIGHT = normalize(vec3(0.3, 0.8, -0.5));

#ifdef ALPHA_SHADOW
const uint OPACITY = 0u;
#else
const uint OPACITY = gl_RayFlagsOpaqueEXT;
#endif

void main() {
    vec3 at = gl_WorldRayOriginEXT + gl_WorldRayDirectionEXT * gl_HitTEXT;
    shadowed = true;
    uint flags = gl_RayFlagsTerminateOnFirstHitEXT | gl_RayFlagsSkipClosestHitShaderEXT | OPACITY;
    traceRayEXT(sceneTlas, flags, 0xFF, SHADOW_OFFSET, SHADOW_STRIDE, SHADOW_MISS,
                at + TO_LIGHT * 0.01, T_MIN, TO_LIGHT, T_MAX, 1);
    if (shadowed) atomicAdd(counters.shadowedHits, 1u); else atomicAdd(counters.litHits, 1u);
    shade.color = (shadowed ? 0.2 : 1.0) * vec3(bary, 1.0 - bary.x - bary.y);
    shade.dist = gl_HitTEXT;
    shade.instance = uint(gl_InstanceCustomIndexEXT);
}
