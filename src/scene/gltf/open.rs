//! Opening a glTF file: the JSON (or GLB) read without validation first, so that an unsupported
//! `extensionsRequired` entry (any: rtprobe reads none) is named in rtprobe's own words, then validated by the `gltf`
//! crate, then its buffers (`.bin` files, data URIs, the GLB blob) read (`uri`). Images are not touched
//! here: each is decoded only when a cell needs it ([`super::Loaded::decode_image`]).
use super::error::{one_line, LoadError};
use std::path::Path;

pub(super) struct Opened {
    pub document: gltf::Document,
    pub buffers: Vec<Vec<u8>>,
}

pub(super) fn open(path: &Path) -> Result<Opened, LoadError> {
    let bytes = std::fs::read(path)
        .map_err(|e| LoadError::Read { path: path.to_path_buf(), message: e.to_string() })?;
    let parse =
        |e: gltf::Error| LoadError::Parse { path: path.to_path_buf(), message: one_line(&e) };
    let gltf::Gltf { document, blob } =
        gltf::Gltf::from_slice_without_validation(&bytes).map_err(parse)?;
    // No required extension is read: the gltf crate is built without them, and one a file
    // requires changes what its data means.
    if let Some(ext) = document.extensions_required().next() {
        return Err(LoadError::Extension { path: path.to_path_buf(), extension: ext.to_string() });
    }
    let root = document.into_json();
    positions_in_range(path, &root)?;
    let document = gltf::Document::from_json(root).map_err(parse)?;
    let base = path.parent().unwrap_or(Path::new("."));
    let buffers = read_buffers(path, &document, base, blob)?;
    Ok(Opened { document, buffers })
}

/// Each buffer's bytes (the GLB blob, a data URI or a file beside the scene: [`super::uri`]), at
/// least its `byteLength`, or one line naming the buffer that could not be read.
fn read_buffers(
    path: &Path,
    document: &gltf::Document,
    base: &Path,
    mut blob: Option<Vec<u8>>,
) -> Result<Vec<Vec<u8>>, LoadError> {
    let mut out = Vec::new();
    for b in document.buffers() {
        let part = format!("buffer {}", b.index());
        let data = match b.source() {
            gltf::buffer::Source::Bin => blob.take().ok_or_else(|| {
                LoadError::part(path, &part, "refers to the GLB binary chunk, which is missing or used twice; export the scene again")
            })?,
            gltf::buffer::Source::Uri(uri) => {
                super::uri::read(base, uri, "buffer").map_err(|e| LoadError::part(path, &part, e))?
            }
        };
        if data.len() < b.length() {
            return Err(LoadError::part(
                path,
                part,
                format!(
                    "{} bytes where the file says {}; the .bin file is truncated or another one",
                    data.len(),
                    b.length()
                ),
            ));
        }
        out.push(data);
    }
    Ok(out)
}

/// Every primitive's POSITION accessor exists: gltf-json 1.4.1's validation indexes the
/// accessors with it unchecked (`primitive_validate_hook`) and panics on a file that names an
/// accessor past the end.
fn positions_in_range(path: &Path, root: &gltf::json::Root) -> Result<(), LoadError> {
    use gltf::json::validation::Checked;
    let n = root.accessors.len();
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            let pos = prim.attributes.get(&Checked::Valid(gltf::json::mesh::Semantic::Positions));
            if let Some(a) = pos.filter(|a| a.value() >= n) {
                return Err(LoadError::Parse {
                    path: path.to_path_buf(),
                    message: format!(
                        "invalid at meshes[{m}].primitives[{p}].attributes.POSITION: accessor {} of {n}",
                        a.value()
                    ),
                });
            }
        }
    }
    Ok(())
}
