//! The textures of the `scene_layout` texture cells (`resource=sampled_image`): the glTF ray
//! tracing tutorial keeps every material's base-colour texture in one descriptor array, and its
//! closest-hit selects the element by the hit primitive's material (`nonuniformEXT`).
//!
//! Which image each primitive entry's material samples ([`SceneTextures`], held by the
//! [`Scene`]): for a `--scene` glTF file its material's base-colour image, decoded only when a
//! texture cell needs it ([`Textures::of`]; `Loaded::decode_image`, never every image); for the
//! procedural scene one of [`SYNTHETIC`] small seeded textures, entry `k`'s the `k mod 4`-th, so
//! neighbouring entries sample different textures and a wrong entry or texture shows.
//!
//! The probe reads the texel at (`gl_PrimitiveID mod width`, `(gl_PrimitiveID / width) mod
//! height`) with `texelFetch` (no filtering, no sampler state involved) from an
//! `R8G8B8A8_UNORM` image, rounds it back to its bytes and records them ([`Textured::value`]), so
//! the CPU reference knows the record exactly.
use super::gltf::{LoadError, Loaded, Texture};
use super::rng::Rng;
use std::sync::{Arc, OnceLock};

/// The material index of primitive entry 0 (`layout::material`; the material table's entries
/// below it hold [`NO_TEXTURE`]).
pub const FIRST_MATERIAL: u32 = 100;
/// Synthetic textures of the procedural scene.
pub const SYNTHETIC: usize = 4;
/// Their sizes: unlike each other, so a wrong texture's texel coordinate differs too.
const SYNTHETIC_SIZES: [(u32, u32); SYNTHETIC] = [(8, 8), (4, 16), (16, 4), (5, 3)];
/// The material table's word for a material without a base-colour texture (the tutorial's −1).
pub const NO_TEXTURE: u32 = u32::MAX;

/// Where a scene's base-colour images come from.
pub enum ImageSource {
    /// The procedural scene's [`SYNTHETIC`] seeded textures (seed: the scene's).
    Synthetic(u64),
    /// A loaded glTF file: its images, decoded on demand.
    File(Arc<Loaded>),
}

/// Per mesh, per BLAS geometry (primitive entry), the base-colour image it samples, and where the
/// images come from.
pub struct SceneTextures {
    pub geometry_image: Vec<Vec<Option<usize>>>,
    pub source: ImageSource,
    /// [`Textures::of`], decoded at the first [`SceneTextures::decoded`] (the executor's upload
    /// and the reference share it).
    decoded: OnceLock<Result<Textures, TextureError>>,
}

impl SceneTextures {
    /// The procedural scene's: primitive entry `k` (mesh by mesh, geometry by geometry) samples
    /// synthetic texture `k mod SYNTHETIC`.
    pub fn synthetic(geometries: &[usize], seed: u64) -> SceneTextures {
        let mut k = 0;
        let geometry_image = geometries
            .iter()
            .map(|&n| {
                (0..n)
                    .map(|_| {
                        k += 1;
                        Some((k - 1) % SYNTHETIC)
                    })
                    .collect()
            })
            .collect();
        SceneTextures::new(geometry_image, ImageSource::Synthetic(seed))
    }

    fn new(geometry_image: Vec<Vec<Option<usize>>>, source: ImageSource) -> SceneTextures {
        SceneTextures { geometry_image, source, decoded: OnceLock::new() }
    }

    /// The scene's texture array and material table, decoded once.
    pub fn decoded(&self) -> Result<&Textures, &TextureError> {
        self.decoded.get_or_init(|| Textures::of(self)).as_ref()
    }
}

impl SceneTextures {
    /// A glTF file's: each primitive's material's base-colour image (none for a primitive
    /// without a material or texture) of each mesh a node places, then the AS probe's floor
    /// quad's two untextured entries (`Scene::with_meshes` puts it after the file's meshes).
    pub fn of_file(loaded: Loaded) -> SceneTextures {
        let image = |m: Option<usize>| m.and_then(|k| loaded.materials[k].base_color_image);
        // Per BLAS, as `fit::to_scene` makes them: the meshes a node places, in file order.
        let mut geometry_image: Vec<Vec<Option<usize>>> = loaded
            .meshes
            .iter()
            .filter(|m| !m.unused)
            .map(|m| m.primitives.iter().map(|p| image(p.material)).collect())
            .collect();
        geometry_image.push(vec![None; 2]);
        SceneTextures::new(geometry_image, ImageSource::File(Arc::new(loaded)))
    }
}

impl SceneTextures {
    /// The images some primitive entry samples, ascending; none is refused.
    fn used(&self) -> Result<Vec<usize>, TextureError> {
        let mut used: Vec<usize> =
            self.geometry_image.iter().flatten().flatten().copied().collect();
        used.sort_unstable();
        used.dedup();
        if used.is_empty() {
            return Err(TextureError::NoTextures);
        }
        Ok(used)
    }

    /// The name and size of each image [`Textures::of`] would hold, in its order, from each
    /// image's header alone: no texel is decoded, so an image larger than the device allows is
    /// refused (`cli::scene_check`) without allocating it; [`SceneTextures::validate`] decodes.
    pub fn sizes(&self) -> Result<Vec<(String, u32, u32)>, TextureError> {
        let used = self.used()?;
        Ok(match &self.source {
            ImageSource::Synthetic(_) => used
                .iter()
                .map(|&i| {
                    let (w, h) = SYNTHETIC_SIZES[i % SYNTHETIC];
                    (format!("synthetic texture {i}"), w, h)
                })
                .collect(),
            ImageSource::File(l) => used
                .iter()
                .map(|&i| l.image_size(i).map(|(w, h)| (l.image_name(i), w, h)))
                .collect::<Result<Vec<_>, _>>()?,
        })
    }

    /// Each image [`Textures::of`] would hold decoded and dropped in turn (a header can be whole
    /// over a broken body): the run's check before any GPU work, holding no texel.
    pub fn validate(&self) -> Result<(), TextureError> {
        if let ImageSource::File(l) = &self.source {
            for i in self.used()? {
                l.decode_image(i)?;
            }
        }
        Ok(())
    }
}

/// The descriptors of a texture cell's array of `images` images and `slots` probe slots
/// ([`Textures::elements`]).
pub fn element_count(images: usize, slots: u32) -> usize {
    (slots as usize).max(images)
}

/// Why a scene cannot run the texture cells (not the device's fault).
#[derive(Debug, thiserror::Error)]
pub enum TextureError {
    #[error("the scene's materials have no base-colour texture, so the scene_layout texture cells (resource=sampled_image) have nothing to sample; give a scene with textures or leave them out with --filter resource=storage_buffer")]
    NoTextures,
    #[error(transparent)]
    Load(#[from] LoadError),
}

/// The texture array of a scene, in element order, and per material index (`layout::material`)
/// its element or [`NO_TEXTURE`].
pub struct Textures {
    pub images: Vec<Texture>,
    /// Each image's name in messages: the file's `images[N] (uri …)`, or `synthetic texture k`.
    pub names: Vec<String>,
    pub material_texture: Vec<u32>,
}

impl Textures {
    /// The images the scene's primitive entries sample, each decoded once, in ascending image
    /// order; a scene where none samples an image is refused.
    pub fn of(t: &SceneTextures) -> Result<Textures, TextureError> {
        let used = t.used()?;
        let (images, names) = match &t.source {
            ImageSource::Synthetic(seed) => (
                used.iter().map(|&i| synthetic(i, *seed)).collect(),
                used.iter().map(|i| format!("synthetic texture {i}")).collect(),
            ),
            ImageSource::File(l) => (
                used.iter().map(|&i| l.decode_image(i)).collect::<Result<Vec<_>, _>>()?,
                used.iter().map(|&i| l.image_name(i)).collect(),
            ),
        };
        let entries = t.geometry_image.iter().flatten();
        let mut material_texture = vec![NO_TEXTURE; FIRST_MATERIAL as usize];
        material_texture.extend(entries.map(|img| match img {
            Some(i) => used.binary_search(i).expect("collected above") as u32,
            None => NO_TEXTURE,
        }));
        Ok(Textures { images, names, material_texture })
    }

    /// The image of texture element `e`: the array at binding 2 holds the images again and again
    /// up to the probe's slot count (`probe::slot_count`), so that a mutant's index (`index-next`
    /// wraps at the slot count) stays inside it.
    pub fn element_image(&self, e: u32) -> usize {
        e as usize % self.images.len()
    }

    /// The elements of the texture array of a cell whose array holds `slots` descriptors: every
    /// element's image, at least one element per image.
    pub fn elements(&self, slots: u32) -> Vec<usize> {
        (0..element_count(self.images.len(), slots)).map(|e| self.element_image(e as u32)).collect()
    }

    /// The material table as the shader reads it: one word per material index.
    pub fn material_bytes(&self) -> Vec<u8> {
        self.material_texture.iter().flat_map(|w| w.to_le_bytes()).collect()
    }

    /// What a texture cell records for a hit on primitive `primitive` whose entry has `material`.
    pub fn fetch(&self, material: u32, primitive: u32) -> Textured {
        self.fetch_read(material, primitive, |e| e)
    }

    /// [`Textures::fetch`] where the descriptor read at element `e` goes to element `read(e)`
    /// (a mutant's rewritten index, `reference::mutation`): the record still holds the element
    /// the material table gave, the texel is the read element's image's ([`Textures::element_image`]).
    pub fn fetch_read(&self, material: u32, primitive: u32, read: impl Fn(u32) -> u32) -> Textured {
        let texture = self.material_texture.get(material as usize).copied().unwrap_or(NO_TEXTURE);
        if texture == NO_TEXTURE {
            return Textured { texel: None, material };
        }
        let img = &self.images[self.element_image(read(texture))];
        let (x, y) = texel_of(img, primitive);
        let at = 4 * (y * img.width + x) as usize;
        let rgba = [0, 1, 2, 3].map(|k| img.rgba8[at + k]);
        Textured { texel: Some((texture, rgba)), material }
    }
}

/// The texel primitive `primitive` reads of `img`.
pub fn texel_of(img: &Texture, primitive: u32) -> (u32, u32) {
    (primitive % img.width, (primitive / img.width) % img.height)
}

/// Synthetic texture `i` of seed `seed`: seeded RGBA8 texels, alpha never 0.
pub fn synthetic(i: usize, seed: u64) -> Texture {
    let (width, height) = SYNTHETIC_SIZES[i % SYNTHETIC];
    let mut rng = Rng::new(seed ^ 0x7465_7874_7572_6500 ^ i as u64);
    let rgba8 = (0..width * height)
        .flat_map(|_| {
            let w = rng.next_u64();
            [w as u8, (w >> 8) as u8, (w >> 16) as u8, ((w >> 24) as u8) | 1]
        })
        .collect();
    Texture { width, height, rgba8 }
}

/// What a texture cell's closest-hit samples: the texture element and the texel's bytes (`None`:
/// the material has no texture), and the material index it came from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Textured {
    pub texel: Option<(u32, [u8; 4])>,
    pub material: u32,
}

impl Textured {
    /// The record's `value`: red | green << 8 | blue << 16, alpha, the texture element, the
    /// material index (each exact as a float); −1 in the first three without a texture.
    pub fn value(&self) -> [f32; 4] {
        match self.texel {
            Some((t, [r, g, b, a])) => [
                (r as u32 | (g as u32) << 8 | (b as u32) << 16) as f32,
                a as f32,
                t as f32,
                self.material as f32,
            ],
            None => [-1.0, -1.0, -1.0, self.material as f32],
        }
    }
}

/// The GLSL of the texture read, after either layout's fetch (which defines `materialIndex`; the
/// `per_mesh` one after `SceneDesc sceneDesc`, for the material table's address):
/// the material table's element, `nonuniformEXT`, `texelFetch` at the primitive's texel.
pub const DECLS: &str = "layout(set = 0, binding = 2) uniform sampler2D sceneTex[];\n";

pub const BODY: &str = "    uint texIndex = SceneWords(sceneDesc.materials).w[materialIndex];\n    \
if (texIndex == 0xFFFFFFFFu) {\n        probeValue = vec4(-1.0, -1.0, -1.0, float(materialIndex));\n    } else {\n        \
ivec2 texSize = textureSize(sceneTex[nonuniformEXT(texIndex)], 0);\n        \
uint prim = uint(gl_PrimitiveID);\n        \
ivec2 texel = ivec2(int(prim % uint(texSize.x)), int((prim / uint(texSize.x)) % uint(texSize.y)));\n        \
uvec4 b = uvec4(round(texelFetch(sceneTex[nonuniformEXT(texIndex)], texel, 0) * 255.0));\n        \
probeValue = vec4(float(b.r | (b.g << 8u) | (b.b << 16u)), float(b.a), float(texIndex), float(materialIndex));\n    }\n";

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::SceneParams;
    use crate::scene::Scene;

    /// The procedural scene's neighbouring entries sample different textures; every texture has
    /// a texel that differs from the other textures' at the same primitive (a wrong texture
    /// shows); a texture-less scene is refused with what to do.
    #[test]
    fn synthetic_textures_discriminate_and_a_textureless_scene_is_refused() {
        let scene = Scene::build(&SceneParams::default());
        let t = scene.textures.decoded().unwrap();
        assert_eq!(t.images.len(), SYNTHETIC);
        let first = super::FIRST_MATERIAL as usize;
        for k in first..t.material_texture.len() - 1 {
            assert_ne!(t.material_texture[k], t.material_texture[k + 1]);
        }
        for prim in 0..8 {
            let a = t.fetch(first as u32, prim);
            let b = t.fetch(first as u32 + 1, prim);
            assert_ne!(a.value(), b.value());
        }
        let mut bare = Scene::build(&SceneParams::default());
        bare.textures.geometry_image.iter_mut().flatten().for_each(|g| *g = None);
        let e = bare.textures.decoded().err().unwrap().to_string();
        assert!(e.contains("no base-colour texture") && e.contains("--filter"), "{e}");
        assert_eq!(Textured { texel: None, material: 7 }.value(), [-1.0, -1.0, -1.0, 7.0]);
    }
}
