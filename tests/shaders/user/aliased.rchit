#version 460
// A bindless closest-hit reading one storage buffer through two aliased blocks at one binding
// (floats and words), as engines alias a raw buffer under several views.
#extension GL_EXT_ray_tracing : require
#extension GL_EXT_nonuniform_qualifier : require
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(set = 1, binding = 0) readonly buffer Floats { vec4 v[]; } floats[];
layout(set = 1, binding = 0) readonly buffer Words { uint u[]; } words[];

layout(location = 0) rayPayloadInEXT Shade shade;

void main() {
    uint k = uint(gl_InstanceCustomIndexEXT);
    uint slot = words[nonuniformEXT(k)].u[gl_PrimitiveID & 15u] & 15u;
    shade.color = floats[nonuniformEXT(k)].v[slot].rgb;
    shade.dist = gl_HitTEXT;
    shade.instance = k;
}
