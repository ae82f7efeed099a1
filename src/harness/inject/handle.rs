//! An acceleration structure access's fault tied to the handle's use: an AS handle has no bits
//! (SPIR-V converts integers to acceleration structures, never back), so the fault after its
//! descriptor load takes a constant input, and its result (`bump`, zero at run time but not to
//! a compiler) is XOR-ed into the cull mask of every ray the handle traces — each
//! `OpTraceRayKHR`, `OpRayQueryInitializeKHR`, `OpHitObjectTraceRay*`, `OpTrace*NV` taking it
//! (or an `OpCopyObject` of it) in the load's function ([`consumers`], [`feed`]). The XOR sits
//! right before its consumer: the load's block dominates every use of the handle, so the fault
//! (right after the load) dominates the XOR, and the cull mask (the consumer's operand) does too.
//!
//! Deleting the trace deletes the tie; a loaded handle with no such consumer in its function
//! (handed to another function, or unused) is not injected at all (`inject` lists it as
//! skipped; a TLAS variable passed by pointer and loaded in the callee is no site at all): a
//! fault nothing uses can be dropped by a driver's compiler, and a reduction must not keep a
//! load for a fault that no longer does anything. The mask is XOR-ed, not OR-ed: the bump is
//! 0 or 1, and `0xFF | bump` is `0xFF` to a compiler that knows the bump's bits (lavapipe
//! folded it and dropped the fault: the first shadow run passed); `0xFF ^ bump` is not.
use crate::patches::edit::{self, id_operand, next_id};
use rspirv::dr::{Instruction, Module, Operand};
use rspirv::spirv::{Op, Word};
use std::collections::HashSet;

/// The operand position of the acceleration structure in an instruction that traces a ray
/// with it; its cull mask is two further (`AS, RayFlags, CullMask`, the same in every one).
fn as_operand(op: Op) -> Option<usize> {
    match op {
        Op::TraceRayKHR | Op::TraceNV | Op::TraceMotionNV | Op::TraceRayMotionNV => Some(0),
        Op::RayQueryInitializeKHR
        | Op::HitObjectTraceRayNV
        | Op::HitObjectTraceRayMotionNV
        | Op::HitObjectTraceRayEXT
        | Op::HitObjectTraceRayMotionEXT
        | Op::HitObjectTraceReorderExecuteEXT
        | Op::HitObjectTraceMotionReorderExecuteEXT => Some(1),
        _ => None,
    }
}

/// `handle` and every `OpCopyObject` of it in function `f`.
fn aliases(m: &Module, f: usize, handle: Word) -> HashSet<Word> {
    let mut set = HashSet::from([handle]);
    for i in m.functions[f].blocks.iter().flat_map(|b| &b.instructions) {
        if i.class.opcode == Op::CopyObject && id_operand(i, 0).is_some_and(|a| set.contains(&a)) {
            set.extend(i.result_id);
        }
    }
    set
}

/// Where `handle` traces a ray in function `f`: (block, instruction, cull mask operand).
pub fn consumers(m: &Module, f: usize, handle: Word) -> Vec<(usize, usize, usize)> {
    let names = aliases(m, f, handle);
    let mut out = Vec::new();
    for (bi, b) in m.functions[f].blocks.iter().enumerate() {
        for (ii, i) in b.instructions.iter().enumerate() {
            let Some(p) = as_operand(i.class.opcode) else { continue };
            if id_operand(i, p).is_some_and(|a| names.contains(&a)) {
                out.push((bi, ii, p + 2));
            }
        }
    }
    out
}

/// Each consumer's cull mask made `mask ^ bump`; how many were fed.
pub fn feed(m: &mut Module, f: usize, handle: Word, bump: Word) -> usize {
    let found = consumers(m, f, handle);
    // Last first: an insertion never moves a consumer still to do.
    for &(b, i, at) in found.iter().rev() {
        let Some(mask) = id_operand(&m.functions[f].blocks[b].instructions[i], at) else {
            continue;
        };
        let ty = edit::def(m, mask)
            .and_then(|d| d.result_type)
            .unwrap_or_else(|| edit::type_int(m, 32, false));
        let new = next_id(m);
        let xor = Instruction::new(
            Op::BitwiseXor,
            Some(ty),
            Some(new),
            vec![Operand::IdRef(mask), Operand::IdRef(bump)],
        );
        let block = &mut m.functions[f].blocks[b];
        block.instructions[i].operands[at] = Operand::IdRef(new);
        block.instructions.insert(i, xor);
    }
    found.len()
}
