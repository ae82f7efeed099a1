#version 460
// A glTF-style closest-hit: a per-instance "ObjDesc" record holds the device addresses of the
// mesh's vertex and index buffers (uint64_t), which the shader casts to buffer references and
// reads the hit triangle's vertices through.
#extension GL_EXT_ray_tracing : require
#extension GL_EXT_nonuniform_qualifier : require
#extension GL_EXT_buffer_reference2 : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#extension GL_EXT_scalar_block_layout : require
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

struct Vertex {
    vec3 position;
    vec3 normal;
};

struct ObjDesc {
    uint64_t vertexAddress;
    uint64_t indexAddress;
    uint materialIndex;
    uint flags;
};

layout(buffer_reference, scalar) readonly buffer Vertices { Vertex v[]; };
layout(buffer_reference, scalar) readonly buffer Indices { uvec3 i[]; };

layout(set = 1, binding = 0, scalar) readonly buffer ObjDescs { ObjDesc d[]; } objDescs;

layout(location = 0) rayPayloadInEXT Shade shade;
hitAttributeEXT vec2 bary;

void main() {
    ObjDesc obj = objDescs.d[gl_InstanceCustomIndexEXT];
    Indices indices = Indices(obj.indexAddress);
    Vertices vertices = Vertices(obj.vertexAddress);
    uvec3 tri = indices.i[gl_PrimitiveID];
    Vertex a = vertices.v[tri.x];
    Vertex b = vertices.v[tri.y];
    Vertex c = vertices.v[tri.z];
    vec3 w = vec3(1.0 - bary.x - bary.y, bary.x, bary.y);
    vec3 n = a.normal * w.x + b.normal * w.y + c.normal * w.z;
    shade.color = abs(n) + vec3(float(obj.materialIndex & 7u) * 0.125);
    shade.dist = gl_HitTEXT;
    shade.instance = uint(gl_InstanceCustomIndexEXT);
}
