#version 460
// The bindless textured closest-hit with separate images and one sampler: an unbounded
// texture2D array combined at the lookup with a sampler of its own binding, as engines that
// share a few samplers across every texture declare them.
#extension GL_EXT_ray_tracing : require
#extension GL_EXT_nonuniform_qualifier : require
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

struct Material {
    vec4 tint;
    uint normalMap;
    uint flags;
    vec2 pad;
};

layout(set = 1, binding = 0) readonly buffer Materials { Material m[]; } materials[];
layout(set = 1, binding = 1) uniform texture2D textures[];
layout(set = 1, binding = 2) uniform sampler linearClamp;
layout(push_constant) uniform Draw {
    uint materialBase;
    uint textureBase;
} draw;

layout(location = 0) rayPayloadInEXT Shade shade;
hitAttributeEXT vec2 bary;

vec4 fetch(uint index, vec2 uv) {
    return textureLod(sampler2D(textures[nonuniformEXT(index)], linearClamp), uv, 0.0);
}

void main() {
    uint mat = (draw.materialBase & 31u) + uint(gl_InstanceCustomIndexEXT);
    uint tex = (draw.textureBase & 31u) + uint(gl_InstanceCustomIndexEXT);
    Material m = materials[nonuniformEXT(mat)].m[gl_GeometryIndexEXT];
    vec2 uv = fract(bary * 0.97 + 0.01);
    vec4 base = fetch(tex, uv);
    // The normal map's index comes from the material (a small integer the harness fills).
    vec4 n = fetch(m.normalMap & 31u, uv.yx);
    shade.color = base.rgb * m.tint.rgb + 0.05 * n.xyz;
    shade.dist = gl_HitTEXT;
    shade.instance = uint(gl_InstanceCustomIndexEXT);
}
