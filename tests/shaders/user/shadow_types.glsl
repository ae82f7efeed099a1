// Shared by the ray-type tests' shaders (written for rtprobe's tests, engine-like): the shadow
// ray type of the DXR / nvpro convention — SBT record offset 1, stride 2 (two ray types), miss
// index 1, a `bool` payload at location 1 — and the counters its stages keep.
#ifndef USER_SHADOW_TYPES_GLSL
#define USER_SHADOW_TYPES_GLSL
#ifndef SHADOW_OFFSET
#define SHADOW_OFFSET 1
#endif
const uint SHADOW_STRIDE = 2;
const uint SHADOW_MISS = 1;

layout(set = 0, binding = 1) buffer Counters {
    uint shadowedHits;
    uint litHits;
    uint shadowMisses;
    uint wrongMisses;
    uint alphaTests;
    uint wrongAlphaTests;
} counters;

bool isShadowRay(uint flags) {
    return (flags & gl_RayFlagsSkipClosestHitShaderEXT) != 0u
        && (flags & gl_RayFlagsTerminateOnFirstHitEXT) != 0u;
}
#endif
