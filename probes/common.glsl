// rtprobe probe contract, included in every generated probe shader after the declarations that
// src/probe.rs generates (struct Record, the Records buffer, the push constants, ELEMENTS,
// PROBE_DIR, emptyRecord(), probeRecord()). The functions here mirror functions of src/probe.rs
// and src/scene (named in each comment); edit both sides together.

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

// The element a probe reads outside hit stages, as probe::element.
uint pixelElement(uvec2 p) {
    return ((p.x >> 1u) ^ p.y) & (ELEMENTS - 1u);
}

// The element a probe reads in hit stages, as probe::element.
uint hitElement(uint instanceId, uint geometry, uint primitive) {
    return (primitive + geometry + instanceId) & (ELEMENTS - 1u);
}

// The AS probe's value, as probe::as_value.
vec4 asProbeValue(bool hit, uint custom) {
    return vec4(hit ? float(custom + 1u) : 0.0, 0.0, 0.0, 1.0);
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
