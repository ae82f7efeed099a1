//! The set layout and pipeline layout of the set-based models: bindings 0..=2 seen by the key's
//! stages, the probed array partially bound (and update-after-bind where the device allows it)
//! under `descriptor_indexing`, a descriptor-buffer layout under `descriptor_buffer`; the probes'
//! push constants.
use super::key::LayoutKey;
use crate::exec::resources::{descriptor_type, Target};
use crate::model::{DescriptorModel, Resource};
use crate::vk::{Gpu, VkError, VkResultExt};
use ash::vk;

/// The probes' block plus the 8-byte table address the address patches append.
pub const PUSH_CONSTANT_BYTES: u32 = crate::probe::PUSH_CONSTANT_BYTES;

/// Whether the device allows update-after-bind for descriptors of `kind`.
fn update_after_bind_supported(gpu: &Gpu, kind: Resource) -> bool {
    let v12 = gpu.info.features.v12.unwrap_or_default();
    let on = |b: vk::Bool32| b == vk::TRUE;
    match kind {
        Resource::StorageBuffer => on(v12.descriptor_binding_storage_buffer_update_after_bind),
        Resource::UniformBuffer => on(v12.descriptor_binding_uniform_buffer_update_after_bind),
        Resource::SampledImage => on(v12.descriptor_binding_sampled_image_update_after_bind),
        Resource::StorageImage => on(v12.descriptor_binding_storage_image_update_after_bind),
        Resource::AccelerationStructure => gpu
            .info
            .features
            .accel
            .is_some_and(|a| on(a.descriptor_binding_acceleration_structure_update_after_bind)),
    }
}

/// Each binding's flags: under descriptor indexing the probed array (binding 2) is partially
/// bound, and update-after-bind where the device allows it for its kind; no flags otherwise.
pub(super) fn binding_flags(
    gpu: &Gpu,
    key: LayoutKey,
    targets: &[(u32, Resource, Vec<Target>)],
) -> Vec<vk::DescriptorBindingFlags> {
    targets
        .iter()
        .map(|(b, kind, _)| {
            if *b == 2 && key.model == DescriptorModel::DescriptorIndexing {
                let mut f = vk::DescriptorBindingFlags::PARTIALLY_BOUND;
                if update_after_bind_supported(gpu, *kind) {
                    f |= vk::DescriptorBindingFlags::UPDATE_AFTER_BIND;
                }
                f
            } else {
                vk::DescriptorBindingFlags::empty()
            }
        })
        .collect()
}

/// The set layout of `targets` (seen by `key.stages`) under `key.model`: with the binding `flags`
/// and an update-after-bind pool (`uab`) for descriptor indexing, for a descriptor buffer
/// otherwise.
pub(super) fn set_layout(
    gpu: &Gpu,
    key: LayoutKey,
    targets: &[(u32, Resource, Vec<Target>)],
    flags: &[vk::DescriptorBindingFlags],
    uab: bool,
) -> Result<vk::DescriptorSetLayout, VkError> {
    let bindings: Vec<_> = targets
        .iter()
        .map(|(b, kind, t)| {
            vk::DescriptorSetLayoutBinding::default()
                .binding(*b)
                .descriptor_type(descriptor_type(*kind))
                .descriptor_count(t.len() as u32)
                .stage_flags(key.stages)
        })
        .collect();
    let mut flags_info =
        vk::DescriptorSetLayoutBindingFlagsCreateInfo::default().binding_flags(flags);
    let mut ci = vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings);
    match key.model {
        DescriptorModel::DescriptorIndexing => {
            if uab {
                ci = ci.flags(vk::DescriptorSetLayoutCreateFlags::UPDATE_AFTER_BIND_POOL);
            }
            ci = ci.push_next(&mut flags_info);
        }
        DescriptorModel::DescriptorBuffer => {
            ci = ci.flags(vk::DescriptorSetLayoutCreateFlags::DESCRIPTOR_BUFFER_EXT)
        }
        DescriptorModel::DescriptorHeap => unreachable!("heap bindings have no set layout"),
    }
    unsafe { gpu.device.create_descriptor_set_layout(&ci, None) }.at("vkCreateDescriptorSetLayout")
}

/// The contents of the set and pipeline layouts [`set_layout`] and [`pipeline_layout`] make from
/// the same arguments, hashed: each binding's number, type, count, stages and flags, the set
/// layout's flags and the push-constant range (part of a pipeline's identity across runs).
pub(super) fn digest(
    key: LayoutKey,
    targets: &[(u32, Resource, Vec<Target>)],
    flags: &[vk::DescriptorBindingFlags],
    uab: bool,
) -> u128 {
    let mut h = crate::stable_hash::StableHash::default();
    h.str(key.model.as_str()).u32(key.stages.as_raw()).u32(u32::from(uab));
    for (i, (b, kind, t)) in targets.iter().enumerate() {
        h.u32(*b).u32(descriptor_type(*kind).as_raw() as u32).u64(t.len() as u64);
        h.u32(flags.get(i).map_or(0, |f| f.as_raw()));
    }
    h.u32(PUSH_CONSTANT_BYTES);
    h.finish()
}

/// The pipeline layout: `set_layout` and the probes' push constants, both seen by `stages`.
pub(super) fn pipeline_layout(
    gpu: &Gpu,
    stages: vk::ShaderStageFlags,
    set_layout: vk::DescriptorSetLayout,
) -> Result<vk::PipelineLayout, VkError> {
    let ranges =
        [vk::PushConstantRange { stage_flags: stages, offset: 0, size: PUSH_CONSTANT_BYTES }];
    let layouts = [set_layout];
    unsafe {
        gpu.device.create_pipeline_layout(
            &vk::PipelineLayoutCreateInfo::default()
                .set_layouts(&layouts)
                .push_constant_ranges(&ranges),
            None,
        )
    }
    .at("vkCreatePipelineLayout")
}
