#version 460
// A closest-hit shading in half precision, as engines do to save registers and bandwidth: its
// material tints are 16-bit floats in a storage buffer (16-bit storage), the arithmetic is
// float16_t (the Float16 capability), and the result is widened for the payload.
#extension GL_EXT_ray_tracing : require
#extension GL_EXT_shader_explicit_arithmetic_types_float16 : require
#extension GL_EXT_shader_16bit_storage : require
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(set = 1, binding = 0) readonly buffer Tints { f16vec4 tint[]; } tints;

layout(location = 0) rayPayloadInEXT Shade shade;
hitAttributeEXT vec2 bary;

void main() {
    f16vec4 t = tints.tint[gl_InstanceCustomIndexEXT & 7];
    f16vec3 b = f16vec3(float16_t(bary.x), float16_t(bary.y), float16_t(1.0 - bary.x - bary.y));
    f16vec3 c = b * t.rgb * float16_t(0.5) + t.a * float16_t(0.25);
    shade.color = vec3(c);
    shade.dist = gl_HitTEXT;
    shade.instance = uint(gl_InstanceCustomIndexEXT);
}
