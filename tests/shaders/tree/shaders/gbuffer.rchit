#version 460
// An engine closest-hit shader split over several files, as engines ship them: bindings and
// vertex layout in the engine's include tree (-I engine/include), a local helper next to it,
// and the material table size from a define (-D MAX_MATERIALS=...).
#extension GL_EXT_ray_tracing : require
#extension GL_GOOGLE_include_directive : require

#include <render/bindings.glsl>
#include "local_shading.glsl"

layout(location = 0) rayPayloadInEXT vec4 color;
hitAttributeEXT vec2 bary;

void main() {
    uint mesh = gl_InstanceCustomIndexEXT;
    vec2 uv = interpolateUv(mesh, gl_PrimitiveID, bary);
    color = shade(materials.albedoTexture[mesh % MAX_MATERIALS], uv);
}
