//! [`DeviceInfo`]: the one struct holding everything rtprobe knows about a physical device —
//! extensions, features and properties — queried in one place ([`DeviceInfo::query`]), which is
//! also the only place that builds the `pNext` chains for `vkGetPhysicalDevice{Features,Properties}2`.
//!
//! Each extension-provided struct is an `Option`: `Some` exactly when the driver lists the
//! extension (or the core version that promoted it), `None` otherwise. The core Vulkan 1.1/1.2/1.3
//! structs are `Some` when the device's API version has them.
use super::error::{VkError, VkResultExt};
use super::instance::Instance;
use super::{binary, heap, rt_ext};
use ash::{ext, khr, nv, vk};
use std::collections::BTreeMap;
use std::ffi::CStr;

/// An extension rtprobe looks for, and the group the caps text lists it under.
#[derive(Clone, Copy, Debug)]
pub struct Tracked {
    pub name: &'static CStr,
    pub group: &'static str,
}

const fn t(group: &'static str, name: &'static CStr) -> Tracked {
    Tracked { name, group }
}

/// Extensions rtprobe looks for (the only place their names are listed; names come from ash, or
/// from [`heap`] / [`rt_ext`] where ash 0.38 lacks them): every ray tracing extension the Vulkan
/// headers define, present or not, then what rtprobe's descriptor models and checks rely on.
pub const TRACKED_EXTENSIONS: &[Tracked] = &[
    t("ray tracing pipeline", khr::ray_tracing_pipeline::NAME),
    t("ray tracing pipeline", khr::ray_tracing_maintenance1::NAME),
    t("ray tracing pipeline", khr::pipeline_library::NAME),
    t("ray tracing pipeline", ext::pipeline_library_group_handles::NAME),
    t("ray tracing pipeline", binary::NAME),
    t("ray tracing pipeline", nv::ray_tracing_validation::NAME),
    t("ray tracing pipeline", nv::ray_tracing::NAME),
    t("invocation reorder", nv::ray_tracing_invocation_reorder::NAME),
    t("invocation reorder", rt_ext::EXT_RAY_TRACING_INVOCATION_REORDER),
    t("acceleration structures", khr::acceleration_structure::NAME),
    t("acceleration structures", khr::deferred_host_operations::NAME),
    t("acceleration structures", rt_ext::NV_CLUSTER_ACCELERATION_STRUCTURE),
    t("acceleration structures", rt_ext::NV_PARTITIONED_ACCELERATION_STRUCTURE),
    t("acceleration structures", rt_ext::AMDX_DENSE_GEOMETRY_FORMAT),
    t("geometry", nv::ray_tracing_motion_blur::NAME),
    t("geometry", rt_ext::NV_RAY_TRACING_LINEAR_SWEPT_SPHERES),
    t("geometry", khr::ray_tracing_position_fetch::NAME),
    t("micromaps", ext::opacity_micromap::NAME),
    t("micromaps", rt_ext::KHR_OPACITY_MICROMAP),
    t("micromaps", rt_ext::ARM_PIPELINE_OPACITY_MICROMAP),
    t("micromaps", nv::displacement_micromap::NAME),
    t("ray query", khr::ray_query::NAME),
    t("shaders", khr::spirv_1_4::NAME),
    t("shaders", khr::shader_float_controls::NAME),
    t("descriptors and memory", khr::buffer_device_address::NAME),
    t("descriptors and memory", ext::descriptor_indexing::NAME),
    t("descriptors and memory", ext::descriptor_buffer::NAME),
    t("descriptors and memory", heap::NAME),
    t("descriptors and memory", heap::UNTYPED_POINTERS_NAME),
    t("robustness and faults", ext::robustness2::NAME),
    t("robustness and faults", ext::device_fault::NAME),
    t("maintenance", khr::maintenance4::NAME),
    t("maintenance", khr::maintenance5::NAME),
    t("maintenance", khr::maintenance6::NAME),
    t("maintenance", khr::synchronization2::NAME),
];

/// Features of the device. Extension structs are `Some` only when the extension is present.
#[derive(Clone, Default)]
pub struct Features {
    pub core: vk::PhysicalDeviceFeatures,
    pub v11: Option<vk::PhysicalDeviceVulkan11Features<'static>>,
    /// Descriptor indexing, buffer device address, timeline semaphores, ...
    pub v12: Option<vk::PhysicalDeviceVulkan12Features<'static>>,
    pub v13: Option<vk::PhysicalDeviceVulkan13Features<'static>>,
    pub rt_pipeline: Option<vk::PhysicalDeviceRayTracingPipelineFeaturesKHR<'static>>,
    pub accel: Option<vk::PhysicalDeviceAccelerationStructureFeaturesKHR<'static>>,
    pub ray_query: Option<vk::PhysicalDeviceRayQueryFeaturesKHR<'static>>,
    pub rt_maintenance1: Option<vk::PhysicalDeviceRayTracingMaintenance1FeaturesKHR<'static>>,
    pub position_fetch: Option<vk::PhysicalDeviceRayTracingPositionFetchFeaturesKHR<'static>>,
    pub descriptor_buffer: Option<vk::PhysicalDeviceDescriptorBufferFeaturesEXT<'static>>,
    pub descriptor_heap: Option<heap::PhysicalDeviceDescriptorHeapFeaturesEXT>,
    pub untyped_pointers: Option<heap::PhysicalDeviceShaderUntypedPointersFeaturesKHR>,
    pub robustness2: Option<vk::PhysicalDeviceRobustness2FeaturesEXT<'static>>,
    pub fault: Option<vk::PhysicalDeviceFaultFeaturesEXT<'static>>,
    pub maintenance5: Option<vk::PhysicalDeviceMaintenance5FeaturesKHR<'static>>,
    pub maintenance6: Option<vk::PhysicalDeviceMaintenance6FeaturesKHR<'static>>,
    pub pipeline_library_group_handles:
        Option<vk::PhysicalDevicePipelineLibraryGroupHandlesFeaturesEXT<'static>>,
    pub pipeline_binary: Option<binary::PhysicalDevicePipelineBinaryFeaturesKHR>,
    pub rt_validation: Option<vk::PhysicalDeviceRayTracingValidationFeaturesNV<'static>>,
    pub invocation_reorder_nv:
        Option<vk::PhysicalDeviceRayTracingInvocationReorderFeaturesNV<'static>>,
    pub invocation_reorder_ext:
        Option<rt_ext::PhysicalDeviceRayTracingInvocationReorderFeaturesEXT>,
    pub cluster_accel: Option<rt_ext::PhysicalDeviceClusterAccelerationStructureFeaturesNV>,
    pub partitioned_accel: Option<rt_ext::PhysicalDevicePartitionedAccelerationStructureFeaturesNV>,
    pub dense_geometry_format: Option<rt_ext::PhysicalDeviceDenseGeometryFormatFeaturesAMDX>,
    pub motion_blur: Option<vk::PhysicalDeviceRayTracingMotionBlurFeaturesNV<'static>>,
    pub linear_swept_spheres: Option<rt_ext::PhysicalDeviceRayTracingLinearSweptSpheresFeaturesNV>,
    pub opacity_micromap: Option<vk::PhysicalDeviceOpacityMicromapFeaturesEXT<'static>>,
    pub opacity_micromap_khr: Option<rt_ext::PhysicalDeviceOpacityMicromapFeaturesKHR>,
    pub pipeline_opacity_micromap: Option<rt_ext::PhysicalDevicePipelineOpacityMicromapFeaturesARM>,
    pub displacement_micromap: Option<vk::PhysicalDeviceDisplacementMicromapFeaturesNV<'static>>,
}

/// Properties and limits of the device, same `Option` rule as [`Features`].
#[derive(Clone, Default)]
pub struct Properties {
    pub core: vk::PhysicalDeviceProperties,
    pub v11: Option<vk::PhysicalDeviceVulkan11Properties<'static>>,
    /// Driver id/name/info, conformance version, descriptor indexing limits.
    pub v12: Option<vk::PhysicalDeviceVulkan12Properties<'static>>,
    pub v13: Option<vk::PhysicalDeviceVulkan13Properties<'static>>,
    pub rt_pipeline: Option<vk::PhysicalDeviceRayTracingPipelinePropertiesKHR<'static>>,
    pub accel: Option<vk::PhysicalDeviceAccelerationStructurePropertiesKHR<'static>>,
    pub descriptor_buffer: Option<vk::PhysicalDeviceDescriptorBufferPropertiesEXT<'static>>,
    pub descriptor_heap: Option<heap::PhysicalDeviceDescriptorHeapPropertiesEXT>,
    pub robustness2: Option<vk::PhysicalDeviceRobustness2PropertiesEXT<'static>>,
    pub pipeline_binary: Option<binary::PhysicalDevicePipelineBinaryPropertiesKHR>,
    /// VK_NV_ray_tracing (the legacy NV pipeline; it has no feature struct).
    pub rt_nv: Option<vk::PhysicalDeviceRayTracingPropertiesNV<'static>>,
    pub invocation_reorder_nv:
        Option<vk::PhysicalDeviceRayTracingInvocationReorderPropertiesNV<'static>>,
    pub invocation_reorder_ext:
        Option<rt_ext::PhysicalDeviceRayTracingInvocationReorderPropertiesEXT>,
    pub cluster_accel: Option<rt_ext::PhysicalDeviceClusterAccelerationStructurePropertiesNV>,
    pub partitioned_accel:
        Option<rt_ext::PhysicalDevicePartitionedAccelerationStructurePropertiesNV>,
    pub opacity_micromap: Option<vk::PhysicalDeviceOpacityMicromapPropertiesEXT<'static>>,
    pub opacity_micromap_khr: Option<rt_ext::PhysicalDeviceOpacityMicromapPropertiesKHR>,
    pub displacement_micromap: Option<vk::PhysicalDeviceDisplacementMicromapPropertiesNV<'static>>,
}

/// Everything rtprobe knows about one physical device.
#[derive(Clone)]
pub struct DeviceInfo {
    /// Index in the loader's enumeration order (what `--device N` selects).
    pub index: usize,
    pub raw: vk::PhysicalDevice,
    /// Extension name → spec version, for every extension the driver lists.
    pub extensions: BTreeMap<String, u32>,
    pub features: Features,
    pub properties: Properties,
    pub queue_families: Vec<vk::QueueFamilyProperties>,
    pub memory: vk::PhysicalDeviceMemoryProperties,
    /// Format features of [`PROBE_IMAGE_FORMAT`], the format of the probes' images.
    pub probe_image_format: vk::FormatProperties,
}

/// A device that lists nothing: no extension, feature, property, queue family or memory, for
/// tests that set the fields they hold to.
#[cfg(test)]
pub fn blank_device() -> DeviceInfo {
    DeviceInfo {
        index: 0,
        raw: vk::PhysicalDevice::null(),
        extensions: Default::default(),
        features: Default::default(),
        properties: Default::default(),
        queue_families: vec![],
        memory: Default::default(),
        probe_image_format: Default::default(),
    }
}

/// The format rtprobe's sampled and storage image probes use.
pub const PROBE_IMAGE_FORMAT: vk::Format = vk::Format::R32G32B32A32_SFLOAT;

fn null_next<T>(s: &mut Option<T>, f: impl Fn(&mut T)) {
    if let Some(x) = s.as_mut() {
        f(x)
    }
}

/// The device's extensions with their spec versions, less those `RTPROBE_HIDE_EXTENSIONS` hides.
fn extensions(
    inst: &ash::Instance,
    pd: vk::PhysicalDevice,
) -> Result<BTreeMap<String, u32>, VkError> {
    let extensions: BTreeMap<String, u32> =
        unsafe { inst.enumerate_device_extension_properties(pd) }
            .at("vkEnumerateDeviceExtensionProperties")?
            .iter()
            .filter_map(|e| {
                e.extension_name_as_c_str()
                    .ok()
                    .map(|n| (n.to_string_lossy().into_owned(), e.spec_version))
            })
            .collect();
    let mut extensions = extensions;
    // What-if switch: hide extensions (comma-separated names) as if the driver lacked them;
    // their feature structs are then never chained. Used to preview plans for older drivers.
    if let Ok(hide) = std::env::var("RTPROBE_HIDE_EXTENSIONS") {
        for name in hide.split(',').map(str::trim).filter(|n| !n.is_empty()) {
            if extensions.remove(name).is_some() {
                tracing::info!("RTPROBE_HIDE_EXTENSIONS: hiding {name}");
            }
        }
    }
    Ok(extensions)
}

impl Features {
    /// A default struct for each feature struct the device has (its Vulkan version, or its
    /// extension `has`), to be queried.
    fn present(has: &dyn Fn(&CStr) -> bool, v12: bool, v13: bool) -> Features {
        Features {
            v11: v12.then(Default::default),
            v12: v12.then(Default::default),
            v13: v13.then(Default::default),
            rt_pipeline: has(khr::ray_tracing_pipeline::NAME).then(Default::default),
            accel: has(khr::acceleration_structure::NAME).then(Default::default),
            ray_query: has(khr::ray_query::NAME).then(Default::default),
            rt_maintenance1: has(khr::ray_tracing_maintenance1::NAME).then(Default::default),
            position_fetch: has(khr::ray_tracing_position_fetch::NAME).then(Default::default),
            descriptor_buffer: has(ext::descriptor_buffer::NAME).then(Default::default),
            descriptor_heap: has(heap::NAME).then(Default::default),
            untyped_pointers: has(heap::UNTYPED_POINTERS_NAME).then(Default::default),
            robustness2: has(ext::robustness2::NAME).then(Default::default),
            fault: has(ext::device_fault::NAME).then(Default::default),
            maintenance5: has(khr::maintenance5::NAME).then(Default::default),
            maintenance6: has(khr::maintenance6::NAME).then(Default::default),
            pipeline_library_group_handles: has(ext::pipeline_library_group_handles::NAME)
                .then(Default::default),
            pipeline_binary: has(binary::NAME).then(Default::default),
            rt_validation: has(nv::ray_tracing_validation::NAME).then(Default::default),
            invocation_reorder_nv: has(nv::ray_tracing_invocation_reorder::NAME)
                .then(Default::default),
            invocation_reorder_ext: has(rt_ext::EXT_RAY_TRACING_INVOCATION_REORDER)
                .then(Default::default),
            cluster_accel: has(rt_ext::NV_CLUSTER_ACCELERATION_STRUCTURE).then(Default::default),
            partitioned_accel: has(rt_ext::NV_PARTITIONED_ACCELERATION_STRUCTURE)
                .then(Default::default),
            dense_geometry_format: has(rt_ext::AMDX_DENSE_GEOMETRY_FORMAT).then(Default::default),
            motion_blur: has(nv::ray_tracing_motion_blur::NAME).then(Default::default),
            linear_swept_spheres: has(rt_ext::NV_RAY_TRACING_LINEAR_SWEPT_SPHERES)
                .then(Default::default),
            opacity_micromap: has(ext::opacity_micromap::NAME).then(Default::default),
            opacity_micromap_khr: has(rt_ext::KHR_OPACITY_MICROMAP).then(Default::default),
            pipeline_opacity_micromap: has(rt_ext::ARM_PIPELINE_OPACITY_MICROMAP)
                .then(Default::default),
            displacement_micromap: has(nv::displacement_micromap::NAME).then(Default::default),
            core: Default::default(),
        }
    }
}

impl Properties {
    /// A default struct for each property struct the device has (as [`Features::present`]).
    fn present(
        f: &Features,
        has: &dyn Fn(&CStr) -> bool,
        v12: bool,
        v13: bool,
        core_props: vk::PhysicalDeviceProperties,
    ) -> Properties {
        Properties {
            v11: v12.then(Default::default),
            v12: v12.then(Default::default),
            v13: v13.then(Default::default),
            rt_pipeline: f.rt_pipeline.map(|_| Default::default()),
            accel: f.accel.map(|_| Default::default()),
            descriptor_buffer: f.descriptor_buffer.map(|_| Default::default()),
            descriptor_heap: f.descriptor_heap.map(|_| Default::default()),
            robustness2: f.robustness2.map(|_| Default::default()),
            pipeline_binary: f.pipeline_binary.map(|_| Default::default()),
            rt_nv: has(nv::ray_tracing::NAME).then(Default::default),
            invocation_reorder_nv: f.invocation_reorder_nv.map(|_| Default::default()),
            invocation_reorder_ext: f.invocation_reorder_ext.map(|_| Default::default()),
            cluster_accel: f.cluster_accel.map(|_| Default::default()),
            partitioned_accel: f.partitioned_accel.map(|_| Default::default()),
            opacity_micromap: f.opacity_micromap.map(|_| Default::default()),
            opacity_micromap_khr: f.opacity_micromap_khr.map(|_| Default::default()),
            displacement_micromap: f.displacement_micromap.map(|_| Default::default()),
            core: core_props,
        }
    }
}

/// Query every present struct of `f` and `p` through one `pNext` chain each.
fn query_chains(
    inst: &ash::Instance,
    pd: vk::PhysicalDevice,
    f: &mut Features,
    p: &mut Properties,
) {
    // The one place the pNext chains are built. Each Some(..) struct is chained, queried,
    // then its pNext is cleared so the stored copies hold no dangling pointers. Each list of
    // chained members is written once (`feature_structs!` / `property_structs!`).
    macro_rules! feature_structs { ($m:ident) => { $m!(f; v11, v12, v13, rt_pipeline, accel, ray_query, rt_maintenance1,
        position_fetch, descriptor_buffer, descriptor_heap, untyped_pointers, robustness2, fault, maintenance5, maintenance6,
        pipeline_library_group_handles, pipeline_binary, rt_validation, invocation_reorder_nv, invocation_reorder_ext, cluster_accel,
        partitioned_accel, dense_geometry_format, motion_blur, linear_swept_spheres, opacity_micromap,
        opacity_micromap_khr, pipeline_opacity_micromap, displacement_micromap) } }
    macro_rules! property_structs { ($m:ident) => { $m!(p; v11, v12, v13, rt_pipeline, accel, descriptor_buffer,
        descriptor_heap, robustness2, pipeline_binary, rt_nv, invocation_reorder_nv, invocation_reorder_ext, cluster_accel,
        partitioned_accel, opacity_micromap, opacity_micromap_khr, displacement_micromap) } }
    macro_rules! chain { ($top:ident, $v:ident; $($s:ident),*) => { $( if let Some(x) = $v.$s.as_mut() { $top = $top.push_next(x); } )* } }
    macro_rules! clear { ($v:ident; $($s:ident),*) => { $( null_next(&mut $v.$s, |x| x.p_next = std::ptr::null_mut()); )* } }
    {
        let mut f2 = vk::PhysicalDeviceFeatures2::default();
        macro_rules! chain_f { ($v:ident; $($s:ident),*) => { chain!(f2, $v; $($s),*) } }
        feature_structs!(chain_f);
        unsafe { inst.get_physical_device_features2(pd, &mut f2) };
        f.core = f2.features;
    }
    feature_structs!(clear);
    {
        let mut p2 = vk::PhysicalDeviceProperties2::default();
        macro_rules! chain_p { ($v:ident; $($s:ident),*) => { chain!(p2, $v; $($s),*) } }
        property_structs!(chain_p);
        unsafe { inst.get_physical_device_properties2(pd, &mut p2) };
        p.core = p2.properties;
    }
    property_structs!(clear);
}

impl DeviceInfo {
    pub fn query(
        instance: &Instance,
        index: usize,
        pd: vk::PhysicalDevice,
    ) -> Result<Self, VkError> {
        let inst = &instance.raw;
        let core_props = unsafe { inst.get_physical_device_properties(pd) };
        let api = core_props.api_version;
        let extensions = extensions(inst, pd)?;
        let has = |n: &CStr| extensions.contains_key(n.to_str().unwrap_or_default());
        let (v12, v13) = (api >= vk::API_VERSION_1_2, api >= vk::API_VERSION_1_3);
        let mut f = Features::present(&has, v12, v13);
        let mut p = Properties::present(&f, &has, v12, v13, core_props);
        query_chains(inst, pd, &mut f, &mut p);
        let queue_families = unsafe { inst.get_physical_device_queue_family_properties(pd) };
        let memory = unsafe { inst.get_physical_device_memory_properties(pd) };
        let probe_image_format =
            unsafe { inst.get_physical_device_format_properties(pd, PROBE_IMAGE_FORMAT) };
        Ok(Self {
            index,
            raw: pd,
            extensions,
            features: f,
            properties: p,
            queue_families,
            memory,
            probe_image_format,
        })
    }

    /// The device with its driver, as reports name it: `llvmpipe (…) (llvmpipe 25.0.7)`.
    pub fn label(&self) -> String {
        format!("{} ({} {})", self.name(), self.driver_name(), self.driver_version())
    }

    pub fn name(&self) -> String {
        self.properties
            .core
            .device_name_as_c_str()
            .map(|c| c.to_string_lossy().into_owned())
            .unwrap_or_default()
    }

    /// Whether subgroup ballot works in probe stage `stage`: `subgroupSupportedStages` has it and
    /// `subgroupSupportedOperations` has BALLOT (Vulkan 1.1 properties; the probe's lane evidence
    /// needs both, VUID-RuntimeSpirv-None-06343).
    pub fn subgroup_ballot(&self, stage: crate::model::Stage) -> bool {
        use crate::model::Stage;
        let flag = match stage {
            Stage::Raygen => vk::ShaderStageFlags::RAYGEN_KHR,
            Stage::ClosestHit => vk::ShaderStageFlags::CLOSEST_HIT_KHR,
            Stage::AnyHit => vk::ShaderStageFlags::ANY_HIT_KHR,
            Stage::Miss => vk::ShaderStageFlags::MISS_KHR,
            Stage::Intersection => vk::ShaderStageFlags::INTERSECTION_KHR,
            Stage::Callable => vk::ShaderStageFlags::CALLABLE_KHR,
            Stage::Fragment => vk::ShaderStageFlags::FRAGMENT,
            Stage::Compute => vk::ShaderStageFlags::COMPUTE,
        };
        self.properties.v11.is_some_and(|p| {
            p.subgroup_supported_stages.contains(flag)
                && p.subgroup_supported_operations.contains(vk::SubgroupFeatureFlags::BALLOT)
        })
    }

    /// Whether subgroup vote works in every ray tracing stage (`subgroupSupportedStages` and
    /// `subgroupSupportedOperations`): `run --shader`'s index check then records whether an
    /// index differed within its subgroup.
    pub fn subgroup_vote_in_ray_tracing(&self) -> bool {
        let rt = vk::ShaderStageFlags::RAYGEN_KHR
            | vk::ShaderStageFlags::CLOSEST_HIT_KHR
            | vk::ShaderStageFlags::ANY_HIT_KHR
            | vk::ShaderStageFlags::MISS_KHR
            | vk::ShaderStageFlags::INTERSECTION_KHR
            | vk::ShaderStageFlags::CALLABLE_KHR;
        self.properties.v11.is_some_and(|p| {
            p.subgroup_supported_stages.contains(rt)
                && p.subgroup_supported_operations.contains(vk::SubgroupFeatureFlags::VOTE)
        })
    }

    pub fn has_extension(&self, name: &CStr) -> bool {
        self.extensions.contains_key(name.to_str().unwrap_or_default())
    }

    pub fn api_version(&self) -> u32 {
        self.properties.core.api_version
    }

    pub fn driver_id(&self) -> vk::DriverId {
        self.properties.v12.map(|p| p.driver_id).unwrap_or_default()
    }

    pub fn driver_name(&self) -> String {
        self.properties
            .v12
            .and_then(|p| p.driver_name_as_c_str().ok().map(|c| c.to_string_lossy().into_owned()))
            .unwrap_or_default()
    }

    pub fn driver_info(&self) -> String {
        self.properties
            .v12
            .and_then(|p| p.driver_info_as_c_str().ok().map(|c| c.to_string_lossy().into_owned()))
            .unwrap_or_default()
    }

    /// The decoded driver version. Some Mesa drivers (lavapipe) put a placeholder in
    /// `driverVersion`; for Mesa drivers the version in `driverInfo` ("Mesa 25.0.7-...") wins.
    pub fn driver_version(&self) -> String {
        if let Some(v) = super::driver_version::mesa_version_from_info(&self.driver_info()) {
            return v;
        }
        super::driver_version::decode_driver_version(
            self.properties.core.vendor_id,
            self.driver_id(),
            self.properties.core.driver_version,
        )
    }

    /// A queue family that supports graphics and compute (ray tracing runs on such a queue).
    pub fn universal_queue_family(&self) -> Option<u32> {
        let want = vk::QueueFlags::GRAPHICS | vk::QueueFlags::COMPUTE;
        self.queue_families.iter().position(|q| q.queue_flags.contains(want)).map(|i| i as u32)
    }

    /// Why this device cannot run rtprobe's ray tracing pipelines; empty when it can.
    pub fn rt_pipeline_missing(&self) -> Vec<String> {
        let mut m = Vec::new();
        if self.api_version() < vk::API_VERSION_1_2 {
            m.push(format!(
                "Vulkan 1.2 (device has {})",
                super::driver_version::format_api_version(self.api_version())
            ));
        }
        for ext in [
            khr::ray_tracing_pipeline::NAME,
            khr::acceleration_structure::NAME,
            khr::deferred_host_operations::NAME,
        ] {
            if !self.has_extension(ext) {
                m.push(ext.to_string_lossy().into_owned());
            }
        }
        let f = &self.features;
        if f.rt_pipeline.is_some_and(|x| x.ray_tracing_pipeline == vk::FALSE) {
            m.push("rayTracingPipeline feature".into());
        }
        if f.accel.is_some_and(|x| x.acceleration_structure == vk::FALSE) {
            m.push("accelerationStructure feature".into());
        }
        if f.v12.is_some_and(|x| x.buffer_device_address == vk::FALSE) {
            m.push("bufferDeviceAddress feature".into());
        }
        if self.universal_queue_family().is_none() {
            m.push("a graphics+compute queue".into());
        }
        m
    }

    pub fn memory_type_index(&self, type_bits: u32, flags: vk::MemoryPropertyFlags) -> Option<u32> {
        (0..self.memory.memory_type_count).find(|&i| {
            type_bits & (1 << i) != 0
                && self.memory.memory_types[i as usize].property_flags.contains(flags)
        })
    }
}

/// Query every physical device, in enumeration order.
pub fn query_all(instance: &Instance) -> Result<Vec<DeviceInfo>, VkError> {
    instance
        .physical_devices()?
        .into_iter()
        .enumerate()
        .map(|(i, pd)| DeviceInfo::query(instance, i, pd))
        .collect()
}

/// Resolve `--device` (an index, or a case-insensitive substring of the name). Without a spec,
/// the first device that can run RT pipelines, preferring discrete GPUs.
pub fn select<'a>(
    devices: &'a [DeviceInfo],
    spec: Option<&str>,
) -> Result<&'a DeviceInfo, VkError> {
    let listing = || {
        devices.iter().map(|d| format!("{}: {}", d.index, d.name())).collect::<Vec<_>>().join(", ")
    };
    match spec {
        Some(s) => {
            if let Ok(i) = s.trim().parse::<usize>() {
                return devices
                    .get(i)
                    .ok_or_else(|| VkError::NoSuchDevice { spec: s.into(), available: listing() });
            }
            let needle = s.to_lowercase();
            let hits: Vec<&DeviceInfo> =
                devices.iter().filter(|d| d.name().to_lowercase().contains(&needle)).collect();
            match hits.as_slice() {
                [] => Err(VkError::NoSuchDevice { spec: s.into(), available: listing() }),
                [one] => Ok(one),
                many => Err(VkError::AmbiguousDevice {
                    spec: s.into(),
                    matches: many
                        .iter()
                        .map(|d| format!("{}: {}", d.index, d.name()))
                        .collect::<Vec<_>>()
                        .join(", "),
                }),
            }
        }
        None => {
            let capable = devices.iter().filter(|d| d.rt_pipeline_missing().is_empty());
            let best = capable
                .clone()
                .find(|d| d.properties.core.device_type == vk::PhysicalDeviceType::DISCRETE_GPU)
                .or_else(|| capable.clone().next());
            best.ok_or_else(|| VkError::NoRtDevice {
                details: devices
                    .iter()
                    .map(|d| {
                        format!(
                            "{}: {} lacks {}",
                            d.index,
                            d.name(),
                            d.rt_pipeline_missing().join(", ")
                        )
                    })
                    .collect::<Vec<_>>()
                    .join("; "),
            })
        }
    }
}
