#version 460
// A closest-hit that tests its shadow with an inline ray query instead of a second traceRay
// (no shadow miss shader, no recursion): the first candidate toward the light ends the query.
// Lit and shadowed hits are counted.
#extension GL_EXT_ray_tracing : require
#extension GL_EXT_ray_query : require
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(set = 0, binding = 0) uniform accelerationStructureEXT sceneTlas;
layout(set = 0, binding = 1) buffer Lit { uint shadowedHits; uint litHits; } lit;

layout(location = 0) rayPayloadInEXT Shade shade;
hitAttributeEXT vec2 bary;

const vec3 TO_LIGHT = normalize(vec3(0.3, 0.8, -0.5));

void main() {
    vec3 at = gl_WorldRayOriginEXT + gl_WorldRayDirectionEXT * gl_HitTEXT;
    rayQueryEXT q;
    uint flags = gl_RayFlagsTerminateOnFirstHitEXT | gl_RayFlagsOpaqueEXT;
    rayQueryInitializeEXT(q, sceneTlas, flags, 0xFF, at + TO_LIGHT * 0.01, T_MIN, TO_LIGHT, T_MAX);
    while (rayQueryProceedEXT(q)) {
    }
    bool shadowed = rayQueryGetIntersectionTypeEXT(q, true) != gl_RayQueryCommittedIntersectionNoneEXT;
    if (shadowed) atomicAdd(lit.shadowedHits, 1u); else atomicAdd(lit.litHits, 1u);
    shade.color = (shadowed ? 0.2 : 1.0) * vec3(bary, 1.0 - bary.x - bary.y);
    shade.dist = gl_HitTEXT;
    shade.instance = uint(gl_InstanceCustomIndexEXT);
}
