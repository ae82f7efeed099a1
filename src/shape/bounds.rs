//! Whether every descriptor index of a module is provably in bounds, for `reduce`'s
//! interestingness test: spirv-reduce's OperandToUndef pass turns indices into `OpUndef`, and
//! other passes turn them into other constants. A candidate whose descriptor access reads an
//! undefined index, or a constant one past the array, may fault for a reason that is not the
//! finding's (an index past the array is the harness's `error` under GPU-AV in `run --shader`,
//! never a finding), so it is refused: no slippage into another bug.
use super::defs::{is_chain, Defs};
use super::index;
use rspirv::dr::{Module, Operand};
use rspirv::spirv::{Decoration, Op, Word};

/// Why an index is not provably in bounds.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum OutOfBounds {
    #[error("an access chain into {var} has an undefined index (OpUndef or a never-written variable reaches %{index})")]
    Undef { var: String, index: Word },
    #[error("{var}[{value}]: a constant index past its {len} descriptors")]
    Constant { var: String, value: u64, len: u32 },
    #[error("a read's pointer %{ptr} is OpUndef")]
    UndefPointer { ptr: Word },
    #[error("%{user} uses %{handle}, an OpUndef {what}")]
    UndefHandle { user: Word, handle: Word, what: &'static str },
}

/// Check every access chain rooted at a descriptor variable or the resource heap: no index
/// reached by `OpUndef` (or a never-written variable); a constant descriptor index below the
/// array's length (`runtime_len` for a runtime array: the descriptors the harness writes; a
/// heap's constant index is not checked, its bound is the heap layout's).
pub fn check(m: &Module, runtime_len: u32) -> Result<(), OutOfBounds> {
    let d = Defs::new(m);
    let body = m.functions.iter().flat_map(|f| f.blocks.iter().flat_map(|b| &b.instructions));
    for i in body {
        if matches!(i.class.opcode, Op::Load | Op::Store) {
            if let Some(Operand::IdRef(p)) = i.operands.first() {
                if d.get(*p).is_some_and(|x| x.class.opcode == Op::Undef) {
                    return Err(OutOfBounds::UndefPointer { ptr: *p });
                }
            }
        }
        undef_handle(&d, i)?;
        if let Some(h) = i.result_id.and_then(|r| super::heap::access(&d, r)) {
            // A heap index's bound is the heap layout's, not known here: undef only.
            if index::leaves(&d, h.index).undef {
                return Err(OutOfBounds::Undef { var: "resource_heap".into(), index: h.index });
            }
            continue;
        }
        if !is_chain(i.class.opcode) {
            continue;
        }
        let Some(Operand::IdRef(base)) = i.operands.first() else { continue };
        let (var, _) = d.root(*base);
        let heap = super::heap::access(&d, var).is_some();
        if d.decoration(var, Decoration::DescriptorSet).is_none() && !heap {
            continue;
        }
        for x in i.operands.iter().skip(1).filter_map(|o| match o {
            Operand::IdRef(w) => Some(*w),
            _ => None,
        }) {
            if index::leaves(&d, x).undef {
                return Err(OutOfBounds::Undef { var: d.name(var), index: x });
            }
        }
        if *base == var {
            constant_index(&d, var, i.operands.get(1), runtime_len)?;
        }
    }
    Ok(())
}

/// A constant first index into descriptor array `var` below its length.
fn constant_index(
    d: &Defs,
    var: Word,
    first: Option<&Operand>,
    runtime_len: u32,
) -> Result<(), OutOfBounds> {
    let Some(ty) = d.pointee(var) else { return Ok(()) };
    let len = match ty.class.opcode {
        Op::TypeRuntimeArray => runtime_len,
        Op::TypeArray => match ty.operands.get(1).and_then(|o| constant(d, o)) {
            Some(n) => n as u32,
            None => return Ok(()),
        },
        _ => return Ok(()),
    };
    match first.and_then(|o| constant(d, o)) {
        Some(v) if v >= len as u64 => {
            Err(OutOfBounds::Constant { var: d.name(var), value: v, len })
        }
        _ => Ok(()),
    }
}

/// The value of a plain integer constant (`OpConstantNull`: 0), as unsigned.
fn constant(d: &Defs, o: &Operand) -> Option<u64> {
    let Operand::IdRef(id) = o else { return None };
    let c = d.get(*id)?;
    match (c.class.opcode, c.operands.first()) {
        (Op::Constant, Some(Operand::LiteralBit32(v))) => Some(*v as u64),
        (Op::Constant, Some(Operand::LiteralBit64(v))) => Some(*v),
        (Op::ConstantNull, _) => Some(0),
        _ => None,
    }
}

/// An instruction using an `OpUndef` image, sampler, acceleration structure or pointer: what
/// it reads is no descriptor at all.
fn undef_handle(d: &Defs, i: &rspirv::dr::Instruction) -> Result<(), OutOfBounds> {
    for o in &i.operands {
        let Operand::IdRef(x) = o else { continue };
        let Some(u) = d.get(*x).filter(|u| u.class.opcode == Op::Undef) else { continue };
        let what = match u.result_type.and_then(|t| d.get(t)).map(|t| t.class.opcode) {
            Some(Op::TypeImage) => "image",
            Some(Op::TypeSampledImage) => "sampled image",
            Some(Op::TypeSampler) => "sampler",
            Some(Op::TypeAccelerationStructureKHR) => "acceleration structure",
            Some(Op::TypePointer) => "pointer",
            _ => continue,
        };
        let user = i.result_id.unwrap_or(0);
        return Err(OutOfBounds::UndefHandle { user, handle: *x, what });
    }
    Ok(())
}
