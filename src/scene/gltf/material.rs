//! Materials (base colour factor and texture, `alphaMode`) and the one image a cell needs,
//! decoded on demand into RGBA8 (never all images of the file at once).
use super::doc::{Image, Root};
use super::error::LoadError;
pub use super::pixels::Texture;
use std::path::Path;

/// glTF's `alphaMode`: MASK and BLEND make a primitive's geometry non-opaque, so any-hit
/// shaders run on it (as engines mark alpha-tested geometry).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Alpha {
    Opaque,
    /// Alpha below the cutoff is discarded (glTF's default cutoff 0.5).
    Mask(f32),
    Blend,
}

impl Alpha {
    pub fn opaque(self) -> bool {
        matches!(self, Alpha::Opaque)
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    pub name: String,
    pub base_color: [f32; 4],
    /// The base colour texture's image: an index into the document's images.
    pub base_color_image: Option<usize>,
    /// The base colour texture: an index into the document's textures (the glTF ray tracing
    /// tutorial's `pbrBaseColorTexture`).
    pub base_color_texture: Option<usize>,
    /// `emissiveFactor` (glTF's default: black).
    pub emissive: [f32; 3],
    pub alpha: Alpha,
}

/// Material `index` of `root` (validated: its alpha mode known, its texture and image indices
/// in range). glTF 2.0, "Alpha Coverage": `alphaCutoff` defaults to 0.5. A base colour texture
/// of another set than TEXCOORD_0 is read with TEXCOORD_0 (the one set rtprobe reads), logged.
pub(super) fn read(root: &Root, index: usize) -> Material {
    let m = &root.materials[index];
    let pbr = &m.pbr_metallic_roughness;
    let alpha = match m.alpha_mode.as_str() {
        "MASK" => Alpha::Mask(m.alpha_cutoff.unwrap_or(0.5)),
        "BLEND" => Alpha::Blend,
        _ => Alpha::Opaque,
    };
    let texture = pbr.base_color_texture.as_ref();
    if let Some(t) = texture.filter(|t| t.tex_coord != 0) {
        tracing::warn!(
            material = index,
            tex_coord = t.tex_coord,
            "base colour texture of another set than TEXCOORD_0: read with TEXCOORD_0"
        );
    }
    Material {
        name: m.name.clone().unwrap_or_else(|| format!("material {index}")),
        base_color: pbr.base_color_factor,
        base_color_image: texture.and_then(|t| root.textures[t.index].source),
        base_color_texture: texture.map(|t| t.index),
        emissive: m.emissive_factor,
        alpha,
    }
}

/// Image `index` of `root`, decoded (PNG or JPEG, from a file beside the scene, a data URI or a
/// buffer view: [`super::uri`], [`super::pixels`]) and converted to RGBA8; a failure names the
/// image as the file does (`images[N]` and its URI or buffer view, [`describe`]) and what to do.
pub(super) fn decode(
    path: &Path,
    root: &Root,
    buffers: &[Vec<u8>],
    index: usize,
) -> Result<Texture, LoadError> {
    let (part, bytes) = image_bytes(path, root, buffers, index)?;
    super::pixels::decode(&bytes).map_err(|why| LoadError::part(path, &part, why))
}

/// Image `index`'s width and height from its header alone (no texel decoded: an image too large
/// for the device is refused without allocating it).
pub(super) fn size(
    path: &Path,
    root: &Root,
    buffers: &[Vec<u8>],
    index: usize,
) -> Result<(u32, u32), LoadError> {
    let (part, bytes) = image_bytes(path, root, buffers, index)?;
    super::pixels::size(&bytes).map_err(|why| LoadError::part(path, &part, why))
}

/// How the file names image `index`, and its encoded bytes.
fn image_bytes(
    path: &Path,
    root: &Root,
    buffers: &[Vec<u8>],
    index: usize,
) -> Result<(String, Vec<u8>), LoadError> {
    let image = root.images.get(index).ok_or_else(|| {
        LoadError::part(path, format!("images[{index}]"), "no such image in the file")
    })?;
    let part = describe(image, index);
    let fail = |why: String| LoadError::part(path, &part, why);
    let bytes = match (&image.uri, image.buffer_view) {
        (None, Some(v)) => {
            declared(image.mime_type.as_deref(), None).map_err(fail)?;
            let view = &root.buffer_views[v];
            let b = buffers.get(view.buffer).map_or(&[][..], |b| &b[..]);
            let range = usize::try_from(view.byte_offset)
                .ok()
                .zip(usize::try_from(view.byte_offset.saturating_add(view.byte_length)).ok());
            range
                .and_then(|(s, e)| b.get(s..e))
                .ok_or_else(|| {
                    fail("its bufferView runs past its buffer; export the scene again".into())
                })?
                .to_vec()
        }
        (uri, _) => {
            let uri = uri.as_deref().unwrap_or_default();
            declared(image.mime_type.as_deref(), Some(uri)).map_err(fail)?;
            let base = path.parent().unwrap_or(Path::new("."));
            super::uri::read(base, uri, "image").map_err(fail)?
        }
    };
    Ok((part, bytes))
}

/// What the file declares the image to be — its `mimeType`, else its file URI's extension — is
/// PNG or JPEG (glTF 2.0, `image.mimeType`: "image/jpeg" or "image/png"), or nothing is declared.
fn declared(mime: Option<&str>, uri: Option<&str>) -> Result<(), String> {
    let refuse = |what: String| {
        Err(format!("unsupported image encoding ({what}); rtprobe reads PNG and JPEG base-colour images: convert it to PNG"))
    };
    match mime {
        Some("image/png" | "image/jpeg") => return Ok(()),
        Some(other) => return refuse(format!("mimeType {other}")),
        None => {}
    }
    let ext = uri
        .filter(|u| !u.starts_with("data:"))
        .and_then(|u| u.rsplit_once('.'))
        .map(|(_, e)| e.to_ascii_lowercase())
        .filter(|e| !e.contains('/'));
    match ext.as_deref() {
        None | Some("png" | "jpg" | "jpeg") => Ok(()),
        Some(e) => refuse(format!("extension .{e}")),
    }
}

/// How the file names image `image` (number `n`): `images[N] (uri "…")` (a data URI cut short)
/// or `images[N] (bufferView V, MIME)`.
pub(super) fn describe(image: &Image, n: usize) -> String {
    match (&image.uri, image.buffer_view) {
        (Some(uri), _) if uri.starts_with("data:") => {
            let head: String = uri.chars().take(32).collect();
            format!("images[{n}] (uri \"{head}…\")")
        }
        (Some(uri), _) => format!("images[{n}] (uri \"{uri}\")"),
        (None, Some(v)) => {
            format!("images[{n}] (bufferView {v}, {})", image.mime_type.as_deref().unwrap_or(""))
        }
        (None, None) => format!("images[{n}]"),
    }
}
