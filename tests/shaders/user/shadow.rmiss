#version 460
// The shadow ray type's miss shader (miss index 1): nothing between the point and the light.
// It counts its rays, and those that are no shadow ray (a primary ray sent to the wrong miss).
#extension GL_EXT_ray_tracing : require
#extension GL_GOOGLE_include_directive : require
#include "shadow_types.glsl"

layout(location = 1) rayPayloadInEXT bool shadowed;

void main() {
    shadowed = false;
    atomicAdd(counters.shadowMisses, 1u);
    if (!isShadowRay(gl_IncomingRayFlagsEXT)) atomicAdd(counters.wrongMisses, 1u);
}
