//! The probed read itself, written from the cell's probe spec (`probe::spec::ProbeSpec`):
//! declarations of the probed descriptor array (binding 2) or AS address table, and a body that
//! defines `probeSlot`, `probeElement` and `probeValue`. Buffers and images
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
//! Right before the read, the body measures the probed stage's lane evidence (`probeLaneFlag`,
//! `probeLanes`: `probe::lane_evidence_glsl`) where the cell is generated with it.
use crate::model::{Resource, SceneLayout, Stage};
use crate::probe;
use crate::probe::spec::{Access, ArrayAt, Base, ElementMap, ProbeSpec, Sampler, SlotSource};
use crate::scene::{layout, textures};

pub struct ProbeCode {
    pub extensions: Vec<&'static str>,
    pub decls: String,
    /// Statements (indented) that define `uint probeSlot`, `uint probeElement`, `uint
    /// probeLaneFlag`, `uvec4 probeLanes` and `vec4 probeValue`; expect `px`.
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
        Stage::ClosestHit | Stage::AnyHit | Stage::Intersection => {
            "hitElement(uint(gl_InstanceID), uint(gl_GeometryIndexEXT), uint(gl_PrimitiveID))"
        }
        Stage::Raygen | Stage::Miss | Stage::Callable | Stage::Fragment | Stage::Compute => {
            "pixelElement(px)"
        }
    }
}

/// Where a hit stage's dynamic value takes its base from (push data unless the spec says
/// otherwise).
fn base_expr(base: Base) -> &'static str {
    match base {
        Base::None | Base::PushData => "pc.dynBase",
        Base::ShaderRecord => "shaderRecord.dynBase",
        Base::InstanceBuffer => "ProbeBases(pc.baseAddress).base[gl_InstanceID]",
    }
}

/// The stage's runtime slot value (`probe::dynamic_slot`).
fn dynamic_expr(spec: &ProbeSpec) -> String {
    match spec.stage {
        Stage::ClosestHit | Stage::AnyHit | Stage::Intersection => {
            format!("({} + (uint(gl_InstanceCustomIndexEXT) & pc.dynMask))", base_expr(spec.base))
        }
        Stage::Raygen | Stage::Miss | Stage::Callable => {
            "((gl_LaunchIDEXT.x + gl_LaunchIDEXT.y * pc.width) % pc.slotCount)".into()
        }
        Stage::Fragment => "inSlot".into(),
        Stage::Compute => {
            "((gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * pc.width) % pc.slotCount)".into()
        }
    }
}

/// The declarations and extensions the spec's base needs.
fn base_decls(base: Base, extensions: &mut Vec<&'static str>, decls: &mut String) {
    match base {
        Base::None | Base::PushData => {}
        Base::ShaderRecord => *decls += &probe::glsl_shader_record(),
        Base::InstanceBuffer => {
            extensions.extend(["GL_EXT_buffer_reference", "GL_EXT_buffer_reference_uvec2"]);
            *decls += "layout(buffer_reference, std430, buffer_reference_align = 4) readonly buffer ProbeBases { uint base[]; };\n";
        }
    }
}

/// The sampler heap index of a direct sampled-image probe, a dynamic one qualified
/// `nonuniformEXT` where the spec says so (checked as any element otherwise, see `reference`).
fn sampler_expr(spec: &ProbeSpec) -> String {
    match spec.sampler {
        Sampler::None | Sampler::Constant => format!("{}u", probe::SAMPLER_LITERAL),
        Sampler::Dynamic { nonuniform } => {
            let s = format!("({} % {}u)", dynamic_expr(spec), probe::SAMPLER_MODES.len());
            if nonuniform {
                format!("nonuniformEXT({s})")
            } else {
                s
            }
        }
    }
}

/// The slot the probe records (`probeSlot`).
fn index_expr(spec: &ProbeSpec) -> String {
    match spec.slot {
        SlotSource::Literal => format!("{}u", probe::LITERAL_SLOT),
        SlotSource::SpecConstant => "SPEC_SLOT".into(),
        SlotSource::PushConstant => "pc.pushSlot".into(),
        SlotSource::Dynamic => dynamic_expr(spec),
    }
}

/// The descriptor array index: the recorded slot (qualified `nonuniformEXT` where the spec says
/// so), or the packed descriptor's spec-constant slot, the slot selecting inside it. An address
/// table has no descriptor index (the AS probe indexes the table with `idx`).
fn descriptor_expr(spec: &ProbeSpec, idx: &str) -> String {
    match spec.access {
        Access::Slot { nonuniform: true } => format!("nonuniformEXT({idx})"),
        Access::Slot { nonuniform: false } | Access::AddressTable => idx.into(),
        Access::Packed => "SPEC_SLOT".into(),
    }
}

/// The probed array's declaration: at binding 2, or read straight from the heap.
fn array_decl(array: ArrayAt, binding: &str, direct: &str) -> String {
    match array {
        ArrayAt::Binding => binding.to_string(),
        ArrayAt::Heap => direct.to_string(),
    }
}

/// The declaration and the read of a sampled-image probe: a 2D texture, or with the packed
/// descriptor an array texture whose layer is the slot; a combined image sampler at binding 2, or
/// from the heap a texture and a separate sampler, the coordinate shifted so that the sampler's
/// address mode picks the texel (`probe::sampled_element`).
fn sampled_image(spec: &ProbeSpec, sub: &str) -> (String, String) {
    let xy = "(vec2(uvec2(probeElement & 1u, probeElement >> 1u)) + 0.5) * 0.5";
    let layer = spec.element == ElementMap::Layer;
    let dim = if layer { "2DArray" } else { "2D" };
    let at = |xy: String| {
        if layer {
            format!("vec3({xy}, float(probeSlot))")
        } else {
            xy
        }
    };
    match spec.array {
        ArrayAt::Binding => (
            format!("layout(set = 0, binding = 2) uniform sampler{dim} probeTex[];\n"),
            format!("textureLod(probeTex[{sub}], {}, 0.0)", at(xy.to_string())),
        ),
        ArrayAt::Heap => {
            let [du, dv] = probe::SAMPLER_SHIFT;
            let decl = format!("layout(descriptor_heap) uniform texture{dim} probeTex[];\nlayout(descriptor_heap) uniform sampler probeSampler[];\n");
            let read = format!(
                "textureLod(sampler{dim}(probeTex[{sub}], probeSampler[{}]), {}, 0.0)",
                sampler_expr(spec),
                at(format!("({xy} + vec2({du:?}, {dv:?}))"))
            );
            (decl, read)
        }
    }
}

impl ProbeCode {
    /// No probe (canary carriers).
    pub fn none() -> Self {
        ProbeCode {
            extensions: vec![],
            decls: String::new(),
            body: probe::lane_evidence_glsl(false).into(),
            uses_binding: false,
            traces: false,
            ray_query: false,
        }
    }

    /// The probe `spec` describes, measuring its lane evidence where `lanes` (the device's
    /// subgroup ballot works in the probed stage, or the run forces it).
    pub fn new(spec: &ProbeSpec, lanes: bool) -> Self {
        if let Some(layout) = spec.layout {
            return Self::scene_layout(spec, layout, lanes);
        }
        let idx = index_expr(spec);
        let sub = descriptor_expr(spec, &idx);
        let mut extensions = vec!["GL_EXT_nonuniform_qualifier"];
        if lanes {
            extensions.push(probe::LANE_EXTENSION);
        }
        if spec.array == ArrayAt::Heap {
            extensions.push(super::glslang::HEAP_EXTENSION);
        }
        let mut decls = String::new();
        if spec.spec_constant() {
            decls += "layout(constant_id = 0) const uint SPEC_SLOT = 0u;\n";
        }
        base_decls(spec.base, &mut extensions, &mut decls);
        let element = match spec.element {
            ElementMap::None => "0u",
            ElementMap::Own | ElementMap::Packed | ElementMap::Layer => element_expr(spec.stage),
        };
        let body = format!(
            "    uint probeSlot = {idx};\n    uint probeElement = {element};\n{}",
            probe::lane_evidence_glsl(lanes)
        );
        let mut p = ProbeCode {
            extensions,
            decls,
            body,
            uses_binding: true,
            traces: false,
            ray_query: false,
        };
        let array = |binding: &str, direct: &str| array_decl(spec.array, binding, direct);
        match spec.resource {
            Resource::StorageBuffer => {
                let at = match spec.element {
                    ElementMap::Packed => "packedElement(probeSlot, probeElement)",
                    ElementMap::None | ElementMap::Own | ElementMap::Layer => "probeElement",
                };
                let decl = array(
                    "layout(set = 0, binding = 2, std430) readonly buffer ProbeBuffer { vec4 v[]; } probeBuf[];\n",
                    "layout(descriptor_heap, std430) readonly buffer ProbeBuffer { vec4 v[]; } probeBuf[];\n",
                );
                p.read(decl, format!("probeBuf[{sub}].v[{at}]"));
            }
            Resource::UniformBuffer => {
                let decl = array(
                    "layout(set = 0, binding = 2, std140) uniform ProbeUniform { vec4 v[ELEMENTS]; } probeUbo[];\n",
                    "layout(descriptor_heap, std140) uniform ProbeUniform { vec4 v[ELEMENTS]; } probeUbo[];\n",
                );
                p.read(decl, format!("probeUbo[{sub}].v[probeElement]"));
            }
            Resource::SampledImage => {
                let (decl, read) = sampled_image(spec, &sub);
                p.read(decl, read);
            }
            Resource::StorageImage => {
                let decl = array(
                    "layout(set = 0, binding = 2, rgba32f) uniform readonly image2D probeImg[];\n",
                    "layout(descriptor_heap, rgba32f) uniform readonly image2D probeImg[];\n",
                );
                p.read(
                    decl,
                    format!(
                        "imageLoad(probeImg[{sub}], ivec2(probeElement & 1u, probeElement >> 1u))"
                    ),
                );
            }
            Resource::AccelerationStructure => p.trace_as(spec, &idx, &sub),
        }
        p
    }

    /// A scene-layout closest-hit: the mesh slot from the custom index, the hit triangle fetched
    /// through the layout (`scene::layout`), its first index as `probeElement` (`probeTri` holds
    /// the other two for `LAYOUT_STORE`).
    fn scene_layout(spec: &ProbeSpec, layout: SceneLayout, lanes: bool) -> Self {
        let mut extensions = vec!["GL_EXT_nonuniform_qualifier"];
        if lanes {
            extensions.push(probe::LANE_EXTENSION);
        }
        let (decls, fetch, uses_binding) = match layout {
            SceneLayout::SharedBuffers if spec.layout_textures() => {
                extensions.extend(["GL_EXT_buffer_reference", "GL_EXT_buffer_reference_uvec2"]);
                let decls = format!("{}{}", layout::SHARED_DECLS, textures::DECLS);
                (decls, format!("{}{}", layout::SHARED_BODY, textures::BODY), true)
            }
            SceneLayout::SharedBuffers => {
                extensions.extend(["GL_EXT_buffer_reference", "GL_EXT_buffer_reference_uvec2"]);
                (layout::SHARED_DECLS.into(), layout::SHARED_BODY.to_string(), false)
            }
            SceneLayout::PerMesh if spec.layout_textures() => {
                // The material read through the mesh buffers (binding 3), its texture element
                // from the SceneDesc's material table, the texture from binding 2.
                extensions.extend(["GL_EXT_buffer_reference", "GL_EXT_buffer_reference_uvec2"]);
                let meshes = layout::per_mesh_decls(layout::TEXTURE_CELL_MESH_BINDING);
                let decls = format!("{}{meshes}{}", layout::SHARED_DECLS, textures::DECLS);
                let fetch = format!(
                    "    SceneDesc sceneDesc = SceneDesc(pc.sceneDesc);\n{}{}",
                    layout::per_mesh_body("nonuniformEXT(probeSlot)"),
                    textures::BODY
                );
                (decls, fetch, true)
            }
            SceneLayout::PerMesh => (
                layout::per_mesh_decls(2),
                layout::per_mesh_body(&descriptor_expr(spec, "probeSlot")),
                true,
            ),
        };
        let body = format!(
            "    uint probeSlot = {};\n{fetch}    uint probeElement = probeTri.x;\n{}",
            index_expr(spec),
            probe::lane_evidence_glsl(lanes)
        );
        ProbeCode { extensions, decls, body, uses_binding, traces: false, ray_query: false }
    }

    /// Declare the probed array (`decl`) and read `probeValue` as `value`.
    fn read(&mut self, decl: String, value: String) {
        self.decls += &decl;
        self.body += &format!("    vec4 probeValue = {value};\n");
    }

    /// The AS probe: the acceleration structure from the array or the address table, traced from
    /// the pixel's primary origin with traceRayEXT where the stage may, with a ray query elsewhere.
    fn trace_as(&mut self, spec: &ProbeSpec, idx: &str, sub: &str) {
        let as_expr = match spec.access {
            Access::AddressTable => {
                self.uses_binding = false;
                self.extensions.extend([
                    "GL_EXT_buffer_reference",
                    "GL_EXT_shader_explicit_arithmetic_types_int64",
                ]);
                self.decls += "layout(buffer_reference, std430, buffer_reference_align = 8) readonly buffer AsTable { uint64_t a[]; };\n";
                format!("accelerationStructureEXT(AsTable(packUint2x32(pc.asTable)).a[{idx}])")
            }
            Access::Slot { .. } | Access::Packed => {
                self.decls += &array_decl(
                    spec.array,
                    "layout(set = 0, binding = 2) uniform accelerationStructureEXT probeAs[];\n",
                    "layout(descriptor_heap) uniform accelerationStructureEXT probeAs[];\n",
                );
                format!("probeAs[{sub}]")
            }
        };
        if spec.stage.can_trace_ray() {
            self.traces = true;
            self.decls += "layout(location = 1) rayPayloadEXT Record probePl;\n";
            self.body += &format!(
                "    probePl = emptyRecord();\n    traceRayEXT({as_expr}, {PROBE_RAY_FLAG}, 0xFF, 0, 0, 1, primaryOrigin(px), TMIN, PROBE_DIR, TMAX, 1);\n    \
vec4 probeValue = asProbeValue(probePl.flags != 0u, probePl.custom);\n"
            );
        } else {
            self.ray_query = true;
            self.extensions.push("GL_EXT_ray_query");
            self.body += &format!(
                "    rayQueryEXT rq;\n    rayQueryInitializeEXT(rq, {as_expr}, gl_RayFlagsOpaqueEXT, 0xFF, primaryOrigin(px), TMIN, PROBE_DIR, TMAX);\n    \
while (rayQueryProceedEXT(rq)) {{\n        if (rayQueryGetIntersectionTypeEXT(rq, false) == gl_RayQueryCandidateIntersectionAABBEXT) {{\n            \
float tmax = rayQueryGetIntersectionTypeEXT(rq, true) != gl_RayQueryCommittedIntersectionNoneEXT ? rayQueryGetIntersectionTEXT(rq, true) : TMAX;\n            float st;\n            \
if (sphereHit(rayQueryGetIntersectionObjectRayOriginEXT(rq, false), rayQueryGetIntersectionObjectRayDirectionEXT(rq, false), TMIN, tmax, st))\n                rayQueryGenerateIntersectionEXT(rq, st);\n        }}\n    }}\n    \
bool probeHit = rayQueryGetIntersectionTypeEXT(rq, true) != gl_RayQueryCommittedIntersectionNoneEXT;\n    \
vec4 probeValue = asProbeValue(probeHit, probeHit ? uint(rayQueryGetIntersectionInstanceCustomIndexEXT(rq, true)) : 0u);\n"
            );
        }
    }
}
