//! Raw bindings for VK_KHR_pipeline_binary, which ash 0.38 (Vulkan headers 1.3.281) predates,
//! laid out member for member as in Vulkan 1.4.363's `vulkan_core.h` (extension number 484): the
//! feature and property structs (chained only when the driver lists the extension; `caps` and the
//! report list them) and `VkDevicePipelineBinaryInternalCacheControlKHR`, with which a worker that
//! compiles afresh turns the driver's own pipeline cache off where
//! `pipelineBinaryInternalCacheControl` allows (VUID-VkDevicePipelineBinaryInternalCacheControlKHR-disableInternalCache-09602).
//!
//! Pipelines made from stored binaries were measured and not kept (reports/nvidia-h200/perf): on
//! NVIDIA 580.159.04 the driver refused 436 of 528 pipelines' own captured binaries
//! (`VK_PIPELINE_COMPILE_REQUIRED`, or `VK_ERROR_INITIALIZATION_FAILED` with the shader modules
//! given too), every ray tracing pipeline but four, so a warm run was no faster.
use ash::vk;
use std::ffi::{c_void, CStr};

pub const NAME: &CStr = c"VK_KHR_pipeline_binary";

/// A `#[repr(C)]` struct that starts with sType/pNext, and a `Default` that sets its sType and
/// zeroes the rest.
macro_rules! raw_struct {
    ($(#[$doc:meta])* $name:ident, $stype:literal; $($field:ident: $ty:ty),* $(,)?) => {
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
    };
}

raw_struct!(
    /// `VkPhysicalDevicePipelineBinaryFeaturesKHR`.
    PhysicalDevicePipelineBinaryFeaturesKHR, 1_000_483_000;
    pipeline_binaries: vk::Bool32,
);
raw_struct!(
    /// `VkPhysicalDevicePipelineBinaryPropertiesKHR`.
    PhysicalDevicePipelineBinaryPropertiesKHR, 1_000_483_004;
    pipeline_binary_internal_cache: vk::Bool32,
    pipeline_binary_internal_cache_control: vk::Bool32,
    pipeline_binary_prefers_internal_cache: vk::Bool32,
    pipeline_binary_precompiled_internal_cache: vk::Bool32,
    pipeline_binary_compressed_data: vk::Bool32,
);
raw_struct!(
    /// `VkDevicePipelineBinaryInternalCacheControlKHR` (extends `VkDeviceCreateInfo`).
    DevicePipelineBinaryInternalCacheControlKHR, 1_000_483_008;
    disable_internal_cache: vk::Bool32,
);
// SAFETY: each begins with sType/pNext and extends exactly what the registry says it extends.
unsafe impl vk::ExtendsPhysicalDeviceFeatures2 for PhysicalDevicePipelineBinaryFeaturesKHR {}
unsafe impl vk::ExtendsDeviceCreateInfo for PhysicalDevicePipelineBinaryFeaturesKHR {}
unsafe impl vk::ExtendsPhysicalDeviceProperties2 for PhysicalDevicePipelineBinaryPropertiesKHR {}
unsafe impl vk::ExtendsDeviceCreateInfo for DevicePipelineBinaryInternalCacheControlKHR {}

impl PhysicalDevicePipelineBinaryPropertiesKHR {
    /// The members by their Vulkan names (what the report and caps record).
    pub fn by_name(&self) -> std::collections::BTreeMap<String, bool> {
        let on = |b: vk::Bool32| b == vk::TRUE;
        [
            ("pipelineBinaryInternalCache", on(self.pipeline_binary_internal_cache)),
            ("pipelineBinaryInternalCacheControl", on(self.pipeline_binary_internal_cache_control)),
            ("pipelineBinaryPrefersInternalCache", on(self.pipeline_binary_prefers_internal_cache)),
            (
                "pipelineBinaryPrecompiledInternalCache",
                on(self.pipeline_binary_precompiled_internal_cache),
            ),
            ("pipelineBinaryCompressedData", on(self.pipeline_binary_compressed_data)),
        ]
        .into_iter()
        .map(|(k, v)| (k.to_string(), v))
        .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::mem::{offset_of, size_of};

    /// Sizes and offsets a C compiler gives vulkan_core.h 1.4.363's definitions on 64-bit targets.
    #[test]
    fn layouts_match_the_c_header() {
        assert_eq!(size_of::<PhysicalDevicePipelineBinaryFeaturesKHR>(), 24);
        assert_eq!(size_of::<PhysicalDevicePipelineBinaryPropertiesKHR>(), 40);
        assert_eq!(
            offset_of!(PhysicalDevicePipelineBinaryPropertiesKHR, pipeline_binary_compressed_data),
            32
        );
        assert_eq!(size_of::<DevicePipelineBinaryInternalCacheControlKHR>(), 24);
        assert_eq!(
            offset_of!(DevicePipelineBinaryInternalCacheControlKHR, disable_internal_cache),
            16
        );
    }

    #[test]
    fn defaults_carry_their_structure_type_and_names_follow_the_members() {
        assert_eq!(
            PhysicalDevicePipelineBinaryFeaturesKHR::default().s_type.as_raw(),
            1_000_483_000
        );
        assert_eq!(
            DevicePipelineBinaryInternalCacheControlKHR::default().s_type.as_raw(),
            1_000_483_008
        );
        let p = PhysicalDevicePipelineBinaryPropertiesKHR {
            pipeline_binary_internal_cache_control: vk::TRUE,
            ..Default::default()
        };
        let m = p.by_name();
        assert_eq!(m.len(), 5);
        assert!(m["pipelineBinaryInternalCacheControl"]);
        assert!(!m["pipelineBinaryInternalCache"], "another member stays false");
    }
}
