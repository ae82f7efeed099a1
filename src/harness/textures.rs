//! The harness's textures and sampler. Every element of every sampled-image or combined
//! image sampler binding is its own [`TEXTURE_SIZE`]² `R32G32B32A32_SFLOAT` 2D view whose texels
//! encode the texture's number (counted over every texture element, as buffers are numbered)
//! and the texel's own coordinates ([`texel`]), so a read of another element or of another
//! texel changes what the shader computes. The views are layers of a few array images
//! ([`Textures`]: up to `maxImageArrayLayers` layers each, so 65,536 textures are not 65,536
//! images and allocations, which lavapipe cannot map), filled through one staging buffer and
//! left `SHADER_READ_ONLY_OPTIMAL` ([`Textures::upload`]); shaders only read them, so they are
//! never refilled. One nearest, clamp-to-edge sampler (`exec::samplers::sampler_info`) serves every
//! sampler and combined image sampler element.
use super::error::HarnessError;
use crate::vk::memory::{color_range, record_image_upload, Buffer, Image, ImageUse};
use crate::vk::submit::{Submitter, Waited};
use crate::vk::{Gpu, VkError, VkResultExt};
use ash::vk;
use std::time::Duration;

/// Width and height of every texture, in texels.
pub const TEXTURE_SIZE: u32 = 8;
/// Every texture's format: sampleable (nearest) on every Vulkan device, exact for the encoding.
pub const TEXTURE_FORMAT: vk::Format = vk::Format::R32G32B32A32_SFLOAT;
/// Bytes of one texel of [`TEXTURE_FORMAT`].
const TEXEL_BYTES: u32 = 16;

/// Texel (`x`, `y`) of texture `k`: red `k + 1 + x/8`, green `k + 1 + y/8` (so no two textures
/// and no two texels of one hold the same red–green pair), blue `(x + 8y) / 64`, alpha one of
/// ¼, ½, ¾, 1 by `(k + x + y) mod 4` (an alpha test keeps some texels and drops others). Every
/// value is exact in 32-bit floats for `k` below 2²⁰.
pub fn texel(k: u32, x: u32, y: u32) -> [f32; 4] {
    let n = TEXTURE_SIZE as f32;
    [
        k as f32 + 1.0 + x as f32 / n,
        k as f32 + 1.0 + y as f32 / n,
        (x + TEXTURE_SIZE * y) as f32 / (n * n),
        ((k + x + y) % 4 + 1) as f32 / 4.0,
    ]
}

/// The bytes of texture `k`, row by row.
pub fn texels(k: u32) -> Vec<u8> {
    (0..TEXTURE_SIZE)
        .flat_map(|y| (0..TEXTURE_SIZE).map(move |x| texel(k, x, y)))
        .flatten()
        .flat_map(f32::to_le_bytes)
        .collect()
}

/// Every texture of a pipeline: array images, and a 2D view of each layer, texture `k` at
/// layer `k mod max_layers` of image `k / max_layers`.
pub struct Textures {
    images: Vec<Image>,
    pub views: Vec<vk::ImageView>,
    max_layers: u32,
}

impl Textures {
    /// `n` textures, not yet filled, in images of at most `max_layers` layers.
    pub fn new(gpu: &Gpu, n: u32, max_layers: u32) -> Result<Textures, VkError> {
        let max_layers = max_layers.max(1);
        let mut t = Textures { images: Vec::new(), views: Vec::new(), max_layers };
        let extent = vk::Extent2D { width: TEXTURE_SIZE, height: TEXTURE_SIZE };
        let usage = vk::ImageUsageFlags::SAMPLED | vk::ImageUsageFlags::TRANSFER_DST;
        for first in (0..n).step_by(max_layers as usize) {
            let layers = (n - first).min(max_layers);
            let img = Image::with_layers(gpu, extent, TEXTURE_FORMAT, usage, Some(layers))
                .inspect_err(|_| t.destroy(gpu))?;
            let raw = img.raw;
            t.images.push(img);
            for layer in 0..layers {
                let view = layer_view(gpu, raw, layer).inspect_err(|_| t.destroy(gpu))?;
                t.views.push(view);
            }
        }
        Ok(t)
    }

    /// Fill every texture with its [`texels`] in one submission fenced with `timeout`, leaving
    /// them `SHADER_READ_ONLY_OPTIMAL`.
    pub fn upload(
        &self,
        gpu: &Gpu,
        submitter: &Submitter,
        timeout: Duration,
    ) -> Result<(), HarnessError> {
        if self.views.is_empty() {
            return Ok(());
        }
        let bytes: Vec<u8> = (0..self.views.len() as u32).flat_map(texels).collect();
        let staging =
            Buffer::with_data(gpu, &bytes, vk::BufferUsageFlags::TRANSFER_SRC, "texture staging")?;
        let per = (TEXTURE_SIZE * TEXTURE_SIZE * TEXEL_BYTES) as u64;
        let n = self.views.len() as u32;
        let waited = submitter.run(gpu, timeout, |cmd| {
            for (c, img) in self.images.iter().enumerate() {
                let first = c as u32 * self.max_layers;
                let layers = (n - first).min(self.max_layers);
                record_image_upload(
                    gpu,
                    cmd,
                    img,
                    &staging,
                    (first as u64 * per, layers),
                    TRACE_READ,
                );
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

    pub fn destroy(&self, gpu: &Gpu) {
        for v in &self.views {
            unsafe { gpu.device.destroy_image_view(*v, None) };
        }
        for i in &self.images {
            i.destroy(gpu);
        }
    }
}

/// A 2D view of layer `layer` of `image`.
fn layer_view(gpu: &Gpu, image: vk::Image, layer: u32) -> Result<vk::ImageView, VkError> {
    let range =
        vk::ImageSubresourceRange { base_array_layer: layer, layer_count: 1, ..color_range() };
    let vci = vk::ImageViewCreateInfo::default()
        .image(image)
        .view_type(vk::ImageViewType::TYPE_2D)
        .format(TEXTURE_FORMAT)
        .subresource_range(range);
    unsafe { gpu.device.create_image_view(&vci, None) }.at("vkCreateImageView")
}

/// The sampler of every sampler and combined image sampler element.
pub fn new_sampler(gpu: &Gpu) -> Result<vk::Sampler, VkError> {
    let info = crate::exec::samplers::sampler_info();
    unsafe { gpu.device.create_sampler(&info, None) }.at("vkCreateSampler")
}

/// The textures' use after their copy: SHADER_READ_ONLY_OPTIMAL for the trace's reads.
pub(super) const TRACE_READ: ImageUse = (
    vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
    vk::AccessFlags::SHADER_READ,
    vk::PipelineStageFlags::RAY_TRACING_SHADER_KHR,
);

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeSet;

    /// Twin of every texture test: textures whose contents were alike would not tell a read of
    /// the wrong element (or texel) from the right one. Every texture of an array as large as
    /// `--array-size` allows differs from every other, in every texel, and no two texels of one
    /// texture hold the same value.
    #[test]
    fn every_texture_and_every_texel_differs() {
        let n = super::super::sizes::MAX_ARRAY_SIZE;
        // At every texel position, the n textures hold n different values: every pair differs
        // in every texel.
        let positions = (0..TEXTURE_SIZE).flat_map(|y| (0..TEXTURE_SIZE).map(move |x| (x, y)));
        for (x, y) in positions {
            let values: BTreeSet<[u32; 4]> =
                (0..n).map(|k| texel(k, x, y).map(f32::to_bits)).collect();
            assert_eq!(values.len(), n as usize, "texel ({x}, {y})");
        }
        let whole: BTreeSet<Vec<u8>> = (0..256).map(texels).collect();
        assert_eq!(whole.len(), 256);
        // Within one texture, all 64 texels differ; a wrong coordinate reads another value.
        let within: BTreeSet<[u32; 4]> = (0..TEXTURE_SIZE)
            .flat_map(|y| (0..TEXTURE_SIZE).map(move |x| texel(5, x, y).map(f32::to_bits)))
            .collect();
        assert_eq!(within.len(), (TEXTURE_SIZE * TEXTURE_SIZE) as usize);
        assert_eq!(texels(3).len(), (TEXTURE_SIZE * TEXTURE_SIZE * TEXEL_BYTES) as usize);
    }
}
