//! The probes' samplers: nearest-filtered, one per address mode of `probe::SAMPLER_MODES`; the
//! first (clamp to edge) is the sampler of combined image samplers, all of them fill the sampler
//! heap in that order.
use crate::probe::{AddressMode, SAMPLER_MODES};
use crate::vk::{Gpu, VkError, VkResultExt};
use ash::vk;

pub fn create_sampler(gpu: &Gpu) -> Result<vk::Sampler, VkError> {
    unsafe { gpu.device.create_sampler(&sampler_info(), None) }.at("vkCreateSampler")
}

/// The probes' sampler: sampler 0 of the sampler heap (`probe::SAMPLER_MODES[0]`, clamp to edge),
/// the one combined image samplers use.
pub fn sampler_info() -> vk::SamplerCreateInfo<'static> {
    sampler_info_for(SAMPLER_MODES[0])
}

/// A nearest-filtered sampler with `mode` in u, v and w.
fn sampler_info_for(mode: AddressMode) -> vk::SamplerCreateInfo<'static> {
    let mode = match mode {
        AddressMode::ClampToEdge => vk::SamplerAddressMode::CLAMP_TO_EDGE,
        AddressMode::Repeat => vk::SamplerAddressMode::REPEAT,
        AddressMode::MirroredRepeat => vk::SamplerAddressMode::MIRRORED_REPEAT,
    };
    vk::SamplerCreateInfo::default()
        .mag_filter(vk::Filter::NEAREST)
        .min_filter(vk::Filter::NEAREST)
        .mipmap_mode(vk::SamplerMipmapMode::NEAREST)
        .address_mode_u(mode)
        .address_mode_v(mode)
        .address_mode_w(mode)
        .max_lod(0.0)
}

/// The sampler heap's samplers, in heap order (`probe::SAMPLER_MODES`).
pub fn heap_sampler_infos() -> Vec<vk::SamplerCreateInfo<'static>> {
    SAMPLER_MODES.iter().map(|m| sampler_info_for(*m)).collect()
}
