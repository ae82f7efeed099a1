#version 460
#extension GL_EXT_ray_tracing : require
#extension GL_EXT_nonuniform_qualifier : require
#extension GL_KHR_shader_subgroup_ballot : require
// Generated from src/probe.rs (Record, PushConstants): do not edit by hand.
struct Record {
    uint flags; // offset 0
    uint custom; // offset 4
    uint instanceId; // offset 8
    uint geometry; // offset 12
    uint primitive; // offset 16
    float t; // offset 20
    vec2 bary; // offset 24
    uint slot; // offset 32
    uint element; // offset 36
    uint pad; // offset 40
    uint pad2; // offset 44
    vec4 value; // offset 48
    uint lane; // offset 64
    uint leader; // offset 68
    uint activeMask; // offset 72
    uint activeCount; // offset 76
};

layout(set = 0, binding = 0, std430) buffer Records { Record records[]; };

layout(push_constant, std430) uniform PushConstants {
    layout(offset = 0) uint width;
    layout(offset = 4) uint height;
    layout(offset = 8) uint pushSlot;
    layout(offset = 12) uint dynBase;
    layout(offset = 16) uint slotCount;
    layout(offset = 20) uint loopForever;
    layout(offset = 24) uint dynMask;
    layout(offset = 28) uint injectSalt;
    layout(offset = 32) uvec2 asTable;
    layout(offset = 40) uvec2 badAddress;
    layout(offset = 48) uvec2 baseAddress;
} pc;

const uint FLAG_HIT = 1u;
const uint FLAG_PROBE = 2u;
const uint FLAG_LANES = 4u;
const uint ELEMENTS = 4u;
uint packedElement(uint slot, uint element) { return slot * ELEMENTS + element; }
const vec3 PROBE_DIR = vec3(0.25, -0.125, 1.0);

Record emptyRecord() {
    return Record(0u, 0u, 0u, 0u, 0u, 0.0, vec2(0.0), 0u, 0u, 0u, 0u, vec4(0.0), 0u, 0u, 0u, 0u);
}

// A record of a stage that traced no ray (fragment, compute).
Record probeRecord(uint slot, uint element, vec4 value) {
    return Record(FLAG_PROBE, 0u, 0u, 0u, 0u, 0.0, vec2(0.0), slot, element, 0u, 0u, value, 0u, 0u, 0u, 0u);
}

// The probed stage's lane evidence into a record (probe::Record's lane words).
void setLanes(inout Record r, uint laneFlag, uvec4 lanes) {
    r.flags |= laneFlag;
    r.lane = lanes.x;
    r.leader = lanes.y;
    r.activeMask = lanes.z;
    r.activeCount = lanes.w;
}
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

// ---- probe declarations ----
layout(set = 0, binding = 2) uniform sampler2D probeTex[];
layout(location = 0) rayPayloadInEXT Record pl;
hitAttributeEXT vec2 bary;
void main() {
    pl.flags |= FLAG_HIT;
    pl.custom = uint(gl_InstanceCustomIndexEXT);
    pl.instanceId = uint(gl_InstanceID);
    pl.geometry = uint(gl_GeometryIndexEXT);
    pl.primitive = uint(gl_PrimitiveID);
    pl.t = gl_HitTEXT;
    pl.bary = bary;
    uvec2 px = gl_LaunchIDEXT.xy;
    uint probeSlot = 3u;
    uint probeElement = hitElement(uint(gl_InstanceID), uint(gl_GeometryIndexEXT), uint(gl_PrimitiveID));
    uvec4 probeBallot = subgroupBallot(true);
    uint probeLaneFlag = FLAG_LANES;
    uvec4 probeLanes = uvec4(gl_SubgroupInvocationID, subgroupBroadcastFirst(px.x + px.y * pc.width), probeBallot.x, subgroupBallotBitCount(probeBallot));
    vec4 probeValue = textureLod(probeTex[3u], (vec2(uvec2(probeElement & 1u, probeElement >> 1u)) + 0.5) * 0.5, 0.0);
    pl.flags |= FLAG_PROBE;
    pl.slot = probeSlot;
    pl.element = probeElement;
    pl.value = probeValue;
    setLanes(pl, probeLaneFlag, probeLanes);
}
