#version 460
// A bindless closest-hit on the descriptor heap, shaped like the engine fault rtprobe exists
// for: the material comes from a `layout(descriptor_heap)` array of storage buffers indexed by
// a per-draw base (push data) plus gl_InstanceCustomIndexEXT; the mesh's vertex normals (a
// non-indexed mesh: three per triangle) come from the same heap by the custom index, the hit's
// normal is interpolated with the barycentrics and shaded by a sun light. Written for
// rtprobe's tests.
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
layout(descriptor_heap) readonly buffer Normals { vec4 n[]; } normalBuffers[];
layout(push_constant) uniform Draw {
    uint materialBase;
} draw;

layout(location = 0) rayPayloadInEXT Shade shade;
hitAttributeEXT vec2 bary;

const vec3 SUN = vec3(0.48, 0.64, -0.6);

void main() {
    // The base stays below half the heap array, custom indices below the other half.
    uint mat = (draw.materialBase & 31u) + uint(gl_InstanceCustomIndexEXT) + uint(MATERIAL_SHIFT);
    Material m = materials[nonuniformEXT(mat)].m[gl_GeometryIndexEXT];
    uint mesh = uint(gl_InstanceCustomIndexEXT);
    uint first = 3u * uint(gl_PrimitiveID);
    vec3 n0 = normalBuffers[nonuniformEXT(mesh)].n[first].xyz;
    vec3 n1 = normalBuffers[nonuniformEXT(mesh)].n[first + 1u].xyz;
    vec3 n2 = normalBuffers[nonuniformEXT(mesh)].n[first + 2u].xyz;
    vec3 w = vec3(1.0 - bary.x - bary.y, bary.x, bary.y);
    vec3 normal = normalize(n0 * w.x + n1 * w.y + n2 * w.z + vec3(0.0, 0.0, -1e-3));
    float sun = max(dot(normal, SUN), 0.0);
    shade.color = m.albedo.rgb * (0.2 + 0.8 * sun) * vec3(bary, 1.0) + m.emission.rgb * 0.1;
    shade.dist = gl_HitTEXT;
    shade.instance = uint(gl_InstanceCustomIndexEXT);
}
