//! Logical device creation. [`Requirements`] says what the work at hand needs; [`Gpu::new`]
//! enables exactly that — the extensions and the individual feature bits — and nothing else, so
//! a fault can never be blamed on a feature the probe did not ask for.
use super::error::{VkError, VkResultExt};
use super::features::DeviceInfo;
use super::instance::Instance;
use super::shader_features::{ShaderFeatures, Targets};
use ash::{ext, google, khr, nv, vk};
use std::ffi::CStr;
use std::sync::Arc;

/// What a piece of work needs from the device.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Requirements {
    /// VK_KHR_ray_tracing_pipeline + VK_KHR_acceleration_structure (+ deferred host operations).
    pub rt_pipeline: bool,
    /// VK_KHR_ray_query (tracing from fragment / compute / non-tracing RT stages).
    pub ray_query: bool,
    /// Buffer device address (implied by acceleration structures; also AS-by-address, records).
    pub buffer_device_address: bool,
    /// Runtime descriptor arrays, partially bound, variable count, update-after-bind, and the
    /// non-uniform indexing bits the device supports.
    pub descriptor_indexing: bool,
    /// VK_EXT_descriptor_buffer.
    pub descriptor_buffer: bool,
    /// VK_EXT_descriptor_heap (with VK_KHR_maintenance5, which it requires).
    pub descriptor_heap: bool,
    /// VK_KHR_shader_untyped_pointers (SPIR-V of `layout(descriptor_heap)` GLSL).
    pub untyped_pointers: bool,
    /// VK_EXT_device_fault (queried after a device loss).
    pub device_fault: bool,
    /// shaderInt64 (64-bit addresses in shaders).
    pub int64: bool,
    /// fragmentStoresAndAtomics (fragment probes write records to an SSBO).
    pub fragment_stores: bool,
    /// dynamicRendering (Vulkan 1.3; fragment probes render without a render pass object).
    pub dynamic_rendering: bool,
    /// VK_NV_ray_tracing_invocation_reorder (hit objects and reorderThreadNV in raygen).
    pub invocation_reorder: bool,
    /// scalarBlockLayout (user modules whose blocks use `layout(scalar)`).
    pub scalar_block_layout: bool,
    /// timelineSemaphore (Vulkan 1.2): a submission held until the host signals a value later
    /// (`Submitter::run_held`, stress's `stall` test hook).
    pub timeline_semaphore: bool,
    /// VK_KHR_pipeline_library: ray tracing pipelines linked from libraries.
    pub pipeline_library: bool,
    /// `VkDevicePipelineBinaryInternalCacheControlKHR::disableInternalCache`: the driver keeps no
    /// pipeline cache of its own, where `pipelineBinaryInternalCacheControl` allows it (the struct
    /// is VK_KHR_pipeline_binary's: that extension and VK_KHR_maintenance5, which it requires,
    /// are enabled with it).
    pub disable_internal_cache: bool,
    /// Robust buffer and image access an engine turns on (`run --shader --profile`).
    pub robustness: Robustness,
    /// The VK_GOOGLE extensions of the SPIR-V extensions DXC's `-fspv-reflect` writes.
    pub google: GoogleHlsl,
    /// The feature bits the user's modules' capabilities need (`harness::capabilities`).
    pub shader: ShaderFeatures,
}

/// The device extensions a module's `SPV_GOOGLE_*` extensions need, DXC's `-fspv-reflect`
/// output. VUID-VkShaderModuleCreateInfo-pCode-08742 (Vulkan 1.4.360): "If pCode declares any
/// of the SPIR-V extensions listed in the SPIR-V Environment appendix, one of the corresponding
/// requirements must be satisfied"; the appendix (vk.xml's `spirvextension`) gives each its
/// device extension of the same name: SPV_GOOGLE_hlsl_functionality1 needs
/// VK_GOOGLE_hlsl_functionality1, SPV_GOOGLE_user_type VK_GOOGLE_user_type,
/// SPV_GOOGLE_decorate_string VK_GOOGLE_decorate_string.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GoogleHlsl {
    pub hlsl_functionality1: bool,
    pub user_type: bool,
    pub decorate_string: bool,
}

impl GoogleHlsl {
    /// The SPIR-V extensions and their device extensions, as asked for.
    fn asked(&self) -> Vec<(&'static str, &'static CStr)> {
        [
            (
                self.hlsl_functionality1,
                "SPV_GOOGLE_hlsl_functionality1",
                google::hlsl_functionality1::NAME,
            ),
            (self.user_type, "SPV_GOOGLE_user_type", google::user_type::NAME),
            (self.decorate_string, "SPV_GOOGLE_decorate_string", google::decorate_string::NAME),
        ]
        .into_iter()
        .filter(|(on, _, _)| *on)
        .map(|(_, spv, vk)| (spv, vk))
        .collect()
    }

    /// Whether `spirv_extension` (an `OpExtension` name) is one of these; sets it.
    pub fn note(&mut self, spirv_extension: &str) {
        match spirv_extension {
            "SPV_GOOGLE_hlsl_functionality1" => self.hlsl_functionality1 = true,
            "SPV_GOOGLE_user_type" => self.user_type = true,
            "SPV_GOOGLE_decorate_string" => self.decorate_string = true,
            _ => {}
        }
    }

    /// The device extensions to enable.
    pub fn extensions(&self) -> Vec<&'static CStr> {
        self.asked().into_iter().map(|(_, vk)| vk).collect()
    }

    /// Those a device with extensions `has` lacks, each with what to do.
    pub fn missing(&self, has: impl Fn(&CStr) -> bool) -> Vec<String> {
        self.asked()
            .into_iter()
            .filter(|(_, vk)| !has(vk))
            .map(|(spv, vk)| {
                format!(
                    "{} (the modules declare {spv}, which DXC's -fspv-reflect writes: build them without -fspv-reflect)",
                    vk.to_string_lossy()
                )
            })
            .collect()
    }
}

/// The robustness features, each enabled only when asked for: driver faults often depend on
/// them, so a harness reproducing an engine's device enables what the engine enables.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Robustness {
    /// `VkPhysicalDeviceFeatures::robustBufferAccess`.
    pub robust_buffer_access: bool,
    /// `VkPhysicalDeviceVulkan13Features::robustImageAccess`.
    pub robust_image_access: bool,
    /// VK_EXT_robustness2's `robustBufferAccess2`, `robustImageAccess2`, `nullDescriptor`.
    pub robust_buffer_access2: bool,
    pub robust_image_access2: bool,
    pub null_descriptor: bool,
}

impl Robustness {
    /// Whether VK_EXT_robustness2 is needed.
    fn robustness2(&self) -> bool {
        self.robust_buffer_access2 || self.robust_image_access2 || self.null_descriptor
    }

    /// What `info` lacks of these.
    fn missing_on(&self, info: &DeviceInfo) -> Vec<String> {
        let f = &info.features;
        let r2 = f.robustness2.unwrap_or_default();
        // VK_EXT_robustness2's bits count only where the extension can be enabled.
        let r2_ext = info.has_extension(ext::robustness2::NAME);
        let r2_has = |bit: vk::Bool32| if r2_ext { bit } else { vk::FALSE };
        let v13 = f.v13.unwrap_or_default();
        [
            (self.robust_buffer_access, f.core.robust_buffer_access, "robustBufferAccess"),
            (self.robust_image_access, v13.robust_image_access, "robustImageAccess"),
            (self.robust_buffer_access2, r2_has(r2.robust_buffer_access2), "robustBufferAccess2"),
            (self.robust_image_access2, r2_has(r2.robust_image_access2), "robustImageAccess2"),
            (self.null_descriptor, r2_has(r2.null_descriptor), "nullDescriptor"),
        ]
        .iter()
        .filter(|(asked, has, _)| *asked && *has != vk::TRUE)
        .map(|(_, _, name)| name.to_string())
        .collect()
    }
}

impl Requirements {
    /// Requirements that `info` does not meet, as human-readable names.
    pub fn missing_on(&self, info: &DeviceInfo) -> Vec<String> {
        let f = &info.features;
        let mut m = Vec::new();
        if self.rt_pipeline {
            m.extend(info.rt_pipeline_missing());
        }
        let v12 = f.v12.unwrap_or_default();
        if self.ray_query && f.ray_query.is_none_or(|x| x.ray_query != vk::TRUE) {
            m.push("rayQuery (VK_KHR_ray_query)".into());
        }
        if self.buffer_device_address && v12.buffer_device_address == vk::FALSE {
            m.push("bufferDeviceAddress".into());
        }
        if self.descriptor_indexing
            && (v12.runtime_descriptor_array == vk::FALSE
                || v12.descriptor_binding_partially_bound == vk::FALSE)
        {
            m.push("runtimeDescriptorArray + descriptorBindingPartiallyBound".into());
        }
        if self.descriptor_buffer
            && f.descriptor_buffer.is_none_or(|x| x.descriptor_buffer != vk::TRUE)
        {
            m.push("descriptorBuffer (VK_EXT_descriptor_buffer)".into());
        }
        if self.descriptor_heap
            && !(f.descriptor_heap.is_some_and(|x| x.descriptor_heap == vk::TRUE)
                && info.has_extension(khr::maintenance5::NAME))
        {
            m.push("descriptorHeap (VK_EXT_descriptor_heap) + VK_KHR_maintenance5".into());
        }
        if self.untyped_pointers
            && f.untyped_pointers.is_none_or(|x| x.shader_untyped_pointers != vk::TRUE)
        {
            m.push("shaderUntypedPointers (VK_KHR_shader_untyped_pointers)".into());
        }
        if self.device_fault && f.fault.is_none_or(|x| x.device_fault != vk::TRUE) {
            m.push("deviceFault (VK_EXT_device_fault)".into());
        }
        if self.scalar_block_layout && v12.scalar_block_layout == vk::FALSE {
            m.push("scalarBlockLayout".into());
        }
        if self.timeline_semaphore && v12.timeline_semaphore == vk::FALSE {
            m.push("timelineSemaphore".into());
        }
        if self.int64 && f.core.shader_int64 == vk::FALSE {
            m.push("shaderInt64".into());
        }
        if self.fragment_stores && f.core.fragment_stores_and_atomics == vk::FALSE {
            m.push("fragmentStoresAndAtomics".into());
        }
        if self.dynamic_rendering && f.v13.is_none_or(|x| x.dynamic_rendering != vk::TRUE) {
            m.push("dynamicRendering (Vulkan 1.3)".into());
        }
        if self.invocation_reorder
            && f.invocation_reorder_nv.is_none_or(|x| x.ray_tracing_invocation_reorder != vk::TRUE)
        {
            m.push("rayTracingInvocationReorder (VK_NV_ray_tracing_invocation_reorder)".into());
        }
        m.extend(self.missing_pipeline_creation(info));
        m.extend(self.robustness.missing_on(info));
        m.extend(self.google.missing(|e| info.has_extension(e)));
        m.extend(self.shader.missing_on(info));
        m
    }

    /// What pipeline libraries and the internal-cache switch need that `info` lacks.
    fn missing_pipeline_creation(&self, info: &DeviceInfo) -> Vec<String> {
        let mut m = Vec::new();
        if self.disable_internal_cache && !internal_cache_control(info) {
            m.push(
                "pipelineBinaryInternalCacheControl (VK_KHR_pipeline_binary) + VK_KHR_maintenance5"
                    .into(),
            );
        }
        if self.pipeline_library && !info.has_extension(khr::pipeline_library::NAME) {
            m.push("VK_KHR_pipeline_library".into());
        }
        m
    }
}

/// A logical device with one universal queue and the extension loaders it enabled.
pub struct Gpu {
    pub instance: Arc<Instance>,
    pub info: DeviceInfo,
    pub device: ash::Device,
    pub queue: vk::Queue,
    pub queue_family: u32,
    pub enabled: Requirements,
    /// What `vkCreateDevice` was given: extension names, then each feature bit set to true
    /// (Vulkan spelling). Recorded per attempt: it varies with the worker's cells.
    pub enabled_names: Vec<String>,
    pub rt: Option<khr::ray_tracing_pipeline::Device>,
    pub accel: Option<khr::acceleration_structure::Device>,
    pub descriptor_buffer: Option<ext::descriptor_buffer::Device>,
    pub heap: Option<super::heap::HeapFns>,
    pub fault: Option<ext::device_fault::Device>,
}

/// What `vkCreateDevice` is given: the extensions, and each feature struct with exactly the bits
/// the requirements ask for (a struct is chained only when its extension or version is asked for:
/// [`Chosen::create_device`]).
struct Chosen {
    exts: Vec<&'static CStr>,
    core: vk::PhysicalDeviceFeatures,
    v11: vk::PhysicalDeviceVulkan11Features<'static>,
    pf: vk::PhysicalDeviceRayTracingPositionFetchFeaturesKHR<'static>,
    m1: vk::PhysicalDeviceRayTracingMaintenance1FeaturesKHR<'static>,
    v12: vk::PhysicalDeviceVulkan12Features<'static>,
    v13: vk::PhysicalDeviceVulkan13Features<'static>,
    rt: vk::PhysicalDeviceRayTracingPipelineFeaturesKHR<'static>,
    accel: vk::PhysicalDeviceAccelerationStructureFeaturesKHR<'static>,
    rq: vk::PhysicalDeviceRayQueryFeaturesKHR<'static>,
    db: vk::PhysicalDeviceDescriptorBufferFeaturesEXT<'static>,
    fault: vk::PhysicalDeviceFaultFeaturesEXT<'static>,
    reorder: vk::PhysicalDeviceRayTracingInvocationReorderFeaturesNV<'static>,
    dh: super::heap::PhysicalDeviceDescriptorHeapFeaturesEXT,
    m5: vk::PhysicalDeviceMaintenance5FeaturesKHR<'static>,
    up: super::heap::PhysicalDeviceShaderUntypedPointersFeaturesKHR,
    icc: super::binary::DevicePipelineBinaryInternalCacheControlKHR,
    r2: vk::PhysicalDeviceRobustness2FeaturesEXT<'static>,
}

impl Chosen {
    /// The extensions and feature bits `req` needs on a device that supports `sup`.
    fn of(req: &Requirements, info: &DeviceInfo) -> Chosen {
        let sup = &info.features;
        let mut c = Chosen {
            exts: Vec::new(),
            core: vk::PhysicalDeviceFeatures::default(),
            v11: Default::default(),
            pf: Default::default(),
            m1: Default::default(),
            v12: vk::PhysicalDeviceVulkan12Features::default(),
            v13: vk::PhysicalDeviceVulkan13Features::default()
                .dynamic_rendering(req.dynamic_rendering),
            rt: Default::default(),
            accel: Default::default(),
            rq: Default::default(),
            db: Default::default(),
            fault: Default::default(),
            reorder: Default::default(),
            dh: super::heap::PhysicalDeviceDescriptorHeapFeaturesEXT {
                descriptor_heap: vk::TRUE,
                ..Default::default()
            },
            m5: vk::PhysicalDeviceMaintenance5FeaturesKHR::default().maintenance5(true),
            up: super::heap::PhysicalDeviceShaderUntypedPointersFeaturesKHR {
                shader_untyped_pointers: vk::TRUE,
                ..Default::default()
            },
            icc: super::binary::DevicePipelineBinaryInternalCacheControlKHR {
                disable_internal_cache: vk::TRUE,
                ..Default::default()
            },
            r2: Default::default(),
        };
        let bda = req.buffer_device_address
            || req.rt_pipeline
            || req.ray_query
            || req.descriptor_buffer
            || req.descriptor_heap;
        c.ray_tracing(req);
        if bda {
            c.v12.buffer_device_address = vk::TRUE;
        }
        if req.scalar_block_layout {
            c.v12.scalar_block_layout = vk::TRUE;
        }
        if req.timeline_semaphore {
            c.v12.timeline_semaphore = vk::TRUE;
        }
        if req.descriptor_indexing {
            c.descriptor_indexing(sup);
        }
        c.descriptor_models(req);
        if req.device_fault {
            c.exts.push(ext::device_fault::NAME);
            c.fault.device_fault = vk::TRUE;
            c.fault.device_fault_vendor_binary =
                sup.fault.map(|f| f.device_fault_vendor_binary).unwrap_or(vk::FALSE);
        }
        if req.invocation_reorder {
            c.exts.push(nv::ray_tracing_invocation_reorder::NAME);
            c.reorder.ray_tracing_invocation_reorder = vk::TRUE;
        }
        c.core.shader_int64 = if req.int64 || bda { sup.core.shader_int64 } else { vk::FALSE };
        c.core.fragment_stores_and_atomics = if req.fragment_stores { vk::TRUE } else { vk::FALSE };
        c.core.vertex_pipeline_stores_and_atomics = vk::FALSE;
        c.robustness(&req.robustness);
        c.exts.extend(req.google.extensions());
        c.exts.extend(req.shader.extensions());
        req.shader.enable(info, c.targets());
        c
    }

    /// The structs [`ShaderFeatures`] sets its bits in.
    fn targets(&mut self) -> Targets<'_> {
        Targets {
            core: &mut self.core,
            v11: &mut self.v11,
            v12: &mut self.v12,
            rt: &mut self.rt,
            pf: &mut self.pf,
            m1: &mut self.m1,
        }
    }

    /// The robustness bits asked for (VK_EXT_robustness2's with its extension).
    fn robustness(&mut self, r: &Robustness) {
        let b = |on: bool| if on { vk::TRUE } else { vk::FALSE };
        self.core.robust_buffer_access = b(r.robust_buffer_access);
        self.v13.robust_image_access = b(r.robust_image_access);
        if r.robustness2() {
            self.exts.push(ext::robustness2::NAME);
            self.r2.robust_buffer_access2 = b(r.robust_buffer_access2);
            self.r2.robust_image_access2 = b(r.robust_image_access2);
            self.r2.null_descriptor = b(r.null_descriptor);
        }
    }

    /// Acceleration structures, the RT pipeline and ray queries.
    fn ray_tracing(&mut self, req: &Requirements) {
        if req.rt_pipeline || req.ray_query {
            self.exts
                .extend([khr::acceleration_structure::NAME, khr::deferred_host_operations::NAME]);
            self.accel.acceleration_structure = vk::TRUE;
        }
        if req.rt_pipeline {
            self.exts.push(khr::ray_tracing_pipeline::NAME);
            self.rt.ray_tracing_pipeline = vk::TRUE;
        }
        if req.ray_query {
            self.exts.push(khr::ray_query::NAME);
            self.rq.ray_query = vk::TRUE;
        }
    }

    /// Every descriptor-indexing bit the device supports (runtime arrays, partially bound,
    /// variable count, update-after-bind, non-uniform indexing).
    fn descriptor_indexing(&mut self, sup: &super::features::Features) {
        let (c, sup12, core, v12) =
            (&sup.core, sup.v12.unwrap_or_default(), &mut self.core, &mut self.v12);
        core.shader_storage_buffer_array_dynamic_indexing =
            c.shader_storage_buffer_array_dynamic_indexing;
        core.shader_uniform_buffer_array_dynamic_indexing =
            c.shader_uniform_buffer_array_dynamic_indexing;
        core.shader_sampled_image_array_dynamic_indexing =
            c.shader_sampled_image_array_dynamic_indexing;
        core.shader_storage_image_array_dynamic_indexing =
            c.shader_storage_image_array_dynamic_indexing;
        v12.descriptor_indexing = sup12.descriptor_indexing;
        v12.runtime_descriptor_array = sup12.runtime_descriptor_array;
        v12.descriptor_binding_partially_bound = sup12.descriptor_binding_partially_bound;
        v12.descriptor_binding_variable_descriptor_count =
            sup12.descriptor_binding_variable_descriptor_count;
        v12.shader_storage_buffer_array_non_uniform_indexing =
            sup12.shader_storage_buffer_array_non_uniform_indexing;
        v12.shader_uniform_buffer_array_non_uniform_indexing =
            sup12.shader_uniform_buffer_array_non_uniform_indexing;
        v12.shader_sampled_image_array_non_uniform_indexing =
            sup12.shader_sampled_image_array_non_uniform_indexing;
        v12.shader_storage_image_array_non_uniform_indexing =
            sup12.shader_storage_image_array_non_uniform_indexing;
        v12.descriptor_binding_storage_buffer_update_after_bind =
            sup12.descriptor_binding_storage_buffer_update_after_bind;
        v12.descriptor_binding_uniform_buffer_update_after_bind =
            sup12.descriptor_binding_uniform_buffer_update_after_bind;
        v12.descriptor_binding_sampled_image_update_after_bind =
            sup12.descriptor_binding_sampled_image_update_after_bind;
        v12.descriptor_binding_storage_image_update_after_bind =
            sup12.descriptor_binding_storage_image_update_after_bind;
        self.accel.descriptor_binding_acceleration_structure_update_after_bind = sup
            .accel
            .map(|a| a.descriptor_binding_acceleration_structure_update_after_bind)
            .unwrap_or(vk::FALSE);
    }

    /// Descriptor buffers, descriptor heaps (with maintenance5) and untyped pointers.
    fn descriptor_models(&mut self, req: &Requirements) {
        if req.descriptor_buffer {
            self.exts.push(ext::descriptor_buffer::NAME);
            self.db.descriptor_buffer = vk::TRUE;
        }
        if req.descriptor_heap {
            self.exts.extend([super::heap::NAME, khr::maintenance5::NAME]);
        }
        if req.untyped_pointers {
            self.exts.push(super::heap::UNTYPED_POINTERS_NAME);
        }
        if req.disable_internal_cache {
            self.exts.push(super::binary::NAME);
            if !req.descriptor_heap {
                self.exts.push(khr::maintenance5::NAME);
            }
        }
        if req.pipeline_library {
            self.exts.push(khr::pipeline_library::NAME);
        }
    }

    /// `vkCreateDevice` with one queue of `queue_family`, the extensions, and the feature structs
    /// `req` asks for chained after `VkPhysicalDeviceFeatures2`.
    fn create_device(
        &mut self,
        instance: &Instance,
        info: &DeviceInfo,
        queue_family: u32,
        req: &Requirements,
    ) -> Result<ash::Device, VkError> {
        let prio = [1.0f32];
        let qci = [vk::DeviceQueueCreateInfo::default()
            .queue_family_index(queue_family)
            .queue_priorities(&prio)];
        let ext_ptrs: Vec<*const i8> = self.exts.iter().map(|e| e.as_ptr()).collect();
        let mut f2 =
            vk::PhysicalDeviceFeatures2::default().features(self.core).push_next(&mut self.v12);
        if req.dynamic_rendering || req.robustness.robust_image_access {
            f2 = f2.push_next(&mut self.v13);
        }
        if req.robustness.robustness2() {
            f2 = f2.push_next(&mut self.r2);
        }
        if req.rt_pipeline || req.ray_query {
            f2 = f2.push_next(&mut self.accel);
        }
        if req.rt_pipeline {
            f2 = f2.push_next(&mut self.rt);
        }
        if req.ray_query {
            f2 = f2.push_next(&mut self.rq);
        }
        if req.descriptor_buffer {
            f2 = f2.push_next(&mut self.db);
        }
        if req.descriptor_heap {
            f2 = f2.push_next(&mut self.dh);
        }
        if req.descriptor_heap || req.disable_internal_cache {
            f2 = f2.push_next(&mut self.m5);
        }
        if req.untyped_pointers {
            f2 = f2.push_next(&mut self.up);
        }
        if req.device_fault {
            f2 = f2.push_next(&mut self.fault);
        }
        if req.invocation_reorder {
            f2 = f2.push_next(&mut self.reorder);
        }
        if req.shader.v11() {
            f2 = f2.push_next(&mut self.v11);
        }
        if req.shader.position_fetch {
            f2 = f2.push_next(&mut self.pf);
        }
        if req.shader.cull_mask {
            f2 = f2.push_next(&mut self.m1);
        }
        let mut ci = vk::DeviceCreateInfo::default()
            .queue_create_infos(&qci)
            .enabled_extension_names(&ext_ptrs)
            .push_next(&mut f2);
        if req.disable_internal_cache {
            ci = ci.push_next(&mut self.icc);
        }
        unsafe { instance.raw.create_device(info.raw, &ci, None) }.at("vkCreateDevice")
    }

    /// The extension names, then each feature bit given as true (Vulkan spelling).
    fn names(&self, req: &Requirements) -> Vec<String> {
        let exts = self.exts.iter().map(|e| e.to_string_lossy().into_owned());
        let bits = [self.core_names(), self.v12_names(), self.extension_names(req)];
        let mut names: Vec<String> = exts.chain(bits.into_iter().flatten().flatten()).collect();
        let (mut core, mut v11, mut v12) = (self.core, self.v11, self.v12);
        let (mut rt, mut pf, mut m1) = (self.rt, self.pf, self.m1);
        let mut t = Targets {
            core: &mut core,
            v11: &mut v11,
            v12: &mut v12,
            rt: &mut rt,
            pf: &mut pf,
            m1: &mut m1,
        };
        for r in super::shader_features::rows().iter().filter(|r| (r.asked)(&req.shader)) {
            if *t.bit(r.slot) == vk::TRUE && !names.iter().any(|n| n == r.name) {
                names.push(r.name.to_string());
            }
        }
        names
    }

    /// The Vulkan 1.0 feature bits given as true.
    fn core_names(&self) -> Vec<Option<String>> {
        let core = &self.core;
        vec![
            given("robustBufferAccess", core.robust_buffer_access),
            given("shaderInt64", core.shader_int64),
            given("fragmentStoresAndAtomics", core.fragment_stores_and_atomics),
            given(
                "shaderStorageBufferArrayDynamicIndexing",
                core.shader_storage_buffer_array_dynamic_indexing,
            ),
            given(
                "shaderUniformBufferArrayDynamicIndexing",
                core.shader_uniform_buffer_array_dynamic_indexing,
            ),
            given(
                "shaderSampledImageArrayDynamicIndexing",
                core.shader_sampled_image_array_dynamic_indexing,
            ),
            given(
                "shaderStorageImageArrayDynamicIndexing",
                core.shader_storage_image_array_dynamic_indexing,
            ),
        ]
    }

    /// The Vulkan 1.2 feature bits given as true.
    fn v12_names(&self) -> Vec<Option<String>> {
        let v12 = &self.v12;
        vec![
            given("bufferDeviceAddress", v12.buffer_device_address),
            given("scalarBlockLayout", v12.scalar_block_layout),
            given("timelineSemaphore", v12.timeline_semaphore),
            given("descriptorIndexing", v12.descriptor_indexing),
            given("runtimeDescriptorArray", v12.runtime_descriptor_array),
            given("descriptorBindingPartiallyBound", v12.descriptor_binding_partially_bound),
            given(
                "descriptorBindingVariableDescriptorCount",
                v12.descriptor_binding_variable_descriptor_count,
            ),
            given(
                "shaderStorageBufferArrayNonUniformIndexing",
                v12.shader_storage_buffer_array_non_uniform_indexing,
            ),
            given(
                "shaderUniformBufferArrayNonUniformIndexing",
                v12.shader_uniform_buffer_array_non_uniform_indexing,
            ),
            given(
                "shaderSampledImageArrayNonUniformIndexing",
                v12.shader_sampled_image_array_non_uniform_indexing,
            ),
            given(
                "shaderStorageImageArrayNonUniformIndexing",
                v12.shader_storage_image_array_non_uniform_indexing,
            ),
            given(
                "descriptorBindingStorageBufferUpdateAfterBind",
                v12.descriptor_binding_storage_buffer_update_after_bind,
            ),
            given(
                "descriptorBindingUniformBufferUpdateAfterBind",
                v12.descriptor_binding_uniform_buffer_update_after_bind,
            ),
            given(
                "descriptorBindingSampledImageUpdateAfterBind",
                v12.descriptor_binding_sampled_image_update_after_bind,
            ),
            given(
                "descriptorBindingStorageImageUpdateAfterBind",
                v12.descriptor_binding_storage_image_update_after_bind,
            ),
        ]
    }

    /// The feature bits of Vulkan 1.3 and the extensions given as true, where `req` chains their
    /// structs.
    fn extension_names(&self, req: &Requirements) -> Vec<Option<String>> {
        let rtq = req.rt_pipeline || req.ray_query;
        let (v13, r2) = (
            req.dynamic_rendering || req.robustness.robust_image_access,
            req.robustness.robustness2(),
        );
        vec![
            on("dynamicRendering", self.v13.dynamic_rendering, v13),
            on("robustImageAccess", self.v13.robust_image_access, v13),
            on("robustBufferAccess2", self.r2.robust_buffer_access2, r2),
            on("robustImageAccess2", self.r2.robust_image_access2, r2),
            on("nullDescriptor", self.r2.null_descriptor, r2),
            on("accelerationStructure", self.accel.acceleration_structure, rtq),
            on(
                "descriptorBindingAccelerationStructureUpdateAfterBind",
                self.accel.descriptor_binding_acceleration_structure_update_after_bind,
                rtq,
            ),
            on("rayTracingPipeline", self.rt.ray_tracing_pipeline, req.rt_pipeline),
            on("rayQuery", self.rq.ray_query, req.ray_query),
            on("descriptorBuffer", self.db.descriptor_buffer, req.descriptor_buffer),
            on("deviceFault", self.fault.device_fault, req.device_fault),
            on("deviceFaultVendorBinary", self.fault.device_fault_vendor_binary, req.device_fault),
            on("disableInternalCache", self.icc.disable_internal_cache, req.disable_internal_cache),
        ]
    }
}

/// Whether `info` lets a device turn the driver's own pipeline cache off
/// (`pipelineBinaryInternalCacheControl`, with VK_KHR_maintenance5 for the extension).
pub fn internal_cache_control(info: &DeviceInfo) -> bool {
    info.properties
        .pipeline_binary
        .is_some_and(|p| p.pipeline_binary_internal_cache_control == vk::TRUE)
        && info.has_extension(khr::maintenance5::NAME)
}

/// `name` when `bit` is true in a struct that is `chained` (given to vkCreateDevice).
fn on(name: &str, bit: vk::Bool32, chained: bool) -> Option<String> {
    (chained && bit == vk::TRUE).then(|| name.to_string())
}

/// `name` when `bit` is true in a struct that is always chained (1.0, 1.2).
fn given(name: &str, bit: vk::Bool32) -> Option<String> {
    on(name, bit, true)
}

/// Every feature bit (Vulkan member name) a device created on `info` with `req` is given, as
/// [`Gpu::enabled_names`] lists them after the extensions; nothing is created.
pub fn enabled_feature_names(req: &Requirements, info: &DeviceInfo) -> Vec<String> {
    let c = Chosen::of(req, info);
    let n = c.exts.len();
    c.names(req).split_off(n)
}

impl Gpu {
    pub fn new(
        instance: Arc<Instance>,
        info: DeviceInfo,
        req: Requirements,
    ) -> Result<Self, VkError> {
        let missing = req.missing_on(&info);
        if !missing.is_empty() {
            return Err(VkError::Unsupported {
                index: info.index,
                name: info.name(),
                missing: missing.join(", "),
            });
        }
        let queue_family = info.universal_queue_family().ok_or_else(|| VkError::Unsupported {
            index: info.index,
            name: info.name(),
            missing: "a graphics+compute queue".into(),
        })?;
        let mut chosen = Chosen::of(&req, &info);
        let device = chosen.create_device(&instance, &info, queue_family, &req)?;
        let enabled_names = chosen.names(&req);
        let queue = unsafe { device.get_device_queue(queue_family, 0) };
        let inst = &instance.raw;
        let heap = match req
            .descriptor_heap
            .then(|| super::heap::HeapFns::load(&instance.entry, inst, &device))
            .transpose()
        {
            Ok(h) => h,
            Err(missing) => {
                unsafe { device.destroy_device(None) };
                return Err(VkError::Call {
                    call: missing,
                    result: vk::Result::ERROR_EXTENSION_NOT_PRESENT,
                });
            }
        };
        let gpu = Gpu {
            heap,
            rt: req.rt_pipeline.then(|| khr::ray_tracing_pipeline::Device::new(inst, &device)),
            accel: (req.rt_pipeline || req.ray_query)
                .then(|| khr::acceleration_structure::Device::new(inst, &device)),
            descriptor_buffer: req
                .descriptor_buffer
                .then(|| ext::descriptor_buffer::Device::new(inst, &device)),
            fault: req.device_fault.then(|| ext::device_fault::Device::new(inst, &device)),
            instance: instance.clone(),
            info,
            device,
            queue,
            queue_family,
            enabled: req,
            enabled_names,
        };
        Ok(gpu)
    }
}

impl Drop for Gpu {
    fn drop(&mut self) {
        unsafe {
            let _ = self.device.device_wait_idle();
            self.device.destroy_device(None);
        }
    }
}
