// Vertex layout and interpolation, shared by every hit shader.
#ifndef RENDER_VERTEX_GLSL
#define RENDER_VERTEX_GLSL
struct Vertex { vec4 position; vec4 normal; vec2 uv; vec2 pad; };
#endif
