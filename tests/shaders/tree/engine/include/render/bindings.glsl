// Engine bindings: the vertex layout comes from a sibling header.
#ifndef RENDER_BINDINGS_GLSL
#define RENDER_BINDINGS_GLSL
#extension GL_EXT_nonuniform_qualifier : require
#include "vertex.glsl"

#ifndef MAX_MATERIALS
#error "MAX_MATERIALS must be defined (-D MAX_MATERIALS=N)"
#endif

layout(set = 1, binding = 0, std430) readonly buffer MeshVertices { Vertex v[]; } meshVertices[];
layout(set = 1, binding = 1) uniform sampler2D textures[];
layout(set = 0, binding = 3, std430) readonly buffer Materials { uint albedoTexture[MAX_MATERIALS]; } materials;
#endif
