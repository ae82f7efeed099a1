#version 460
// A bindless closest-hit: the material and the texture come from unbounded descriptor arrays
// indexed by a per-draw base (push constants) plus gl_InstanceCustomIndexEXT.
#extension GL_EXT_ray_tracing : require
#extension GL_EXT_nonuniform_qualifier : require
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

struct Material {
    vec4 albedo;
    vec4 emission;
};

layout(set = 1, binding = 0) readonly buffer Materials { Material m[]; } materials[];
layout(set = 1, binding = 1, rgba8) uniform readonly image2D textures[];
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
    ivec2 texel = ivec2(bary * 63.0);
    vec4 t = imageLoad(textures[nonuniformEXT(tex)], texel);
    shade.color = m.albedo.rgb * t.rgb + m.emission.rgb * 0.1;
    shade.dist = gl_HitTEXT;
    shade.instance = uint(gl_InstanceCustomIndexEXT);
}
