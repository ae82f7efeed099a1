//! The `scene_layout` texture cells' resources (`scene::textures`), made the first time such a
//! cell runs: the scene's base-colour images the primitive entries sample (decoded then, and only
//! those), uploaded as `R8G8B8A8_UNORM` 2D images bound as binding 2's combined image samplers,
//! and the material table (per material index its texture element), whose address goes into the
//! `shared_buffers` `SceneDesc` (its fifth address).
use super::error::CellError;
use super::layout_buffers::SharedBuffers;
use super::resources::Target;
use crate::scene::textures::{TextureError, Textures};
use crate::scene::Scene;
use crate::vk::memory::{record_image_upload, Buffer, Image, ImageUse};
use crate::vk::submit::{Submitter, Waited};
use crate::vk::{Gpu, VkError};
use ash::vk;
use std::time::Duration;

/// The textures' use after their copy: GENERAL, read by any shader.
const SHADER_GENERAL: ImageUse =
    (vk::ImageLayout::GENERAL, vk::AccessFlags::SHADER_READ, vk::PipelineStageFlags::ALL_COMMANDS);
/// The textures' format: `texelFetch` returns each byte / 255, which the probe rounds back.
pub const FORMAT: vk::Format = vk::Format::R8G8B8A8_UNORM;
/// The material table's offset in the `SceneDesc`: after the four geometry addresses.
pub const MATERIALS_OFFSET: usize = 32;

/// A scene the texture cells cannot sample (no texture, an image that does not decode) is no
/// fault of the device: rtprobe has nothing to probe on it.
impl From<&TextureError> for CellError {
    fn from(e: &TextureError) -> Self {
        CellError::NotImplemented(e.to_string())
    }
}

pub struct LayoutTextures {
    images: Vec<Image>,
    /// Per element of the array, its image (`Textures::elements`).
    elements: Vec<usize>,
    materials: Buffer,
}

impl LayoutTextures {
    /// The scene's textures on the device, the material table's address written into `shared`'s
    /// `SceneDesc`.
    pub fn create(
        gpu: &Gpu,
        (scene, slots): (&Scene, u32),
        shared: &SharedBuffers,
        (submitter, timeout): (&Submitter, Duration),
    ) -> Result<Self, CellError> {
        let t = scene.textures.decoded()?;
        let usage =
            vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS;
        let materials = Buffer::with_data(gpu, &t.material_bytes(), usage, "scene materials")?;
        let mut made =
            LayoutTextures { images: Vec::new(), elements: t.elements(slots), materials };
        let usage = vk::ImageUsageFlags::SAMPLED | vk::ImageUsageFlags::TRANSFER_DST;
        for img in &t.images {
            let extent = vk::Extent2D { width: img.width, height: img.height };
            match Image::new(gpu, extent, FORMAT, usage) {
                Ok(i) => made.images.push(i),
                Err(e) => {
                    made.destroy(gpu);
                    return Err(e.into());
                }
            }
        }
        if let Err(e) = made.upload(gpu, t, submitter, timeout) {
            // After a timed-out copy the images may still be written: they are left alive
            // (leaked), as VUID-vkDestroyImage-image-01000 asks; any other error ran no copy.
            if !matches!(e, VkError::Call { result: vk::Result::TIMEOUT, .. }) {
                made.destroy(gpu);
            }
            return Err(e.into());
        }
        shared.desc.write(MATERIALS_OFFSET, &made.materials.address.to_le_bytes());
        Ok(made)
    }

    /// Every texel in one staging buffer, copied in one fenced submission; the images left in
    /// `GENERAL` layout.
    fn upload(
        &self,
        gpu: &Gpu,
        t: &Textures,
        submitter: &Submitter,
        timeout: Duration,
    ) -> Result<(), VkError> {
        let bytes: Vec<u8> = t.images.iter().flat_map(|i| i.rgba8.iter().copied()).collect();
        let staging =
            Buffer::with_data(gpu, &bytes, vk::BufferUsageFlags::TRANSFER_SRC, "texture staging")?;
        let waited = submitter.run(gpu, timeout, |cmd| {
            let mut offset = 0u64;
            for (img, tex) in self.images.iter().zip(&t.images) {
                // SAFETY: cmd is recording; the image and staging buffer live past the wait.
                record_image_upload(gpu, cmd, img, &staging, (offset, 1), SHADER_GENERAL);
                offset += tex.rgba8.len() as u64;
            }
        });
        match waited? {
            // The copy may still be running: the staging buffer is left alive (leaked), as
            // VUID-vkDestroyBuffer-buffer-00922 asks (see `SceneGpu::build_with`).
            Waited::TimedOut => Err(VkError::Call {
                call: "texture upload (fence wait)",
                result: vk::Result::TIMEOUT,
            }),
            Waited::Done(_) => {
                staging.destroy(gpu);
                Ok(())
            }
        }
    }

    /// Binding 2's descriptors: element k's image (`Textures::elements`) with `sampler`
    /// (`texelFetch` ignores it).
    pub fn targets(&self, sampler: vk::Sampler) -> Vec<Target> {
        self.elements
            .iter()
            .map(|&k| &self.images[k])
            .map(|i| Target::Image { image: i.raw, view: i.view, sampler, layers: None })
            .collect()
    }

    pub fn destroy(&self, gpu: &Gpu) {
        self.images.iter().for_each(|i| i.destroy(gpu));
        self.materials.destroy(gpu);
    }
}
