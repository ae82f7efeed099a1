//! `element-zero` on the recommended pattern's array texture: the layer the probe samples (the
//! coordinate's third component, `vec3(uv, float(probeSlot))`) becomes 0. (The packed buffer's
//! element index is an index operand: `super::index` rewrites it.)
//!
//! SPIR-V rules relied on: the coordinate of an arrayed 2D image sample is a 3-component float
//! vector whose component 2 is the layer; `OpCompositeInsert` of a float constant replaces one
//! component; it is computed right before the sample, which its operand dominates.
use super::locate::At;
use crate::patches::edit;
use crate::patches::PatchError;
use rspirv::dr::{Instruction, Module, Operand};
use rspirv::spirv::{Op, Word};

fn unsupported(id: Word, what: &str) -> PatchError {
    PatchError::Unsupported { patch: "element-zero", id, what: what.into() }
}

/// Sample layer 0 at the coordinate operand `at`.
fn layer_zero(m: &mut Module, at: At) -> Result<(), PatchError> {
    let coord = at.id(m).ok_or_else(|| unsupported(0, "the coordinate is not an id"))?;
    let vec_t = edit::def(m, coord)
        .and_then(|d| d.result_type)
        .ok_or_else(|| unsupported(coord, "untyped coordinate"))?;
    let float_t = edit::def(m, vec_t)
        .filter(|d| {
            d.class.opcode == Op::TypeVector && d.operands.get(1) == Some(&Operand::LiteralBit32(3))
        })
        .and_then(|d| edit::id_operand(d, 0))
        .ok_or_else(|| unsupported(coord, "not an arrayed 2D coordinate (vec3)"))?;
    let zero = edit::constant(m, float_t, 0, false);
    let out = edit::next_id(m);
    let insert = Instruction::new(
        Op::CompositeInsert,
        Some(vec_t),
        Some(out),
        vec![Operand::IdRef(zero), Operand::IdRef(coord), Operand::LiteralBit32(2)],
    );
    let block = &mut m.functions[at.func].blocks[at.block].instructions;
    block[at.inst].operands[at.operand] = Operand::IdRef(out);
    block.insert(at.inst, insert);
    Ok(())
}

/// Sample layer 0 at every coordinate of `sites`; the count.
pub fn layers_zero(m: &mut Module, mut sites: Vec<At>) -> Result<usize, PatchError> {
    sites.sort();
    for at in sites.iter().rev() {
        layer_zero(m, *at)?;
    }
    Ok(sites.len())
}
