//! The matrix's workarounds on a cell's compiled modules: which apply and in which order
//! (`address_patched` is as-to-address on the descriptor variant, then the cell's own `patch`),
//! and each one's pass with the options rtprobe's probe needs (the probed array at binding 2).
//! The worker (`exec`) and a reader's copy of the shaders (`report::shaders`) both patch here.
use super::{PatchError, PatchName};
use crate::model::{Cell, Workaround};

/// The workarounds the worker applies to `cell`'s generated modules, in order (its probe spec's,
/// `probe::spec::ProbeSpec::workarounds`).
pub fn of_cell(cell: &Cell) -> Vec<Workaround> {
    crate::probe::spec::ProbeSpec::of(cell).workarounds().collect()
}

/// Apply the workaround `w` to one module, restricted to the probed array (binding 2):
/// `Some(words)` when the module had something to rewrite, `None` when not.
pub fn patch_module(words: &[u32], w: Workaround) -> Result<Option<Vec<u32>>, PatchError> {
    let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
    let mut m = super::load(&bytes)?;
    let kv =
        |pairs: &[(&str, String)]| pairs.iter().map(|(k, v)| (k.to_string(), v.clone())).collect();
    let (name, opts) = match w {
        Workaround::AsToAddress => (
            PatchName::AsToAddress,
            kv(&[
                ("binding", "2".into()),
                ("offset", crate::shadergen::PATCHED_TABLE_OFFSET.to_string()),
                ("mode", "table".into()),
            ]),
        ),
        Workaround::Nonuniform => (PatchName::Nonuniform, kv(&[])),
        // SpecId 0 is what every pipeline specializes to crate::probe::SPEC_SLOT.
        Workaround::PinIndex => (
            PatchName::PinIndex,
            kv(&[
                ("binding", "2".into()),
                ("spec-id", "0".into()),
                ("value", crate::probe::SPEC_SLOT.to_string()),
            ]),
        ),
        Workaround::SsboToAddress => (
            PatchName::SsboToAddress,
            kv(&[
                ("binding", "2".into()),
                ("offset", crate::shadergen::PATCHED_TABLE_OFFSET.to_string()),
            ]),
        ),
    };
    match super::apply(&mut m, &[name], &opts) {
        Ok(_) => Ok(Some(super::assemble(&m))),
        Err(PatchError::NothingToPatch { .. }) => Ok(None),
        Err(e) => Err(e),
    }
}
