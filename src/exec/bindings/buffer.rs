//! `descriptor_buffer` (VK_EXT_descriptor_buffer): a host buffer holding every descriptor, each
//! written with vkGetDescriptorEXT at its binding's offset in the set layout (a cell's, or one
//! set of a `run --shader` pipeline).
use crate::exec::resources::{descriptor_type, Target};
use crate::model::Resource;
use crate::vk::memory::{Buffer, Location};
use crate::vk::{Gpu, VkError};
use ash::vk;

/// Bytes of one descriptor of `kind` in a descriptor buffer.
fn descriptor_size(
    props: &vk::PhysicalDeviceDescriptorBufferPropertiesEXT,
    kind: Resource,
) -> usize {
    match kind {
        Resource::StorageBuffer => props.storage_buffer_descriptor_size,
        Resource::UniformBuffer => props.uniform_buffer_descriptor_size,
        Resource::SampledImage => props.combined_image_sampler_descriptor_size,
        Resource::StorageImage => props.storage_image_descriptor_size,
        Resource::AccelerationStructure => props.acceleration_structure_descriptor_size,
    }
}

/// A descriptor buffer for `layout` holding `targets[b]` at each binding b, and the usage it is
/// bound with (SAMPLER only with samplers).
pub fn write(
    gpu: &Gpu,
    layout: vk::DescriptorSetLayout,
    targets: &[(u32, Resource, Vec<Target>)],
) -> Result<(Buffer, vk::BufferUsageFlags), VkError> {
    let db = gpu.descriptor_buffer.as_ref().expect("descriptor buffer enabled");
    let props = gpu.info.properties.descriptor_buffer.expect("descriptor buffer properties");
    let size = unsafe { db.get_descriptor_set_layout_size(layout) };
    let mut usage = vk::BufferUsageFlags::RESOURCE_DESCRIPTOR_BUFFER_EXT;
    if targets.iter().any(|(_, kind, _)| *kind == Resource::SampledImage) {
        usage |= vk::BufferUsageFlags::SAMPLER_DESCRIPTOR_BUFFER_EXT;
    }
    let buffer = Buffer::new(
        gpu,
        size,
        usage | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS,
        Location::Host,
        "descriptor buffer",
    )?;
    let mut bytes = vec![0u8; size as usize];
    for (b, kind, ts) in targets {
        let ty = descriptor_type(*kind);
        let offset = unsafe { db.get_descriptor_set_layout_binding_offset(layout, *b) } as usize;
        let stride = descriptor_size(&props, *kind);
        for (i, t) in ts.iter().enumerate() {
            let at = offset + i * stride;
            get_descriptor(db, ty, t, &mut bytes[at..at + stride]);
        }
    }
    buffer.write(0, &bytes);
    Ok((buffer, usage))
}

/// Write the descriptor of type `ty` for `t` into `dst` (vkGetDescriptorEXT).
fn get_descriptor(
    db: &ash::ext::descriptor_buffer::Device,
    ty: vk::DescriptorType,
    t: &Target,
    dst: &mut [u8],
) {
    // What the descriptor data points at, alive until the call.
    let (address_info, image_info);
    let data = match *t {
        Target::Buffer { address, range, .. } => {
            address_info = vk::DescriptorAddressInfoEXT::default()
                .address(address)
                .range(range)
                .format(vk::Format::UNDEFINED);
            if ty == vk::DescriptorType::UNIFORM_BUFFER {
                vk::DescriptorDataEXT { p_uniform_buffer: &address_info }
            } else {
                vk::DescriptorDataEXT { p_storage_buffer: &address_info }
            }
        }
        Target::Image { view, sampler, .. } => {
            image_info = vk::DescriptorImageInfo {
                sampler,
                image_view: view,
                image_layout: vk::ImageLayout::GENERAL,
            };
            if ty == vk::DescriptorType::COMBINED_IMAGE_SAMPLER {
                vk::DescriptorDataEXT { p_combined_image_sampler: &image_info }
            } else {
                vk::DescriptorDataEXT { p_storage_image: &image_info }
            }
        }
        Target::Accel { address, .. } => vk::DescriptorDataEXT { acceleration_structure: address },
    };
    unsafe { db.get_descriptor(&vk::DescriptorGetInfoEXT::default().ty(ty).data(data), dst) };
}
