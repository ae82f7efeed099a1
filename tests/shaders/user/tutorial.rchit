#version 460
// A closest-hit in the style of the glTF ray tracing tutorial (written for rtprobe's tests): one
// BLAS per primitive, the custom index the primitive's global index. The scene description's
// device address comes in a push constant; it holds the addresses of the shared position,
// normal, UV, index, material and per-primitive buffers. `PrimMeshInfo[gl_InstanceCustomIndexEXT]`
// gives the primitive's offsets and material. Shading: Lambert of the interpolated world-space
// normal from a fixed light plus an ambient term, times the base colour factor, times a term of
// the hit's world-space position interpolated from the position buffer (so positions are checked
// by the image), times 0.9 for a textured material, plus the emissive factor.
// Twins, each wrong where a real shader goes wrong:
// `-D WRONG_PRIM_ZERO`: the table's entry 0 whatever the hit (the custom index ignored).
// `-D WRONG_POSITIONS`: positions read without the primitive's vertexOffset.
// `-D ENGINE_STYLE`: the entry `customIndex + gl_GeometryIndexEXT`, as engines with
// multi-geometry BLASes index it (the same entry here: the geometry index is 0).
// `-D TEXTURED`: the base colour factor also times the material's base colour texture, sampled at
// the interpolated UV from the scene's texture array (`--fill 1.2=scene.textures`, element = the
// texture index the material holds); `textureLod` at LOD 0, as ray tracing stages have no
// implicit derivatives. `-D WRONG_TEX` (with TEXTURED): the texture one element past the material's.
#extension GL_EXT_ray_tracing : require
#extension GL_EXT_buffer_reference2 : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#extension GL_EXT_scalar_block_layout : require
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"
#ifdef TEXTURED
#extension GL_EXT_nonuniform_qualifier : require
layout(set = 1, binding = 2) uniform sampler2D textures[];
#endif

struct PrimMeshInfo {
    uint indexOffset;
    uint vertexOffset;
    int materialIndex;
};

struct GltfShadeMaterial {
    vec4 pbrBaseColorFactor;
    vec3 emissiveFactor;
    int pbrBaseColorTexture;
};

layout(buffer_reference, scalar) readonly buffer Vertices { vec3 v[]; };
layout(buffer_reference, scalar) readonly buffer Uvs { vec2 u[]; };
layout(buffer_reference, scalar) readonly buffer Indices { uint i[]; };
layout(buffer_reference, scalar) readonly buffer Materials { GltfShadeMaterial m[]; };
layout(buffer_reference, scalar) readonly buffer PrimInfos { PrimMeshInfo p[]; };
layout(buffer_reference, scalar) readonly buffer SceneDesc {
    uint64_t vertexAddress;
    uint64_t normalAddress;
    uint64_t uvAddress;
    uint64_t indexAddress;
    uint64_t materialAddress;
    uint64_t primInfoAddress;
};

layout(push_constant) uniform Constants {
    vec4 lightDirection; // unused by the harness: the light is fixed below
    uint64_t sceneDesc;
} pc;

#ifdef DESC_BINDING
// `-D DESC_BINDING`: the scene description in a storage buffer binding, and the normals read
// from a binding of their own instead of through its address.
layout(set = 1, binding = 0, scalar) readonly buffer SceneDescBlock {
    uint64_t vertexAddress;
    uint64_t normalAddress;
    uint64_t uvAddress;
    uint64_t indexAddress;
    uint64_t materialAddress;
    uint64_t primInfoAddress;
} descBlock;
layout(set = 1, binding = 1, scalar) readonly buffer NormalBlock { vec3 v[]; } normalBlock;
#endif

layout(location = 0) rayPayloadInEXT Shade shade;
hitAttributeEXT vec2 bary;

const vec3 LIGHT = vec3(0.48, 0.64, -0.6);
const float AMBIENT = 0.2;

vec3 normalAt(uint k, uint64_t normalAddress) {
#ifdef DESC_BINDING
    return normalBlock.v[k];
#else
    return Vertices(normalAddress).v[k];
#endif
}

void main() {
#ifdef DESC_BINDING
    uint64_t vertexAddress = descBlock.vertexAddress;
    uint64_t normalAddress = descBlock.normalAddress;
    uint64_t indexAddress = descBlock.indexAddress;
    uint64_t materialAddress = descBlock.materialAddress;
    uint64_t primInfoAddress = descBlock.primInfoAddress;
    uint64_t uvAddress = descBlock.uvAddress;
#else
    SceneDesc desc = SceneDesc(pc.sceneDesc);
    uint64_t vertexAddress = desc.vertexAddress;
    uint64_t normalAddress = desc.normalAddress;
    uint64_t indexAddress = desc.indexAddress;
    uint64_t materialAddress = desc.materialAddress;
    uint64_t primInfoAddress = desc.primInfoAddress;
    uint64_t uvAddress = desc.uvAddress;
#endif
    PrimInfos infos = PrimInfos(primInfoAddress);
#if defined(WRONG_PRIM_ZERO)
    PrimMeshInfo prim = infos.p[0];
#elif defined(ENGINE_STYLE)
    PrimMeshInfo prim = infos.p[gl_InstanceCustomIndexEXT + gl_GeometryIndexEXT];
#else
    PrimMeshInfo prim = infos.p[gl_InstanceCustomIndexEXT];
#endif
    Indices indices = Indices(indexAddress);
    uint base = prim.indexOffset + 3u * uint(gl_PrimitiveID);
    uvec3 local = uvec3(indices.i[base], indices.i[base + 1u], indices.i[base + 2u]);
    uvec3 tri = local + prim.vertexOffset;
    vec3 w = vec3(1.0 - bary.x - bary.y, bary.x, bary.y);
    vec3 n = normalAt(tri.x, normalAddress) * w.x + normalAt(tri.y, normalAddress) * w.y
        + normalAt(tri.z, normalAddress) * w.z;
    vec3 worldN = normalize(vec3(n * gl_WorldToObjectEXT));
#ifdef WRONG_POSITIONS
    uvec3 at = local;
#else
    uvec3 at = tri;
#endif
    Vertices positions = Vertices(vertexAddress);
    vec3 p = positions.v[at.x] * w.x + positions.v[at.y] * w.y + positions.v[at.z] * w.z;
    vec3 worldP = gl_ObjectToWorldEXT * vec4(p, 1.0);
    float place = 0.8 + 0.2 * sin(1.7 * worldP.x + 1.1 * worldP.y);
    GltfShadeMaterial mat = Materials(materialAddress).m[prim.materialIndex];
    float textured = mat.pbrBaseColorTexture >= 0 ? 0.9 : 1.0;
    float lambert = max(dot(worldN, normalize(LIGHT)), 0.0);
    vec3 albedo = mat.pbrBaseColorFactor.rgb;
#ifdef TEXTURED
    int tex = mat.pbrBaseColorTexture;
    if (tex >= 0) {
#ifdef WRONG_TEX
        tex += 1;
#endif
        Uvs uvs = Uvs(uvAddress);
        vec2 uv = uvs.u[tri.x] * w.x + uvs.u[tri.y] * w.y + uvs.u[tri.z] * w.z;
        albedo *= textureLod(textures[nonuniformEXT(tex)], uv, 0.0).rgb;
    }
#endif
    shade.color = albedo * (AMBIENT + (1.0 - AMBIENT) * lambert) * place * textured
        + mat.emissiveFactor;
    shade.dist = gl_HitTEXT;
    shade.instance = uint(gl_InstanceCustomIndexEXT);
}
