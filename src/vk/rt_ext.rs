//! Raw bindings for the ray tracing extensions that ash 0.38 (Vulkan headers 1.3.281) predates:
//! their names and their physical-device feature / property structs, laid out member for member
//! as in `vulkan_core.h` / `vulkan_beta.h` of Vulkan-Headers 1.4.359, with the sTypes the
//! registry gives them. Like [`super::heap`], only what feature detection needs; each struct is
//! chained only when the driver lists its extension, so a driver that lacks one never sees its
//! sType.
use ash::vk;
use std::ffi::{c_void, CStr};

pub const NV_CLUSTER_ACCELERATION_STRUCTURE: &CStr = c"VK_NV_cluster_acceleration_structure";
pub const NV_PARTITIONED_ACCELERATION_STRUCTURE: &CStr =
    c"VK_NV_partitioned_acceleration_structure";
pub const NV_RAY_TRACING_LINEAR_SWEPT_SPHERES: &CStr = c"VK_NV_ray_tracing_linear_swept_spheres";
/// The cross-vendor successor of VK_NV_ray_tracing_invocation_reorder.
pub const EXT_RAY_TRACING_INVOCATION_REORDER: &CStr = c"VK_EXT_ray_tracing_invocation_reorder";
pub const KHR_OPACITY_MICROMAP: &CStr = c"VK_KHR_opacity_micromap";
pub const ARM_PIPELINE_OPACITY_MICROMAP: &CStr = c"VK_ARM_pipeline_opacity_micromap";
/// Provisional (`vulkan_beta.h`): dense geometry format for acceleration structure builds.
pub const AMDX_DENSE_GEOMETRY_FORMAT: &CStr = c"VK_AMDX_dense_geometry_format";

/// A `#[repr(C)]` struct that starts with sType/pNext, a `Default` that sets its sType and zeroes
/// the rest, and the `Extends*` marker of the chain it belongs to.
macro_rules! raw_struct {
    ($(#[$doc:meta])* $name:ident, $stype:literal, $extends:ident $(, $extra:ident)*; $($field:ident: $ty:ty),* $(,)?) => {
        $(#[$doc])*
        #[repr(C)]
        #[derive(Clone, Copy, Debug)]
        pub struct $name {
            pub s_type: vk::StructureType,
            pub p_next: *mut c_void,
            $(pub $field: $ty),*
        }

        impl $name {
            pub const STRUCTURE_TYPE: vk::StructureType = vk::StructureType::from_raw($stype);
        }

        impl Default for $name {
            fn default() -> Self {
                // SAFETY: plain-old-data; all-zero is a valid value for every member.
                let mut s: Self = unsafe { std::mem::zeroed() };
                s.s_type = Self::STRUCTURE_TYPE;
                s
            }
        }

        // SAFETY: begins with sType/pNext as VkBaseOutStructure and extends exactly the
        // structures the registry says it extends.
        unsafe impl vk::$extends for $name {}
        $(unsafe impl vk::$extra for $name {})*
    };
}

raw_struct!(
    /// `VkPhysicalDeviceClusterAccelerationStructureFeaturesNV`.
    PhysicalDeviceClusterAccelerationStructureFeaturesNV, 1_000_569_000, ExtendsPhysicalDeviceFeatures2, ExtendsDeviceCreateInfo;
    cluster_acceleration_structure: vk::Bool32,
);
raw_struct!(
    /// `VkPhysicalDeviceClusterAccelerationStructurePropertiesNV`.
    PhysicalDeviceClusterAccelerationStructurePropertiesNV, 1_000_569_001, ExtendsPhysicalDeviceProperties2;
    max_vertices_per_cluster: u32,
    max_triangles_per_cluster: u32,
    cluster_scratch_byte_alignment: u32,
    cluster_byte_alignment: u32,
    cluster_template_byte_alignment: u32,
    cluster_bottom_level_byte_alignment: u32,
    cluster_template_bounds_byte_alignment: u32,
    max_cluster_geometry_index: u32,
);
raw_struct!(
    /// `VkPhysicalDevicePartitionedAccelerationStructureFeaturesNV`.
    PhysicalDevicePartitionedAccelerationStructureFeaturesNV, 1_000_570_000, ExtendsPhysicalDeviceFeatures2, ExtendsDeviceCreateInfo;
    partitioned_acceleration_structure: vk::Bool32,
);
raw_struct!(
    /// `VkPhysicalDevicePartitionedAccelerationStructurePropertiesNV`.
    PhysicalDevicePartitionedAccelerationStructurePropertiesNV, 1_000_570_001, ExtendsPhysicalDeviceProperties2;
    max_partition_count: u32,
);
raw_struct!(
    /// `VkPhysicalDeviceRayTracingLinearSweptSpheresFeaturesNV`.
    PhysicalDeviceRayTracingLinearSweptSpheresFeaturesNV, 1_000_429_008, ExtendsPhysicalDeviceFeatures2, ExtendsDeviceCreateInfo;
    spheres: vk::Bool32,
    linear_swept_spheres: vk::Bool32,
);
raw_struct!(
    /// `VkPhysicalDeviceRayTracingInvocationReorderFeaturesEXT`.
    PhysicalDeviceRayTracingInvocationReorderFeaturesEXT, 1_000_581_000, ExtendsPhysicalDeviceFeatures2, ExtendsDeviceCreateInfo;
    ray_tracing_invocation_reorder: vk::Bool32,
);
raw_struct!(
    /// `VkPhysicalDeviceRayTracingInvocationReorderPropertiesEXT`; the hint is a
    /// `VkRayTracingInvocationReorderModeEXT` (same values as ash's `...ModeNV`).
    PhysicalDeviceRayTracingInvocationReorderPropertiesEXT, 1_000_581_001, ExtendsPhysicalDeviceProperties2;
    ray_tracing_invocation_reorder_reordering_hint: vk::RayTracingInvocationReorderModeNV,
    max_shader_binding_table_record_index: u32,
);
raw_struct!(
    /// `VkPhysicalDeviceOpacityMicromapFeaturesKHR`.
    PhysicalDeviceOpacityMicromapFeaturesKHR, 1_000_623_000, ExtendsPhysicalDeviceFeatures2, ExtendsDeviceCreateInfo;
    micromap: vk::Bool32,
);
raw_struct!(
    /// `VkPhysicalDeviceOpacityMicromapPropertiesKHR`.
    PhysicalDeviceOpacityMicromapPropertiesKHR, 1_000_623_001, ExtendsPhysicalDeviceProperties2;
    max_opacity2_state_subdivision_level: u32,
    max_opacity4_state_subdivision_level: u32,
    max_opacity_lossy4_state_subdivision_level: u32,
    max_micromap_triangles: u64,
);
raw_struct!(
    /// `VkPhysicalDevicePipelineOpacityMicromapFeaturesARM`.
    PhysicalDevicePipelineOpacityMicromapFeaturesARM, 1_000_596_000, ExtendsPhysicalDeviceFeatures2, ExtendsDeviceCreateInfo;
    pipeline_opacity_micromap: vk::Bool32,
);
raw_struct!(
    /// `VkPhysicalDeviceDenseGeometryFormatFeaturesAMDX` (provisional).
    PhysicalDeviceDenseGeometryFormatFeaturesAMDX, 1_000_478_000, ExtendsPhysicalDeviceFeatures2, ExtendsDeviceCreateInfo;
    dense_geometry_format: vk::Bool32,
);

/// `VkRayTracingInvocationReorderModeEXT` (alias `...NV`) as the registry spells it.
pub fn reorder_mode_name(m: vk::RayTracingInvocationReorderModeNV) -> String {
    match m {
        vk::RayTracingInvocationReorderModeNV::NONE => {
            "VK_RAY_TRACING_INVOCATION_REORDER_MODE_NONE_EXT".into()
        }
        vk::RayTracingInvocationReorderModeNV::REORDER => {
            "VK_RAY_TRACING_INVOCATION_REORDER_MODE_REORDER_EXT".into()
        }
        other => format!("{}", other.as_raw()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::mem::{offset_of, size_of};

    /// Sizes and offsets a C compiler gives the `vulkan_core.h` definitions on 64-bit targets.
    #[test]
    fn layouts_match_the_c_headers() {
        assert_eq!(size_of::<PhysicalDeviceClusterAccelerationStructureFeaturesNV>(), 24);
        assert_eq!(size_of::<PhysicalDeviceClusterAccelerationStructurePropertiesNV>(), 48);
        assert_eq!(
            offset_of!(
                PhysicalDeviceClusterAccelerationStructurePropertiesNV,
                max_cluster_geometry_index
            ),
            44
        );
        assert_eq!(size_of::<PhysicalDevicePartitionedAccelerationStructurePropertiesNV>(), 24);
        assert_eq!(size_of::<PhysicalDeviceRayTracingLinearSweptSpheresFeaturesNV>(), 24);
        assert_eq!(size_of::<PhysicalDeviceRayTracingInvocationReorderPropertiesEXT>(), 24);
        assert_eq!(
            offset_of!(
                PhysicalDeviceRayTracingInvocationReorderPropertiesEXT,
                max_shader_binding_table_record_index
            ),
            20
        );
        // The u64 after three u32s is aligned to 8: offset 32, size 40.
        assert_eq!(
            offset_of!(PhysicalDeviceOpacityMicromapPropertiesKHR, max_micromap_triangles),
            32
        );
        assert_eq!(size_of::<PhysicalDeviceOpacityMicromapPropertiesKHR>(), 40);
    }

    #[test]
    fn defaults_carry_their_structure_type() {
        let f = PhysicalDeviceRayTracingInvocationReorderFeaturesEXT::default();
        assert_eq!(f.s_type.as_raw(), 1_000_581_000);
        assert!(f.p_next.is_null());
        assert_eq!(f.ray_tracing_invocation_reorder, vk::FALSE);
        assert_eq!(
            PhysicalDeviceOpacityMicromapPropertiesKHR::default().s_type.as_raw(),
            1_000_623_001
        );
    }
}
