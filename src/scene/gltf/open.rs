//! Opening a glTF file: its JSON (a `.gltf`, or a GLB's JSON chunk: [`super::glb`]) read first
//! for `extensionsRequired` alone, so that any required extension (rtprobe reads none) is named in
//! rtprobe's own words before anything else, then the asset version and the whole document
//! ([`super::doc`]) read and checked ([`super::validate`]), then its buffers (`.bin` files, data
//! URIs, the GLB's BIN chunk) read ([`super::uri`]), each at least its `byteLength`. Images are
//! not touched here: each is decoded only when a cell needs it ([`super::Loaded::decode_image`]).
use super::doc::{Head, Root};
use super::error::LoadError;
use std::path::Path;

pub(super) struct Opened {
    pub root: Root,
    pub buffers: Vec<Vec<u8>>,
}

pub(super) fn open(path: &Path) -> Result<Opened, LoadError> {
    let bytes = std::fs::read(path)
        .map_err(|e| LoadError::Read { path: path.to_path_buf(), message: e.to_string() })?;
    let parse = |message: String| LoadError::Parse { path: path.to_path_buf(), message };
    let (json, bin) = match super::glb::is_glb(&bytes) {
        true => super::glb::split(&bytes).map(|g| (g.json, g.bin)).map_err(parse)?,
        false => (&bytes[..], None),
    };
    let head: Head = serde_json::from_slice(json).map_err(|e| parse(e.to_string()))?;
    // No required extension is read: one a file requires changes what its data means.
    if let Some(ext) = head.extensions_required.into_iter().next() {
        return Err(LoadError::Extension { path: path.to_path_buf(), extension: ext });
    }
    super::validate::version(head.asset.as_ref()).map_err(parse)?;
    let root: Root = serde_json::from_slice(json).map_err(|e| parse(e.to_string()))?;
    super::validate::check(&root).map_err(|m| match m.strip_suffix(super::validate::SPARSE) {
        // Valid glTF 2.0 that rtprobe does not read: the part, not "is not glTF 2.0".
        Some(at) => LoadError::part(
            path,
            at.trim_start_matches("invalid at ").trim_end_matches(": "),
            "a sparse accessor (valid glTF 2.0), which rtprobe does not read; export the scene without sparse accessors, or apply them with a glTF tool",
        ),
        None => parse(m),
    })?;
    let base = path.parent().unwrap_or(Path::new("."));
    let buffers = read_buffers(path, &root, base, bin)?;
    Ok(Opened { root, buffers })
}

/// Each buffer's bytes (the GLB's BIN chunk, a data URI or a file beside the scene:
/// [`super::uri`]), at least its `byteLength`, or one line naming the buffer that could not be
/// read. The BIN chunk is the first buffer's when that has no `uri` (glTF 2.0, "GLB-stored
/// Buffer"); another buffer without one is refused.
fn read_buffers(
    path: &Path,
    root: &Root,
    base: &Path,
    bin: Option<&[u8]>,
) -> Result<Vec<Vec<u8>>, LoadError> {
    let mut out = Vec::new();
    for (i, b) in root.buffers.iter().enumerate() {
        let part = format!("buffer {i}");
        let data = match &b.uri {
            None => bin.filter(|_| i == 0).map(<[u8]>::to_vec).ok_or_else(|| {
                LoadError::part(path, &part, "has no uri, so it is the GLB's BIN chunk, which is missing (or it is not the first buffer); export the scene again")
            })?,
            Some(uri) => {
                super::uri::read(base, uri, "buffer").map_err(|e| LoadError::part(path, &part, e))?
            }
        };
        if (data.len() as u64) < b.byte_length {
            return Err(LoadError::part(
                path,
                part,
                format!(
                    "{} bytes where the file says {}; the .bin file is truncated or another one",
                    data.len(),
                    b.byte_length
                ),
            ));
        }
        out.push(data);
    }
    Ok(out)
}
