//! The probed read itself: declarations of the probed descriptor array (binding 2) or AS address
//! table, and a body that defines `probeSlot`, `probeElement` and `probeValue`. Buffers and images
//! are read at element `probeElement` (per primitive in hit stages, per pixel elsewhere), not
//! always at 0. The AS probe traces a ray unlike the primary one (`PROBE_DIR`) and reads the
//! committed hit's custom index, which names the probe TLAS variant. The index expression is written
//! straight into the access, so the SPIR-V keeps its shape: a literal stays an `OpConstant`, a
//! spec constant an `OpSpecConstant`, a push constant a load from the push block, a dynamic index
//! the stage's runtime value (with `nonuniformEXT` when the cell says so). `heap_access=direct`
//! cells declare the array `layout(descriptor_heap)` instead of at binding 2 (the shader's index
//! is then the heap index; see `exec::heap`), sampled images as a texture heap and a sampler heap.
//! `index=dynamic_element` (the recommended patterns) indexes the array with the spec constant and
//! puts the dynamic value inside the one descriptor: `v[packedElement(probeSlot, probeElement)]`
//! of a buffer, or the layer of a `sampler2DArray` / `texture2DArray`.
//! `base=shader_record|buffer` closest-hit cells read the dynamic index's base from the SBT shader
//! record (`probe::ShaderRecordData`) or from a per-instance buffer at `gl_InstanceID` through a
//! device address, instead of push data. Direct sampled-image cells sample with sampler
//! `probeSampler[s]` of the sampler heap at a shifted coordinate (`probe::SAMPLER_SHIFT`), `s` a
//! literal (`sampler=constant`) or the stage's runtime value modulo the samplers (`dynamic`).
use crate::model::{AsAccess, BaseSource, Cell, HeapAccess, IndexSource, Resource, SamplerIndex, Stage};
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

/// Where a hit stage's dynamic index takes its base from (`base` axis; push data by default).
fn base_expr(base: Option<BaseSource>) -> &'static str {
    match base {
        None => "pc.dynBase",
        Some(BaseSource::ShaderRecord) => "shaderRecord.dynBase",
        Some(BaseSource::Buffer) => "ProbeBases(pc.baseAddress).base[gl_InstanceID]",
    }
}

/// The stage's runtime slot value (`probe::dynamic_slot`).
fn dynamic_expr(cell: &Cell) -> String {
    match cell.stage {
        Stage::ClosestHit | Stage::AnyHit | Stage::Intersection => format!("({} + (uint(gl_InstanceCustomIndexEXT) & pc.dynMask))", base_expr(cell.base)),
        Stage::Raygen | Stage::Miss | Stage::Callable => "((gl_LaunchIDEXT.x + gl_LaunchIDEXT.y * pc.width) % pc.slotCount)".into(),
        Stage::Fragment => "inSlot".into(),
        Stage::Compute => "((gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * pc.width) % pc.slotCount)".into(),
    }
}

/// The declarations and extensions the cell's base needs.
fn base_decls(base: Option<BaseSource>, extensions: &mut Vec<&'static str>, decls: &mut String) {
    match base {
        None => {}
        Some(BaseSource::ShaderRecord) => *decls += &probe::glsl_shader_record(),
        Some(BaseSource::Buffer) => {
            extensions.extend(["GL_EXT_buffer_reference", "GL_EXT_buffer_reference_uvec2"]);
            *decls += "layout(buffer_reference, std430, buffer_reference_align = 4) readonly buffer ProbeBases { uint base[]; };\n";
        }
    }
}

/// The sampler heap index of a direct sampled-image probe (`sampler` axis), a dynamic one
/// qualified `nonuniformEXT` where [`Cell::sampler_nonuniform`] says so (checked as any element
/// otherwise, see `reference`).
fn sampler_expr(cell: &Cell) -> String {
    match cell.sampler {
        None | Some(SamplerIndex::Constant) => format!("{}u", probe::SAMPLER_LITERAL),
        Some(SamplerIndex::Dynamic) => {
            let s = format!("({} % {}u)", dynamic_expr(cell), probe::SAMPLER_MODES.len());
            if cell.sampler_nonuniform() {
                format!("nonuniformEXT({s})")
            } else {
                s
            }
        }
    }
}

/// The slot the probe records (`probeSlot`).
fn index_expr(cell: &Cell) -> String {
    match cell.index {
        IndexSource::Literal => format!("{}u", probe::LITERAL_SLOT),
        IndexSource::SpecConstant => "SPEC_SLOT".into(),
        IndexSource::PushConstant => "pc.pushSlot".into(),
        IndexSource::Dynamic | IndexSource::DynamicElement => dynamic_expr(cell),
    }
}

/// The descriptor array index: the recorded slot, except with `dynamic_element`, where the
/// descriptor is the packed one at the spec-constant slot and the slot selects inside it.
fn descriptor_expr(cell: &Cell, idx: &str) -> String {
    match cell.index {
        IndexSource::DynamicElement => "SPEC_SLOT".into(),
        IndexSource::Literal | IndexSource::SpecConstant | IndexSource::PushConstant | IndexSource::Dynamic => idx.into(),
    }
}

impl ProbeCode {
    /// No probe (canary carriers).
    pub fn none() -> Self {
        ProbeCode { extensions: vec![], decls: String::new(), body: String::new(), uses_binding: false, traces: false, ray_query: false }
    }

    pub fn new(cell: &Cell) -> Self {
        let idx = index_expr(cell);
        let desc = descriptor_expr(cell, &idx);
        let sub = if cell.nonuniform { format!("nonuniformEXT({desc})") } else { desc };
        let packed = cell.index == IndexSource::DynamicElement;
        let mut extensions = vec!["GL_EXT_nonuniform_qualifier"];
        let heap = cell.heap_access == Some(HeapAccess::Direct);
        if heap {
            extensions.push(super::glslang::HEAP_EXTENSION);
        }
        // The probed array's declaration: at binding 2, or read straight from the heap.
        let array = |binding: &str, direct: &str| if heap { direct.to_string() } else { binding.to_string() };
        let mut decls = String::new();
        if matches!(cell.index, IndexSource::SpecConstant | IndexSource::DynamicElement) {
            decls += "layout(constant_id = 0) const uint SPEC_SLOT = 0u;\n";
        }
        base_decls(cell.base, &mut extensions, &mut decls);
        let mut body = format!("    uint probeSlot = {idx};\n");
        let element = if cell.resource == Resource::AccelerationStructure { "0u" } else { element_expr(cell.stage) };
        body += &format!("    uint probeElement = {element};\n");
        let (mut traces, mut ray_query, mut uses_binding) = (false, false, true);
        let read = match cell.resource {
            Resource::StorageBuffer => {
                decls += &array(
                    "layout(set = 0, binding = 2, std430) readonly buffer ProbeBuffer { vec4 v[]; } probeBuf[];\n",
                    "layout(descriptor_heap, std430) readonly buffer ProbeBuffer { vec4 v[]; } probeBuf[];\n",
                );
                let at = if packed { "packedElement(probeSlot, probeElement)" } else { "probeElement" };
                format!("probeBuf[{sub}].v[{at}]")
            }
            Resource::UniformBuffer => {
                decls += &array(
                    "layout(set = 0, binding = 2, std140) uniform ProbeUniform { vec4 v[ELEMENTS]; } probeUbo[];\n",
                    "layout(descriptor_heap, std140) uniform ProbeUniform { vec4 v[ELEMENTS]; } probeUbo[];\n",
                );
                format!("probeUbo[{sub}].v[probeElement]")
            }
            Resource::SampledImage => {
                let xy = "(vec2(uvec2(probeElement & 1u, probeElement >> 1u)) + 0.5) * 0.5";
                // dynamic_element: an array texture, the slot its layer.
                let (dim, at) = if packed { ("2DArray", format!("vec3({xy}, float(probeSlot))")) } else { ("2D", xy.to_string()) };
                if heap {
                    // Separate texture and sampler heaps; the sampled coordinate shifted so that
                    // the sampler's address mode picks the texel (probe::sampled_element).
                    let [du, dv] = probe::SAMPLER_SHIFT;
                    let xy = format!("({xy} + vec2({du:?}, {dv:?}))");
                    let at = if packed { format!("vec3({xy}, float(probeSlot))") } else { xy };
                    decls += &format!("layout(descriptor_heap) uniform texture{dim} probeTex[];\nlayout(descriptor_heap) uniform sampler probeSampler[];\n");
                    format!("textureLod(sampler{dim}(probeTex[{sub}], probeSampler[{}]), {at}, 0.0)", sampler_expr(cell))
                } else {
                    decls += &format!("layout(set = 0, binding = 2) uniform sampler{dim} probeTex[];\n");
                    format!("textureLod(probeTex[{sub}], {at}, 0.0)")
                }
            }
            Resource::StorageImage => {
                decls += &array(
                    "layout(set = 0, binding = 2, rgba32f) uniform readonly image2D probeImg[];\n",
                    "layout(descriptor_heap, rgba32f) uniform readonly image2D probeImg[];\n",
                );
                format!("imageLoad(probeImg[{sub}], ivec2(probeElement & 1u, probeElement >> 1u))")
            }
            Resource::AccelerationStructure => {
                let as_expr = if cell.as_access == Some(AsAccess::Address) {
                    uses_binding = false;
                    extensions.extend(["GL_EXT_buffer_reference", "GL_EXT_shader_explicit_arithmetic_types_int64"]);
                    decls += "layout(buffer_reference, std430, buffer_reference_align = 8) readonly buffer AsTable { uint64_t a[]; };\n";
                    format!("accelerationStructureEXT(AsTable(packUint2x32(pc.asTable)).a[{idx}])")
                } else {
                    decls += &array(
                        "layout(set = 0, binding = 2) uniform accelerationStructureEXT probeAs[];\n",
                        "layout(descriptor_heap) uniform accelerationStructureEXT probeAs[];\n",
                    );
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
