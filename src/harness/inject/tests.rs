//! SPIR-V in → out for the injection: GLSL written for these tests compiled by shaderc, the
//! fault inserted, the result held to spirv-val (through `tools::spirv`'s resolver) and read
//! back: which accesses got it, which did not, and that each fault is fed by its access.
use super::*;
use crate::model::{IndexSource, Resource, Stage};
use crate::patches::{assemble, compiled, validate, Validation};
use rspirv::dr::Operand;
use rspirv::spirv::{AddressingModel, Op, Word};
use shaderc::ShaderKind;

/// An engine-like closest-hit: a bindless material array at a dynamic index, a constant-index
/// scene UBO, a spec-constant-indexed lights SSBO array, a texture array at a push-constant index.
pub(super) const HIT: &str = r#"#version 460
#extension GL_EXT_ray_tracing : require
#extension GL_EXT_nonuniform_qualifier : require
struct Material { vec4 albedo; uint flags; };
layout(set = 0, binding = 0) readonly buffer Materials { Material m[]; } materials[];
layout(set = 0, binding = 1) uniform Scene { vec4 sun; uint frame; } scenes[4];
layout(set = 0, binding = 2) readonly buffer Lights { vec4 l[]; } lights[8];
layout(set = 0, binding = 3) uniform sampler2D textures[16];
layout(constant_id = 0) const uint LIGHT_SET = 3;
layout(push_constant) uniform Draw { uint texture; } draw;
layout(location = 0) rayPayloadInEXT vec4 payload;
void main() {
    uint mat = uint(gl_InstanceCustomIndexEXT) + 1u;
    Material m = materials[nonuniformEXT(mat)].m[gl_PrimitiveID];
    vec4 sun = scenes[2].sun;
    vec4 light = lights[LIGHT_SET].l[0];
    vec4 t = textureLod(textures[draw.texture & 15u], vec2(0.5), 0.0);
    payload = m.albedo * t + sun * light + vec4(float(m.flags));
}
"#;

/// A raygen whose only access is a storage image at a literal index.
const GEN: &str = r#"#version 460
#extension GL_EXT_ray_tracing : require
layout(set = 0, binding = 4, rgba8) uniform readonly image2D history;
layout(set = 0, binding = 5, rgba8) uniform writeonly image2D target;
void main() {
    ivec2 p = ivec2(gl_LaunchIDEXT.xy);
    imageStore(target, p, imageLoad(history, p) * 0.5);
}
"#;

fn hit() -> Module {
    compiled(ShaderKind::ClosestHit, "t.rchit", HIT)
}

fn accesses(m: &Module) -> Vec<Access> {
    sites::find(m).iter().map(|s| s.access).collect()
}

pub(super) fn valid(m: &Module) {
    let v = validate(&assemble(m));
    assert!(matches!(v, Validation::Valid), "{v:?}\n{}", crate::patches::disassemble(m));
}

fn request(s: &str) -> Request {
    Request::parse(s).unwrap()
}

/// Whether `id`'s definition tree (through instruction operands) reaches `target`.
pub(super) fn reaches(m: &Module, id: Word, target: Word, _depth: u32) -> bool {
    let (mut todo, mut seen) = (vec![id], std::collections::HashSet::new());
    while let Some(x) = todo.pop() {
        if x == target {
            return true;
        }
        if !seen.insert(x) {
            continue;
        }
        if let Some(d) = crate::patches::edit::def(m, x) {
            todo.extend(d.operands.iter().filter_map(crate::patches::edit::id_from));
        }
    }
    false
}

/// Whether some `OpStore` (what the shader writes) depends on `target`.
fn written(m: &Module, target: Word) -> bool {
    m.functions
        .iter()
        .flat_map(|f| f.blocks.iter().flat_map(|b| b.instructions.iter()))
        .filter(|i| i.class.opcode == Op::Store)
        .filter_map(|i| crate::patches::edit::id_operand(i, 1))
        .any(|v| reaches(m, v, target, 0))
}

fn phis(m: &Module) -> Vec<Word> {
    m.functions
        .iter()
        .flat_map(|f| f.blocks.iter().flat_map(|b| b.instructions.iter()))
        .filter(|i| i.class.opcode == Op::Phi)
        .filter_map(|i| i.result_id)
        .collect()
}

pub(super) fn marked(m: &Module) -> Vec<Word> {
    m.debug_names
        .iter()
        .filter(|n| matches!(n.operands.get(1), Some(Operand::LiteralString(s)) if s.starts_with(emit::MARKER)))
        .filter_map(|n| crate::patches::edit::id_from(&n.operands[0]))
        .collect()
}

#[test]
fn accesses_are_told_by_stage_resource_and_index_source() {
    let found = accesses(&hit());
    let has =
        |r, i| found.iter().any(|a| (a.stage, a.resource, a.index) == (Stage::ClosestHit, r, i));
    assert!(has(Resource::StorageBuffer, IndexSource::Dynamic), "{found:?}");
    assert!(has(Resource::UniformBuffer, IndexSource::Literal), "{found:?}");
    assert!(has(Resource::StorageBuffer, IndexSource::SpecConstant), "{found:?}");
    assert!(has(Resource::SampledImage, IndexSource::PushConstant), "{found:?}");
    let gen = accesses(&compiled(ShaderKind::RayGeneration, "t.rgen", GEN));
    // The write has no value: only the read is an access.
    assert_eq!(
        gen,
        [Access {
            stage: Stage::Raygen,
            resource: Resource::StorageImage,
            index: IndexSource::Literal
        }]
    );
}

#[test]
fn a_device_fault_follows_each_matching_access_and_is_fed_by_it() {
    let mut m = hit();
    let before = sites::find(&m);
    let dynamic: Vec<_> =
        before.iter().filter(|s| s.access.index == IndexSource::Dynamic).collect();
    assert!(!dynamic.is_empty());
    let got = inject(&mut m, &request("stage=closest_hit,index=dynamic@device"));
    assert_eq!(got.sites.len(), dynamic.len(), "{got:?}");
    assert!(got.skipped.is_empty(), "{got:?}");
    assert!(
        got.sites.iter().all(|s| s.contains("materials") && s.contains("(dynamic index)")),
        "{got:?}"
    );
    assert_eq!(count(&m), dynamic.len());
    let addressing = m.memory_model.as_ref().unwrap().operands[0].clone();
    assert_eq!(addressing, Operand::AddressingModel(AddressingModel::PhysicalStorageBuffer64));
    valid(&m);
    // Each fault's load is fed by an access's value: deleting the access deletes the fault.
    let values: Vec<Word> = dynamic.iter().filter_map(|s| s.value).collect();
    for f in marked(&m) {
        assert!(values.iter().any(|v| reaches(&m, f, *v, 32)), "fault %{f} not fed by an access");
        // … and what the shader writes depends on the fault's load: no compiler may drop it.
        assert!(written(&m, f), "fault %{f} reaches no store");
    }
}

#[test]
fn twins_a_constant_index_and_another_stage_get_nothing() {
    // The constant-index UBO read does not match index=dynamic …
    let mut m = hit();
    let got = inject(&mut m, &request("resource=uniform_buffer,index=dynamic"));
    assert!(got.sites.is_empty() && count(&m) == 0, "{got:?}");
    assert_eq!(assemble(&m), assemble(&hit()), "a module nothing matched is unchanged");
    // … but does match index=literal.
    let got = inject(&mut m, &request("resource=uniform_buffer,index=literal"));
    assert_eq!(got.sites.len(), 1, "{got:?}");
    valid(&m);
    // A raygen predicate on a closest-hit module matches nothing.
    let mut m = hit();
    assert!(inject(&mut m, &request("stage=raygen")).sites.is_empty());
    assert_eq!(count(&m), 0);
}

/// The part a chain of `OpCompositeInsert`s ending in `composite` holds at `lane`, if one
/// of them put it there.
fn lane_part(m: &Module, mut composite: Word, lane: u32) -> Option<Word> {
    loop {
        let d = crate::patches::edit::def(m, composite)?;
        if d.class.opcode != Op::CompositeInsert {
            return None;
        }
        let (part, whole) =
            (crate::patches::edit::id_operand(d, 0)?, crate::patches::edit::id_operand(d, 1)?);
        if d.operands.get(2) == Some(&Operand::LiteralBit32(lane)) && d.operands.len() == 3 {
            return Some(part);
        }
        composite = whole;
    }
}

/// Issue 25: an alpha test reads a texel's alpha alone. The fault feeds every lane of a vector
/// value, so the alpha the shader writes depends on it (fed into `.x` alone, a compiler
/// drops the fault with the unused lanes: lavapipe did).
#[test]
fn a_fault_feeds_every_lane_of_a_vector_value() {
    const ALPHA: &str = "#version 460\n#extension GL_EXT_ray_tracing : require\n\
        layout(set = 0, binding = 0) uniform sampler2D base;\n\
        layout(location = 0) rayPayloadInEXT float alpha;\n\
        void main() { alpha = textureLod(base, vec2(0.5), 0.0).a; }\n";
    let mut m = compiled(ShaderKind::ClosestHit, "a.rchit", ALPHA);
    assert_eq!(inject(&mut m, &request("resource=sampled_image@device")).sites.len(), 1);
    valid(&m);
    let fault = marked(&m)[0];
    let body =
        || m.functions.iter().flat_map(|f| f.blocks.iter().flat_map(|b| b.instructions.iter()));
    let store = body().find(|i| i.class.opcode == Op::Store).expect("the payload's store");
    let value = crate::patches::edit::id_operand(store, 1).unwrap();
    let alpha = body().find(|i| i.result_id == Some(value)).unwrap();
    assert_eq!(alpha.class.opcode, Op::CompositeExtract);
    assert_eq!(alpha.operands[1], Operand::LiteralBit32(3));
    let texel = crate::patches::edit::id_operand(alpha, 0).unwrap();
    let part = lane_part(&m, texel, 3).expect("lane 3 is the fault's");
    assert!(reaches(&m, part, fault, 32), "the alpha does not depend on the fault");
}

/// `tests/shaders/user/heap.rchit` as the sid root's glslang 16.6 compiles it (the host's
/// compilers predate GL_EXT_descriptor_heap; `tests/fixtures/heap/README.md`).
fn heap_module() -> Module {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/fixtures/heap/heap.rchit.spv");
    crate::patches::load(&std::fs::read(path).unwrap()).unwrap()
}

/// Issue 25: `layout(descriptor_heap)` reads (an untyped access chain into `ResourceHeapEXT`,
/// its `OpBufferPointerEXT`, a load): heap.rchit's material read and its three normal reads are
/// storage-buffer accesses with dynamic indices, and each gets the fault; twin: a
/// uniform-buffer predicate matches nothing.
#[test]
fn descriptor_heap_reads_are_accesses() {
    let mut m = heap_module();
    let want = Access {
        stage: Stage::ClosestHit,
        resource: Resource::StorageBuffer,
        index: IndexSource::Dynamic,
    };
    assert_eq!(accesses(&m), [want; 4]);
    assert!(inject(&mut m.clone(), &request("resource=uniform_buffer")).sites.is_empty());
    let got = inject(&mut m, &request("resource=storage_buffer,index=dynamic@device"));
    assert_eq!(got.sites.len(), 4, "{got:?}");
    assert!(got.sites.iter().all(|s| s.contains("resource_heap")), "{got:?}");
    assert_eq!(count(&m), 4);
    for f in marked(&m) {
        assert!(written(&m, f), "fault %{f} reaches no store");
    }
}

#[test]
fn a_hang_is_a_loop_after_each_access_fed_by_it() {
    let mut m = hit();
    let n = sites::find(&m).iter().filter(|s| s.value.is_some()).count();
    let loops = |m: &Module| {
        m.functions
            .iter()
            .flat_map(|f| f.blocks.iter().flat_map(|b| b.instructions.iter()))
            .filter(|i| i.class.opcode == Op::LoopMerge)
            .count()
    };
    let (before, old_phis) = (loops(&m), phis(&m));
    let values: Vec<Word> = sites::find(&m).iter().filter_map(|s| s.value).collect();
    let got = inject(&mut m, &request("stage=closest_hit@hang"));
    assert_eq!((got.sites.len(), count(&m)), (n, n), "{got:?}");
    assert_eq!(loops(&m), before + n);
    valid(&m);
    for f in marked(&m) {
        assert!(values.iter().any(|v| reaches(&m, f, *v, 32)), "loop %{f} not fed by an access");
    }
    // What the shader writes depends on every loop's count.
    let counts: Vec<Word> = phis(&m).into_iter().filter(|p| !old_phis.contains(p)).collect();
    assert_eq!(counts.len(), n);
    assert!(counts.iter().all(|c| written(&m, *c)), "a loop's count reaches no store");
    // The image read of a raygen too (another block layout: the access before a store).
    let mut g = compiled(ShaderKind::RayGeneration, "t.rgen", GEN);
    assert_eq!(inject(&mut g, &request("resource=storage_image@hang")).sites.len(), 1);
    valid(&g);
}

#[test]
fn kinds_without_a_cpu_reference_are_refused_in_one_line() {
    assert_eq!(request("stage=miss").fault, Fault::Device);
    assert_eq!(request("stage=miss@hang").spec, "stage=miss@hang");
    let msg = |s: &str| Request::parse(s).unwrap_err().to_string();
    assert!(
        msg("stage=miss@value:0.5").contains("needs a CPU reference"),
        "{}",
        msg("stage=miss@value:0.5")
    );
    assert!(msg("stage=miss@nan").contains("needs a CPU reference"));
    assert!(msg("stage=miss@flaky:0.5").contains("use @device or @hang"));
    assert!(msg("stage=miss@boom").contains("unknown fault kind"));
    assert!(msg("patch=nonuniform@hang").contains("takes stage, resource, index"));
}
