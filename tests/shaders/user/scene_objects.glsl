// Shared by the user-shader tests' object-table pipelines (written for rtprobe's tests,
// engine-like): a per-instance object record naming its material base and texture offset, as
// a renderer that packs every mesh's materials into one table keeps it.
#ifndef USER_SCENE_OBJECTS_GLSL
#define USER_SCENE_OBJECTS_GLSL
struct ObjectRecord {
    int materialTable;
    int textureOffset;
    vec2 uvScale;
};

struct SurfaceMaterial {
    vec4 baseColor;
    int textureId;
    float roughness;
    vec2 pad;
};
#endif
