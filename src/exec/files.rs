//! A cell's shader files on disk: a repro bundle's SPIR-V read back (`run --cell-spec`) and
//! `--dump`'s GLSL and SPIR-V written per cell.
use crate::model::Cell;
use crate::shadergen;

/// The module of `role` in a repro bundle's `shaders/` (`<role file>.spv`, little-endian words
/// starting with the SPIR-V magic number).
pub(super) fn bundle_spirv(dir: &std::path::Path, role: shadergen::Role) -> Result<Vec<u32>, String> {
    let path = dir.join(format!("{}.spv", role.file_name()));
    let bytes = std::fs::read(&path).map_err(|e| format!("repro bundle: cannot read {}: {e}", path.display()))?;
    let words: Vec<u32> = bytes.chunks_exact(4).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
    if bytes.len() % 4 != 0 || words.first() != Some(&0x0723_0203) {
        return Err(format!("repro bundle: {} is not SPIR-V", path.display()));
    }
    Ok(words)
}

pub(super) fn dump(dir: &std::path::Path, cell: &Cell, shaders: &shadergen::CellShaders, spirv: &[std::sync::Arc<Vec<u32>>]) -> Result<(), String> {
    let d = dir.join(cell.id());
    std::fs::create_dir_all(&d).map_err(|e| format!("--dump {}: {e}", d.display()))?;
    for (s, words) in shaders.shaders.iter().zip(spirv) {
        let glsl = d.join(format!("{}.glsl", s.role.file_name()));
        std::fs::write(&glsl, &s.glsl).map_err(|e| format!("--dump {}: {e}", glsl.display()))?;
        let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
        let spv = d.join(format!("{}.spv", s.role.file_name()));
        std::fs::write(&spv, bytes).map_err(|e| format!("--dump {}: {e}", spv.display()))?;
    }
    Ok(())
}
