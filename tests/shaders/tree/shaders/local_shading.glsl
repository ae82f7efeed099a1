// Next to the shader: found through the including file's own directory.
#ifndef LOCAL_SHADING_GLSL
#define LOCAL_SHADING_GLSL
#include "render/vertex.glsl"

vec2 interpolateUv(uint mesh, int prim, vec2 b) {
    Vertex a = meshVertices[mesh].v[prim * 3 + 0];
    Vertex c1 = meshVertices[mesh].v[prim * 3 + 1];
    Vertex c2 = meshVertices[mesh].v[prim * 3 + 2];
    return a.uv * (1.0 - b.x - b.y) + c1.uv * b.x + c2.uv * b.y;
}

vec4 shade(uint materialIndex, vec2 uv) {
#ifdef DEBUG_UV
    return vec4(uv, 0.0, 1.0);
#else
    return textureLod(textures[materialIndex], uv, 0.0);
#endif
}
#endif
