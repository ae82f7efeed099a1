//! The probed read itself: declarations of the probed descriptor array (binding 2) or AS address
//! table, and a body that defines `probeSlot`, `probeElement` and `probeValue`. Buffers and images
//! are read at element `probeElement` (per primitive in hit stages, per pixel elsewhere), not
//! always at 0. The AS probe traces a ray unlike the primary one (`PROBE_DIR`) and reads the
//! committed hit's custom index, which names the probe TLAS variant. The index expression is written
//! straight into the access, so the SPIR-V keeps its shape: a literal stays an `OpConstant`, a
//! spec constant an `OpSpecConstant`, a push constant a load from the push block, a dynamic index
//! the stage's runtime value (with `nonuniformEXT` when the cell says so).
use crate::matrix::{AsAccess, Cell, IndexSource, Resource, Stage};
use crate::probe;

pub struct ProbeCode {
    pub extensions: Vec<&'static str>,
    pub decls: String,
    /// Statements (indented) that define `uint probeSlot`, `uint probeElement` and `vec4
    /// probeValue`; expect `px`.
    pub body: String,
    pub uses_binding: bool,
    /// The AS probe traces with traceRayEXT (a `Record` payload at location 1, miss index 1, ray
    /// flag [`PROBE_RAY_FLAG`] so that the closest-hit shaders only report the custom index).
    pub traces: bool,
    /// The AS probe uses a ray query.
    pub ray_query: bool,
}

/// The ray flag that marks the AS probe's rays: every geometry is opaque, so culling non-opaque
/// geometry changes nothing, and closest-hit shaders read it from `gl_IncomingRayFlagsEXT`.
pub const PROBE_RAY_FLAG: &str = "gl_RayFlagsCullNoOpaqueEXT";

/// The element a buffer/image probe reads (`probe::element`).
fn element_expr(stage: Stage) -> &'static str {
    match stage {
        Stage::ClosestHit | Stage::AnyHit | Stage::Intersection => "hitElement(uint(gl_InstanceID), uint(gl_GeometryIndexEXT), uint(gl_PrimitiveID))",
        Stage::Raygen | Stage::Miss | Stage::Callable | Stage::Fragment | Stage::Compute => "pixelElement(px)",
    }
}

fn index_expr(cell: &Cell) -> String {
    match cell.index {
        IndexSource::Literal => format!("{}u", probe::LITERAL_SLOT),
        IndexSource::SpecConstant => "SPEC_SLOT".into(),
        IndexSource::PushConstant => "pc.pushSlot".into(),
        IndexSource::Dynamic => match cell.stage {
            Stage::ClosestHit | Stage::AnyHit | Stage::Intersection => "(pc.dynBase + (uint(gl_InstanceCustomIndexEXT) & pc.dynMask))".into(),
            Stage::Raygen | Stage::Miss | Stage::Callable => "((gl_LaunchIDEXT.x + gl_LaunchIDEXT.y * pc.width) % pc.slotCount)".into(),
            Stage::Fragment => "inSlot".into(),
            Stage::Compute => "((gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * pc.width) % pc.slotCount)".into(),
        },
    }
}

impl ProbeCode {
    /// No probe (canary carriers).
    pub fn none() -> Self {
        ProbeCode { extensions: vec![], decls: String::new(), body: String::new(), uses_binding: false, traces: false, ray_query: false }
    }

    pub fn new(cell: &Cell) -> Self {
        let idx = index_expr(cell);
        let sub = if cell.nonuniform { format!("nonuniformEXT({idx})") } else { idx.clone() };
        let mut extensions = vec!["GL_EXT_nonuniform_qualifier"];
        let mut decls = String::new();
        if cell.index == IndexSource::SpecConstant {
            decls += "layout(constant_id = 0) const uint SPEC_SLOT = 0u;\n";
        }
        let mut body = format!("    uint probeSlot = {idx};\n");
        let element = if cell.resource == Resource::AccelerationStructure { "0u" } else { element_expr(cell.stage) };
        body += &format!("    uint probeElement = {element};\n");
        let (mut traces, mut ray_query, mut uses_binding) = (false, false, true);
        let read = match cell.resource {
            Resource::StorageBuffer => {
                decls += "layout(set = 0, binding = 2, std430) readonly buffer ProbeBuffer { vec4 v[]; } probeBuf[];\n";
                format!("probeBuf[{sub}].v[probeElement]")
            }
            Resource::UniformBuffer => {
                decls += "layout(set = 0, binding = 2, std140) uniform ProbeUniform { vec4 v[ELEMENTS]; } probeUbo[];\n";
                format!("probeUbo[{sub}].v[probeElement]")
            }
            Resource::SampledImage => {
                decls += "layout(set = 0, binding = 2) uniform sampler2D probeTex[];\n";
                format!("textureLod(probeTex[{sub}], (vec2(uvec2(probeElement & 1u, probeElement >> 1u)) + 0.5) * 0.5, 0.0)")
            }
            Resource::StorageImage => {
                decls += "layout(set = 0, binding = 2, rgba32f) uniform readonly image2D probeImg[];\n";
                format!("imageLoad(probeImg[{sub}], ivec2(probeElement & 1u, probeElement >> 1u))")
            }
            Resource::AccelerationStructure => {
                let as_expr = if cell.as_access == Some(AsAccess::Address) {
                    uses_binding = false;
                    extensions.extend(["GL_EXT_buffer_reference", "GL_EXT_shader_explicit_arithmetic_types_int64"]);
                    decls += "layout(buffer_reference, std430, buffer_reference_align = 8) readonly buffer AsTable { uint64_t a[]; };\n";
                    format!("accelerationStructureEXT(AsTable(packUint2x32(pc.asTable)).a[{idx}])")
                } else {
                    decls += "layout(set = 0, binding = 2) uniform accelerationStructureEXT probeAs[];\n";
                    format!("probeAs[{sub}]")
                };
                if cell.stage.can_trace_ray() {
                    traces = true;
                    decls += "layout(location = 1) rayPayloadEXT Record probePl;\n";
                    body += &format!(
                        "    probePl = emptyRecord();\n    traceRayEXT({as_expr}, {PROBE_RAY_FLAG}, 0xFF, 0, 0, 1, primaryOrigin(px), TMIN, PROBE_DIR, TMAX, 1);\n    \
vec4 probeValue = asProbeValue(probePl.flags != 0u, probePl.custom);\n"
                    );
                } else {
                    ray_query = true;
                    extensions.push("GL_EXT_ray_query");
                    body += &format!(
                        "    rayQueryEXT rq;\n    rayQueryInitializeEXT(rq, {as_expr}, gl_RayFlagsOpaqueEXT, 0xFF, primaryOrigin(px), TMIN, PROBE_DIR, TMAX);\n    \
while (rayQueryProceedEXT(rq)) {{\n        if (rayQueryGetIntersectionTypeEXT(rq, false) == gl_RayQueryCandidateIntersectionAABBEXT) {{\n            \
float tmax = rayQueryGetIntersectionTypeEXT(rq, true) != gl_RayQueryCommittedIntersectionNoneEXT ? rayQueryGetIntersectionTEXT(rq, true) : TMAX;\n            float st;\n            \
if (sphereHit(rayQueryGetIntersectionObjectRayOriginEXT(rq, false), rayQueryGetIntersectionObjectRayDirectionEXT(rq, false), TMIN, tmax, st))\n                rayQueryGenerateIntersectionEXT(rq, st);\n        }}\n    }}\n    \
bool probeHit = rayQueryGetIntersectionTypeEXT(rq, true) != gl_RayQueryCommittedIntersectionNoneEXT;\n    \
vec4 probeValue = asProbeValue(probeHit, probeHit ? uint(rayQueryGetIntersectionInstanceCustomIndexEXT(rq, true)) : 0u);\n"
                    );
                }
                return ProbeCode { extensions, decls, body, uses_binding, traces, ray_query };
            }
        };
        body += &format!("    vec4 probeValue = {read};\n");
        ProbeCode { extensions, decls, body, uses_binding, traces, ray_query }
    }
}
