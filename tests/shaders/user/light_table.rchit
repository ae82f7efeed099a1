#version 460
// An engine's closest-hit that picks its light's shadow map from a light record: a fixed-size
// array of eight shadow maps indexed by a word read from a buffer, with no mask — the renderer
// trusts its light table. It writes the index it used, so a test can hold the descriptor-index
// check's figure to the index the pipeline itself read.
#extension GL_EXT_ray_tracing : require
#extension GL_EXT_nonuniform_qualifier : require
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"
#include "scene_objects.glsl"

struct LightRecord {
    int shadowMap;
    int flags;
    vec2 range;
    vec4 colorIntensity;
};

layout(set = 1, binding = 0, std430) readonly buffer Lights { LightRecord l[]; } lights;
layout(set = 1, binding = 1) uniform sampler2D shadowMaps[8];
layout(set = 1, binding = 2, std430) buffer Used { uint shadowMapIndex; } used;

layout(location = 0) rayPayloadInEXT Shade shade;
hitAttributeEXT vec2 bary;

void main() {
    LightRecord light = lights.l[0];
    uint k = uint(light.shadowMap);
    used.shadowMapIndex = k;
    float lit = textureLod(shadowMaps[k], bary, 0.0).r;
    shade.color = light.colorIntensity.rgb * lit;
    shade.dist = gl_HitTEXT;
    shade.instance = uint(gl_InstanceCustomIndexEXT);
}
