#version 460
// A bindless closest-hit on the descriptor heap, shaped like the engine fault rtprobe exists
// for: the material comes from a `layout(descriptor_heap)` array of storage buffers indexed by
// a per-draw base (push data) plus gl_InstanceCustomIndexEXT.
#extension GL_EXT_ray_tracing : require
#extension GL_EXT_nonuniform_qualifier : require
#extension GL_EXT_descriptor_heap : require
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

// Tests shift the index with -D MATERIAL_SHIFT=1: other descriptors, other data.
#ifndef MATERIAL_SHIFT
#define MATERIAL_SHIFT 0
#endif

struct Material {
    vec4 albedo;
    vec4 emission;
};

layout(descriptor_heap) readonly buffer Materials { Material m[]; } materials[];
layout(push_constant) uniform Draw {
    uint materialBase;
} draw;

layout(location = 0) rayPayloadInEXT Shade shade;
hitAttributeEXT vec2 bary;

void main() {
    // The base stays below half the heap array, custom indices below the other half.
    uint mat = (draw.materialBase & 31u) + uint(gl_InstanceCustomIndexEXT) + uint(MATERIAL_SHIFT);
    Material m = materials[nonuniformEXT(mat)].m[gl_GeometryIndexEXT];
    shade.color = m.albedo.rgb * vec3(bary, 1.0) + m.emission.rgb * 0.1;
    shade.dist = gl_HitTEXT;
    shade.instance = uint(gl_InstanceCustomIndexEXT);
}
