#version 460
// A closest-hit using a subgroup ballot (as engines group shading work by material): it checks
// that its own lane is in the ballot of the active lanes and shades by that, so the image is
// the same however the lanes are grouped.
#extension GL_EXT_ray_tracing : require
#extension GL_KHR_shader_subgroup_ballot : require
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(location = 0) rayPayloadInEXT Shade shade;
hitAttributeEXT vec2 bary;

void main() {
    uvec4 lanes = subgroupBallot(true);
    float me = subgroupBallotBitExtract(lanes, gl_SubgroupInvocationID) ? 1.0 : 0.0;
    shade.color = vec3(bary, me);
    shade.dist = gl_HitTEXT;
    shade.instance = uint(gl_InstanceCustomIndexEXT);
}
