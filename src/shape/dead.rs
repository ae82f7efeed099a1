//! Dead instructions that spirv-reduce leaves: it counts a decoration as a use, so a load or
//! access chain decorated `NonUniform` stays after everything that read it is gone. [`strip`]
//! removes side-effect-free instructions whose results nothing uses, with the decorations and
//! names that name them, until none is left; `reduce` keeps the result only when its
//! interestingness test still says yes.
use rspirv::dr::{Module, Operand};
use rspirv::spirv::{Op, Word};
use std::collections::HashSet;

/// Whether `op` has no effect beyond its result (a division by zero gives an undefined
/// value, no effect: SPIR-V 1.6, OpUDiv).
fn pure(op: Op) -> bool {
    matches!(
        op,
        Op::Load
            | Op::AccessChain
            | Op::InBoundsAccessChain
            | Op::CopyObject
            | Op::CopyLogical
            | Op::Bitcast
            | Op::UConvert
            | Op::SConvert
            | Op::ConvertUToF
            | Op::ConvertSToF
            | Op::IAdd
            | Op::ISub
            | Op::IMul
            | Op::UDiv
            | Op::SDiv
            | Op::UMod
            | Op::SMod
            | Op::SRem
            | Op::SNegate
            | Op::Not
            | Op::ShiftLeftLogical
            | Op::ShiftRightLogical
            | Op::ShiftRightArithmetic
            | Op::BitwiseAnd
            | Op::BitwiseOr
            | Op::BitwiseXor
            | Op::FAdd
            | Op::FSub
            | Op::FMul
            | Op::FDiv
            | Op::FNegate
            | Op::ConvertFToU
            | Op::ConvertFToS
            | Op::Select
            | Op::VectorShuffle
            | Op::CompositeExtract
            | Op::CompositeConstruct
            | Op::SampledImage
            | Op::UntypedAccessChainKHR
            | Op::UntypedInBoundsAccessChainKHR
            | Op::BufferPointerEXT
    )
}

/// The ids function instructions use (not annotations or names).
fn used(m: &Module) -> HashSet<Word> {
    let body = m.functions.iter().flat_map(|f| f.blocks.iter().flat_map(|b| &b.instructions));
    let mut out: HashSet<Word> = body
        .flat_map(|i| i.operands.iter())
        .filter_map(|o| match o {
            Operand::IdRef(w) => Some(*w),
            _ => None,
        })
        .collect();
    for ep in &m.entry_points {
        out.extend(ep.operands.iter().filter_map(|o| match o {
            Operand::IdRef(w) => Some(*w),
            _ => None,
        }));
    }
    out
}

/// Remove dead pure instructions of `m`'s functions (and what names them); how many.
pub fn strip(m: &mut Module) -> usize {
    let mut removed = 0;
    loop {
        let live = used(m);
        let dead: HashSet<Word> = m
            .functions
            .iter()
            .flat_map(|f| f.blocks.iter().flat_map(|b| &b.instructions))
            .filter(|i| pure(i.class.opcode))
            .filter_map(|i| i.result_id)
            .filter(|r| !live.contains(r))
            .collect();
        if dead.is_empty() {
            return removed;
        }
        removed += dead.len();
        for f in &mut m.functions {
            for b in &mut f.blocks {
                b.instructions.retain(|i| !i.result_id.is_some_and(|r| dead.contains(&r)));
            }
        }
        let names = |i: &rspirv::dr::Instruction| matches!(i.operands.first(), Some(Operand::IdRef(t)) if dead.contains(t));
        m.annotations.retain(|i| !names(i));
        m.debug_names.retain(|i| !names(i));
    }
}
