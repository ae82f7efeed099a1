#version 460
// The sphere's closest-hit: shades by the normal the intersection shader reported.
#extension GL_EXT_ray_tracing : require
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

struct SphereHit {
    vec3 normal;
    float entry;
};
layout(location = 0) rayPayloadInEXT Shade shade;
hitAttributeEXT SphereHit hit;

void main() {
    shade.color = 0.5 + 0.5 * hit.normal;
    shade.dist = gl_HitTEXT + 0.001 * hit.entry;
    shade.instance = uint(gl_InstanceCustomIndexEXT) + 100u;
}
