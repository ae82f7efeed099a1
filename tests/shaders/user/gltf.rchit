#version 460
// A glTF-style closest-hit: one scene-description SSBO holds the device addresses of the
// merged vertex, index, UV and material buffers (buffer references) and, per primitive mesh,
// its offsets into them; the base colour comes from the material's texture in an unbounded
// array of combined image samplers, offset per mesh as merged scenes do.
#extension GL_EXT_ray_tracing : require
#extension GL_EXT_nonuniform_qualifier : require
#extension GL_EXT_buffer_reference2 : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#extension GL_EXT_scalar_block_layout : require
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

struct PrimMesh {
    uint firstIndex;
    uint vertexOffset;
    uint materialIndex;
    uint textureOffset;
};

struct ShadeMaterial {
    vec4 baseColorFactor;
    int baseColorTexture;
    float metallic;
    float roughness;
    uint alphaMode;
};

layout(buffer_reference, scalar) readonly buffer Positions { vec3 p[]; };
layout(buffer_reference, scalar) readonly buffer TexCoords { vec2 t[]; };
layout(buffer_reference, scalar) readonly buffer Indices { uint i[]; };
layout(buffer_reference, scalar) readonly buffer Materials { ShadeMaterial m[]; };

layout(set = 1, binding = 0, scalar) readonly buffer SceneDesc {
    uint64_t positionAddress;
    uint64_t texCoordAddress;
    uint64_t indexAddress;
    uint64_t materialAddress;
    PrimMesh meshes[];
} scene;
layout(set = 1, binding = 1) uniform sampler2D textureSamplers[];

layout(location = 0) rayPayloadInEXT Shade shade;
hitAttributeEXT vec2 bary;

void main() {
    PrimMesh mesh = scene.meshes[gl_InstanceCustomIndexEXT];
    Indices indices = Indices(scene.indexAddress);
    Positions positions = Positions(scene.positionAddress);
    TexCoords uvs = TexCoords(scene.texCoordAddress);
    uint first = mesh.firstIndex + 3u * uint(gl_PrimitiveID);
    uvec3 tri = uvec3(indices.i[first], indices.i[first + 1u], indices.i[first + 2u]) + mesh.vertexOffset;
    vec3 w = vec3(1.0 - bary.x - bary.y, bary.x, bary.y);
    vec2 uv = uvs.t[tri.x] * w.x + uvs.t[tri.y] * w.y + uvs.t[tri.z] * w.z;
    vec3 p = positions.p[tri.x] * w.x + positions.p[tri.y] * w.y + positions.p[tri.z] * w.z;
    ShadeMaterial mat = Materials(scene.materialAddress).m[mesh.materialIndex];
    vec3 color = mat.baseColorFactor.rgb + vec3(0.25);
    if (mat.baseColorTexture > -1) {
        uint txtId = uint(mat.baseColorTexture) + mesh.textureOffset;
        // The UVs spread over the texture: a read of another texel changes the colour.
        vec2 st = fract(uv + bary + p.xy * 0.01);
        color *= textureLod(textureSamplers[nonuniformEXT(txtId)], st, 0.0).rgb;
    }
    shade.color = color;
    shade.dist = gl_HitTEXT;
    shade.instance = uint(gl_InstanceCustomIndexEXT);
}
