// Shared by the user-shader tests' pipelines (written for rtprobe's tests, engine-like): the
// raygen's own payload, an orthographic camera over the harness scene, and a tone map.
#ifndef USER_COMMON_GLSL
#define USER_COMMON_GLSL
struct Shade {
    vec3 color;
    float dist;
    uint instance;
    uint bounces;
};

const float T_MIN = 0.001;
const float T_MAX = 100.0;
const vec3 VIEW_DIR = vec3(0.0, 0.0, 1.0);

vec3 viewOrigin(uvec2 pixel, uvec2 size) {
    vec2 uv = (vec2(pixel) + 0.5) / vec2(size);
    return vec3(-6.0 + uv.x * 12.0, 6.0 - uv.y * 12.0, -10.0);
}

vec3 toneMap(vec3 c) {
    return c / (c + vec3(1.0));
}
#endif
