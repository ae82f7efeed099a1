//! `index_bounds`: an instrumentation, not a workaround — every dynamically indexed
//! descriptor-array access records its index and reads a clamped one, so `run --shader` can tell
//! whether the data it traced with sends a shader past a binding before it calls a fault the
//! driver's (`cli::shader_bounds` runs it).
//!
//! Each `OpAccessChain` / `OpInBoundsAccessChain` whose base is a descriptor variable of array
//! type listed in the [`Probe`] gets, right before it, with `i` its first index as 32-bit
//! unsigned (`OpBitcast` of a signed one), on the probe's storage buffer (`uint seen[6K]` at the
//! probe's set and binding, K slots, filled by the caller as [`Probe::initial`] says), in group
//! 0 for every access and again in group 1 for one whose index is dynamic and carries no
//! `NonUniform` (group `g` at word `3gK`):
//! - `OpAtomicUMax(seen[3gK + slot], i)`: the largest index;
//! - `OpAtomicOr(seen[3gK + K + slot], 1 | 2 * !OpGroupNonUniformAllEqual(Subgroup, i))`: bit 0
//!   the access ran, bit 1 its index differed among the subgroup's active invocations (what
//!   `VUID-RuntimeSpirv-subgroupSize-10149` calls "not uniform within the subgroup") — only with
//!   [`Probe::vote`], where the device has subgroup vote in every ray tracing stage (lavapipe 25
//!   has no subgroup operations there); else `OpAtomicOr(…, 1)`;
//! - `OpAtomicUMin(seen[3gK + 2K + slot], i)`: the smallest;
//!
//! and the chain then indexes `i < count ? i : count - 1` (`OpULessThan`, `OpSelect`), so the
//! instrumented pipeline itself stays inside every binding. A watched variable used any other way
//! (passed to a function, copied, loaded whole) is counted in [`Report::escaped`]: its accesses
//! are out of the pass's sight.
//!
//! The rules relied on (Vulkan 1.4.360, checked against Vulkan-Docs):
//! - chapter "Shader Interfaces", DescriptorSet and Binding Assignment: "If the array is
//!   runtime-sized, then array elements greater than or equal to the size of that binding in the
//!   bound descriptor set must not be used", and a fixed-size array "must be no larger than the
//!   number of descriptors in the binding"; SPIR-V leaves an access chain index past its array's
//!   size undefined ("Validity and Defined Behavior"). An index outside the binding is the
//!   input's fault, whatever the driver then does.
//! - an access-chain index may be any scalar integer of either signedness; a `NonUniform`
//!   decoration on the replaced index is put on its replacement (and on the unsigned copy), so a
//!   `nonuniformEXT` index stays decorated; the chain's own decorations stay.
//! - the atomic's memory scope is `Device`, or `QueueFamily` in a module of the Vulkan memory
//!   model (where `Device` needs `vulkanMemoryModelDeviceScope`); semantics `None` (relaxed):
//!   only the maximum is read, after the trace.
//! - SPIR-V 1.4 and later list every global a function uses in the entry point's interface.
//!
//! - with [`Probe::vote`], `GroupNonUniformVote` (with `GroupNonUniform`) is added; the harness
//!   asks the device for subgroup vote in the stages that run it.
//!
//! Indices of another width than 32 bits are left alone and counted in [`Report::skipped`].
use super::dynamic_access;
use super::edit;
use rspirv::dr::{Instruction, Module, Operand};
use rspirv::spirv::{Capability, Decoration, MemoryModel, Op, StorageClass, Word};

/// One descriptor array the probe watches — a binding as one declaration declares it: its slot
/// is its place in [`Probe::slots`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Slot {
    pub set: u32,
    pub binding: u32,
    /// A fixed-size declaration (`count` its own size), else a runtime-sized one (`count` the
    /// descriptors the harness binds).
    pub fixed: bool,
    /// The elements an index must stay below.
    pub count: u32,
}

/// Where the probe's buffer goes and which arrays it watches (the same for every module of a
/// pipeline, so a slot means one binding in every stage).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Probe {
    pub set: u32,
    pub binding: u32,
    pub slots: Vec<Slot>,
    /// Record whether an index differed within its subgroup (`OpGroupNonUniformAllEqual`).
    pub vote: bool,
}

impl Probe {
    /// The bytes the probe's buffer starts with: in both groups each slot's largest index and
    /// flags 0, its smallest index `u32::MAX`.
    pub fn initial(&self) -> Vec<u8> {
        let k = self.slots.len().max(1);
        let mut group = vec![0u8; 8 * k];
        group.extend(std::iter::repeat_n(0xff, 4 * k));
        [group.clone(), group].concat()
    }
}

/// What the instrumentation did to one module.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Report {
    /// Accesses that now record and clamp their index.
    pub instrumented: usize,
    /// Accesses of watched arrays left alone (an index that is not a 32-bit integer, a
    /// declaration no slot matches).
    pub skipped: usize,
    /// Uses of a watched array other than as an access chain's base (a function argument, a
    /// copy, a whole load): accesses the pass cannot follow.
    pub escaped: usize,
}

/// Variable `v`'s array: `Some(Some(n))` fixed-size of `n` — an `OpConstant` length or an
/// `OpSpecConstant`'s default, as the harness's reflection reads it (`reflect::index`) —,
/// `Some(None)` runtime-sized, `None` not an array or a length neither says.
fn declared_size(m: &Module, v: Word) -> Option<Option<u32>> {
    let pointee = pointee(m, v)?;
    match pointee.class.opcode {
        Op::TypeRuntimeArray => Some(None),
        Op::TypeArray => {
            let len = edit::def(m, edit::id_operand(pointee, 1)?)?;
            match (len.class.opcode, len.operands.first()) {
                (Op::Constant | Op::SpecConstant, Some(Operand::LiteralBit32(n))) => Some(Some(*n)),
                _ => None,
            }
        }
        _ => None,
    }
}

/// The type variable `v` points at.
fn pointee(m: &Module, v: Word) -> Option<&Instruction> {
    let (_, p) = edit::pointer_info(m, edit::def(m, v)?.result_type?)?;
    edit::def(m, p)
}

/// Whether variable `v` is an array of descriptors (what the pass watches; a single
/// descriptor's loads are no index to check).
fn is_array(m: &Module, v: Word) -> bool {
    pointee(m, v).is_some_and(|a| matches!(a.class.opcode, Op::TypeArray | Op::TypeRuntimeArray))
}

/// Uses of the watched variables `vars` other than as the base of an access chain.
fn escapes(m: &Module, vars: &[Word]) -> usize {
    let chain =
        |i: &Instruction| matches!(i.class.opcode, Op::AccessChain | Op::InBoundsAccessChain);
    m.functions
        .iter()
        .flat_map(|f| f.blocks.iter().flat_map(|b| b.instructions.iter()))
        .map(|i| {
            i.operands
                .iter()
                .enumerate()
                .filter(|(k, o)| {
                    // A chain with an index is watched; one without (the whole array again)
                    // is not.
                    let based = chain(i) && *k == 0 && i.operands.len() > 1;
                    matches!(o, Operand::IdRef(w) if vars.contains(w)) && !based
                })
                .count()
        })
        .sum()
}

/// The ids the inserted code shares.
struct Ids {
    uint: Word,
    bool_t: Word,
    ptr_uint: Word,
    var: Word,
    zero: Word,
    scope: Word,
    relaxed: Word,
    subgroup: Word,
    /// The number of slots, K.
    k: u32,
    vote: bool,
}

/// The probe's `buffer { uint seen[K]; }` at its set and binding, and the shared ids.
fn declare(m: &mut Module, p: &Probe) -> Ids {
    let uint = edit::type_int(m, 32, false);
    let bool_t = edit::type_bool(m);
    let len = edit::constant(m, uint, 6 * p.slots.len().max(1) as u64, false);
    let (arr, st, var) = (edit::next_id(m), edit::next_id(m), edit::next_id(m));
    let g = &mut m.types_global_values;
    g.push(Instruction::new(
        Op::TypeArray,
        None,
        Some(arr),
        vec![Operand::IdRef(uint), Operand::IdRef(len)],
    ));
    g.push(Instruction::new(Op::TypeStruct, None, Some(st), vec![Operand::IdRef(arr)]));
    let ptr_st = edit::type_pointer(m, StorageClass::StorageBuffer, st);
    m.types_global_values.push(Instruction::new(
        Op::Variable,
        Some(ptr_st),
        Some(var),
        vec![Operand::StorageClass(StorageClass::StorageBuffer)],
    ));
    edit::decorate(m, arr, Decoration::ArrayStride, &[Operand::LiteralBit32(4)]);
    edit::decorate(m, st, Decoration::Block, &[]);
    m.annotations.push(Instruction::new(
        Op::MemberDecorate,
        None,
        None,
        vec![
            Operand::IdRef(st),
            Operand::LiteralBit32(0),
            Operand::Decoration(Decoration::Offset),
            Operand::LiteralBit32(0),
        ],
    ));
    edit::decorate(m, var, Decoration::DescriptorSet, &[Operand::LiteralBit32(p.set)]);
    edit::decorate(m, var, Decoration::Binding, &[Operand::LiteralBit32(p.binding)]);
    m.debug_names.push(Instruction::new(
        Op::Name,
        None,
        None,
        vec![Operand::IdRef(var), Operand::LiteralString("rtprobeIndexBounds".into())],
    ));
    edit::add_to_interfaces(m, var);
    let ptr_uint = edit::type_pointer(m, StorageClass::StorageBuffer, uint);
    let vulkan_model = m
        .memory_model
        .as_ref()
        .is_some_and(|i| i.operands.get(1) == Some(&Operand::MemoryModel(MemoryModel::Vulkan)));
    // Scope Device = 1, QueueFamily = 5; MemorySemantics None = 0.
    let scope = edit::constant(m, uint, if vulkan_model { 5 } else { 1 }, false);
    let zero = edit::constant(m, uint, 0, false);
    // Scope Subgroup = 3.
    let subgroup = edit::constant(m, uint, 3, false);
    if p.vote {
        edit::add_capability(m, Capability::GroupNonUniform);
        edit::add_capability(m, Capability::GroupNonUniformVote);
    }
    let k = p.slots.len().max(1) as u32;
    Ids { uint, bool_t, ptr_uint, var, zero, scope, relaxed: zero, subgroup, k, vote: p.vote }
}

/// Record and clamp every watched descriptor-array index of `m` (see the module's doc).
pub fn apply(m: &mut Module, p: &Probe) -> Report {
    let lit = |m: &Module, v, d| edit::decoration_literal(m, v, d).unwrap_or(0);
    let mut unmatched = 0;
    let mut watched: Vec<(dynamic_access::Access, usize, bool)> = Vec::new();
    for a in dynamic_access::find_all(m) {
        let key = (lit(m, a.var, Decoration::DescriptorSet), lit(m, a.var, Decoration::Binding));
        if !p.slots.iter().any(|s| (s.set, s.binding) == key) {
            continue;
        }
        // A watched binding's access whose declaration no slot matches is out of sight: said,
        // never run unclamped as if checked.
        let Some(fixed) = declared_size(m, a.var) else {
            unmatched += 1;
            continue;
        };
        let slot = p.slots.iter().position(|s| {
            (s.set, s.binding) == key
                && s.fixed == fixed.is_some()
                && fixed.is_none_or(|n| n == s.count)
        });
        let Some(slot) = slot else {
            unmatched += 1;
            continue;
        };
        let plain = !edit::is_constant(m, a.index) && !super::uniformity::decorated(m, &a);
        watched.push((a, slot, plain));
    }
    let vars: Vec<Word> = edit::descriptor_variables(m)
        .into_iter()
        .filter(|v| {
            let key = (lit(m, *v, Decoration::DescriptorSet), lit(m, *v, Decoration::Binding));
            p.slots.iter().any(|s| (s.set, s.binding) == key) && is_array(m, *v)
        })
        .collect();
    let mut report = Report { escaped: escapes(m, &vars), skipped: unmatched, ..Report::default() };
    if watched.is_empty() {
        return report;
    }
    let ids = declare(m, p);
    // Last first, so the positions of the accesses still to come stay right.
    watched.sort_by_key(|(a, _, _)| std::cmp::Reverse((a.func, a.block, a.inst)));
    for (a, slot, plain) in watched {
        match edit::int_type_of(m, a.index) {
            Some((32, signed)) => {
                let at = (slot as u32, p.slots[slot].count, plain);
                let code = clamp(m, &ids, (a.index, signed), at);
                let (code, clamped) = code;
                let b = &mut m.functions[a.func].blocks[a.block];
                b.instructions[a.inst].operands[1] = Operand::IdRef(clamped);
                b.instructions.splice(a.inst..a.inst, code);
                report.instrumented += 1;
            }
            _ => report.skipped += 1,
        }
    }
    report
}

/// The instructions that record `index` in `slot` (in group 1 too when `plain`: dynamic, no
/// `NonUniform`) and give it clamped below `count`, and the clamped index's id.
fn clamp(
    m: &mut Module,
    ids: &Ids,
    index: (Word, bool),
    (slot, count, plain): (u32, u32, bool),
) -> (Vec<Instruction>, Word) {
    let (index, signed) = index;
    let nonuniform = edit::has_decoration(m, index, Decoration::NonUniform);
    let mut code = Vec::new();
    let u = if signed {
        let u = edit::next_id(m);
        code.push(Instruction::new(
            Op::Bitcast,
            Some(ids.uint),
            Some(u),
            vec![Operand::IdRef(index)],
        ));
        u
    } else {
        index
    };
    let count_c = edit::constant(m, ids.uint, count as u64, false);
    let last_c = edit::constant(m, ids.uint, count.saturating_sub(1) as u64, false);
    let (lt, clamped) = (edit::next_id(m), edit::next_id(m));
    let id = Operand::IdRef;
    code.extend(record(m, ids, u, slot));
    if plain {
        code.extend(record(m, ids, u, 3 * ids.k + slot));
    }
    code.push(Instruction::new(
        Op::ULessThan,
        Some(ids.bool_t),
        Some(lt),
        vec![id(u), id(count_c)],
    ));
    code.push(Instruction::new(
        Op::Select,
        Some(ids.uint),
        Some(clamped),
        vec![id(lt), id(u), id(last_c)],
    ));
    if nonuniform {
        if u != index {
            edit::decorate(m, u, Decoration::NonUniform, &[]);
        }
        edit::decorate(m, clamped, Decoration::NonUniform, &[]);
    }
    (code, clamped)
}

/// `OpAtomic{op}(seen[word], value)`.
fn atomic(m: &mut Module, ids: &Ids, op: Op, word: u32, value: Word) -> [Instruction; 2] {
    let id = Operand::IdRef;
    let at = edit::constant(m, ids.uint, word as u64, false);
    let (ptr, res) = (edit::next_id(m), edit::next_id(m));
    [
        Instruction::new(
            Op::AccessChain,
            Some(ids.ptr_uint),
            Some(ptr),
            vec![id(ids.var), id(ids.zero), id(at)],
        ),
        Instruction::new(
            op,
            Some(ids.uint),
            Some(res),
            vec![id(ptr), id(ids.scope), id(ids.relaxed), id(value)],
        ),
    ]
}

/// `seen[at] = max(…, i)`, `seen[2K + at] = min(…, i)` and `seen[K + at] |= 1 | (i differs in
/// the subgroup ? 2 : 0)` (bit 1 only with [`Probe::vote`]).
fn record(m: &mut Module, ids: &Ids, u: Word, at: u32) -> Vec<Instruction> {
    let id = Operand::IdRef;
    let one = edit::constant(m, ids.uint, 1, false);
    let mut code = atomic(m, ids, Op::AtomicUMax, at, u).to_vec();
    code.extend(atomic(m, ids, Op::AtomicUMin, 2 * ids.k + at, u));
    let bits = if ids.vote {
        let three = edit::constant(m, ids.uint, 3, false);
        let (all, bits) = (edit::next_id(m), edit::next_id(m));
        code.push(Instruction::new(
            Op::GroupNonUniformAllEqual,
            Some(ids.bool_t),
            Some(all),
            vec![id(ids.subgroup), id(u)],
        ));
        code.push(Instruction::new(
            Op::Select,
            Some(ids.uint),
            Some(bits),
            vec![id(all), id(one), id(three)],
        ));
        bits
    } else {
        one
    };
    code.extend(atomic(m, ids, Op::AtomicOr, ids.k + at, bits));
    code
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::patches::{assemble, validate, Validation};

    const GLSL: &str = "#version 460\n#extension GL_EXT_ray_tracing : require\n\
        #extension GL_EXT_nonuniform_qualifier : require\n\
        layout(set = 1, binding = 0) uniform sampler2D maps[];\n\
        layout(set = 1, binding = 1) readonly buffer B { vec4 v[]; } bufs[4];\n\
        layout(set = 1, binding = 2) readonly buffer Ids { int id[]; } ids;\n\
        layout(location = 0) rayPayloadInEXT vec4 c;\n\
        void main() { int k = ids.id[gl_InstanceCustomIndexEXT];\n\
        c = textureLod(maps[nonuniformEXT(k + 1)], vec2(0), 0.0) + bufs[uint(k) & 3u].v[0]\n\
          + bufs[2].v[1]; }\n";

    fn probe() -> Probe {
        let slots = vec![
            Slot { set: 1, binding: 0, fixed: false, count: 64 },
            Slot { set: 1, binding: 1, fixed: true, count: 4 },
        ];
        Probe { set: 1, binding: 9, slots, vote: true }
    }

    fn ops(m: &Module, op: Op) -> Vec<&Instruction> {
        m.functions
            .iter()
            .flat_map(|f| f.blocks.iter().flat_map(|b| b.instructions.iter()))
            .filter(|i| i.class.opcode == op)
            .collect()
    }

    /// Both watched arrays' accesses (the constant index too) record and clamp; the result
    /// validates; the buffer sits at the probe's place; `nonuniformEXT` stays on the new index.
    #[test]
    fn every_watched_access_records_and_clamps_its_index() {
        let mut m = crate::patches::compiled(shaderc::ShaderKind::ClosestHit, "t.rchit", GLSL);
        let r = apply(&mut m, &probe());
        assert_eq!(r, Report { instrumented: 3, skipped: 0, escaped: 0 });
        // Group 0 for each of the three, group 1 again for the one dynamic index without
        // `NonUniform` (`bufs[uint(k) & 3u]`): not the `nonuniformEXT` one, not the constant.
        assert_eq!(ops(&m, Op::AtomicUMax).len(), 4);
        assert_eq!(ops(&m, Op::GroupNonUniformAllEqual).len(), 4);
        // spirv-val is installed wherever the tests run (scripts/setup): a missing one fails.
        let v = validate(&assemble(&m));
        assert!(matches!(v, Validation::Valid), "{v:?}");
        let var = m
            .debug_names
            .iter()
            .find(|n| {
                n.operands.get(1) == Some(&Operand::LiteralString("rtprobeIndexBounds".into()))
            })
            .and_then(|n| edit::id_operand(n, 0))
            .expect("the probe's buffer is named");
        assert_eq!(edit::decoration_literal(&m, var, Decoration::Binding), Some(9));
        assert_eq!(edit::decoration_literal(&m, var, Decoration::DescriptorSet), Some(1));
        // Every watched chain now indexes an OpSelect's result: the clamp.
        let selects: Vec<Word> = ops(&m, Op::Select).iter().filter_map(|i| i.result_id).collect();
        let chained = ops(&m, Op::AccessChain)
            .iter()
            .filter(|i| edit::id_operand(i, 1).is_some_and(|x| selects.contains(&x)))
            .count();
        assert_eq!(chained, 3);
        let decorated = selects
            .iter()
            .filter(|s| edit::has_decoration(&m, **s, Decoration::NonUniform))
            .count();
        assert_eq!(decorated, 1, "only the nonuniformEXT index is decorated");
    }

    /// An array passed to a function is out of the pass's sight: counted as escaped, so the
    /// caller can say the check did not see every access.
    #[test]
    fn an_array_passed_to_a_function_escapes() {
        let glsl = "#version 460\n#extension GL_EXT_ray_tracing : require\n\
            layout(set = 1, binding = 0) uniform sampler2D maps[8];\n\
            layout(location = 0) rayPayloadInEXT vec4 c;\n\
            vec4 look(sampler2D s[8], uint i) { return textureLod(s[i], vec2(0), 0.0); }\n\
            void main() { c = look(maps, uint(gl_InstanceCustomIndexEXT) & 7u); }\n";
        let mut m = crate::patches::compiled(shaderc::ShaderKind::ClosestHit, "t.rchit", glsl);
        let slots = vec![Slot { set: 1, binding: 0, fixed: true, count: 8 }];
        let r = apply(&mut m, &Probe { set: 1, binding: 9, slots, vote: false });
        assert!(r.escaped >= 1, "{r:?}");
    }

    /// Loads of single descriptors (a texture, the TLAS a raygen traces) are no escape: only
    /// arrays are watched.
    #[test]
    fn single_descriptors_do_not_escape() {
        let glsl = "#version 460\n#extension GL_EXT_ray_tracing : require\n\
            layout(set = 1, binding = 0) uniform sampler2D maps[8];\n\
            layout(set = 1, binding = 1) uniform sampler2D env;\n\
            layout(set = 0, binding = 0) uniform accelerationStructureEXT scene;\n\
            layout(location = 0) rayPayloadInEXT vec4 c;\n\
            void main() { c = textureLod(maps[uint(gl_InstanceCustomIndexEXT) & 7u], vec2(0), 0.0)\n\
              + textureLod(env, vec2(0), 0.0);\n\
              traceRayEXT(scene, 0u, 255u, 0u, 0u, 0u, vec3(0), 0.0, vec3(1, 0, 0), 1.0, 0); }\n";
        let mut m = crate::patches::compiled(shaderc::ShaderKind::ClosestHit, "t.rchit", glsl);
        let slot = |set, binding, count| Slot { set, binding, fixed: true, count };
        let slots = vec![slot(1, 0, 8), slot(1, 1, 1), slot(0, 0, 1)];
        let r = apply(&mut m, &Probe { set: 2, binding: 0, slots, vote: false });
        assert_eq!(r, Report { instrumented: 1, skipped: 0, escaped: 0 });
    }

    /// A fixed array whose length is a spec constant is held to the constant's default (as the
    /// harness's reflection sizes it); a declaration no slot matches is skipped, never left
    /// unclamped as if checked.
    #[test]
    fn a_spec_constant_length_is_its_default_and_a_stranger_is_skipped() {
        let glsl = "#version 460\n#extension GL_EXT_ray_tracing : require\n\
            layout(constant_id = 0) const int N = 4;\n\
            layout(set = 1, binding = 0) uniform sampler2D maps[N];\n\
            layout(location = 0) rayPayloadInEXT vec4 c;\n\
            void main() { c = textureLod(maps[uint(gl_InstanceCustomIndexEXT)], vec2(0), 0.0); }\n";
        let module = crate::patches::compiled(shaderc::ShaderKind::ClosestHit, "t.rchit", glsl);
        let slot = |count| Slot { set: 1, binding: 0, fixed: true, count };
        let probe = |count| Probe { set: 2, binding: 0, slots: vec![slot(count)], vote: false };
        let r = apply(&mut module.clone(), &probe(4));
        assert_eq!(r, Report { instrumented: 1, skipped: 0, escaped: 0 });
        let r = apply(&mut module.clone(), &probe(5));
        assert_eq!(r, Report { instrumented: 0, skipped: 1, escaped: 0 });
    }

    /// An array the probe does not list is left alone, and a module without watched accesses
    /// gets no buffer at all.
    #[test]
    fn unwatched_arrays_are_left_alone() {
        let mut m = crate::patches::compiled(shaderc::ShaderKind::ClosestHit, "t.rchit", GLSL);
        let before = assemble(&m);
        let slots = vec![Slot { set: 2, binding: 0, fixed: true, count: 8 }];
        let p = Probe { set: 1, binding: 9, slots, vote: false };
        assert_eq!(apply(&mut m, &p), Report::default());
        assert_eq!(assemble(&m), before);
    }
}
