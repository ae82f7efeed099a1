//! The device features a user's SPIR-V modules declare they need ([`ShaderFeatures`]), filled
//! from their `OpCapability`s by `harness::capabilities`: each bit's place in the feature
//! structs ([`rows`]), what a device lacks of them ([`ShaderFeatures::missing_on`]) and the bits
//! `vk::device` enables ([`ShaderFeatures::enable`]).
//!
//! VUID-VkShaderModuleCreateInfo-pCode-08740 (Vulkan 1.4.360): "If pCode declares any of the
//! capabilities listed in the SPIR-V Environment appendix, one of the corresponding requirements
//! must be satisfied" — the appendix's table is vk.xml's `<spirvcapability>` entries; each row
//! here is one of them, its feature bit named as there.
use super::features::DeviceInfo;
use ash::{khr, vk};
use std::ffi::CStr;

/// Shader feature bits asked for by the modules; each is enabled only when asked for.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ShaderFeatures {
    pub float16: bool,
    pub int16: bool,
    pub int8: bool,
    pub float64: bool,
    pub int64_atomics: bool,
    pub storage_buffer16: bool,
    pub uniform_and_storage_buffer16: bool,
    pub storage_push_constant16: bool,
    pub storage_input_output16: bool,
    pub storage_buffer8: bool,
    pub uniform_and_storage_buffer8: bool,
    pub storage_push_constant8: bool,
    pub image_gather_extended: bool,
    pub image_cube_array: bool,
    pub min_lod: bool,
    pub read_without_format: bool,
    pub write_without_format: bool,
    pub uniform_buffer_dynamic: bool,
    pub sampled_image_dynamic: bool,
    pub storage_buffer_dynamic: bool,
    pub storage_image_dynamic: bool,
    pub runtime_descriptor_array: bool,
    pub uniform_buffer_non_uniform: bool,
    pub sampled_image_non_uniform: bool,
    pub storage_buffer_non_uniform: bool,
    pub storage_image_non_uniform: bool,
    pub variable_pointers: bool,
    pub variable_pointers_storage_buffer: bool,
    pub draw_parameters: bool,
    pub vulkan_memory_model: bool,
    pub vulkan_memory_model_device_scope: bool,
    pub primitive_culling: bool,
    /// VK_KHR_ray_tracing_position_fetch's `rayTracingPositionFetch`.
    pub position_fetch: bool,
    /// VK_KHR_ray_tracing_maintenance1's `rayTracingMaintenance1` (`RayCullMaskKHR`).
    pub cull_mask: bool,
    /// The subgroup operations (`GroupNonUniform*`) the modules use; the appendix asks them of
    /// `VkPhysicalDeviceVulkan11Properties::subgroupSupportedOperations`.
    pub subgroup: vk::SubgroupFeatureFlags,
    /// The stages of the modules that use subgroup operations: VUID-RuntimeSpirv-None-06343
    /// (Vulkan 1.4.360) asks them of `subgroupSupportedStages`.
    pub subgroup_stages: vk::ShaderStageFlags,
    /// A SPIR-V extension the appendix enables with Vulkan 1.3 (`SPV_KHR_non_semantic_info`, …).
    pub vulkan13: bool,
}

/// One bit of feature struct `T`.
pub type Bit<T> = for<'a> fn(&'a mut T) -> &'a mut vk::Bool32;

/// The feature struct a bit lives in, and the bit.
#[derive(Clone, Copy)]
pub enum Slot {
    Core(Bit<vk::PhysicalDeviceFeatures>),
    V11(Bit<vk::PhysicalDeviceVulkan11Features<'static>>),
    V12(Bit<vk::PhysicalDeviceVulkan12Features<'static>>),
    RtPipeline(Bit<vk::PhysicalDeviceRayTracingPipelineFeaturesKHR<'static>>),
    PositionFetch,
    Maintenance1,
}

/// One `<spirvcapability>` requirement: whether it is asked for, its feature's name, where it
/// lives, and whether Vulkan 1.3 satisfies it without the bit (`StorageImage*WithoutFormat`).
#[derive(Clone, Copy)]
pub struct Row {
    pub asked: fn(&ShaderFeatures) -> bool,
    pub name: &'static str,
    pub slot: Slot,
    pub core_in_1_3: bool,
}

const fn row(asked: fn(&ShaderFeatures) -> bool, name: &'static str, slot: Slot) -> Row {
    Row { asked, name, slot, core_in_1_3: false }
}

/// Every feature bit a module's capability can ask for.
pub fn rows() -> Vec<Row> {
    use Slot::{Core, V11, V12};
    let mut r = vec![
        row(|s| s.float16, "shaderFloat16", V12(|f| &mut f.shader_float16)),
        row(|s| s.int16, "shaderInt16", Core(|f| &mut f.shader_int16)),
        row(|s| s.int8, "shaderInt8", V12(|f| &mut f.shader_int8)),
        row(|s| s.float64, "shaderFloat64", Core(|f| &mut f.shader_float64)),
        row(
            |s| s.int64_atomics,
            "shaderBufferInt64Atomics",
            V12(|f| &mut f.shader_buffer_int64_atomics),
        ),
        row(
            |s| s.storage_buffer16,
            "storageBuffer16BitAccess",
            V11(|f| &mut f.storage_buffer16_bit_access),
        ),
        row(
            |s| s.uniform_and_storage_buffer16,
            "uniformAndStorageBuffer16BitAccess",
            V11(|f| &mut f.uniform_and_storage_buffer16_bit_access),
        ),
        row(
            |s| s.storage_push_constant16,
            "storagePushConstant16",
            V11(|f| &mut f.storage_push_constant16),
        ),
        row(
            |s| s.storage_input_output16,
            "storageInputOutput16",
            V11(|f| &mut f.storage_input_output16),
        ),
        row(
            |s| s.storage_buffer8,
            "storageBuffer8BitAccess",
            V12(|f| &mut f.storage_buffer8_bit_access),
        ),
        row(
            |s| s.uniform_and_storage_buffer8,
            "uniformAndStorageBuffer8BitAccess",
            V12(|f| &mut f.uniform_and_storage_buffer8_bit_access),
        ),
        row(
            |s| s.storage_push_constant8,
            "storagePushConstant8",
            V12(|f| &mut f.storage_push_constant8),
        ),
        row(
            |s| s.image_gather_extended,
            "shaderImageGatherExtended",
            Core(|f| &mut f.shader_image_gather_extended),
        ),
        row(|s| s.image_cube_array, "imageCubeArray", Core(|f| &mut f.image_cube_array)),
        row(|s| s.min_lod, "shaderResourceMinLod", Core(|f| &mut f.shader_resource_min_lod)),
        Row {
            core_in_1_3: true,
            ..row(
                |s| s.read_without_format,
                "shaderStorageImageReadWithoutFormat",
                Core(|f| &mut f.shader_storage_image_read_without_format),
            )
        },
        Row {
            core_in_1_3: true,
            ..row(
                |s| s.write_without_format,
                "shaderStorageImageWriteWithoutFormat",
                Core(|f| &mut f.shader_storage_image_write_without_format),
            )
        },
    ];
    r.extend(indexing_rows());
    r.extend(ray_rows());
    r
}

/// The descriptor-indexing capabilities' bits (`descriptor_indexing` also enables what the
/// device has of them; these are checked).
fn indexing_rows() -> Vec<Row> {
    use Slot::{Core, V11, V12};
    vec![
        row(
            |s| s.uniform_buffer_dynamic,
            "shaderUniformBufferArrayDynamicIndexing",
            Core(|f| &mut f.shader_uniform_buffer_array_dynamic_indexing),
        ),
        row(
            |s| s.sampled_image_dynamic,
            "shaderSampledImageArrayDynamicIndexing",
            Core(|f| &mut f.shader_sampled_image_array_dynamic_indexing),
        ),
        row(
            |s| s.storage_buffer_dynamic,
            "shaderStorageBufferArrayDynamicIndexing",
            Core(|f| &mut f.shader_storage_buffer_array_dynamic_indexing),
        ),
        row(
            |s| s.storage_image_dynamic,
            "shaderStorageImageArrayDynamicIndexing",
            Core(|f| &mut f.shader_storage_image_array_dynamic_indexing),
        ),
        row(
            |s| s.runtime_descriptor_array,
            "runtimeDescriptorArray",
            V12(|f| &mut f.runtime_descriptor_array),
        ),
        row(
            |s| s.uniform_buffer_non_uniform,
            "shaderUniformBufferArrayNonUniformIndexing",
            V12(|f| &mut f.shader_uniform_buffer_array_non_uniform_indexing),
        ),
        row(
            |s| s.sampled_image_non_uniform,
            "shaderSampledImageArrayNonUniformIndexing",
            V12(|f| &mut f.shader_sampled_image_array_non_uniform_indexing),
        ),
        row(
            |s| s.storage_buffer_non_uniform,
            "shaderStorageBufferArrayNonUniformIndexing",
            V12(|f| &mut f.shader_storage_buffer_array_non_uniform_indexing),
        ),
        row(
            |s| s.storage_image_non_uniform,
            "shaderStorageImageArrayNonUniformIndexing",
            V12(|f| &mut f.shader_storage_image_array_non_uniform_indexing),
        ),
        row(|s| s.variable_pointers, "variablePointers", V11(|f| &mut f.variable_pointers)),
        row(
            |s| s.variable_pointers_storage_buffer,
            "variablePointersStorageBuffer",
            V11(|f| &mut f.variable_pointers_storage_buffer),
        ),
        row(|s| s.draw_parameters, "shaderDrawParameters", V11(|f| &mut f.shader_draw_parameters)),
        row(|s| s.vulkan_memory_model, "vulkanMemoryModel", V12(|f| &mut f.vulkan_memory_model)),
        row(
            |s| s.vulkan_memory_model_device_scope,
            "vulkanMemoryModelDeviceScope",
            V12(|f| &mut f.vulkan_memory_model_device_scope),
        ),
    ]
}

/// The ray tracing capabilities' bits beyond the pipeline and ray queries themselves.
fn ray_rows() -> Vec<Row> {
    vec![
        row(
            |s| s.primitive_culling,
            "rayTraversalPrimitiveCulling",
            Slot::RtPipeline(|f| &mut f.ray_traversal_primitive_culling),
        ),
        row(|s| s.position_fetch, "rayTracingPositionFetch", Slot::PositionFetch),
        row(|s| s.cull_mask, "rayTracingMaintenance1", Slot::Maintenance1),
    ]
}

/// The feature structs a device is created with, as `vk::device` holds them.
pub struct Targets<'a> {
    pub core: &'a mut vk::PhysicalDeviceFeatures,
    pub v11: &'a mut vk::PhysicalDeviceVulkan11Features<'static>,
    pub v12: &'a mut vk::PhysicalDeviceVulkan12Features<'static>,
    pub rt: &'a mut vk::PhysicalDeviceRayTracingPipelineFeaturesKHR<'static>,
    pub pf: &'a mut vk::PhysicalDeviceRayTracingPositionFetchFeaturesKHR<'static>,
    pub m1: &'a mut vk::PhysicalDeviceRayTracingMaintenance1FeaturesKHR<'static>,
}

impl Targets<'_> {
    /// The bit of `slot` in these structs.
    pub fn bit(&mut self, slot: Slot) -> &mut vk::Bool32 {
        match slot {
            Slot::Core(f) => f(self.core),
            Slot::V11(f) => f(self.v11),
            Slot::V12(f) => f(self.v12),
            Slot::RtPipeline(f) => f(self.rt),
            Slot::PositionFetch => &mut self.pf.ray_tracing_position_fetch,
            Slot::Maintenance1 => &mut self.m1.ray_tracing_maintenance1,
        }
    }
}

impl ShaderFeatures {
    /// Whether any bit of VkPhysicalDeviceVulkan11Features is asked for.
    pub fn v11(&self) -> bool {
        rows().iter().any(|r| (r.asked)(self) && matches!(r.slot, Slot::V11(_)))
    }

    /// The device extensions these need (each with its feature struct chained).
    pub fn extensions(&self) -> Vec<&'static CStr> {
        let mut e = Vec::new();
        if self.position_fetch {
            e.push(khr::ray_tracing_position_fetch::NAME);
        }
        if self.cull_mask {
            e.push(khr::ray_tracing_maintenance1::NAME);
        }
        e
    }

    /// Whether `info` has the bit of `slot` (an extension's only where the driver lists it).
    fn has(info: &DeviceInfo, slot: Slot) -> bool {
        let f = &info.features;
        let (mut core, mut v11, mut v12) =
            (f.core, f.v11.unwrap_or_default(), f.v12.unwrap_or_default());
        let mut rt = f.rt_pipeline.unwrap_or_default();
        let mut pf = f
            .position_fetch
            .filter(|_| info.has_extension(khr::ray_tracing_position_fetch::NAME))
            .unwrap_or_default();
        let mut m1 = f
            .rt_maintenance1
            .filter(|_| info.has_extension(khr::ray_tracing_maintenance1::NAME))
            .unwrap_or_default();
        let mut t = Targets {
            core: &mut core,
            v11: &mut v11,
            v12: &mut v12,
            rt: &mut rt,
            pf: &mut pf,
            m1: &mut m1,
        };
        *t.bit(slot) == vk::TRUE
    }

    /// What `info` lacks of these, each named as the appendix names it.
    pub fn missing_on(&self, info: &DeviceInfo) -> Vec<String> {
        let v13 = info.properties.core.api_version >= vk::API_VERSION_1_3;
        let mut m: Vec<String> = rows()
            .iter()
            .filter(|r| (r.asked)(self) && !Self::has(info, r.slot) && !(r.core_in_1_3 && v13))
            .map(|r| r.name.to_string())
            .collect();
        let ops = info
            .properties
            .v11
            .map_or(vk::SubgroupFeatureFlags::empty(), |p| p.subgroup_supported_operations);
        if !ops.contains(self.subgroup) {
            m.push(format!("subgroupSupportedOperations {:?}", self.subgroup & !ops));
        }
        let stages = info
            .properties
            .v11
            .map_or(vk::ShaderStageFlags::empty(), |p| p.subgroup_supported_stages);
        if !stages.contains(self.subgroup_stages) {
            m.push(format!(
                "subgroupSupportedStages {:?} (subgroup operations in that stage)",
                self.subgroup_stages & !stages
            ));
        }
        if self.vulkan13 && !v13 {
            m.push("Vulkan 1.3 (a SPIR-V extension core in 1.3)".into());
        }
        m
    }

    /// Sets each asked bit the device has in `t` (a `core_in_1_3` bit it lacks stays off: the
    /// version satisfies the capability).
    pub fn enable(&self, info: &DeviceInfo, mut t: Targets) {
        for r in rows().iter().filter(|r| (r.asked)(self) && Self::has(info, r.slot)) {
            *t.bit(r.slot) = vk::TRUE;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A device with the given core 1.0 and 1.2 features, and API version `api`.
    fn device(
        core: vk::PhysicalDeviceFeatures,
        v12: vk::PhysicalDeviceVulkan12Features<'static>,
        api: u32,
    ) -> DeviceInfo {
        let mut info = crate::vk::features::blank_device();
        info.features.core = core;
        info.features.v12 = Some(v12);
        info.properties.core.api_version = api;
        info
    }

    /// Each asked bit the device lacks is named; the twin, a device with it, lacks nothing and
    /// gets the bit enabled. Formatless storage-image reads are satisfied by Vulkan 1.3.
    #[test]
    fn missing_bits_are_named_and_present_ones_enabled() {
        let asked = ShaderFeatures { float16: true, int16: true, ..Default::default() };
        let bare = device(Default::default(), Default::default(), vk::API_VERSION_1_2);
        assert_eq!(asked.missing_on(&bare), ["shaderFloat16", "shaderInt16"]);
        let core = vk::PhysicalDeviceFeatures::default().shader_int16(true);
        let v12 = vk::PhysicalDeviceVulkan12Features::default().shader_float16(true);
        let full = device(core, v12, vk::API_VERSION_1_2);
        assert!(asked.missing_on(&full).is_empty());
        let (mut c, mut v11, mut v12) = Default::default();
        let (mut rt, mut pf, mut m1) = Default::default();
        let t = Targets {
            core: &mut c,
            v11: &mut v11,
            v12: &mut v12,
            rt: &mut rt,
            pf: &mut pf,
            m1: &mut m1,
        };
        asked.enable(&full, t);
        assert_eq!((c.shader_int16, v12.shader_float16), (vk::TRUE, vk::TRUE));
        assert_eq!(c.shader_float64, vk::FALSE, "only what was asked for");
        let read = ShaderFeatures { read_without_format: true, ..Default::default() };
        assert_eq!(read.missing_on(&bare), ["shaderStorageImageReadWithoutFormat"]);
        let v13 = device(Default::default(), Default::default(), vk::API_VERSION_1_3);
        assert!(read.missing_on(&v13).is_empty());
        let rq =
            ShaderFeatures { subgroup: vk::SubgroupFeatureFlags::BALLOT, ..Default::default() };
        assert_eq!(rq.missing_on(&full).len(), 1, "no subgroup operations reported");
        // Subgroup operations in a closest-hit: the stage must be in subgroupSupportedStages.
        let chit = vk::ShaderStageFlags::CLOSEST_HIT_KHR;
        let ballot = vk::SubgroupFeatureFlags::BALLOT;
        let asked =
            ShaderFeatures { subgroup: ballot, subgroup_stages: chit, ..Default::default() };
        let mut dev = device(Default::default(), Default::default(), vk::API_VERSION_1_2);
        let v11 = vk::PhysicalDeviceVulkan11Properties::default()
            .subgroup_supported_operations(ballot)
            .subgroup_supported_stages(vk::ShaderStageFlags::COMPUTE);
        dev.properties.v11 = Some(v11);
        let m = asked.missing_on(&dev);
        assert_eq!(m.len(), 1, "{m:?}");
        assert!(m[0].starts_with("subgroupSupportedStages CLOSEST_HIT_KHR"), "{m:?}");
        // The twin: the stage supported, nothing missing.
        dev.properties.v11 =
            Some(v11.subgroup_supported_stages(chit | vk::ShaderStageFlags::COMPUTE));
        assert!(asked.missing_on(&dev).is_empty());
    }
}
