//! Generates the GLSL of every shader a cell needs, from the cell's probe spec
//! (`probe::spec::ProbeSpec`): the probed stage reads the resource the way the spec says (slot,
//! descriptor or address table, element, base, sampler); every other stage stays trivial. The GLSL
//! is what is written before any SPIR-V workaround (`as_access=address_patched` is the descriptor
//! variant's, a `patch` cell its base cell's; the worker patches the SPIR-V after). Shared
//! declarations come from `probes/common.glsl`. [`compile`] turns sources into SPIR-V with
//! shaderc, caching by source.
pub mod compile;
pub mod disk_cache;
pub mod error;
pub mod glslang;
pub mod include;
mod inject;
pub mod preflight;
mod probe_code;
mod role;

use crate::model::{Canary, Cell, Reorder, Stage};
use crate::probe::spec::ProbeSpec;
use probe_code::ProbeCode;

pub use role::Role;

const COMMON: &str = include_str!("../../probes/common.glsl");

#[derive(Clone, Debug)]
pub struct ShaderSource {
    pub role: Role,
    pub glsl: String,
}

/// Which pipeline a cell runs in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PipelineKind {
    RayTracing,
    Graphics,
    Compute,
}

#[derive(Clone, Debug)]
pub struct CellShaders {
    pub kind: PipelineKind,
    pub shaders: Vec<ShaderSource>,
    /// `maxPipelineRayRecursionDepth` the pipeline needs.
    pub recursion_depth: u32,
    /// The probed array is bound at binding 2 (false when AS are reached by address).
    pub uses_probe_binding: bool,
    /// The scene TLAS is bound at binding 1 (ray tracing pipelines).
    pub uses_scene_tlas: bool,
    /// Uses ray queries.
    pub uses_ray_query: bool,
}

impl CellShaders {
    pub fn get(&self, role: Role) -> Option<&ShaderSource> {
        self.shaders.iter().find(|s| s.role == role)
    }
}

fn header(rt: bool, probe: Option<&ProbeCode>, extra_ext: &[&str]) -> String {
    let mut s = String::from("#version 460\n");
    if rt {
        s += "#extension GL_EXT_ray_tracing : require\n";
    }
    let mut exts: Vec<&str> = extra_ext.to_vec();
    if let Some(p) = probe {
        exts.extend(p.extensions.iter().copied());
    }
    exts.sort();
    exts.dedup();
    for e in exts {
        s += &format!("#extension {e} : require\n");
    }
    s += &crate::probe::glsl_declarations();
    s += COMMON;
    if let Some(p) = probe {
        s += "\n// ---- probe declarations ----\n";
        s += &p.decls;
    }
    s
}

/// Generate all shaders of `cell`, without lane evidence (what needs only their shape: the
/// resources a cell binds).
pub fn generate(cell: &Cell) -> CellShaders {
    generate_with(cell, None, false)
}

/// Generate all shaders of `cell` (as its probe spec says), with `fault` injected at the probed
/// read, and the probed stage's lane evidence (`probe::FLAG_LANES`) where `lanes`.
pub fn generate_with(
    cell: &Cell,
    fault: Option<crate::model::FaultKind>,
    lanes: bool,
) -> CellShaders {
    let mut shaders = generate_probe(cell, fault, lanes);
    copy_constant(&mut shaders, cell.copy);
    shaders
}

/// A `--cells-scale` copy's own constant in the first stage (raygen, vertex or compute): an
/// early return on an image width no run has (`0xFFFFFFFF - copy`), so the copy's SPIR-V, and
/// so its pipeline, differ from every other copy's while its records stay its base cell's.
fn copy_constant(shaders: &mut CellShaders, copy: u32) {
    if copy == 0 {
        return;
    }
    if let Some(first) = shaders.shaders.first_mut() {
        let line = format!("void main() {{\n    if (pc.width == {}u) return;\n", u32::MAX - copy);
        first.glsl = first.glsl.replacen("void main() {\n", &line, 1);
    }
}

fn generate_probe(cell: &Cell, fault: Option<crate::model::FaultKind>, lanes: bool) -> CellShaders {
    let spec = ProbeSpec::of(cell);
    if let Some(c) = spec.canary {
        return canary(c);
    }
    let mut probe = ProbeCode::new(&spec, lanes);
    if let Some(f) = fault {
        inject::apply(&mut probe, f);
    }
    let probe = probe;
    let here = |s: Stage| (spec.stage == s).then_some(&probe);
    match spec.stage {
        Stage::Fragment => {
            let vert = format!(
                "{}\nlayout(location = 0) flat out uint outSlot;\nconst vec2 corners[6] = vec2[](vec2(0, 0), vec2(1, 0), vec2(0, 1), vec2(1, 0), vec2(1, 1), vec2(0, 1));\n\
void main() {{\n    uint tilesX = pc.width / {t}u;\n    uint tile = uint(gl_InstanceIndex);\n    vec2 corner = (vec2(float(tile % tilesX), float(tile / tilesX)) + corners[gl_VertexIndex]) * {t}.0;\n    \
gl_Position = vec4(corner / vec2(float(pc.width), float(pc.height)) * 2.0 - 1.0, 0.0, 1.0);\n    outSlot = tile % pc.slotCount;\n}}\n",
                header(false, None, &[]),
                t = crate::probe::TILE
            );
            let frag = format!(
                "{}\nlayout(location = 0) flat in uint inSlot;\nlayout(location = 0) out vec4 color;\nvoid main() {{\n    uvec2 px = uvec2(gl_FragCoord.xy);\n    uint i = px.x + px.y * pc.width;\n{}    \
Record r = probeRecord(probeSlot, probeElement, probeValue);\n    setLanes(r, probeLaneFlag, probeLanes);\n    records[i] = r;\n    color = vec4(0.0);\n}}\n",
                header(false, Some(&probe), &[]),
                probe.body
            );
            CellShaders {
                kind: PipelineKind::Graphics,
                shaders: vec![
                    ShaderSource { role: Role::Vertex, glsl: vert },
                    ShaderSource { role: Role::Fragment, glsl: frag },
                ],
                recursion_depth: 0,
                uses_probe_binding: probe.uses_binding,
                uses_scene_tlas: false,
                uses_ray_query: probe.ray_query,
            }
        }
        Stage::Compute => {
            let comp = format!(
                "{}\nlayout(local_size_x = 8, local_size_y = 8) in;\nvoid main() {{\n    uvec2 px = gl_GlobalInvocationID.xy;\n    if (px.x >= pc.width || px.y >= pc.height) return;\n    uint i = px.x + px.y * pc.width;\n{}    \
Record r = probeRecord(probeSlot, probeElement, probeValue);\n    setLanes(r, probeLaneFlag, probeLanes);\n    records[i] = r;\n}}\n",
                header(false, Some(&probe), &[]),
                probe.body
            );
            CellShaders {
                kind: PipelineKind::Compute,
                shaders: vec![ShaderSource { role: Role::Compute, glsl: comp }],
                recursion_depth: 0,
                uses_probe_binding: probe.uses_binding,
                uses_scene_tlas: false,
                uses_ray_query: probe.ray_query,
            }
        }
        Stage::Raygen
        | Stage::ClosestHit
        | Stage::AnyHit
        | Stage::Miss
        | Stage::Intersection
        | Stage::Callable => ray_tracing(&spec, &probe, here),
    }
}

fn ray_flags(spec: &ProbeSpec) -> &'static str {
    if spec.stage == Stage::AnyHit {
        "gl_RayFlagsNoOpaqueEXT"
    } else {
        "gl_RayFlagsOpaqueEXT"
    }
}

/// The raygen's primary ray: `traceRayEXT`, or with a `reorder` value, the same ray traced into a
/// hit object, the invocations reordered (with the hit instance's custom index as coherence hint
/// for `reorder_hint`; misses get a hint of their own), then the hit object's closest-hit or miss
/// shader run — the same records, with invocations regrouped before the probed closest-hit read.
fn primary_trace(spec: &ProbeSpec) -> String {
    let args = format!(
        "sceneTlas, {}, 0xFF, 0, 0, 0, primaryOrigin(px), TMIN, vec3(0.0, 0.0, 1.0), TMAX, 0",
        ray_flags(spec)
    );
    let reorder = match spec.reorder {
        None => return format!("    traceRayEXT({args});\n"),
        Some(Reorder::Reorder) => "    reorderThreadNV(hitObj);\n".to_string(),
        Some(Reorder::ReorderHint) => "    uint hint = hitObjectIsHitNV(hitObj) ? uint(hitObjectGetInstanceCustomIndexNV(hitObj)) : 0xFFFFu;\n    \
reorderThreadNV(hitObj, hint, 16);\n"
            .to_string(),
    };
    format!("    hitObjectNV hitObj;\n    hitObjectTraceRayNV(hitObj, {args});\n{reorder}    hitObjectExecuteShaderNV(hitObj, 0);\n")
}

/// The probe's result copied into the payload (raygen, miss, closest-hit and any-hit probes).
const STORE: &str = "    pl.flags |= FLAG_PROBE;\n    pl.slot = probeSlot;\n    pl.element = probeElement;\n    pl.value = probeValue;\n    setLanes(pl, probeLaneFlag, probeLanes);\n";
/// A scene-layout probe's other two vertex indices (`probe::FLAG_LAYOUT`).
const LAYOUT_STORE: &str =
    "    pl.pad = probeTri.y;\n    pl.pad2 = probeTri.z;\n    pl.flags |= FLAG_LAYOUT;\n";
/// What a callable probe hands back to raygen.
const CALL_DATA: &str =
    "struct CallData { uint slot; uint element; uint laneFlag; uint p2; vec4 value; uvec4 lanes; };\n";
/// What an intersection probe hands to the procedural closest-hit shader, in the 32 bytes every
/// device allows (`maxRayHitAttributeSize` is at least 32): the element, lane, active count and
/// lane flag share `packed` (8 bits each; an element is below `ELEMENTS`, a lane below 128 and an
/// active count at most 128, the largest subgroup size).
const PROBE_ATTR: &str =
    "struct ProbeAttr { vec4 value; uint slot; uint packed; uint leader; uint mask; };\nhitAttributeEXT ProbeAttr attr;\n";

fn ray_tracing<'a>(
    spec: &ProbeSpec,
    probe: &'a ProbeCode,
    here: impl Fn(Stage) -> Option<&'a ProbeCode>,
) -> CellShaders {
    let mut shaders = vec![
        ShaderSource { role: Role::Raygen, glsl: raygen(spec, probe, here(Stage::Raygen)) },
        ShaderSource { role: Role::Miss, glsl: miss(probe, here(Stage::Miss)) },
    ];
    // miss 1: the AS probe ray's miss (its payload stays an empty record)
    let pmiss = format!("{}layout(location = 1) rayPayloadInEXT Record probePl;\nvoid main() {{\n    probePl.flags = 0u;\n}}\n", header(true, None, &[]));
    shaders.push(ShaderSource { role: Role::ProbeMiss, glsl: pmiss });
    let (tri, proc_) = closest_hits(spec, probe, here(Stage::ClosestHit));
    shaders.push(ShaderSource { role: Role::ClosestHitTriangles, glsl: tri });
    shaders.push(ShaderSource { role: Role::ClosestHitProcedural, glsl: proc_ });
    shaders.push(ShaderSource {
        role: Role::Intersection,
        glsl: intersection(probe, here(Stage::Intersection)),
    });
    if spec.stage == Stage::AnyHit {
        let mut ahit = header(true, Some(probe), &[]);
        ahit += "layout(location = 0) rayPayloadInEXT Record pl;\nvoid main() {\n    uvec2 px = gl_LaunchIDEXT.xy;\n";
        ahit += &probe.body;
        ahit += STORE;
        ahit += "}\n";
        shaders.push(ShaderSource { role: Role::AnyHit, glsl: ahit });
    }
    if spec.stage == Stage::Callable {
        let mut call = header(true, Some(probe), &[]);
        call += CALL_DATA;
        call += "layout(location = 2) callableDataInEXT CallData cd;\nvoid main() {\n    uvec2 px = gl_LaunchIDEXT.xy;\n";
        call += &probe.body;
        call += "    cd.slot = probeSlot;\n    cd.element = probeElement;\n    cd.value = probeValue;\n    cd.laneFlag = probeLaneFlag;\n    cd.lanes = probeLanes;\n}\n";
        shaders.push(ShaderSource { role: Role::Callable, glsl: call });
    }
    let traces_from_hit_or_miss =
        probe.traces && matches!(spec.stage, Stage::ClosestHit | Stage::Miss);
    CellShaders {
        kind: PipelineKind::RayTracing,
        shaders,
        recursion_depth: if traces_from_hit_or_miss { 2 } else { 1 },
        uses_probe_binding: probe.uses_binding,
        uses_scene_tlas: true,
        uses_ray_query: probe.ray_query,
    }
}

/// The raygen shader: the primary trace, then the probe when it runs here (`here`), or the
/// callable's, into the record of its pixel.
fn raygen(spec: &ProbeSpec, probe: &ProbeCode, here: Option<&ProbeCode>) -> String {
    let reorder_ext: &[&str] =
        if spec.reorder.is_some() { &["GL_NV_shader_invocation_reorder"] } else { &[] };
    let mut rgen = header(true, here, reorder_ext);
    rgen += "layout(set = 0, binding = 1) uniform accelerationStructureEXT sceneTlas;\nlayout(location = 0) rayPayloadEXT Record pl;\n";
    if spec.stage == Stage::Callable {
        rgen += CALL_DATA;
        rgen += "layout(location = 2) callableDataEXT CallData cd;\n";
    }
    rgen += "void main() {\n    uvec2 px = gl_LaunchIDEXT.xy;\n    uint i = px.x + px.y * pc.width;\n    pl = emptyRecord();\n";
    rgen += &primary_trace(spec);
    if here.is_some() {
        rgen += &probe.body;
        rgen += STORE;
    }
    if spec.stage == Stage::Callable {
        rgen += "    executeCallableEXT(0, 2);\n    pl.flags |= FLAG_PROBE;\n    pl.slot = cd.slot;\n    pl.element = cd.element;\n    pl.value = cd.value;\n    setLanes(pl, cd.laneFlag, cd.lanes);\n";
    }
    rgen += "    records[i] = pl;\n}\n";
    rgen
}

/// Miss shader 0 (the primary ray's), with the probe when it runs here.
fn miss(probe: &ProbeCode, here: Option<&ProbeCode>) -> String {
    let mut miss = header(true, here, &[]);
    miss += "layout(location = 0) rayPayloadInEXT Record pl;\nvoid main() {\n";
    if here.is_some() {
        miss += "    uvec2 px = gl_LaunchIDEXT.xy;\n";
        miss += &probe.body;
        miss += STORE;
    }
    miss += "}\n";
    miss
}

/// The triangle and procedural closest-hit shaders: the hit's record, then the probe when it runs
/// here (`chit_probe`); the procedural one takes an intersection probe's result from its attributes.
fn closest_hits(
    spec: &ProbeSpec,
    probe: &ProbeCode,
    chit_probe: Option<&ProbeCode>,
) -> (String, String) {
    // An AS probe ray (see probe_code::PROBE_RAY_FLAG) only wants the committed custom index.
    let probe_ray = if probe.traces {
        format!("    if ((gl_IncomingRayFlagsEXT & {}) != 0u) {{\n        pl.flags = FLAG_HIT;\n        pl.custom = uint(gl_InstanceCustomIndexEXT);\n        return;\n    }}\n", probe_code::PROBE_RAY_FLAG)
    } else {
        String::new()
    };
    let chit_common = "    pl.flags |= FLAG_HIT;\n    pl.custom = uint(gl_InstanceCustomIndexEXT);\n    pl.instanceId = uint(gl_InstanceID);\n    pl.geometry = uint(gl_GeometryIndexEXT);\n    pl.primitive = uint(gl_PrimitiveID);\n    pl.t = gl_HitTEXT;\n";
    // A scene-layout closest-hit fetches a triangle: the procedural group has none to fetch.
    let proc_probe = if spec.layout.is_some() { None } else { chit_probe };
    let chit_body = |extra: &str, here: Option<&ProbeCode>| {
        let mut b = String::new();
        b += "void main() {\n";
        b += &probe_ray;
        b += chit_common;
        b += extra;
        if here.is_some() {
            b += "    uvec2 px = gl_LaunchIDEXT.xy;\n";
            b += &probe.body;
            b += STORE;
            if spec.layout.is_some() {
                b += LAYOUT_STORE;
            }
        }
        b += "}\n";
        b
    };
    let mut tri = header(true, chit_probe, &[]);
    tri += "layout(location = 0) rayPayloadInEXT Record pl;\nhitAttributeEXT vec2 bary;\n";
    tri += &chit_body("    pl.bary = bary;\n", chit_probe);

    let mut proc_ = header(true, proc_probe, &[]);
    proc_ += "layout(location = 0) rayPayloadInEXT Record pl;\n";
    proc_ += PROBE_ATTR;
    let from_attr = if spec.stage == Stage::Intersection {
        "    pl.bary = vec2(0.0);\n    pl.flags |= FLAG_PROBE;\n    pl.slot = attr.slot;\n    pl.element = attr.packed & 0xffu;\n    pl.value = attr.value;\n    \
setLanes(pl, (attr.packed >> 24u) != 0u ? FLAG_LANES : 0u, uvec4((attr.packed >> 8u) & 0xffu, attr.leader, attr.mask, (attr.packed >> 16u) & 0xffu));\n"
    } else {
        "    pl.bary = vec2(0.0);\n"
    };
    proc_ += &chit_body(from_attr, proc_probe);
    (tri, proc_)
}

/// The sphere's intersection shader, with the probe when it runs here (its result goes to the
/// hit attributes).
fn intersection(probe: &ProbeCode, here: Option<&ProbeCode>) -> String {
    let mut rint = header(true, here, &[]);
    rint += PROBE_ATTR;
    rint += "void main() {\n    float t;\n    if (sphereHit(gl_ObjectRayOriginEXT, gl_ObjectRayDirectionEXT, gl_RayTminEXT, gl_RayTmaxEXT, t)) {\n";
    if here.is_some() {
        rint += "    uvec2 px = gl_LaunchIDEXT.xy;\n";
        rint += &probe.body;
        rint += "        attr.slot = probeSlot;\n        attr.value = probeValue;\n        \
attr.packed = (probeElement & 0xffu) | ((probeLanes.x & 0xffu) << 8u) | ((probeLanes.w & 0xffu) << 16u) | (probeLaneFlag != 0u ? 1u << 24u : 0u);\n        \
attr.leader = probeLanes.y;\n        attr.mask = probeLanes.z;\n";
    } else {
        rint += "        attr.slot = 0u;\n        attr.packed = 0u;\n        attr.leader = 0u;\n        attr.mask = 0u;\n        attr.value = vec4(0.0);\n";
    }
    rint += "        reportIntersectionEXT(t, 0u);\n    }\n}\n";
    rint
}

fn canary(c: Canary) -> CellShaders {
    let carrier = ProbeSpec::of(&Cell::canary(c));
    let mut shaders = ray_tracing(&carrier, &ProbeCode::none(), |_| None).shaders;
    let exts: &[&str] = match c {
        Canary::InvalidAddress => {
            &["GL_EXT_buffer_reference", "GL_EXT_shader_explicit_arithmetic_types_int64"]
        }
        Canary::InfiniteLoop => &[],
    };
    let mut rgen = header(true, None, exts);
    rgen += "layout(set = 0, binding = 1) uniform accelerationStructureEXT sceneTlas;\n";
    let body = match c {
        Canary::InvalidAddress => {
            rgen += "layout(buffer_reference, std430) readonly buffer Bad { vec4 v[]; };\n";
            "    Bad bad = Bad(packUint2x32(pc.badAddress));\n    vec4 v = bad.v[i * 4096u];\n    records[i] = probeRecord(0u, 0u, v);\n"
        }
        Canary::InfiniteLoop => {
            "    uint n = 0u;\n    while (pc.loopForever != 0u) {\n        n += 1u;\n        records[i].pad = n;\n    }\n    Record r = probeRecord(0u, 0u, vec4(0.0));\n    r.pad = n;\n    records[i] = r;\n"
        }
    };
    rgen += &format!("void main() {{\n    uvec2 px = gl_LaunchIDEXT.xy;\n    uint i = px.x + px.y * pc.width;\n{body}}}\n");
    shaders[0] = ShaderSource { role: Role::Raygen, glsl: rgen };
    CellShaders {
        kind: PipelineKind::RayTracing,
        shaders,
        recursion_depth: 1,
        uses_probe_binding: false,
        uses_scene_tlas: true,
        uses_ray_query: false,
    }
}

/// Push-constant offset of the table address the address patches add (the end of the probes'
/// own block, `probe::PushConstants`).
pub const PATCHED_TABLE_OFFSET: u32 = crate::probe::PATCHED_TABLE_OFFSET;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{AsAccess, DescriptorModel, IndexSource, Resource};

    fn reorder_cell(r: Option<Reorder>, resource: Resource) -> Cell {
        let as_access =
            (resource == Resource::AccelerationStructure).then_some(AsAccess::Descriptor);
        Cell {
            nonuniform: true,
            as_access,
            reorder: r,
            ..Cell::new(
                Stage::ClosestHit,
                resource,
                IndexSource::Dynamic,
                DescriptorModel::DescriptorIndexing,
            )
        }
    }

    /// The recommended patterns: the descriptor index is the spec constant, the dynamic value sits
    /// inside the descriptor (element of the buffer, layer of the array texture); valid SPIR-V.
    #[test]
    fn dynamic_element_cells_index_the_spec_slot_and_move_the_dynamic_value_inside() {
        let mut c = compile::Compiler::new().unwrap();
        for (resource, read) in [
            (Resource::StorageBuffer, "probeBuf[SPEC_SLOT].v[packedElement(probeSlot, probeElement)]"),
            (Resource::SampledImage, "textureLod(probeTex[SPEC_SLOT], vec3((vec2(uvec2(probeElement & 1u, probeElement >> 1u)) + 0.5) * 0.5, float(probeSlot)), 0.0)"),
        ] {
            for stage in [Stage::ClosestHit, Stage::Compute] {
                let cell = Cell::new(stage, resource, IndexSource::DynamicElement, DescriptorModel::DescriptorIndexing);
                let shaders = generate(&cell);
                let probed = shaders.shaders.iter().find(|s| s.glsl.contains("uint probeSlot")).unwrap();
                assert!(probed.glsl.contains(read) && probed.glsl.contains("layout(constant_id = 0) const uint SPEC_SLOT"), "{}", probed.glsl);
                assert!(probed.glsl.contains("uint probeSlot = (pc.dynBase + (uint(gl_InstanceCustomIndexEXT) & pc.dynMask))") == (stage == Stage::ClosestHit), "{}", probed.glsl);
                for s in &shaders.shaders {
                    let (words, _) = c.compile(s.role, &s.glsl).unwrap_or_else(|e| panic!("{:?}: {e}\n{}", s.role, s.glsl));
                    if let crate::patches::Validation::Invalid(m) = crate::patches::validate(&words) {
                        panic!("{:?}: {m}", s.role);
                    }
                }
            }
        }
    }

    /// `base=shader_record|buffer`: the closest-hit probe's base comes from the generated shader
    /// record block or the per-instance buffer, never from push data, and the shaders compile to
    /// valid SPIR-V (shaderc; the heap cells' direct GLSL is compiled by the root's glslang in the
    /// heap tests).
    #[test]
    fn base_cells_read_their_base_where_the_axis_says() {
        use crate::model::BaseSource;
        let mut c = compile::Compiler::new().unwrap();
        for resource in [Resource::StorageBuffer, Resource::SampledImage] {
            for base in [None, Some(BaseSource::ShaderRecord), Some(BaseSource::Buffer)] {
                let cell = Cell { base, ..reorder_cell(None, resource) };
                let shaders = generate(&cell);
                let chit = &shaders.get(Role::ClosestHitTriangles).unwrap().glsl;
                let want = match base {
                    None => "uint probeSlot = (pc.dynBase + (uint(gl_InstanceCustomIndexEXT) & pc.dynMask))",
                    Some(BaseSource::ShaderRecord) => "uint probeSlot = (shaderRecord.dynBase + (uint(gl_InstanceCustomIndexEXT) & pc.dynMask))",
                    Some(BaseSource::Buffer) => "uint probeSlot = (ProbeBases(pc.baseAddress).base[gl_InstanceID] + (uint(gl_InstanceCustomIndexEXT) & pc.dynMask))",
                };
                assert!(chit.contains(want), "{chit}");
                assert_eq!(
                    chit.contains("layout(shaderRecordEXT, std430) buffer ShaderRecordData"),
                    base == Some(BaseSource::ShaderRecord),
                    "{chit}"
                );
                for s in &shaders.shaders {
                    let (words, _) = c
                        .compile(s.role, &s.glsl)
                        .unwrap_or_else(|e| panic!("{base:?} {:?}: {e}\n{}", s.role, s.glsl));
                    if let crate::patches::Validation::Invalid(m) = crate::patches::validate(&words)
                    {
                        panic!("{base:?} {:?}: {m}", s.role);
                    }
                }
            }
        }
    }

    /// The GLSL is what is written before any SPIR-V workaround: `as_access=address_patched` is
    /// the descriptor variant's, a `patch` cell its base cell's (the worker patches after).
    #[test]
    fn patched_cells_generate_the_glsl_they_patch() {
        use crate::model::Workaround;
        let glsl = |c: &Cell| generate(c).shaders.into_iter().map(|s| s.glsl).collect::<Vec<_>>();
        let d = Cell { nonuniform: false, ..reorder_cell(None, Resource::AccelerationStructure) };
        let patched = Cell {
            as_access: Some(AsAccess::AddressPatched),
            patch: Some(Workaround::PinIndex),
            ..d
        };
        assert_eq!(glsl(&patched), glsl(&d));
        let written = glsl(&Cell { as_access: Some(AsAccess::Address), ..d });
        assert_ne!(written, glsl(&d));
        assert!(written
            .iter()
            .any(|g| g.contains("accelerationStructureEXT(AsTable(packUint2x32(pc.asTable)).a[")));
        let ssbo = reorder_cell(None, Resource::StorageBuffer);
        assert_eq!(glsl(&Cell { patch: Some(Workaround::SsboToAddress), ..ssbo }), glsl(&ssbo));
    }

    /// Lane evidence: in every probed stage the probe measures lane, leader, mask and count with
    /// subgroup ballot next to its read and hands them to the record (through the payload, the
    /// callable data or the packed hit attributes); without it, no subgroup code at all. Every
    /// shader compiles to valid SPIR-V either way.
    #[test]
    fn lane_evidence_is_measured_in_the_probed_stage_only_when_asked() {
        let mut c = compile::Compiler::new().unwrap();
        for stage in Stage::ALL {
            let cell = Cell::new(
                *stage,
                Resource::StorageBuffer,
                IndexSource::Dynamic,
                DescriptorModel::DescriptorIndexing,
            );
            for lanes in [false, true] {
                let shaders = generate_with(&cell, None, lanes);
                let probed = shaders.get(Role::probed(*stage)).unwrap();
                assert_eq!(
                    probed.glsl.contains("subgroupBroadcastFirst(px.x + px.y * pc.width)"),
                    lanes,
                    "{stage:?}"
                );
                for s in shaders.shaders.iter().filter(|s| s.role != Role::probed(*stage)) {
                    let procedural =
                        *stage == Stage::ClosestHit && s.role == Role::ClosestHitProcedural;
                    assert!(
                        procedural || !s.glsl.contains("subgroupBallot("),
                        "{stage:?} {:?}",
                        s.role
                    );
                }
                let writes = shaders.shaders.iter().any(|s| s.glsl.contains("setLanes(pl,"))
                    || probed.glsl.contains("setLanes(r, probeLaneFlag, probeLanes)");
                assert!(writes, "{stage:?}");
                for s in &shaders.shaders {
                    let (words, _) = c
                        .compile(s.role, &s.glsl)
                        .unwrap_or_else(|e| panic!("{stage:?} {:?}: {e}\n{}", s.role, s.glsl));
                    if let crate::patches::Validation::Invalid(m) = crate::patches::validate(&words)
                    {
                        panic!("{stage:?} {:?} lanes {lanes}: {m}", s.role);
                    }
                }
            }
        }
    }

    /// Lavapipe has no SER, so these shaders never reach a driver in the test suite: they are
    /// compiled here and checked with spirv-val (when installed) instead.
    #[test]
    fn reorder_cells_trace_into_a_hit_object_and_compile_to_valid_spirv() {
        let mut c = compile::Compiler::new().unwrap();
        for resource in [Resource::StorageBuffer, Resource::AccelerationStructure] {
            for r in Reorder::ALL {
                let shaders = generate(&reorder_cell(Some(*r), resource));
                let rgen = &shaders.get(Role::Raygen).unwrap().glsl;
                assert!(
                    rgen.contains("hitObjectTraceRayNV(hitObj, sceneTlas")
                        && rgen.contains("hitObjectExecuteShaderNV(hitObj, 0)"),
                    "{rgen}"
                );
                assert!(!rgen.contains("traceRayEXT("), "{rgen}");
                assert_eq!(
                    rgen.contains("hitObjectGetInstanceCustomIndexNV"),
                    *r == Reorder::ReorderHint,
                    "{rgen}"
                );
                for s in &shaders.shaders {
                    let (words, _) = c
                        .compile(s.role, &s.glsl)
                        .unwrap_or_else(|e| panic!("{r:?} {:?}: {e}\n{}", s.role, s.glsl));
                    match crate::patches::validate(&words) {
                        crate::patches::Validation::Invalid(m) => panic!("{r:?} {:?}: {m}", s.role),
                        crate::patches::Validation::TooOld { validator, what } => {
                            panic!("{r:?} {:?}: {validator} too old for {what}", s.role)
                        }
                        crate::patches::Validation::Valid
                        | crate::patches::Validation::Unavailable => {}
                    }
                }
                // Every shader but the raygen is the plain cell's.
                let plain = generate(&reorder_cell(None, resource));
                for s in plain.shaders.iter().filter(|s| s.role != Role::Raygen) {
                    assert_eq!(shaders.get(s.role).map(|x| &x.glsl), Some(&s.glsl), "{:?}", s.role);
                }
                assert!(plain.get(Role::Raygen).unwrap().glsl.contains("traceRayEXT(sceneTlas"));
            }
        }
    }
}

#[cfg(test)]
mod copy_tests {
    use super::*;
    use crate::model::{DescriptorModel, IndexSource, Resource};

    /// A copy differs from its base cell and from every other copy in its first stage only, and
    /// that stage still compiles (a copy that compiled to its base's SPIR-V would share its
    /// pipeline and measure nothing).
    #[test]
    fn copies_have_first_stages_of_their_own_that_compile() {
        let mut compiler = compile::Compiler::new().expect("shaderc");
        for stage in [Stage::Raygen, Stage::Fragment, Stage::Compute] {
            let base = Cell::new(
                stage,
                Resource::StorageBuffer,
                IndexSource::Dynamic,
                DescriptorModel::DescriptorIndexing,
            );
            let g = |copy| generate(&Cell { copy, ..base });
            let (b, c1, c2) = (g(0), g(1), g(2));
            assert_ne!(b.shaders[0].glsl, c1.shaders[0].glsl, "{stage:?}");
            assert_ne!(c1.shaders[0].glsl, c2.shaders[0].glsl, "{stage:?}");
            for i in 1..b.shaders.len() {
                assert_eq!(b.shaders[i].glsl, c1.shaders[i].glsl, "{stage:?} stage {i}");
            }
            let spirv = |s: &ShaderSource, c: &mut compile::Compiler| {
                c.compile(s.role, &s.glsl).map(|r| r.0)
            };
            let (sb, s1) =
                (spirv(&b.shaders[0], &mut compiler), spirv(&c1.shaders[0], &mut compiler));
            assert_ne!(sb.expect("base compiles"), s1.expect("copy compiles"), "{stage:?}");
        }
    }
}
