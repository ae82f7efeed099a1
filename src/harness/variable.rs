//! The layout count of a variable-sized descriptor binding (`--profile` with
//! `descriptorBindingVariableDescriptorCount`): an engine declares the binding at the device's
//! upper bound and allocates each set with the number it uses, so the layout's
//! `descriptorCount` and the set's `VkDescriptorSetVariableDescriptorCountAllocateInfo` count
//! differ. The bound is what the pipeline layout's limits leave for the binding (every harness
//! binding is seen by every ray tracing stage, so a per-stage total is the pipeline's total),
//! at most [`CAP`]; the allocated count is the binding's own (`--array-size`).
//!
//! The rules relied on (Vulkan 1.4.360):
//! - VUID-VkDescriptorSetAllocateInfo-pSetLayouts-09380: "If pSetLayouts[i] was created with an
//!   element of pBindingFlags that includes VK_DESCRIPTOR_BINDING_VARIABLE_DESCRIPTOR_COUNT_BIT,
//!   and VkDescriptorSetVariableDescriptorCountAllocateInfo is included in the pNext chain, and
//!   VkDescriptorSetVariableDescriptorCountAllocateInfo::descriptorSetCount is not zero, then
//!   VkDescriptorSetVariableDescriptorCountAllocateInfo::pDescriptorCounts[i] must be less than
//!   or equal to VkDescriptorSetLayoutBinding::descriptorCount for the corresponding binding
//!   used to create pSetLayouts[i]": the allocated count never exceeds the layout's.
//! - VUID-VkDescriptorSetLayoutBindingFlagsCreateInfo-pBindingFlags-03004: "If an element of
//!   pBindingFlags includes VK_DESCRIPTOR_BINDING_VARIABLE_DESCRIPTOR_COUNT_BIT, then it must be
//!   the element with the highest binding number" (`super::profile::set_flags`).
//! - VK_DESCRIPTOR_BINDING_VARIABLE_DESCRIPTOR_COUNT_BIT: "The value of descriptorCount is
//!   treated as an upper bound on the size of the binding. [...] For the purposes of counting
//!   against limits such as maxDescriptorSet* and maxPerStageDescriptor*, the full value of
//!   descriptorCount is counted": the bound leaves room for every other binding under each
//!   limit. VUID-VkPipelineLayoutCreateInfo-descriptorType-03016: "The total number of
//!   descriptors in descriptor set layouts created without the
//!   VK_DESCRIPTOR_SET_LAYOUT_CREATE_UPDATE_AFTER_BIND_POOL_BIT bit set with a descriptorType of
//!   VK_DESCRIPTOR_TYPE_SAMPLER and VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER accessible to any
//!   given shader stage across all elements of pSetLayouts must be less than or equal to
//!   VkPhysicalDeviceLimits::maxPerStageDescriptorSamplers"; -03023: "The total number of
//!   descriptors with a descriptorType of VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER [...] accessible
//!   to any given shader stage across all elements of pSetLayouts must be less than or equal to
//!   the maximum of [...] maxPerStageDescriptorUniformBuffers and [...]
//!   maxPerStageDescriptorUpdateAfterBindUniformBuffers"; the same two rules for every other
//!   type, per stage and per set (-03571 to -03574 for acceleration structures), and for
//!   maxPerStageResources.
//! - vkAllocateDescriptorSets "may fail due to lack of space if the call [...] would cause the
//!   number of any given descriptor type to exceed the sum of all the descriptorCount members
//!   of [...] pPoolSizes": a variable-sized binding holds the allocated count of descriptors,
//!   so the pool is sized by those.
use super::profile::set_flags;
use super::reflect::{Binding, BindingKind};
use crate::model::profile::BindingFlags;
use crate::vk::DeviceInfo;
use std::collections::BTreeMap;

/// The largest layout count the harness gives a variable-sized binding, whatever the device
/// allows (2^20: above every `--array-size`, 65536 at most, and the 500 000 to 1 000 000 of
/// bindless engines' texture tables).
pub const CAP: u32 = 1 << 20;

/// Which descriptors a device limit counts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Counted {
    Samplers,
    UniformBuffers,
    StorageBuffers,
    SampledImages,
    StorageImages,
    AccelerationStructures,
    /// maxPerStageResources: buffers and images.
    Resources,
}

impl Counted {
    fn counts(self, kind: BindingKind) -> bool {
        use BindingKind as K;
        match self {
            Counted::Samplers => matches!(kind, K::Sampler | K::CombinedImageSampler),
            Counted::UniformBuffers => matches!(kind, K::UniformBuffer(_)),
            Counted::StorageBuffers => matches!(kind, K::StorageBuffer(_)),
            Counted::SampledImages => matches!(kind, K::SampledImage | K::CombinedImageSampler),
            Counted::StorageImages => matches!(kind, K::StorageImage(_)),
            Counted::AccelerationStructures => matches!(kind, K::AccelerationStructure),
            Counted::Resources => !matches!(kind, K::Sampler | K::AccelerationStructure),
        }
    }
}

/// One device limit on a pipeline layout's descriptors: its value for layouts without
/// UPDATE_AFTER_BIND_POOL (counting those only) and its update-after-bind value (every layout
/// counts against the larger of the two).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limit {
    pub counted: Counted,
    pub plain: u32,
    pub update_after_bind: u32,
}

/// The device's per-stage and per-set descriptor limits.
pub fn limits(info: &DeviceInfo) -> Vec<Limit> {
    let l = &info.properties.core.limits;
    let v = info.properties.v12.unwrap_or_default();
    let a = info.properties.accel.unwrap_or_default();
    let lim = |counted, plain, update_after_bind| Limit { counted, plain, update_after_bind };
    use Counted as C;
    vec![
        lim(
            C::Samplers,
            l.max_per_stage_descriptor_samplers,
            v.max_per_stage_descriptor_update_after_bind_samplers,
        ),
        lim(
            C::Samplers,
            l.max_descriptor_set_samplers,
            v.max_descriptor_set_update_after_bind_samplers,
        ),
        lim(
            C::UniformBuffers,
            l.max_per_stage_descriptor_uniform_buffers,
            v.max_per_stage_descriptor_update_after_bind_uniform_buffers,
        ),
        lim(
            C::UniformBuffers,
            l.max_descriptor_set_uniform_buffers,
            v.max_descriptor_set_update_after_bind_uniform_buffers,
        ),
        lim(
            C::StorageBuffers,
            l.max_per_stage_descriptor_storage_buffers,
            v.max_per_stage_descriptor_update_after_bind_storage_buffers,
        ),
        lim(
            C::StorageBuffers,
            l.max_descriptor_set_storage_buffers,
            v.max_descriptor_set_update_after_bind_storage_buffers,
        ),
        lim(
            C::SampledImages,
            l.max_per_stage_descriptor_sampled_images,
            v.max_per_stage_descriptor_update_after_bind_sampled_images,
        ),
        lim(
            C::SampledImages,
            l.max_descriptor_set_sampled_images,
            v.max_descriptor_set_update_after_bind_sampled_images,
        ),
        lim(
            C::StorageImages,
            l.max_per_stage_descriptor_storage_images,
            v.max_per_stage_descriptor_update_after_bind_storage_images,
        ),
        lim(
            C::StorageImages,
            l.max_descriptor_set_storage_images,
            v.max_descriptor_set_update_after_bind_storage_images,
        ),
        lim(
            C::AccelerationStructures,
            a.max_per_stage_descriptor_acceleration_structures,
            a.max_per_stage_descriptor_update_after_bind_acceleration_structures,
        ),
        lim(
            C::AccelerationStructures,
            a.max_descriptor_set_acceleration_structures,
            a.max_descriptor_set_update_after_bind_acceleration_structures,
        ),
        lim(C::Resources, l.max_per_stage_resources, v.max_per_stage_update_after_bind_resources),
    ]
}

/// A variable-sized binding's two counts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct VariableCount {
    /// The layout binding's `descriptorCount`: the upper bound.
    pub layout: u32,
    /// The set's `VkDescriptorSetVariableDescriptorCountAllocateInfo` count.
    pub allocated: u32,
}

/// Each variable-sized binding of `bindings` (one per set and binding) under `flags`, by set and
/// binding, with its layout bound under `limits` (never below the allocated count: a device
/// without room keeps the binding at its own count).
pub fn counts(
    bindings: &BTreeMap<(u32, u32), Binding>,
    flags: &BindingFlags,
    limits: &[Limit],
) -> BTreeMap<(u32, u32), VariableCount> {
    // Each binding's layout count so far, and whether its set is UPDATE_AFTER_BIND_POOL.
    let mut layout: BTreeMap<(u32, u32), (u32, bool)> = BTreeMap::new();
    let mut variable = Vec::new();
    let sets: std::collections::BTreeSet<u32> = bindings.keys().map(|k| k.0).collect();
    for set in sets {
        let bs: Vec<&Binding> = bindings.values().filter(|b| b.set == set).collect();
        let (bf, uab) = set_flags(flags, &bs);
        for (b, f) in bs.iter().zip(&bf) {
            layout.insert((b.set, b.binding), (b.count, uab));
            if f.contains(ash::vk::DescriptorBindingFlags::VARIABLE_DESCRIPTOR_COUNT) {
                variable.push((b.set, b.binding));
            }
        }
    }
    let mut out = BTreeMap::new();
    for key in variable {
        let (b, (allocated, uab)) = (&bindings[&key], layout[&key]);
        let room = limits
            .iter()
            .filter(|l| l.counted.counts(b.kind))
            .flat_map(|l| {
                let others = |plain_only: bool| -> u64 {
                    let counted = layout.iter().filter(|(k, (_, u))| {
                        **k != key && !(plain_only && *u) && l.counted.counts(bindings[*k].kind)
                    });
                    counted.map(|(_, (n, _))| *n as u64).sum()
                };
                let most = l.plain.max(l.update_after_bind) as u64;
                let with_uab = most.saturating_sub(others(false));
                let plain = (!uab).then(|| (l.plain as u64).saturating_sub(others(true)));
                std::iter::once(with_uab).chain(plain)
            })
            .min()
            .unwrap_or(CAP as u64);
        let bound = room.min(CAP as u64).max(allocated as u64) as u32;
        layout.insert(key, (bound, uab));
        out.insert(key, VariableCount { layout: bound, allocated });
    }
    out
}

/// The counts in words, for the report (`set 1 binding 3: layout 999998, allocated 64`).
pub fn words(counts: &BTreeMap<(u32, u32), VariableCount>) -> Vec<String> {
    counts
        .iter()
        .map(|((s, b), c)| {
            format!("set {s} binding {b}: layout {}, allocated {}", c.layout, c.allocated)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn binding(set: u32, b: u32, kind: BindingKind, count: u32, runtime: bool) -> Binding {
        Binding {
            set,
            binding: b,
            kind,
            count,
            runtime,
            writable: false,
            ints: Default::default(),
            atomic: false,
            records: None,
        }
    }

    fn all(list: Vec<Binding>) -> BTreeMap<(u32, u32), Binding> {
        list.into_iter().map(|b| ((b.set, b.binding), b)).collect()
    }

    fn limit(counted: Counted, plain: u32, update_after_bind: u32) -> Limit {
        Limit { counted, plain, update_after_bind }
    }

    /// The layout takes what the limits leave after the other bindings of the kinds they count;
    /// the allocated count stays the binding's own.
    #[test]
    fn the_layout_takes_the_room_the_limits_leave() {
        let b = all(vec![
            binding(0, 0, BindingKind::AccelerationStructure, 1, false),
            binding(0, 1, BindingKind::CombinedImageSampler, 2, false),
            binding(1, 0, BindingKind::SampledImage, 64, true),
        ]);
        let f = BindingFlags { variable_count: true, ..Default::default() };
        let lims = [
            limit(Counted::SampledImages, 1000, 5000),
            limit(Counted::Resources, 900, 5000),
            limit(Counted::Samplers, 10, 10),
        ];
        let c = counts(&b, &f, &lims);
        // maxPerStageResources 900 less the combined image sampler's 2.
        assert_eq!(c[&(1, 0)], VariableCount { layout: 898, allocated: 64 });
        assert_eq!(words(&c), ["set 1 binding 0: layout 898, allocated 64"]);
        // Twin: without the variable count flag nothing is variable.
        assert!(counts(&b, &BindingFlags::default(), &lims).is_empty());
    }

    /// Update-after-bind sets count only against the update-after-bind limits; a device without
    /// room keeps the allocated count; the cap holds on a device with room to spare.
    #[test]
    fn update_after_bind_limits_cap_and_no_room() {
        let b = all(vec![
            binding(0, 0, BindingKind::StorageBuffer(16), 4, false),
            binding(0, 1, BindingKind::StorageBuffer(16), 8, true),
        ]);
        let mut f = BindingFlags { variable_count: true, ..Default::default() };
        let lims = [limit(Counted::StorageBuffers, 100, 50_000)];
        assert_eq!(counts(&b, &f, &lims)[&(0, 1)].layout, 96);
        f.update_after_bind.storage_buffer = true;
        assert_eq!(counts(&b, &f, &lims)[&(0, 1)].layout, 49_996);
        let tight = [limit(Counted::StorageBuffers, 6, 6)];
        assert_eq!(counts(&b, &f, &tight)[&(0, 1)], VariableCount { layout: 8, allocated: 8 });
        let huge = [limit(Counted::StorageBuffers, u32::MAX, u32::MAX)];
        assert_eq!(counts(&b, &f, &huge)[&(0, 1)].layout, CAP);
    }
}
