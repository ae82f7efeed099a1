//! Raw bindings for VK_EXT_descriptor_heap, which ash 0.38 (Vulkan headers 1.3.281) predates,
//! laid out exactly as in Vulkan 1.4.363's `vulkan_core.h` (extension number 136): the features /
//! properties structs (chained only when the driver lists the extension, so a driver that lacks
//! it never sees these sTypes), the descriptor-writing, heap-binding and push-data structs, the
//! set/binding mapping structs, and the device commands, loaded with `vkGetDeviceProcAddr`
//! ([`HeapFns`]) only on devices created with the extension.
use ash::vk;
use std::ffi::{c_void, CStr};

pub const NAME: &CStr = c"VK_EXT_descriptor_heap";
/// VK_KHR_shader_untyped_pointers: the SPIR-V of `layout(descriptor_heap)` GLSL uses untyped pointers.
pub const UNTYPED_POINTERS_NAME: &CStr = c"VK_KHR_shader_untyped_pointers";
pub const STRUCTURE_TYPE_PHYSICAL_DEVICE_SHADER_UNTYPED_POINTERS_FEATURES_KHR: vk::StructureType =
    vk::StructureType::from_raw(1_000_387_000);

/// `VkPhysicalDeviceShaderUntypedPointersFeaturesKHR`.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct PhysicalDeviceShaderUntypedPointersFeaturesKHR {
    pub s_type: vk::StructureType,
    pub p_next: *mut c_void,
    pub shader_untyped_pointers: vk::Bool32,
}

impl Default for PhysicalDeviceShaderUntypedPointersFeaturesKHR {
    fn default() -> Self {
        Self {
            s_type: STRUCTURE_TYPE_PHYSICAL_DEVICE_SHADER_UNTYPED_POINTERS_FEATURES_KHR,
            p_next: std::ptr::null_mut(),
            shader_untyped_pointers: 0,
        }
    }
}

// SAFETY: begins with sType/pNext; extends the structures the registry says it extends.
unsafe impl vk::ExtendsPhysicalDeviceFeatures2 for PhysicalDeviceShaderUntypedPointersFeaturesKHR {}
unsafe impl vk::ExtendsDeviceCreateInfo for PhysicalDeviceShaderUntypedPointersFeaturesKHR {}
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

pub const STRUCTURE_TYPE_IMAGE_DESCRIPTOR_INFO_EXT: vk::StructureType =
    vk::StructureType::from_raw(1_000_135_001);
pub const STRUCTURE_TYPE_RESOURCE_DESCRIPTOR_INFO_EXT: vk::StructureType =
    vk::StructureType::from_raw(1_000_135_002);
pub const STRUCTURE_TYPE_BIND_HEAP_INFO_EXT: vk::StructureType =
    vk::StructureType::from_raw(1_000_135_003);
pub const STRUCTURE_TYPE_PUSH_DATA_INFO_EXT: vk::StructureType =
    vk::StructureType::from_raw(1_000_135_004);
pub const STRUCTURE_TYPE_DESCRIPTOR_SET_AND_BINDING_MAPPING_EXT: vk::StructureType =
    vk::StructureType::from_raw(1_000_135_005);
pub const STRUCTURE_TYPE_SHADER_DESCRIPTOR_SET_AND_BINDING_MAPPING_INFO_EXT: vk::StructureType =
    vk::StructureType::from_raw(1_000_135_006);

/// `VK_BUFFER_USAGE_DESCRIPTOR_HEAP_BIT_EXT`.
pub const BUFFER_USAGE_DESCRIPTOR_HEAP: vk::BufferUsageFlags =
    vk::BufferUsageFlags::from_raw(0x1000_0000);
/// `VK_PIPELINE_CREATE_2_DESCRIPTOR_HEAP_BIT_EXT` (through VkPipelineCreateFlags2CreateInfo).
pub const PIPELINE_CREATE_2_DESCRIPTOR_HEAP: vk::PipelineCreateFlags2KHR =
    vk::PipelineCreateFlags2KHR::from_raw(0x10_0000_0000);
/// `VK_SPIRV_RESOURCE_TYPE_ALL_EXT`.
pub const SPIRV_RESOURCE_TYPE_ALL: u32 = 0x7FFF_FFFF;

/// `VkDescriptorMappingSourceEXT` (the values rtprobe uses).
#[repr(i32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MappingSource {
    HeapWithConstantOffset = 0,
    HeapWithPushIndex = 1,
    HeapWithIndirectIndex = 2,
    HeapWithShaderRecordIndex = 8,
}

/// `VkDeviceAddressRangeEXT` (= VkDeviceAddressRangeKHR).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default)]
pub struct DeviceAddressRange {
    pub address: vk::DeviceAddress,
    pub size: vk::DeviceSize,
}

/// `VkHostAddressRangeEXT`.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct HostAddressRange {
    pub address: *mut c_void,
    pub size: usize,
}

/// `VkHostAddressRangeConstEXT`.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct HostAddressRangeConst {
    pub address: *const c_void,
    pub size: usize,
}

/// `VkImageDescriptorInfoEXT`: an image descriptor is made from a view *description*.
#[repr(C)]
#[derive(Clone, Copy)]
pub struct ImageDescriptorInfo {
    pub s_type: vk::StructureType,
    pub p_next: *const c_void,
    pub p_view: *const vk::ImageViewCreateInfo<'static>,
    pub layout: vk::ImageLayout,
}

/// `VkResourceDescriptorDataEXT` (the members rtprobe uses; all are pointers).
#[repr(C)]
#[derive(Clone, Copy)]
pub union ResourceDescriptorData {
    pub p_image: *const ImageDescriptorInfo,
    pub p_address_range: *const DeviceAddressRange,
}

/// `VkResourceDescriptorInfoEXT`.
#[repr(C)]
#[derive(Clone, Copy)]
pub struct ResourceDescriptorInfo {
    pub s_type: vk::StructureType,
    pub p_next: *const c_void,
    pub ty: vk::DescriptorType,
    pub data: ResourceDescriptorData,
}

/// `VkBindHeapInfoEXT`.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct BindHeapInfo {
    pub s_type: vk::StructureType,
    pub p_next: *const c_void,
    pub heap_range: DeviceAddressRange,
    pub reserved_range_offset: vk::DeviceSize,
    pub reserved_range_size: vk::DeviceSize,
}

/// `VkPushDataInfoEXT`.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct PushDataInfo {
    pub s_type: vk::StructureType,
    pub p_next: *const c_void,
    pub offset: u32,
    pub data: HostAddressRangeConst,
}

/// `VkDescriptorMappingSourceConstantOffsetEXT`.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct MappingConstantOffset {
    pub heap_offset: u32,
    pub heap_array_stride: u32,
    pub p_embedded_sampler: *const vk::SamplerCreateInfo<'static>,
    pub sampler_heap_offset: u32,
    pub sampler_heap_array_stride: u32,
}

/// `VkDescriptorMappingSourcePushIndexEXT`.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct MappingPushIndex {
    pub heap_offset: u32,
    pub push_offset: u32,
    pub heap_index_stride: u32,
    pub heap_array_stride: u32,
    pub p_embedded_sampler: *const vk::SamplerCreateInfo<'static>,
    pub use_combined_image_sampler_index: vk::Bool32,
    pub sampler_heap_offset: u32,
    pub sampler_push_offset: u32,
    pub sampler_heap_index_stride: u32,
    pub sampler_heap_array_stride: u32,
}

/// `VkDescriptorMappingSourceIndirectIndexEXT`: the heap index is read from a buffer whose
/// address is in push data.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct MappingIndirectIndex {
    pub heap_offset: u32,
    pub push_offset: u32,
    pub address_offset: u32,
    pub heap_index_stride: u32,
    pub heap_array_stride: u32,
    pub p_embedded_sampler: *const vk::SamplerCreateInfo<'static>,
    pub use_combined_image_sampler_index: vk::Bool32,
    pub sampler_heap_offset: u32,
    pub sampler_push_offset: u32,
    pub sampler_address_offset: u32,
    pub sampler_heap_index_stride: u32,
    pub sampler_heap_array_stride: u32,
}

/// `VkDescriptorMappingSourceShaderRecordIndexEXT`.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct MappingShaderRecordIndex {
    pub heap_offset: u32,
    pub shader_record_offset: u32,
    pub heap_index_stride: u32,
    pub heap_array_stride: u32,
    pub p_embedded_sampler: *const vk::SamplerCreateInfo<'static>,
    pub use_combined_image_sampler_index: vk::Bool32,
    pub sampler_heap_offset: u32,
    pub sampler_shader_record_offset: u32,
    pub sampler_heap_index_stride: u32,
    pub sampler_heap_array_stride: u32,
}

/// `VkDescriptorMappingSourceDataEXT` (the members rtprobe uses; `_size` keeps the C size, 56 bytes,
/// that of its largest member, `VkDescriptorMappingSourceIndirectIndexEXT`).
#[repr(C)]
#[derive(Clone, Copy)]
pub union MappingSourceData {
    pub constant_offset: MappingConstantOffset,
    pub push_index: MappingPushIndex,
    pub indirect_index: MappingIndirectIndex,
    pub shader_record_index: MappingShaderRecordIndex,
    _size: [u64; 7],
}

/// `VkDescriptorSetAndBindingMappingEXT`.
#[repr(C)]
#[derive(Clone, Copy)]
pub struct SetAndBindingMapping {
    pub s_type: vk::StructureType,
    pub p_next: *const c_void,
    pub descriptor_set: u32,
    pub first_binding: u32,
    pub binding_count: u32,
    pub resource_mask: u32,
    pub source: MappingSource,
    pub source_data: MappingSourceData,
}

/// `VkShaderDescriptorSetAndBindingMappingInfoEXT`, chained to VkPipelineShaderStageCreateInfo.
#[repr(C)]
#[derive(Clone, Copy)]
pub struct ShaderSetAndBindingMappingInfo {
    pub s_type: vk::StructureType,
    pub p_next: *const c_void,
    pub mapping_count: u32,
    pub p_mappings: *const SetAndBindingMapping,
}

// SAFETY: begins with sType/pNext and extends VkPipelineShaderStageCreateInfo per the registry.
unsafe impl vk::ExtendsPipelineShaderStageCreateInfo for ShaderSetAndBindingMappingInfo {}

type PfnWriteSamplerDescriptors = unsafe extern "system" fn(
    vk::Device,
    u32,
    *const vk::SamplerCreateInfo<'_>,
    *const HostAddressRange,
) -> vk::Result;
type PfnWriteResourceDescriptors = unsafe extern "system" fn(
    vk::Device,
    u32,
    *const ResourceDescriptorInfo,
    *const HostAddressRange,
) -> vk::Result;
type PfnCmdBindHeap = unsafe extern "system" fn(vk::CommandBuffer, *const BindHeapInfo);
type PfnCmdPushData = unsafe extern "system" fn(vk::CommandBuffer, *const PushDataInfo);
type PfnGetDescriptorSize =
    unsafe extern "system" fn(vk::PhysicalDevice, vk::DescriptorType) -> vk::DeviceSize;

/// The device commands of VK_EXT_descriptor_heap.
pub struct HeapFns {
    pub write_sampler_descriptors: PfnWriteSamplerDescriptors,
    pub write_resource_descriptors: PfnWriteResourceDescriptors,
    pub cmd_bind_sampler_heap: PfnCmdBindHeap,
    pub cmd_bind_resource_heap: PfnCmdBindHeap,
    pub cmd_push_data: PfnCmdPushData,
    /// vkGetPhysicalDeviceDescriptorSizeEXT (a physical-device command: from the instance).
    pub get_descriptor_size: PfnGetDescriptorSize,
}

impl HeapFns {
    /// Load the commands from a device created with VK_EXT_descriptor_heap; `None` names the
    /// first command the driver did not return.
    pub fn load(
        entry: &ash::Entry,
        instance: &ash::Instance,
        device: &ash::Device,
    ) -> Result<HeapFns, &'static str> {
        let get = |name: &'static CStr| {
            unsafe { (instance.fp_v1_0().get_device_proc_addr)(device.handle(), name.as_ptr()) }
                .ok_or(name.to_str().unwrap_or("?"))
        };
        let get_inst = |name: &'static CStr| {
            unsafe { entry.get_instance_proc_addr(instance.handle(), name.as_ptr()) }
                .ok_or(name.to_str().unwrap_or("?"))
        };
        // SAFETY: each pointer is the driver's entry point of the named command, whose C
        // signature the matching Pfn type reproduces from vulkan_core.h.
        unsafe {
            Ok(HeapFns {
                write_sampler_descriptors: std::mem::transmute::<
                    unsafe extern "system" fn(),
                    PfnWriteSamplerDescriptors,
                >(get(c"vkWriteSamplerDescriptorsEXT")?),
                write_resource_descriptors: std::mem::transmute::<
                    unsafe extern "system" fn(),
                    PfnWriteResourceDescriptors,
                >(get(
                    c"vkWriteResourceDescriptorsEXT",
                )?),
                cmd_bind_sampler_heap: std::mem::transmute::<
                    unsafe extern "system" fn(),
                    PfnCmdBindHeap,
                >(get(c"vkCmdBindSamplerHeapEXT")?),
                cmd_bind_resource_heap: std::mem::transmute::<
                    unsafe extern "system" fn(),
                    PfnCmdBindHeap,
                >(get(c"vkCmdBindResourceHeapEXT")?),
                cmd_push_data: std::mem::transmute::<unsafe extern "system" fn(), PfnCmdPushData>(
                    get(c"vkCmdPushDataEXT")?,
                ),
                get_descriptor_size: std::mem::transmute::<
                    unsafe extern "system" fn(),
                    PfnGetDescriptorSize,
                >(get_inst(
                    c"vkGetPhysicalDeviceDescriptorSizeEXT",
                )?),
            })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::mem::{offset_of, size_of};

    /// Sizes and offsets as a C compiler lays out vulkan_core.h 1.4.363 on 64-bit targets.
    #[test]
    fn layouts_match_the_c_header() {
        assert_eq!(size_of::<MappingPushIndex>(), 48);
        assert_eq!(size_of::<MappingShaderRecordIndex>(), 48);
        assert_eq!(size_of::<MappingConstantOffset>(), 24);
        assert_eq!(size_of::<MappingIndirectIndex>(), 56);
        assert_eq!(offset_of!(MappingIndirectIndex, p_embedded_sampler), 24);
        assert_eq!(offset_of!(MappingIndirectIndex, sampler_heap_array_stride), 52);
        assert_eq!(size_of::<MappingSourceData>(), 56);
        assert_eq!(offset_of!(SetAndBindingMapping, source_data), 40);
        assert_eq!(size_of::<SetAndBindingMapping>(), 96);
        assert_eq!(size_of::<BindHeapInfo>(), 48);
        assert_eq!(size_of::<PushDataInfo>(), 40);
        assert_eq!(size_of::<ResourceDescriptorInfo>(), 32);
        assert_eq!(offset_of!(ResourceDescriptorInfo, data), 24);
    }
}
