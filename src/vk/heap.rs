//! Raw bindings for VK_EXT_descriptor_heap, which ash 0.38 (Vulkan headers 1.3.281) predates.
//! Only what feature detection needs: the extension name and the features / properties structs,
//! laid out as in the Vulkan registry (`VkPhysicalDeviceDescriptorHeapFeaturesEXT`,
//! `VkPhysicalDeviceDescriptorHeapPropertiesEXT`, extension number 136). They are chained only
//! when the driver lists the extension, so a driver that lacks it never sees these sTypes.
use ash::vk;
use std::ffi::{c_void, CStr};

pub const NAME: &CStr = c"VK_EXT_descriptor_heap";
pub const STRUCTURE_TYPE_PHYSICAL_DEVICE_DESCRIPTOR_HEAP_PROPERTIES_EXT: vk::StructureType =
    vk::StructureType::from_raw(1_000_135_008);
pub const STRUCTURE_TYPE_PHYSICAL_DEVICE_DESCRIPTOR_HEAP_FEATURES_EXT: vk::StructureType =
    vk::StructureType::from_raw(1_000_135_009);

#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct PhysicalDeviceDescriptorHeapFeaturesEXT {
    pub s_type: vk::StructureType,
    pub p_next: *mut c_void,
    pub descriptor_heap: vk::Bool32,
    pub descriptor_heap_capture_replay: vk::Bool32,
}

impl Default for PhysicalDeviceDescriptorHeapFeaturesEXT {
    fn default() -> Self {
        Self {
            s_type: STRUCTURE_TYPE_PHYSICAL_DEVICE_DESCRIPTOR_HEAP_FEATURES_EXT,
            p_next: std::ptr::null_mut(),
            descriptor_heap: 0,
            descriptor_heap_capture_replay: 0,
        }
    }
}

#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct PhysicalDeviceDescriptorHeapPropertiesEXT {
    pub s_type: vk::StructureType,
    pub p_next: *mut c_void,
    pub sampler_heap_alignment: vk::DeviceSize,
    pub resource_heap_alignment: vk::DeviceSize,
    pub max_sampler_heap_size: vk::DeviceSize,
    pub max_resource_heap_size: vk::DeviceSize,
    pub min_sampler_heap_reserved_range: vk::DeviceSize,
    pub min_sampler_heap_reserved_range_with_embedded: vk::DeviceSize,
    pub min_resource_heap_reserved_range: vk::DeviceSize,
    pub sampler_descriptor_size: vk::DeviceSize,
    pub image_descriptor_size: vk::DeviceSize,
    pub buffer_descriptor_size: vk::DeviceSize,
    pub sampler_descriptor_alignment: vk::DeviceSize,
    pub image_descriptor_alignment: vk::DeviceSize,
    pub buffer_descriptor_alignment: vk::DeviceSize,
    pub max_push_data_size: vk::DeviceSize,
    pub image_capture_replay_opaque_data_size: usize,
    pub max_descriptor_heap_embedded_samplers: u32,
    pub sampler_ycbcr_conversion_count: u32,
    pub sparse_descriptor_heaps: vk::Bool32,
    pub protected_descriptor_heaps: vk::Bool32,
}

impl Default for PhysicalDeviceDescriptorHeapPropertiesEXT {
    fn default() -> Self {
        // SAFETY: plain-old-data; all-zero is a valid value for every field.
        let mut s: Self = unsafe { std::mem::zeroed() };
        s.s_type = STRUCTURE_TYPE_PHYSICAL_DEVICE_DESCRIPTOR_HEAP_PROPERTIES_EXT;
        s
    }
}

// SAFETY: both structs begin with sType/pNext as VkBaseOutStructure and extend exactly the
// structures the registry says they extend.
unsafe impl vk::ExtendsPhysicalDeviceFeatures2 for PhysicalDeviceDescriptorHeapFeaturesEXT {}
unsafe impl vk::ExtendsDeviceCreateInfo for PhysicalDeviceDescriptorHeapFeaturesEXT {}
unsafe impl vk::ExtendsPhysicalDeviceProperties2 for PhysicalDeviceDescriptorHeapPropertiesEXT {}
