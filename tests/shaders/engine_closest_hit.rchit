#version 460
// An engine-like closest-hit shader: per-mesh vertex data in an SSBO array and per-material
// textures, both selected by the instance's custom index.
#extension GL_EXT_ray_tracing : require
#extension GL_EXT_nonuniform_qualifier : require

struct Vertex { vec4 position; vec4 normal; vec2 uv; vec2 pad; };
layout(set = 1, binding = 0, std430) readonly buffer MeshVertices { Vertex v[]; } meshVertices[];
layout(set = 1, binding = 1) uniform sampler2D textures[];
layout(set = 0, binding = 3, std430) readonly buffer Materials { uint albedoTexture[]; } materials;

layout(location = 0) rayPayloadInEXT vec4 color;
hitAttributeEXT vec2 bary;

void main() {
    uint mesh = gl_InstanceCustomIndexEXT;
    uint materialIndex = materials.albedoTexture[mesh];
    Vertex a = meshVertices[mesh].v[gl_PrimitiveID * 3 + 0];
    Vertex b = meshVertices[mesh].v[gl_PrimitiveID * 3 + 1];
    Vertex c = meshVertices[mesh].v[gl_PrimitiveID * 3 + 2];
    vec2 uv = a.uv * (1.0 - bary.x - bary.y) + b.uv * bary.x + c.uv * bary.y;
    color = textureLod(textures[materialIndex], uv, 0.0);
}
