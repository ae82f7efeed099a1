#version 460
// A closest-hit in the style of the glTF ray tracing tutorial: the scene description's device
// address comes in a push constant; it holds the addresses of the shared vertex, normal, index,
// material and per-primitive buffers. The mesh's header in `PrimMeshInfo` (by the custom index,
// the mesh's index) gives its first primitive's entry; `+ gl_GeometryIndexEXT` gives this one's
// offsets and material. Shading: the interpolated normal in world space, Lambert from a fixed
// light direction plus an ambient term, times the material's base colour factor.
// `-D WRONG_PRIM`: the per-primitive table indexed by the custom index alone (the header read as
// if it were the primitive's entry), as a tutorial with one BLAS per primitive would.
// `-D TEXTURED`: the base colour factor times the material's base colour texture, sampled at the
// interpolated UV from the scene's texture array (`--fill 1.2=scene.textures`, element = the
// image index the material holds); `textureLod` at LOD 0, as ray tracing stages have no implicit
// derivatives. `-D WRONG_TEX` (with TEXTURED): the texture one element past the material's.
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

struct GltfMaterial {
    vec4 baseColorFactor;
    int baseColorTexture;
    float alphaCutoff;
    uint alphaMode;
    uint pad;
};

layout(buffer_reference, scalar) readonly buffer Vertices { vec3 v[]; };
layout(buffer_reference, scalar) readonly buffer Uvs { vec2 u[]; };
layout(buffer_reference, scalar) readonly buffer Indices { uint i[]; };
layout(buffer_reference, scalar) readonly buffer Materials { GltfMaterial m[]; };
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
    uint64_t primInfoAddress = descBlock.primInfoAddress;
    uint64_t indexAddress = descBlock.indexAddress;
    uint64_t materialAddress = descBlock.materialAddress;
    uint64_t normalAddress = descBlock.normalAddress;
    uint64_t uvAddress = descBlock.uvAddress;
#else
    SceneDesc desc = SceneDesc(pc.sceneDesc);
    uint64_t primInfoAddress = desc.primInfoAddress;
    uint64_t indexAddress = desc.indexAddress;
    uint64_t materialAddress = desc.materialAddress;
    uint64_t normalAddress = desc.normalAddress;
    uint64_t uvAddress = desc.uvAddress;
#endif
    PrimInfos infos = PrimInfos(primInfoAddress);
#ifdef WRONG_PRIM
    PrimMeshInfo prim = infos.p[gl_InstanceCustomIndexEXT + gl_GeometryIndexEXT];
#else
    uint first = infos.p[gl_InstanceCustomIndexEXT].indexOffset;
    PrimMeshInfo prim = infos.p[first + uint(gl_GeometryIndexEXT)];
#endif
    Indices indices = Indices(indexAddress);
    uint base = prim.indexOffset + 3u * uint(gl_PrimitiveID);
    uvec3 tri = uvec3(indices.i[base], indices.i[base + 1u], indices.i[base + 2u]) + prim.vertexOffset;
    vec3 w = vec3(1.0 - bary.x - bary.y, bary.x, bary.y);
    vec3 n = normalAt(tri.x, normalAddress) * w.x + normalAt(tri.y, normalAddress) * w.y
        + normalAt(tri.z, normalAddress) * w.z;
    vec3 worldN = normalize(vec3(n * gl_WorldToObjectEXT));
    GltfMaterial mat = Materials(materialAddress).m[prim.materialIndex];
    float lambert = max(dot(worldN, normalize(LIGHT)), 0.0);
    vec3 albedo = mat.baseColorFactor.rgb;
#ifdef TEXTURED
    int tex = mat.baseColorTexture;
    if (tex >= 0) {
#ifdef WRONG_TEX
        tex += 1;
#endif
        Uvs uvs = Uvs(uvAddress);
        vec2 uv = uvs.u[tri.x] * w.x + uvs.u[tri.y] * w.y + uvs.u[tri.z] * w.z;
        albedo *= textureLod(textures[nonuniformEXT(tex)], uv, 0.0).rgb;
    }
#endif
    shade.color = albedo * (AMBIENT + (1.0 - AMBIENT) * lambert);
    shade.dist = gl_HitTEXT;
    shade.instance = uint(gl_InstanceCustomIndexEXT);
}
