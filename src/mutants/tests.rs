//! Every mutation, SPIR-V in → out: rtprobe's own probes generated for a cell, compiled (shaderc;
//! `layout(descriptor_heap)` probes by the heap-capable glslang where one is found, else
//! skipped), mutated, checked with `spirv-val`, and read back: the rewritten operand is the
//! mutation's (a constant 0, `(i + 1) mod n`, a broadcast of `i`, …), one instruction per site
//! changed and nothing else, so the slot the probe records is the unmutated one. The twins: a
//! mutation whose target a probe lacks rewrites nothing, and `site` says why.
use super::*;
use crate::model::{
    AsAccess, BaseSource, Cell, DescriptorModel, HeapAccess, IndexSource, Resource, SamplerIndex,
    Stage, Workaround,
};
use crate::patches::{self, edit, Validation};
use crate::shadergen::{self, compile::Compiler, Role};
use rspirv::dr::Operand;
use rspirv::spirv::Op;

const SLOTS: u32 = 20;

fn cell(stage: Stage, resource: Resource, index: IndexSource) -> Cell {
    let as_access = (resource == Resource::AccelerationStructure).then_some(AsAccess::Descriptor);
    Cell { as_access, ..Cell::new(stage, resource, index, DescriptorModel::DescriptorIndexing) }
}

fn direct(c: Cell) -> Cell {
    Cell {
        descriptor_model: DescriptorModel::DescriptorHeap,
        heap_access: Some(HeapAccess::Direct),
        ..c
    }
}

/// The cell's modules as the worker has them before a mutant: compiled, workarounds applied.
/// `None` when a direct-heap cell has no heap-capable glslang here.
fn modules(c: &Cell) -> Option<Vec<(Role, Vec<u32>)>> {
    if c.heap_access == Some(HeapAccess::Direct) && shadergen::glslang::find().is_none() {
        eprintln!("skipped {}: {}", c.id(), shadergen::glslang::missing_reason());
        return None;
    }
    let mut compiler = Compiler::new().unwrap();
    let spec = crate::probe::spec::ProbeSpec::of(c);
    let out = shadergen::generate(c)
        .shaders
        .iter()
        .map(|s| {
            let (words, _) = compiler.compile(s.role, &s.glsl).unwrap_or_else(|e| panic!("{e}"));
            let mut words = words.to_vec();
            for w in spec.workarounds() {
                if let Some(p) = patches::workaround::patch_module(&words, w).unwrap() {
                    words = p;
                }
            }
            (s.role, words)
        })
        .collect();
    Some(out)
}

fn load(words: &[u32]) -> Module {
    patches::load(&words.iter().flat_map(|w| w.to_le_bytes()).collect::<Vec<u8>>()).unwrap()
}

fn valid(words: &[u32], what: &str) {
    if let Validation::Invalid(m) = patches::validate(words) {
        panic!("{what}: spirv-val: {m}");
    }
}

/// `m` applied to every module of `c`: (role, the unmutated module, the mutated one) for those
/// it rewrote, each valid.
fn mutated(c: &Cell, m: Mutant) -> Option<Vec<(Role, Module, Module)>> {
    let site = site(&crate::probe::spec::ProbeSpec::of(c), m, SLOTS)
        .unwrap_or_else(|e| panic!("{}: {e}", c.id()));
    let mut out = vec![];
    for (role, words) in modules(c)? {
        if let Some(after) = mutate_module(&words, site).unwrap() {
            valid(&after, &format!("{} × {} {role:?}", c.id(), m.as_str()));
            out.push((role, load(&words), load(&after)));
        }
    }
    Some(out)
}

/// Instructions the mutation changed (lines it removed, the header's id bound left out): one per
/// site.
fn changed(before: &Module, after: &Module) -> Vec<String> {
    patches::diff(&patches::disassemble(before), &patches::disassemble(after))
        .lines()
        .filter(|l| l.starts_with("- ") && !l.starts_with("- ;"))
        .map(String::from)
        .collect()
}

fn def(m: &Module, id: u32) -> &rspirv::dr::Instruction {
    edit::def(m, id).unwrap_or_else(|| panic!("no definition of %{id}"))
}

fn literal(m: &Module, id: u32) -> Option<u32> {
    let d = def(m, id);
    match (d.class.opcode, d.operands.first()) {
        (Op::Constant, Some(Operand::LiteralBit32(v))) => Some(*v),
        _ => None,
    }
}

/// The operand at each site of `sites` in `after`, with the id the same operand had `before`.
fn rewritten(
    before: &Module,
    after: &Module,
    sites: impl Fn(&Module) -> Vec<locate::At>,
) -> Vec<(u32, u32)> {
    let (b, a) = (sites(before), sites(after));
    assert_eq!(b.len(), a.len());
    assert!(!a.is_empty(), "no site");
    b.iter().zip(&a).map(|(x, y)| (x.id(before).unwrap(), y.id(after).unwrap())).collect()
}

/// `id` is `op(first, second)` (`OpUMod` standing for either modulo); returns (first, second).
fn binary(m: &Module, id: u32, op: Op) -> (u32, u32) {
    let d = def(m, id);
    let got = if d.class.opcode == Op::SMod { Op::UMod } else { d.class.opcode };
    assert_eq!(got, op, "%{id}");
    (edit::id_operand(d, 0).unwrap(), edit::id_operand(d, 1).unwrap())
}

#[test]
fn descriptor_index_mutations_rewrite_only_the_access_in_both_closest_hit_shaders() {
    let c = Cell {
        nonuniform: true,
        ..cell(Stage::ClosestHit, Resource::StorageBuffer, IndexSource::Dynamic)
    };
    let sites = |m: &Module| locate::descriptor_indices(m, false);
    for mutant in [
        Mutant::IndexZero,
        Mutant::IndexNext,
        Mutant::StrideDouble,
        Mutant::IndexBroadcast,
        Mutant::BaseDropped,
    ] {
        let got = mutated(&c, mutant).unwrap();
        let roles: Vec<Role> = got.iter().map(|(r, _, _)| *r).collect();
        assert_eq!(roles, [Role::ClosestHitTriangles, Role::ClosestHitProcedural], "{mutant:?}");
        for (_, before, after) in &got {
            assert_eq!(changed(before, after).len(), 1, "{mutant:?}: {:?}", changed(before, after));
            for (old, new) in rewritten(before, after, sites) {
                match mutant {
                    Mutant::IndexZero => assert_eq!(literal(after, new), Some(0)),
                    Mutant::IndexNext => {
                        let (sum, n) = binary(after, new, Op::UMod);
                        assert_eq!(
                            (binary(after, sum, Op::IAdd).0, literal(after, n)),
                            (old, Some(SLOTS))
                        );
                        assert!(
                            edit::has_decoration(after, new, rspirv::spirv::Decoration::NonUniform),
                            "nonuniformEXT kept"
                        );
                    }
                    Mutant::StrideDouble => {
                        let (wrapped, two) = binary(after, new, Op::IMul);
                        let (i, half) = binary(after, wrapped, Op::UMod);
                        assert_eq!(
                            (i, literal(after, half), literal(after, two)),
                            (old, Some(SLOTS / 2), Some(2))
                        );
                    }
                    Mutant::IndexBroadcast => {
                        let d = def(after, new);
                        assert_eq!(d.class.opcode, Op::GroupNonUniformBroadcastFirst);
                        let Some(Operand::IdScope(scope)) = d.operands.first() else {
                            panic!("{d:?}")
                        };
                        let (scope, i) = (*scope, edit::id_operand(d, 1).unwrap());
                        assert_eq!((literal(after, scope), i), (Some(3), old));
                    }
                    Mutant::BaseDropped => assert_eq!(def(after, new).class.opcode, Op::BitwiseAnd),
                    other => unreachable!("{other:?}"),
                }
            }
        }
    }
}

#[test]
fn fixed_indices_rewrite_their_constant_and_have_no_base() {
    let c = cell(Stage::Raygen, Resource::UniformBuffer, IndexSource::Literal);
    let got = mutated(&c, Mutant::IndexNext).unwrap();
    assert_eq!(got.len(), 1);
    let (_, before, after) = &got[0];
    let [(old, new)] = rewritten(before, after, |m| locate::descriptor_indices(m, false))[..]
    else {
        panic!()
    };
    assert_eq!(literal(before, old), Some(crate::probe::LITERAL_SLOT));
    let (sum, n) = binary(after, new, Op::UMod);
    assert_eq!((binary(after, sum, Op::IAdd).0, literal(after, n)), (old, Some(SLOTS)));
    // The twins: no base, no sampler, no address, no packed element in this probe.
    let spec = crate::probe::spec::ProbeSpec::of(&c);
    for m in [Mutant::BaseDropped, Mutant::SamplerNext, Mutant::TlasOther, Mutant::ElementZero] {
        assert!(site(&spec, m, SLOTS).is_err(), "{m:?}");
    }
    // A site a module lacks rewrites nothing: the probe's module has no sampler heap, the miss
    // shader no probe at all.
    let all = modules(&c).unwrap();
    let probed = &all.iter().find(|(r, _)| *r == Role::Raygen).unwrap().1;
    let sampler = Mutation::SamplerIndex { to: IndexFn::Next(3) };
    assert_eq!(mutate_module(probed, sampler).unwrap(), None);
    let miss = &all.iter().find(|(r, _)| *r == Role::Miss).unwrap().1;
    let index = Mutation::DescriptorIndex { heap: false, to: IndexFn::Zero };
    assert_eq!(mutate_module(miss, index).unwrap(), None);
    assert_eq!(mutate_module(miss, Mutation::PackedElement { heap: false }).unwrap(), None);
    assert_eq!(mutate_module(miss, Mutation::ValueBits).unwrap(), None);
}

#[test]
fn fragment_and_compute_probes_mutate_their_one_module() {
    for stage in [Stage::Fragment, Stage::Compute] {
        let c = cell(stage, Resource::StorageImage, IndexSource::Dynamic);
        let got = mutated(&c, Mutant::IndexZero).unwrap();
        assert_eq!(got.len(), 1, "{stage:?}");
        let got = mutated(&c, Mutant::ValueBits).unwrap();
        assert_eq!(got.len(), 1, "{stage:?}");
    }
}

#[test]
fn value_bits_flip_the_last_word_of_the_stored_value() {
    let c = cell(Stage::Miss, Resource::SampledImage, IndexSource::PushConstant);
    let got = mutated(&c, Mutant::ValueBits).unwrap();
    assert_eq!(got.len(), 1);
    let (_, before, after) = &got[0];
    assert_eq!(changed(before, after).len(), 1);
    let var = locate::probe_value_variable(after).unwrap();
    let [(old, new)] = rewritten(before, after, |m| locate::stores_to(m, var))[..] else {
        panic!()
    };
    let d = def(after, new);
    assert_eq!(
        (d.class.opcode, d.operands.get(2)),
        (Op::CompositeInsert, Some(&Operand::LiteralBit32(3)))
    );
    assert_eq!(edit::id_operand(d, 1), Some(old));
    let back = def(after, edit::id_operand(d, 0).unwrap());
    let (bits, mask) = binary(after, edit::id_operand(back, 0).unwrap(), Op::BitwiseXor);
    assert_eq!(
        (def(after, bits).class.opcode, literal(after, mask)),
        (Op::Bitcast, Some(value::FLIPPED))
    );
    assert_ne!(value::flip(1.0), 1.0);
    assert!(value::flip(0.25).is_normal() && value::flip(1.0).is_normal());
}

#[test]
fn element_zero_reads_element_zero_of_the_packed_buffer_and_layer_zero_of_the_array_texture() {
    let buffer = Cell {
        base: Some(BaseSource::ShaderRecord),
        ..cell(Stage::ClosestHit, Resource::StorageBuffer, IndexSource::DynamicElement)
    };
    for (_, before, after) in mutated(&buffer, Mutant::ElementZero).unwrap() {
        assert_eq!(changed(&before, &after).len(), 1);
        for (_, new) in rewritten(&before, &after, |m| locate::packed_elements(m, false)) {
            assert_eq!(literal(&after, new), Some(0));
        }
    }
    let image = cell(Stage::Compute, Resource::SampledImage, IndexSource::DynamicElement);
    let got = mutated(&image, Mutant::ElementZero).unwrap();
    assert_eq!(got.len(), 1);
    let (_, before, after) = &got[0];
    let [(old, new)] = rewritten(before, after, locate::sample_coordinates)[..] else { panic!() };
    let d = def(after, new);
    assert_eq!(
        (d.class.opcode, edit::id_operand(d, 1), d.operands.get(2)),
        (Op::CompositeInsert, Some(old), Some(&Operand::LiteralBit32(2)))
    );
    // The packed descriptor has no other descriptor to read in bounds: no index mutant.
    let spec = crate::probe::spec::ProbeSpec::of(&image);
    assert!(site(&spec, Mutant::IndexZero, SLOTS).unwrap_err().contains("packed"));
}

#[test]
fn tlas_other_rewrites_the_table_index_written_or_patched() {
    for access in [AsAccess::Address, AsAccess::AddressPatched] {
        let c = Cell {
            as_access: Some(access),
            ..cell(Stage::Raygen, Resource::AccelerationStructure, IndexSource::Dynamic)
        };
        let got = mutated(&c, Mutant::TlasOther).unwrap();
        assert_eq!(got.len(), 1, "{access:?}");
        let (_, before, after) = &got[0];
        for (old, new) in rewritten(before, after, locate::address_indices) {
            let (sum, n) = binary(after, new, Op::UMod);
            assert_eq!(
                (binary(after, sum, Op::IAdd).0, literal(after, n)),
                (old, Some(SLOTS)),
                "{access:?}"
            );
        }
        let spec = crate::probe::spec::ProbeSpec::of(&c);
        assert!(site(&spec, Mutant::IndexNext, SLOTS).unwrap_err().contains("address"));
    }
    // Through a descriptor: no address to rewrite, the index mutants do.
    let d = cell(Stage::Raygen, Resource::AccelerationStructure, IndexSource::Dynamic);
    let spec = crate::probe::spec::ProbeSpec::of(&d);
    assert!(site(&spec, Mutant::TlasOther, SLOTS).is_err());
    assert_eq!(mutated(&d, Mutant::IndexNext).unwrap().len(), 1);
}

#[test]
fn direct_heap_probes_mutate_their_heap_accesses() {
    let sampled = direct(Cell {
        sampler: Some(SamplerIndex::Dynamic),
        nonuniform: true,
        ..cell(Stage::ClosestHit, Resource::SampledImage, IndexSource::Dynamic)
    });
    let Some(got) = mutated(&sampled, Mutant::SamplerNext) else { return };
    assert_eq!(got.len(), 2);
    for (_, before, after) in &got {
        for (old, new) in rewritten(before, after, locate::sampler_indices) {
            let (sum, n) = binary(after, new, Op::UMod);
            assert_eq!((binary(after, sum, Op::IAdd).0, literal(after, n)), (old, Some(3)));
        }
    }
    for (_, before, after) in mutated(&sampled, Mutant::IndexZero).unwrap() {
        for (_, new) in rewritten(&before, &after, |m| locate::descriptor_indices(m, true)) {
            assert_eq!(literal(&after, new), Some(0));
        }
    }
    let packed =
        direct(cell(Stage::ClosestHit, Resource::StorageBuffer, IndexSource::DynamicElement));
    for (_, before, after) in mutated(&packed, Mutant::ElementZero).unwrap() {
        for (_, new) in rewritten(&before, &after, |m| locate::packed_elements(m, true)) {
            assert_eq!(literal(&after, new), Some(0));
        }
    }
    let buffer = direct(cell(Stage::ClosestHit, Resource::StorageBuffer, IndexSource::Dynamic));
    assert_eq!(mutated(&buffer, Mutant::BaseDropped).unwrap().len(), 2);
    assert_eq!(mutated(&buffer, Mutant::ValueBits).unwrap().len(), 2);
}

/// lavapipe 26's mutant run: on direct-heap storage images (glslang 16 wraps the heap array in a
/// block, `%heap 0 %slot`) index-zero rewrote the member index 0 to 0 (a no-op, reported as a
/// probe defect) and index-next made member 1 (an invalid pipeline). The descriptor index is the
/// one after the member: each mutant changes the module, at the slot.
#[test]
fn direct_heap_storage_images_mutate_the_slot_not_the_block_member() {
    for index in [IndexSource::SpecConstant, IndexSource::Literal] {
        let image = direct(cell(Stage::Raygen, Resource::StorageImage, index));
        let Some(got) = mutated(&image, Mutant::IndexZero) else { return };
        assert_eq!(got.len(), 1, "{}", image.id());
        for (_, before, after) in &got {
            assert_eq!(changed(before, after).len(), 1, "{}: one access rewritten", image.id());
            for (old, new) in rewritten(before, after, |m| locate::descriptor_indices(m, true)) {
                assert_ne!(literal(before, old), Some(0), "the slot, not the member: %{old}");
                assert_eq!(literal(after, new), Some(0));
            }
        }
        for (_, before, after) in mutated(&image, Mutant::IndexNext).unwrap() {
            for (old, new) in rewritten(&before, &after, |m| locate::descriptor_indices(m, true)) {
                let (sum, _) = binary(&after, new, Op::UMod);
                assert_eq!(binary(&after, sum, Op::IAdd).0, old);
            }
        }
    }
}

#[test]
fn workaround_variants_keep_their_sites_or_say_why_not() {
    let c = cell(Stage::ClosestHit, Resource::StorageBuffer, IndexSource::Dynamic);
    let spec =
        crate::probe::spec::ProbeSpec::of(&Cell { patch: Some(Workaround::SsboToAddress), ..c });
    assert!(site(&spec, Mutant::IndexZero, SLOTS).unwrap_err().contains("ssbo-to-address"));
    assert!(site(
        &crate::probe::spec::ProbeSpec::of(&Cell::canary(crate::model::Canary::InfiniteLoop)),
        Mutant::ValueBits,
        SLOTS
    )
    .is_err());
}

/// The scene-layout cells: the texture cells' texture element and the `per_mesh` cells' mesh
/// slot are rewritten at every access into binding 2 (a `per_mesh` fetch reads its buffer
/// several times: each read goes to the same wrong buffer), broadcast included, each module
/// valid; a `shared_buffers` geometry cell reads no descriptor, and the mutants without a
/// prediction there say why.
#[test]
fn scene_layout_cells_rewrite_the_descriptor_they_select() {
    use crate::model::SceneLayout;
    let layout = |resource, nonuniform, l| Cell {
        nonuniform,
        scene_layout: Some(l),
        ..cell(Stage::ClosestHit, resource, IndexSource::Dynamic)
    };
    let textures = layout(Resource::SampledImage, true, SceneLayout::SharedBuffers);
    let per_mesh = layout(Resource::StorageBuffer, true, SceneLayout::PerMesh);
    // the per_mesh texture cell: binding 2 holds its textures (the mesh buffers are at 3)
    let per_mesh_textures = layout(Resource::SampledImage, true, SceneLayout::PerMesh);
    let sites = |m: &Module| locate::descriptor_indices(m, false);
    for (c, accesses) in [(&textures, 2), (&per_mesh, 8), (&per_mesh_textures, 2)] {
        for m in
            [Mutant::IndexZero, Mutant::IndexNext, Mutant::IndexBroadcast, Mutant::StrideDouble]
        {
            let got = mutated(c, m).unwrap();
            assert_eq!(got.len(), 1, "{} {m:?}: only the triangles' closest-hit", c.id());
            let (_, before, after) = &got[0];
            let pairs = rewritten(before, after, sites);
            assert!(pairs.len() >= accesses, "{} {m:?}: {} sites", c.id(), pairs.len());
            assert_eq!(changed(before, after).len(), pairs.len(), "{} {m:?}", c.id());
            if m == Mutant::IndexBroadcast {
                for (old, new) in pairs {
                    let d = def(after, new);
                    assert_eq!(d.class.opcode, Op::GroupNonUniformBroadcastFirst);
                    assert_eq!(edit::id_operand(d, 1), Some(old));
                }
            }
        }
        let spec = crate::probe::spec::ProbeSpec::of(c);
        for m in [
            Mutant::BaseDropped,
            Mutant::ElementZero,
            Mutant::SamplerNext,
            Mutant::TlasOther,
            Mutant::ValueBits,
        ] {
            assert!(site(&spec, m, SLOTS).is_err(), "{} {m:?}", c.id());
        }
    }
    let shared = layout(Resource::StorageBuffer, false, SceneLayout::SharedBuffers);
    let spec = crate::probe::spec::ProbeSpec::of(&shared);
    let why = site(&spec, Mutant::IndexBroadcast, SLOTS).unwrap_err();
    assert!(why.contains("reads no descriptor"), "{why}");
    for m in Mutant::ALL {
        assert!(site(&spec, *m, SLOTS).is_err(), "{m:?}");
    }
}
