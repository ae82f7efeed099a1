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
use super::textures::TRACE_READ;
use crate::scene::gltf::{LoadError, Loaded, Texture};
use crate::vk::memory::{record_image_upload, Buffer, Image};
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
    /// The images of `loaded` for the bindings `targets` that `scene.textures` fills (none:
    /// nothing made), decoded, uploaded in one submission fenced with `timeout`, left
    /// `SHADER_READ_ONLY_OPTIMAL`.
    pub fn new(
        gpu: &Gpu,
        loaded: &Loaded,
        targets: Vec<(u32, u32)>,
        (submitter, timeout): (&Submitter, Duration),
    ) -> Result<Option<SceneTextures>, HarnessError> {
        if targets.is_empty() {
            return Ok(None);
        }
        let decoded = decoded(loaded).map_err(|e| HarnessError::Unsupported(e.to_string()))?;
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
                record_image_upload(gpu, cmd, img, &staging, (offset, 1), TRACE_READ);
                offset += d.rgba8.len() as u64;
            }
        });
        match waited? {
            Waited::Done(_) => {
                staging.destroy(gpu);
                Ok(())
            }
            // The copy may still be running: the staging buffer is left alive (leaked), as
            // VUID-vkDestroyBuffer-buffer-00922 asks.
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

#[cfg(test)]
mod tests {
    use super::*;

    const GLSL: &str = "#version 460\n#extension GL_EXT_ray_tracing : require\n\
        #extension GL_EXT_nonuniform_qualifier : require\n\
        layout(set = 0, binding = 0) buffer B { vec4 v[]; } b;\n\
        layout(set = 0, binding = 1) uniform sampler2D fixedMaps[3];\n\
        layout(set = 0, binding = 2) uniform texture2D maps[];\n\
        layout(set = 0, binding = 3) uniform sampler s;\n\
        layout(location = 0) rayPayloadInEXT vec4 c;\n\
        void main() { c = textureLod(fixedMaps[uint(c.x) % 3u], vec2(0.5), 0.0) + b.v[0]\n\
          + textureLod(sampler2D(maps[nonuniformEXT(uint(c.y))], s), vec2(0.5), 0.0); }\n";

    fn modules() -> Vec<UserModule> {
        let words = crate::patches::assemble(&crate::patches::compiled(
            shaderc::ShaderKind::Miss,
            "t",
            GLSL,
        ));
        vec![UserModule::new("t.rmiss", &words).unwrap()]
    }

    fn checked(text: &str, images: usize) -> Result<(), String> {
        let r = super::super::fill::parse(text).unwrap();
        check(&r, &modules(), images).map_err(|e| e.to_string())
    }

    /// A texture array with room for every image takes them; the twins — a buffer, a sampler,
    /// an address, one element, too small an array, no images — are one line each saying what
    /// to give.
    #[test]
    fn only_a_texture_array_with_room_for_every_image_takes_them() {
        assert_eq!(checked("0.1=scene.textures", 3), Ok(()));
        assert_eq!(checked("0.2=scene.textures", 64), Ok(()));
        let refused = [
            ("0.0=scene.textures", 2, "set 0 binding 0 is not an array of sampled images"),
            ("0.3=scene.textures", 2, "set 0 binding 3 is not an array of sampled images"),
            ("push.0=scene.textures", 2, "give one of those as TARGET"),
            ("0.1[0]=scene.textures", 2, "(SET.BINDING, no element)"),
            ("0.1=scene.textures", 4, "holds 3 textures, the scene has 4 images; declare it"),
            ("0.2=scene.textures", 65, "give --array-size at least 65"),
            ("0.1=scene.textures", 0, "the scene has no images"),
        ];
        for (text, images, why) in refused {
            let e = checked(text, images).unwrap_err();
            assert!(e.contains(why) && !e.contains('\n'), "{text}: {e}");
        }
    }

    #[test]
    fn the_images_bytes_are_their_rgba8_texels() {
        let t =
            |w: u32, h: u32| Texture { width: w, height: h, rgba8: vec![0; (4 * w * h) as usize] };
        assert_eq!(bytes(&[t(16, 16), t(3, 5)]), 4 * (256 + 15));
        assert_eq!(bytes(&[]), 0);
    }
}
