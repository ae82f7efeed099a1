//! The device's descriptor-heap properties and commands, and the descriptor sizes read from them:
//! the bytes a descriptor write fills and the stride of each descriptor class in a heap.
use crate::vk::heap as h;
use crate::vk::Gpu;
use ash::vk;

pub(super) fn props(gpu: &Gpu) -> h::PhysicalDeviceDescriptorHeapPropertiesEXT {
    gpu.info.properties.descriptor_heap.unwrap_or_default()
}

pub(super) fn fns(gpu: &Gpu) -> &h::HeapFns {
    gpu.heap.as_ref().expect("descriptor heap enabled for heap cells (worker::requirements)")
}

/// A descriptor type as the heaps hold it: heaps have no combined descriptors, a sampled image's
/// image goes to the resource heap, its sampler to the sampler heap.
pub(super) fn heap_type(ty: vk::DescriptorType) -> vk::DescriptorType {
    if ty == vk::DescriptorType::COMBINED_IMAGE_SAMPLER {
        vk::DescriptorType::SAMPLED_IMAGE
    } else {
        ty
    }
}

/// The device's descriptor sizes, and the commands that write descriptors.
pub(super) struct Sizes<'a> {
    pub gpu: &'a Gpu,
    pub p: h::PhysicalDeviceDescriptorHeapPropertiesEXT,
    pub f: &'a h::HeapFns,
}

impl Sizes<'_> {
    /// How many bytes a descriptor write fills: vkGetPhysicalDeviceDescriptorSizeEXT ("for
    /// tools"; only those bytes are written and read).
    pub fn written(&self, ty: vk::DescriptorType) -> u32 {
        unsafe { (self.f.get_descriptor_size)(self.gpu.info.raw, heap_type(ty)) as u32 }
    }

    /// The stride of a descriptor array in the heap is its class's descriptor size: buffers and
    /// acceleration structures (address ranges) `bufferDescriptorSize`, images
    /// `imageDescriptorSize`. A shader reading the heap directly strides by
    /// `OpConstantSizeOfEXT` of the type, which is that class size, not the exact size above
    /// (on lavapipe 26 an AS descriptor is 8 bytes, the buffer class 16).
    pub fn class(&self, ty: vk::DescriptorType) -> u32 {
        let p = &self.p;
        (match heap_type(ty) {
            vk::DescriptorType::SAMPLED_IMAGE | vk::DescriptorType::STORAGE_IMAGE => {
                p.image_descriptor_size
            }
            vk::DescriptorType::SAMPLER => p.sampler_descriptor_size,
            _ => p.buffer_descriptor_size,
        }) as u32
    }
}
