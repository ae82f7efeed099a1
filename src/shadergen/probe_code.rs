//! The probed read itself: declarations of the probed descriptor array (binding 2) or AS address
//! table, and a body that defines `probeSlot` and `probeValue`. The index expression is written
//! straight into the access, so the SPIR-V keeps its shape: a literal stays an `OpConstant`, a
//! spec constant an `OpSpecConstant`, a push constant a load from the push block, a dynamic index
//! the stage's runtime value (with `nonuniformEXT` when the cell says so). `heap_access=direct`
//! cells declare the array `layout(descriptor_heap)` instead of at binding 2 (the shader's index
//! is then the heap index; see `exec::heap`), sampled images as a texture heap and a sampler heap.
use crate::matrix::{AsAccess, Cell, HeapAccess, IndexSource, Resource, Stage};
use crate::probe;

pub struct ProbeCode {
    pub extensions: Vec<&'static str>,
    pub decls: String,
    /// Statements (indented) that define `uint probeSlot` and `vec4 probeValue`; expect `px`.
    pub body: String,
    pub uses_binding: bool,
    /// The AS probe traces with traceRayEXT (payload location 1, miss index 1).
    pub traces: bool,
    /// The AS probe uses a ray query.
    pub ray_query: bool,
}

fn index_expr(cell: &Cell) -> String {
    match cell.index {
        IndexSource::Literal => format!("{}u", probe::LITERAL_SLOT),
        IndexSource::SpecConstant => "SPEC_SLOT".into(),
        IndexSource::PushConstant => "pc.pushSlot".into(),
        IndexSource::Dynamic => match cell.stage {
            Stage::ClosestHit | Stage::AnyHit | Stage::Intersection => "(pc.dynBase + uint(gl_InstanceCustomIndexEXT))".into(),
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
        let heap = cell.heap_access == Some(HeapAccess::Direct);
        if heap {
            extensions.push(super::glslang::HEAP_EXTENSION);
        }
        // The probed array's declaration: at binding 2, or read straight from the heap.
        let array = |binding: &str, direct: &str| if heap { direct.to_string() } else { binding.to_string() };
        let mut decls = String::new();
        if cell.index == IndexSource::SpecConstant {
            decls += "layout(constant_id = 0) const uint SPEC_SLOT = 0u;\n";
        }
        let mut body = format!("    uint probeSlot = {idx};\n");
        let (mut traces, mut ray_query, mut uses_binding) = (false, false, true);
        let read = match cell.resource {
            Resource::StorageBuffer => {
                decls += &array(
                    "layout(set = 0, binding = 2, std430) readonly buffer ProbeBuffer { vec4 v[]; } probeBuf[];\n",
                    "layout(descriptor_heap, std430) readonly buffer ProbeBuffer { vec4 v[]; } probeBuf[];\n",
                );
                format!("probeBuf[{sub}].v[0]")
            }
            Resource::UniformBuffer => {
                decls += &array(
                    "layout(set = 0, binding = 2, std140) uniform ProbeUniform { vec4 v; } probeUbo[];\n",
                    "layout(descriptor_heap, std140) uniform ProbeUniform { vec4 v; } probeUbo[];\n",
                );
                format!("probeUbo[{sub}].v")
            }
            Resource::SampledImage => {
                if heap {
                    decls += "layout(descriptor_heap) uniform texture2D probeTex[];\nlayout(descriptor_heap) uniform sampler probeSampler[];\n";
                    format!("textureLod(sampler2D(probeTex[{sub}], probeSampler[0]), vec2(0.5), 0.0)")
                } else {
                    decls += "layout(set = 0, binding = 2) uniform sampler2D probeTex[];\n";
                    format!("textureLod(probeTex[{sub}], vec2(0.5), 0.0)")
                }
            }
            Resource::StorageImage => {
                decls += &array(
                    "layout(set = 0, binding = 2, rgba32f) uniform readonly image2D probeImg[];\n",
                    "layout(descriptor_heap, rgba32f) uniform readonly image2D probeImg[];\n",
                );
                format!("imageLoad(probeImg[{sub}], ivec2(0, 0))")
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
                    decls += "layout(location = 1) rayPayloadEXT uint probeHit;\n";
                    body += &format!(
                        "    probeHit = 1u;\n    traceRayEXT({as_expr}, gl_RayFlagsOpaqueEXT | gl_RayFlagsTerminateOnFirstHitEXT | gl_RayFlagsSkipClosestHitShaderEXT, 0xFF, 0, 0, 1, primaryOrigin(px), TMIN, vec3(0.0, 0.0, 1.0), TMAX, 1);\n    \
vec4 probeValue = vec4(float(probeHit), 0.0, 0.0, 1.0);\n"
                    );
                } else {
                    ray_query = true;
                    extensions.push("GL_EXT_ray_query");
                    body += &format!(
                        "    rayQueryEXT rq;\n    rayQueryInitializeEXT(rq, {as_expr}, gl_RayFlagsOpaqueEXT | gl_RayFlagsTerminateOnFirstHitEXT, 0xFF, primaryOrigin(px), TMIN, vec3(0.0, 0.0, 1.0), TMAX);\n    \
while (rayQueryProceedEXT(rq)) {{\n        if (rayQueryGetIntersectionTypeEXT(rq, false) == gl_RayQueryCandidateIntersectionAABBEXT) {{\n            float st;\n            \
if (sphereHit(rayQueryGetIntersectionObjectRayOriginEXT(rq, false), rayQueryGetIntersectionObjectRayDirectionEXT(rq, false), TMIN, TMAX, st))\n                rayQueryGenerateIntersectionEXT(rq, st);\n        }}\n    }}\n    \
vec4 probeValue = vec4(rayQueryGetIntersectionTypeEXT(rq, true) != gl_RayQueryCommittedIntersectionNoneEXT ? 1.0 : 0.0, 0.0, 0.0, 1.0);\n"
                    );
                }
                return ProbeCode { extensions, decls, body, uses_binding, traces, ray_query };
            }
        };
        body += &format!("    vec4 probeValue = {read};\n");
        ProbeCode { extensions, decls, body, uses_binding, traces, ray_query }
    }
}
