// rtprobe probe contract, included in every generated probe shader (see src/probe.rs for the
// CPU side: record layout, flags, slots, values). Edit both sides together.

struct Record {
    uint flags;     // 1 = primary ray hit, 2 = the probed stage ran
    uint instance;  // gl_InstanceCustomIndexEXT of the committed hit
    uint primitive; // gl_PrimitiveID
    float t;        // gl_HitTEXT
    vec2 bary;      // triangle barycentrics (weights of v1, v2)
    uint slot;      // descriptor slot the probe read
    uint pad;
    vec4 value;     // what the probe read
};

layout(set = 0, binding = 0, std430) buffer Records { Record records[]; };

layout(push_constant, std430) uniform PushConstants {
    uint width;
    uint height;
    uint pushSlot;    // index=push_constant
    uint dynBase;     // runtime base of index=dynamic in hit stages
    uint slotCount;   // size of the probed descriptor array
    uint loopForever; // canary.infinite_loop
    uvec2 asTable;    // device address of the TLAS address table (as_access=address)
    uvec2 badAddress; // canary.invalid_address
} pc;

const float VIEW_HALF = 6.0;
const float RAY_Z = -10.0;
const float TMIN = 0.001;
const float TMAX = 100.0;
const float SPHERE_R = 0.5;

// The orthographic primary ray of pixel p (direction +z), exactly as Scene::primary_ray.
vec3 primaryOrigin(uvec2 p) {
    float sx = (2.0 * VIEW_HALF) / float(pc.width);
    float sy = (2.0 * VIEW_HALF) / float(pc.height);
    return vec3(-VIEW_HALF + (float(p.x) + 0.5) * sx, VIEW_HALF - (float(p.y) + 0.5) * sy, RAY_Z);
}

// The procedural sphere in object space, as reference::intersect::sphere.
bool sphereHit(vec3 o, vec3 d, float tmin, float tmax, out float t) {
    float a = dot(d, d);
    float b = 2.0 * dot(o, d);
    float c = dot(o, o) - SPHERE_R * SPHERE_R;
    float disc = b * b - 4.0 * a * c;
    t = 0.0;
    if (disc < 0.0) return false;
    float s = sqrt(disc);
    float t0 = (-b - s) / (2.0 * a);
    float t1 = (-b + s) / (2.0 * a);
    if (t0 >= tmin && t0 <= tmax) { t = t0; return true; }
    if (t1 >= tmin && t1 <= tmax) { t = t1; return true; }
    return false;
}
