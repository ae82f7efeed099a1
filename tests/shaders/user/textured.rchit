#version 460
// A bindless textured closest-hit: the material comes from an unbounded SSBO array and its
// albedo map from an unbounded array of combined image samplers, both indexed by a per-draw
// base (push constants) plus gl_InstanceCustomIndexEXT, non-uniform across the wave.
#extension GL_EXT_ray_tracing : require
#extension GL_EXT_nonuniform_qualifier : require
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

struct Material {
    vec4 tint;
    vec4 emission;
    vec2 uvScale;
    float roughness;
    float pad;
};

layout(set = 1, binding = 0) readonly buffer Materials { Material m[]; } materials[];
layout(set = 1, binding = 1) uniform sampler2D albedoMaps[];
layout(push_constant) uniform Draw {
    uint materialBase;
    uint textureBase;
} draw;

layout(location = 0) rayPayloadInEXT Shade shade;
hitAttributeEXT vec2 bary;

void main() {
    // The bases stay below half the arrays, custom indices below the other half.
    uint mat = (draw.materialBase & 31u) + uint(gl_InstanceCustomIndexEXT);
    uint tex = (draw.textureBase & 31u) + uint(gl_InstanceCustomIndexEXT);
    Material m = materials[nonuniformEXT(mat)].m[gl_GeometryIndexEXT];
    vec2 uv = fract(bary * 0.97 + 0.01);
    vec4 albedo = textureLod(albedoMaps[nonuniformEXT(tex)], uv, 0.0);
    shade.color = albedo.rgb * m.tint.rgb * albedo.a + m.emission.rgb * 0.1;
    shade.dist = gl_HitTEXT;
    shade.instance = uint(gl_InstanceCustomIndexEXT);
}
