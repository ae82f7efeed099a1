//! `descriptor_indexing`: a descriptor pool (update-after-bind where the layout is) with one set,
//! each binding's descriptors written with vkUpdateDescriptorSets.
use crate::exec::resources::{descriptor_type, Target};
use crate::model::Resource;
use crate::vk::{Gpu, VkError, VkResultExt};
use ash::vk;

/// A pool and one set of `layout`, holding `targets[b]` at each binding b.
pub(super) fn write(
    gpu: &Gpu,
    layout: vk::DescriptorSetLayout,
    uab: bool,
    targets: &[(u32, Resource, Vec<Target>)],
) -> Result<(vk::DescriptorPool, vk::DescriptorSet), VkError> {
    let d = &gpu.device;
    let sizes: Vec<vk::DescriptorPoolSize> = targets
        .iter()
        .map(|(_, kind, t)| vk::DescriptorPoolSize {
            ty: descriptor_type(*kind),
            descriptor_count: t.len() as u32,
        })
        .collect();
    let mut pci = vk::DescriptorPoolCreateInfo::default().max_sets(1).pool_sizes(&sizes);
    if uab {
        pci = pci.flags(vk::DescriptorPoolCreateFlags::UPDATE_AFTER_BIND);
    }
    let pool = unsafe { d.create_descriptor_pool(&pci, None) }.at("vkCreateDescriptorPool")?;
    let layouts = [layout];
    let set = unsafe {
        d.allocate_descriptor_sets(
            &vk::DescriptorSetAllocateInfo::default().descriptor_pool(pool).set_layouts(&layouts),
        )
    }
    .at("vkAllocateDescriptorSets")?[0];
    for (b, kind, ts) in targets {
        let ty = &descriptor_type(*kind);
        let mut buffer_infos = Vec::new();
        let mut image_infos = Vec::new();
        let mut accels = Vec::new();
        for t in ts {
            match *t {
                Target::Buffer { raw, range, .. } => {
                    buffer_infos.push(vk::DescriptorBufferInfo { buffer: raw, offset: 0, range })
                }
                Target::Image { view, sampler, .. } => image_infos.push(vk::DescriptorImageInfo {
                    sampler,
                    image_view: view,
                    image_layout: vk::ImageLayout::GENERAL,
                }),
                Target::Accel { raw, .. } => accels.push(raw),
            }
        }
        let mut as_write = vk::WriteDescriptorSetAccelerationStructureKHR::default()
            .acceleration_structures(&accels);
        let mut w =
            vk::WriteDescriptorSet::default().dst_set(set).dst_binding(*b).descriptor_type(*ty);
        if !buffer_infos.is_empty() {
            w = w.buffer_info(&buffer_infos);
        } else if !image_infos.is_empty() {
            w = w.image_info(&image_infos);
        } else {
            w.descriptor_count = accels.len() as u32;
            w = w.push_next(&mut as_write);
        }
        unsafe { d.update_descriptor_sets(&[w], &[]) };
    }
    Ok((pool, set))
}
