//! Materials (base colour factor and texture, `alphaMode`) and the one image a cell needs,
//! decoded on demand into RGBA8: `gltf::import` would decode every image of the file.
use super::error::LoadError;
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

pub(super) fn read(m: &gltf::Material) -> Material {
    let pbr = m.pbr_metallic_roughness();
    let alpha = match m.alpha_mode() {
        gltf::material::AlphaMode::Opaque => Alpha::Opaque,
        gltf::material::AlphaMode::Mask => Alpha::Mask(m.alpha_cutoff().unwrap_or(0.5)),
        gltf::material::AlphaMode::Blend => Alpha::Blend,
    };
    Material {
        name: m.name().map_or_else(|| format!("material {}", m.index().unwrap_or(0)), String::from),
        base_color: pbr.base_color_factor(),
        base_color_image: pbr.base_color_texture().map(|t| t.texture().source().index()),
        base_color_texture: pbr.base_color_texture().map(|t| t.texture().index()),
        emissive: m.emissive_factor(),
        alpha,
    }
}

/// An image decoded to 8-bit RGBA.
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    pub width: u32,
    pub height: u32,
    pub rgba8: Vec<u8>,
}

/// Image `index` of `document`, decoded (PNG or JPEG, from a file beside the scene, a data URI or
/// a buffer view) and converted to RGBA8; a failure names the image as the file does
/// (`images[N]` and its URI or buffer view, [`describe`]) and what to do.
pub(super) fn decode(
    path: &Path,
    document: &gltf::Document,
    buffers: &[gltf::buffer::Data],
    index: usize,
) -> Result<Texture, LoadError> {
    let image = document.images().nth(index).ok_or_else(|| {
        LoadError::part(path, format!("images[{index}]"), "no such image in the file")
    })?;
    let part = describe(&image);
    let base = path.parent().unwrap_or(Path::new("."));
    let data = gltf::image::Data::from_source(image.source(), Some(base), buffers)
        .map_err(|e| LoadError::part(path, &part, why_not(&e)))?;
    let rgba8 = to_rgba8(&data).ok_or_else(|| {
        LoadError::part(
            path,
            &part,
            format!(
                "format {:?}; rtprobe reads 8- and 16-bit images: export it as an 8-bit PNG or JPEG",
                data.format
            ),
        )
    })?;
    Ok(Texture { width: data.width, height: data.height, rgba8 })
}

/// How the file names image `image`: `images[N] (uri "…")` (a data URI cut short) or
/// `images[N] (bufferView V, MIME)`.
pub fn describe(image: &gltf::Image) -> String {
    let n = image.index();
    match image.source() {
        gltf::image::Source::Uri { uri, .. } if uri.starts_with("data:") => {
            let head: String = uri.chars().take(32).collect();
            format!("images[{n}] (uri \"{head}…\")")
        }
        gltf::image::Source::Uri { uri, .. } => format!("images[{n}] (uri \"{uri}\")"),
        gltf::image::Source::View { view, mime_type } => {
            format!("images[{n}] (bufferView {}, {mime_type})", view.index())
        }
    }
}

/// Why an image's bytes do not decode, and what to do, in one line.
fn why_not(e: &gltf::Error) -> String {
    let first = super::error::one_line(e);
    match e {
        gltf::Error::Io(_) => format!(
            "cannot read the image file: {first}; put it beside the .gltf file (the uri is relative to it) or fix the uri"
        ),
        gltf::Error::UnsupportedImageEncoding => format!(
            "{first} (neither the mimeType nor the uri's extension says PNG or JPEG); rtprobe reads PNG and JPEG base-colour images: convert it to PNG"
        ),
        gltf::Error::Image(_) => {
            format!("does not decode: {first}; export the image again as PNG or JPEG")
        }
        _ => format!("{first}; give a PNG or JPEG image by a relative uri, a data URI or a bufferView"),
    }
}

fn to_rgba8(d: &gltf::image::Data) -> Option<Vec<u8>> {
    use gltf::image::Format as F;
    let px = &d.pixels;
    let (channels, wide) = match d.format {
        F::R8 => (1, false),
        F::R8G8 => (2, false),
        F::R8G8B8 => (3, false),
        F::R8G8B8A8 => (4, false),
        F::R16 => (1, true),
        F::R16G16 => (2, true),
        F::R16G16B16 => (3, true),
        F::R16G16B16A16 => (4, true),
        F::R32G32B32FLOAT | F::R32G32B32A32FLOAT => return None,
    };
    let step = if wide { 2 } else { 1 };
    // 16-bit channels are native-endian u16s: their high byte is the 8-bit value.
    let byte =
        |i: usize| if wide { (u16::from_ne_bytes([px[i], px[i + 1]]) >> 8) as u8 } else { px[i] };
    let texels = px.len() / (channels * step);
    let mut out = Vec::with_capacity(texels * 4);
    for t in 0..texels {
        let c = |k: usize| byte((t * channels + k) * step);
        let rgba = match channels {
            1 => [c(0), c(0), c(0), 255],
            2 => [c(0), c(0), c(0), c(1)],
            3 => [c(0), c(1), c(2), 255],
            _ => [c(0), c(1), c(2), c(3)],
        };
        out.extend(rgba);
    }
    Some(out)
}
