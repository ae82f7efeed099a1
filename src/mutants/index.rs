//! Rewriting an index operand (descriptor, sampler, address-table, element): the new index is
//! computed by instructions inserted right before the instruction that uses it, and only that
//! operand is changed, so the slot the probe records (computed by its own instructions: the GLSL
//! writes the index expression twice) stays the unmutated one and the reference can tell the
//! read apart.
//!
//! SPIR-V rules relied on: an instruction inserted right before a use is dominated by the used
//! value's definition (which dominates the use); `OpIAdd` and `OpIMul` take integer operands of
//! the result's type whatever their signedness, the modulo is `OpUMod` for an unsigned type and
//! `OpSMod` for a signed one (glslang types a literal index `int`; values here are small and
//! non-negative, where both agree); `OpGroupNonUniformBroadcastFirst` takes a `Subgroup` scope id (a constant 3)
//! and needs the `GroupNonUniformBallot` capability (SPIR-V 1.3+). A new index replacing one
//! decorated `NonUniform` is decorated too (SPIR-V 2.16.2: the decoration only permits
//! non-uniformity).
use super::locate::At;
use crate::patches::edit;
use crate::patches::PatchError;
use rspirv::dr::{Instruction, Module, Operand};
use rspirv::spirv::{Capability, Decoration, Op, Word};

/// What an index becomes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum IndexFn {
    /// The constant 0.
    Zero,
    /// `(i + 1) mod n` ([`next`]).
    Next(u32),
    /// `2 · (i mod ⌈n/2⌉)` ([`doubled`]).
    Doubled(u32),
    /// The first active lane's `i` (`OpGroupNonUniformBroadcastFirst`).
    Broadcast,
    /// `base + (custom & mask)` without the base: the `OpBitwiseAnd` operand of the `OpIAdd` the
    /// index is (through `OpCopyObject` / `OpBitcast`, as `nonuniformEXT` and casts leave it).
    DropBase,
}

/// `(i + 1) mod n`: the next slot, inside an array of `n`.
pub fn next(i: u32, n: u32) -> u32 {
    (i + 1) % n.max(1)
}

/// `2 · (i mod ⌈n/2⌉)`: the slot read at twice the stride, the index kept so that it stays inside
/// an array of `n` (`2 · (⌈n/2⌉ - 1) ≤ n - 1`).
pub fn doubled(i: u32, n: u32) -> u32 {
    2 * (i % n.div_ceil(2).max(1))
}

/// The value `f` makes of index `i` in an array of `n` (what the reference predicts; `Broadcast`
/// and `DropBase` depend on more than `i`, their callers decide).
pub fn apply_fn(f: IndexFn, i: u32) -> Option<u32> {
    match f {
        IndexFn::Zero => Some(0),
        IndexFn::Next(n) => Some(next(i, n)),
        IndexFn::Doubled(n) => Some(doubled(i, n)),
        IndexFn::Broadcast | IndexFn::DropBase => None,
    }
}

fn unsupported(id: Word, what: impl Into<String>) -> PatchError {
    PatchError::Unsupported { patch: "mutant", id, what: what.into() }
}

/// The type of `id`.
fn type_of(m: &Module, id: Word) -> Result<Word, PatchError> {
    edit::def(m, id)
        .and_then(|d| d.result_type)
        .ok_or_else(|| unsupported(id, "index without a type"))
}

/// The modulo of integer type `ty`: `OpUMod` for an unsigned type, `OpSMod` for a signed one.
fn modulo(m: &Module, ty: Word) -> Op {
    let signed =
        edit::def(m, ty).is_some_and(|d| d.operands.get(1) == Some(&Operand::LiteralBit32(1)));
    if signed {
        Op::SMod
    } else {
        Op::UMod
    }
}

/// The masked custom index the index adds its base to (see [`IndexFn::DropBase`]).
fn masked_operand(m: &Module, index: Word) -> Result<Word, PatchError> {
    let mut id = index;
    for _ in 0..8 {
        let d = edit::def(m, id).ok_or_else(|| unsupported(index, "index without a definition"))?;
        match d.class.opcode {
            Op::CopyObject | Op::Bitcast => {
                id = edit::id_operand(d, 0).ok_or_else(|| unsupported(id, "no operand"))?;
            }
            Op::IAdd => {
                return (0..2)
                    .filter_map(|k| edit::id_operand(d, k))
                    .find(|o| edit::def(m, *o).is_some_and(|x| x.class.opcode == Op::BitwiseAnd))
                    .ok_or_else(|| {
                        unsupported(id, "no masked custom index among the addition's operands")
                    });
            }
            _ => break,
        }
    }
    Err(unsupported(index, "the index is not base + (custom & mask)"))
}

/// Rewrite the operand at `at` with `f`; returns the new index id.
pub fn rewrite(m: &mut Module, at: At, f: IndexFn) -> Result<Word, PatchError> {
    let old = at.id(m).ok_or_else(|| unsupported(0, "the operand is not an id"))?;
    let ty = type_of(m, old)?;
    let mut insert: Vec<Instruction> = vec![];
    let new = match f {
        IndexFn::Zero => edit::constant(m, ty, 0, false),
        IndexFn::DropBase => masked_operand(m, old)?,
        IndexFn::Next(n) => {
            let (one, modulus) =
                (edit::constant(m, ty, 1, false), edit::constant(m, ty, n.into(), false));
            let (sum, r) = (edit::next_id(m), edit::next_id(m));
            insert.push(binary(Op::IAdd, ty, sum, old, one));
            insert.push(binary(modulo(m, ty), ty, r, sum, modulus));
            r
        }
        IndexFn::Doubled(n) => {
            let half = edit::constant(m, ty, n.div_ceil(2).max(1).into(), false);
            let two = edit::constant(m, ty, 2, false);
            let (wrapped, r) = (edit::next_id(m), edit::next_id(m));
            insert.push(binary(modulo(m, ty), ty, wrapped, old, half));
            insert.push(binary(Op::IMul, ty, r, wrapped, two));
            r
        }
        IndexFn::Broadcast => {
            edit::add_capability(m, Capability::GroupNonUniformBallot);
            let u32_t = edit::type_int(m, 32, false);
            let subgroup = edit::constant(m, u32_t, 3, false);
            let r = edit::next_id(m);
            insert.push(Instruction::new(
                Op::GroupNonUniformBroadcastFirst,
                Some(ty),
                Some(r),
                vec![Operand::IdRef(subgroup), Operand::IdRef(old)],
            ));
            r
        }
    };
    if !insert.is_empty() && edit::has_decoration(m, old, Decoration::NonUniform) {
        edit::decorate(m, new, Decoration::NonUniform, &[]);
    }
    let block = &mut m.functions[at.func].blocks[at.block].instructions;
    block[at.inst].operands[at.operand] = Operand::IdRef(new);
    for (k, i) in insert.into_iter().enumerate() {
        block.insert(at.inst + k, i);
    }
    Ok(new)
}

fn binary(op: Op, ty: Word, result: Word, a: Word, b: Word) -> Instruction {
    Instruction::new(op, Some(ty), Some(result), vec![Operand::IdRef(a), Operand::IdRef(b)])
}

/// Rewrite every operand of `sites` with `f`, last first (insertions do not move the places not
/// yet rewritten). The count rewritten.
pub fn rewrite_all(m: &mut Module, mut sites: Vec<At>, f: IndexFn) -> Result<usize, PatchError> {
    sites.sort();
    for at in sites.iter().rev() {
        rewrite(m, *at, f)?;
    }
    Ok(sites.len())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mutated_indices_stay_inside_the_array() {
        for n in 1..40 {
            for i in 0..n {
                assert!(next(i, n) < n && doubled(i, n) < n, "{i} of {n}");
            }
        }
        assert_eq!((next(19, 20), doubled(3, 20), doubled(13, 20)), (0, 6, 6));
        assert_eq!(apply_fn(IndexFn::Zero, 7), Some(0));
        assert_eq!(apply_fn(IndexFn::Broadcast, 7), None);
    }
}
