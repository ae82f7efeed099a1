//! `value-bits`: the probed value's last word gets its low bits flipped before the probe stores
//! it. The last component is never 0 (`probe::resource_value`'s `0.25 + element`, the AS probe's
//! 1.0), so the flipped word stays a normal float: no driver can flush it back to the original.
//!
//! SPIR-V rules relied on: `OpCompositeExtract` / `OpCompositeInsert` of component 3 of a
//! 4-component vector; `OpBitcast` between a 32-bit float and a 32-bit integer; `OpBitwiseXor`
//! on integers. The new value is computed right before the store, which its operand dominates.
use super::locate::{self, At};
use crate::patches::edit;
use crate::patches::PatchError;
use rspirv::dr::{Instruction, Module, Operand};
use rspirv::spirv::{Op, Word};

/// The bits flipped in the last word.
pub const FLIPPED: u32 = 0b111;

/// The word `w` with [`FLIPPED`] flipped (what the reference predicts).
pub fn flip(w: f32) -> f32 {
    f32::from_bits(w.to_bits() ^ FLIPPED)
}

fn unsupported(id: Word, what: &str) -> PatchError {
    PatchError::Unsupported { patch: "value-bits", id, what: what.into() }
}

/// Flip the last word of the value stored at `at` (a store's value operand).
fn flip_at(m: &mut Module, at: At) -> Result<(), PatchError> {
    let v = at.id(m).ok_or_else(|| unsupported(0, "the store's value is not an id"))?;
    let vec_t = edit::def(m, v)
        .and_then(|d| d.result_type)
        .ok_or_else(|| unsupported(v, "untyped value"))?;
    let comp_t = edit::def(m, vec_t)
        .filter(|d| {
            d.class.opcode == Op::TypeVector && d.operands.get(1) == Some(&Operand::LiteralBit32(4))
        })
        .and_then(|d| edit::id_operand(d, 0))
        .ok_or_else(|| unsupported(v, "the probe's value is not a 4-component vector"))?;
    let u32_t = edit::type_int(m, 32, false);
    let mask = edit::constant(m, u32_t, FLIPPED.into(), false);
    let ids: Vec<Word> = (0..5).map(|_| edit::next_id(m)).collect();
    let (w, bits, flipped, back, out) = (ids[0], ids[1], ids[2], ids[3], ids[4]);
    let three = Operand::LiteralBit32(3);
    let id = Operand::IdRef;
    let new = [
        Instruction::new(Op::CompositeExtract, Some(comp_t), Some(w), vec![id(v), three.clone()]),
        Instruction::new(Op::Bitcast, Some(u32_t), Some(bits), vec![id(w)]),
        Instruction::new(Op::BitwiseXor, Some(u32_t), Some(flipped), vec![id(bits), id(mask)]),
        Instruction::new(Op::Bitcast, Some(comp_t), Some(back), vec![id(flipped)]),
        Instruction::new(Op::CompositeInsert, Some(vec_t), Some(out), vec![id(back), id(v), three]),
    ];
    let block = &mut m.functions[at.func].blocks[at.block].instructions;
    block[at.inst].operands[at.operand] = Operand::IdRef(out);
    for (k, i) in new.into_iter().enumerate() {
        block.insert(at.inst + k, i);
    }
    Ok(())
}

/// Flip the last word of every value the probe stores to `probeValue`; the count.
pub fn apply(m: &mut Module) -> Result<usize, PatchError> {
    let Some(var) = locate::probe_value_variable(m) else { return Ok(0) };
    let mut sites = locate::stores_to(m, var);
    sites.sort();
    for at in sites.iter().rev() {
        flip_at(m, *at)?;
    }
    Ok(sites.len())
}
