//! `--fill SET.BINDING=scene.textures`: the `--scene` glTF's images as the elements of a texture
//! array, as the glTF ray tracing tutorial binds them. Element `i` is image `i` of the document
//! (glTF image order), so the `materials` fill's `baseColorTexture` — the base colour texture's
//! `source`, an image index — selects its element. Each image is decoded on its own
//! (`Loaded::decode_image`, never `gltf::import`) to RGBA8 and uploaded once as one
//! `R8G8B8A8_SRGB` 2D image ([`FORMAT`]: glTF base colour textures are sRGB-encoded, so a sample
//! returns linear values), no mipmaps, bound `SHADER_READ_ONLY_OPTIMAL` with the harness's sampler
//! (nearest, clamp to edge). Elements past the image count keep the harness's own textures
//! (`super::textures`). The parent checks the target ([`check`]) and counts the texel bytes for
//! the memory check ([`decoded`]); the child makes the images ([`SceneTextures`]).
use super::error::HarnessError;
use super::fill::{FillError, Request, Target};
use super::module::UserModule;
use super::reflect::BindingKind;
use super::scene_data::SceneFill;
use super::scene_item::Item;
use crate::scene::gltf::{LoadError, Loaded, Texture};
use crate::vk::memory::{Buffer, Image};
use crate::vk::submit::{Submitter, Waited};
use crate::vk::Gpu;
use ash::vk;
use std::time::Duration;

/// The format of every scene image: glTF 2.0 says base colour textures are sRGB-encoded.
pub const FORMAT: vk::Format = vk::Format::R8G8B8A8_SRGB;

/// `scene.textures` into `r`'s target, held to `modules` and a scene of `images` images: a
/// binding of sampled images or combined image samplers with room for every image.
pub fn check(r: &Request, modules: &[UserModule], images: usize) -> Result<(), FillError> {
    let refuse = |why: String| FillError::Target(r.text.clone(), why);
    let Target::Binding { set, binding, element: None } = r.target else {
        return Err(refuse(
            "scene.textures goes to a sampled-image or combined-image-sampler array binding; give one of those as TARGET (SET.BINDING, no element)".into(),
        ));
    };
    let all: Vec<_> = modules.iter().flat_map(|m| m.iface.bindings.iter().cloned()).collect();
    let merged = super::bindings::merged(&all).unwrap_or_default();
    let b = merged
        .get(&(set, binding))
        .filter(|b| matches!(b.kind, BindingKind::SampledImage | BindingKind::CombinedImageSampler))
        .ok_or_else(|| refuse(format!("set {set} binding {binding} is not an array of sampled images or combined image samplers; scene.textures goes to one (texture2D textures[] or sampler2D textures[])")))?;
    if images == 0 {
        return Err(refuse(
            "the scene has no images; give a scene with textures or drop this fill".into(),
        ));
    }
    if (b.count as usize) < images {
        let how = if b.runtime { "give --array-size at least" } else { "declare it at least" };
        return Err(refuse(format!(
            "set {set} binding {binding} holds {} textures, the scene has {images} images; {how} {images}",
            b.count
        )));
    }
    Ok(())
}

/// Whether `fills` put the scene's images anywhere.
pub fn wanted(fills: &[SceneFill]) -> bool {
    fills.iter().any(|f| f.item == Item::Textures)
}

/// Every image of `loaded`, decoded (the parent's memory check and cell id).
pub fn decoded(loaded: &Loaded) -> Result<Vec<Texture>, LoadError> {
    (0..loaded.images).map(|i| loaded.decode_image(i)).collect()
}

/// The device bytes of `textures` as [`FORMAT`] images.
pub fn bytes(textures: &[Texture]) -> u64 {
    textures.iter().map(|t| 4 * t.width as u64 * t.height as u64).sum()
}

/// The scene's images on the device, and the bindings whose elements they are.
pub struct SceneTextures {
    images: Vec<Image>,
    targets: Vec<(u32, u32)>,
}

impl SceneTextures {
    /// The images of `loaded` when `fills` name `scene.textures`, decoded, uploaded in one
    /// submission fenced with `timeout`, left `SHADER_READ_ONLY_OPTIMAL`.
    pub fn new(
        gpu: &Gpu,
        loaded: &Loaded,
        fills: &[SceneFill],
        (submitter, timeout): (&Submitter, Duration),
    ) -> Result<Option<SceneTextures>, HarnessError> {
        if !wanted(fills) {
            return Ok(None);
        }
        let decoded = decoded(loaded).map_err(|e| HarnessError::Unsupported(e.to_string()))?;
        let targets = fills
            .iter()
            .filter(|f| f.item == Item::Textures)
            .filter_map(|f| match f.target {
                Target::Binding { set, binding, .. } => Some((set, binding)),
                Target::Push(_) | Target::Record(_) => None,
            })
            .collect();
        let mut t = SceneTextures { images: Vec::new(), targets };
        let usage = vk::ImageUsageFlags::SAMPLED | vk::ImageUsageFlags::TRANSFER_DST;
        for d in &decoded {
            let extent = vk::Extent2D { width: d.width, height: d.height };
            let img = Image::new(gpu, extent, FORMAT, usage).inspect_err(|_| t.destroy(gpu))?;
            t.images.push(img);
        }
        t.upload(gpu, &decoded, submitter, timeout).inspect_err(|_| t.destroy(gpu))?;
        Ok(Some(t))
    }

    fn upload(
        &self,
        gpu: &Gpu,
        decoded: &[Texture],
        submitter: &Submitter,
        timeout: Duration,
    ) -> Result<(), HarnessError> {
        let bytes: Vec<u8> = decoded.iter().flat_map(|d| d.rgba8.iter().copied()).collect();
        let staging =
            Buffer::with_data(gpu, &bytes, vk::BufferUsageFlags::TRANSFER_SRC, "scene textures")?;
        let waited = submitter.run(gpu, timeout, |cmd| {
            let mut offset = 0u64;
            for (img, d) in self.images.iter().zip(decoded) {
                super::textures::record_copy(gpu, cmd, img, &staging, (offset, 1));
                offset += d.rgba8.len() as u64;
            }
        });
        staging.destroy(gpu);
        match waited? {
            Waited::Done(_) => Ok(()),
            Waited::TimedOut => Err(HarnessError::Timeout(timeout)),
        }
    }

    /// The view of element `k` of binding `key`: image `k`'s when a fill put the scene's images
    /// there and the scene has that many, else `None` (the harness's own texture).
    pub fn view(&self, key: (u32, u32), k: u32) -> Option<vk::ImageView> {
        self.targets.contains(&key).then(|| self.images.get(k as usize).map(|i| i.view)).flatten()
    }

    pub fn destroy(&self, gpu: &Gpu) {
        self.images.iter().for_each(|i| i.destroy(gpu));
    }
}
