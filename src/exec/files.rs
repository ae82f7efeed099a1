//! A cell's files on disk: a repro bundle's SPIR-V read back (`run --cell-spec`), and `--dump`'s
//! GLSL and SPIR-V and the records the cell's trace wrote (`records.bin`), per cell.
use crate::model::Cell;
use crate::shadergen;
use std::path::PathBuf;

/// A bundle's SPIR-V that cannot be read, or a `--dump` file that cannot be written.
#[derive(Debug, thiserror::Error)]
pub enum FileError {
    #[error("repro bundle: cannot read {}: {err}", .path.display())]
    BundleUnreadable { path: PathBuf, err: std::io::Error },
    #[error("repro bundle: {} is not SPIR-V", .0.display())]
    NotSpirv(PathBuf),
    /// A folder or file under `--dump` (`path`).
    #[error("--dump {}: {err}", .path.display())]
    Dump { path: PathBuf, err: std::io::Error },
}

/// The module of `role` in a repro bundle's `shaders/` (`<role file>.spv`, little-endian words
/// starting with the SPIR-V magic number).
pub(super) fn bundle_spirv(
    dir: &std::path::Path,
    role: shadergen::Role,
) -> Result<Vec<u32>, FileError> {
    let path = dir.join(format!("{}.spv", role.file_name()));
    let bytes = std::fs::read(&path)
        .map_err(|err| FileError::BundleUnreadable { path: path.clone(), err })?;
    let words: Vec<u32> =
        bytes.chunks_exact(4).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
    if bytes.len() % 4 != 0 || words.first() != Some(&0x0723_0203) {
        return Err(FileError::NotSpirv(path));
    }
    Ok(words)
}

pub(super) fn dump(
    dir: &std::path::Path,
    cell: &Cell,
    shaders: &shadergen::CellShaders,
    spirv: &[std::sync::Arc<Vec<u32>>],
) -> Result<(), FileError> {
    let d = dir.join(cell.id());
    std::fs::create_dir_all(&d).map_err(|err| FileError::Dump { path: d.clone(), err })?;
    for (s, words) in shaders.shaders.iter().zip(spirv) {
        let glsl = d.join(format!("{}.glsl", s.role.file_name()));
        std::fs::write(&glsl, &s.glsl)
            .map_err(|err| FileError::Dump { path: glsl.clone(), err })?;
        let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
        let spv = d.join(format!("{}.spv", s.role.file_name()));
        std::fs::write(&spv, bytes).map_err(|err| FileError::Dump { path: spv.clone(), err })?;
    }
    Ok(())
}

/// `--dump`'s `DIR/<cell id>/records.bin`: the records buffer as the worker read it back
/// (`probe::Record::to_bytes`, pixel (x, y) at record x + y × width), what an Amber script's
/// EXPECTs are checked against (`report::amber::check`).
pub(super) fn dump_records(
    dir: &std::path::Path,
    cell: &Cell,
    records: &[crate::probe::Record],
) -> Result<(), FileError> {
    let d = dir.join(cell.id());
    std::fs::create_dir_all(&d).map_err(|err| FileError::Dump { path: d.clone(), err })?;
    let path = d.join("records.bin");
    let bytes: Vec<u8> = records.iter().flat_map(|r| r.to_bytes()).collect();
    std::fs::write(&path, bytes).map_err(|err| FileError::Dump { path, err })
}
