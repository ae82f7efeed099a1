#version 460
// An engine's closest-hit that finds its texture through two tables: the instance's object
// record gives a material table and a texture offset, the material a texture id, and the
// texture is `textures[material.textureId + object.textureOffset]` — a sum of two values read
// from buffers, as renderers that append each mesh's textures to one bindless array index it.
// -D FIXED_TEXTURES=N declares the array with N elements; -D NO_NONUNIFORM drops nonuniformEXT.
#extension GL_EXT_ray_tracing : require
#extension GL_EXT_nonuniform_qualifier : require
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"
#include "scene_objects.glsl"

#ifdef NO_NONUNIFORM
#define NU(i) (i)
#else
#define NU(i) nonuniformEXT(i)
#endif

layout(set = 1, binding = 0, std430) readonly buffer Objects { ObjectRecord o[]; } objects;
layout(set = 1, binding = 1, std430) readonly buffer Materials { SurfaceMaterial m[]; } tables[];
#ifdef FIXED_TEXTURES
layout(set = 1, binding = 2) uniform sampler2D textures[FIXED_TEXTURES];
#else
layout(set = 1, binding = 2) uniform sampler2D textures[];
#endif

layout(location = 0) rayPayloadInEXT Shade shade;
hitAttributeEXT vec2 bary;

void main() {
    ObjectRecord obj = objects.o[gl_InstanceCustomIndexEXT];
    SurfaceMaterial mat = tables[NU(obj.materialTable)].m[gl_PrimitiveID & 15];
    uint tex = uint(mat.textureId + obj.textureOffset);
    vec4 albedo = textureLod(textures[NU(tex)], bary * obj.uvScale, 0.0);
    shade.color = mat.baseColor.rgb * albedo.rgb;
    shade.dist = gl_HitTEXT;
    shade.instance = uint(gl_InstanceCustomIndexEXT);
}
