//! Turns the feature / property structs of [`DeviceInfo`] into JSON objects keyed by the Vulkan
//! structure name and member names (`"VkPhysicalDeviceRayTracingPipelineFeaturesKHR":
//! {"rayTracingPipeline": true}`) — the layout the Vulkan Profiles JSON format uses, so the caps
//! report and the profile export share one representation. A struct the device lacks is absent.
use crate::vk::features::{Features, Properties};
use crate::vk::{rt_ext, DeviceInfo};
use ash::vk;
use serde_json::{json, Map, Value};

macro_rules! obj {
    ($s:expr; $($kind:ident $name:literal $field:ident),* $(,)?) => {{
        let s = &$s;
        let mut m = Map::new();
        $( m.insert($name.to_string(), obj!(@v $kind s.$field)); )*
        Value::Object(m)
    }};
    (@v b $e:expr) => { Value::Bool($e == vk::TRUE) };
    (@v n $e:expr) => { json!($e) };
    (@v reorder $e:expr) => { json!(rt_ext::reorder_mode_name($e)) };
}

fn put(m: &mut Map<String, Value>, key: &str, v: Option<Value>) {
    if let Some(v) = v {
        m.insert(key.to_string(), v);
    }
}

/// Features, one object per Vulkan struct the device has.
pub fn features(info: &DeviceInfo) -> Map<String, Value> {
    let f = &info.features;
    let mut m = Map::new();
    core_features(f, &mut m);
    rt_features(f, &mut m);
    descriptor_and_device_features(f, &mut m);
    rt_extension_features(f, &mut m);
    rt_geometry_features(f, &mut m);
    m
}

/// The core features rtprobe relies on, and those of Vulkan 1.1, 1.2 and 1.3.
fn core_features(f: &Features, m: &mut Map<String, Value>) {
    put(
        m,
        "VkPhysicalDeviceFeatures",
        Some(obj!(f.core;
            b "robustBufferAccess" robust_buffer_access, b "shaderInt64" shader_int64, b "shaderInt16" shader_int16,
            b "shaderFloat64" shader_float64, b "fragmentStoresAndAtomics" fragment_stores_and_atomics,
            b "vertexPipelineStoresAndAtomics" vertex_pipeline_stores_and_atomics,
            b "shaderUniformBufferArrayDynamicIndexing" shader_uniform_buffer_array_dynamic_indexing,
            b "shaderSampledImageArrayDynamicIndexing" shader_sampled_image_array_dynamic_indexing,
            b "shaderStorageBufferArrayDynamicIndexing" shader_storage_buffer_array_dynamic_indexing,
            b "shaderStorageImageArrayDynamicIndexing" shader_storage_image_array_dynamic_indexing,
        )),
    );
    put(m, "VkPhysicalDeviceVulkan11Features", f.v11.map(|s| obj!(s;
        b "storageBuffer16BitAccess" storage_buffer16_bit_access, b "variablePointersStorageBuffer" variable_pointers_storage_buffer,
        b "variablePointers" variable_pointers, b "shaderDrawParameters" shader_draw_parameters,
    )));
    put(m, "VkPhysicalDeviceVulkan12Features", f.v12.map(|s| obj!(s;
        b "descriptorIndexing" descriptor_indexing,
        b "shaderUniformBufferArrayNonUniformIndexing" shader_uniform_buffer_array_non_uniform_indexing,
        b "shaderSampledImageArrayNonUniformIndexing" shader_sampled_image_array_non_uniform_indexing,
        b "shaderStorageBufferArrayNonUniformIndexing" shader_storage_buffer_array_non_uniform_indexing,
        b "shaderStorageImageArrayNonUniformIndexing" shader_storage_image_array_non_uniform_indexing,
        b "descriptorBindingUniformBufferUpdateAfterBind" descriptor_binding_uniform_buffer_update_after_bind,
        b "descriptorBindingSampledImageUpdateAfterBind" descriptor_binding_sampled_image_update_after_bind,
        b "descriptorBindingStorageImageUpdateAfterBind" descriptor_binding_storage_image_update_after_bind,
        b "descriptorBindingStorageBufferUpdateAfterBind" descriptor_binding_storage_buffer_update_after_bind,
        b "descriptorBindingUpdateUnusedWhilePending" descriptor_binding_update_unused_while_pending,
        b "descriptorBindingPartiallyBound" descriptor_binding_partially_bound,
        b "descriptorBindingVariableDescriptorCount" descriptor_binding_variable_descriptor_count,
        b "runtimeDescriptorArray" runtime_descriptor_array,
        b "bufferDeviceAddress" buffer_device_address, b "bufferDeviceAddressCaptureReplay" buffer_device_address_capture_replay,
        b "scalarBlockLayout" scalar_block_layout, b "timelineSemaphore" timeline_semaphore,
        b "vulkanMemoryModel" vulkan_memory_model, b "shaderInt8" shader_int8, b "shaderFloat16" shader_float16,
    )));
    put(m, "VkPhysicalDeviceVulkan13Features", f.v13.map(|s| obj!(s;
        b "robustImageAccess" robust_image_access, b "synchronization2" synchronization2,
        b "maintenance4" maintenance4, b "dynamicRendering" dynamic_rendering, b "inlineUniformBlock" inline_uniform_block,
    )));
}

/// The ray tracing pipeline, acceleration structures, ray query, maintenance1 and position fetch:
/// the extensions rtprobe's matrix uses.
fn rt_features(f: &Features, m: &mut Map<String, Value>) {
    put(m, "VkPhysicalDeviceRayTracingPipelineFeaturesKHR", f.rt_pipeline.map(|s| obj!(s;
        b "rayTracingPipeline" ray_tracing_pipeline,
        b "rayTracingPipelineShaderGroupHandleCaptureReplay" ray_tracing_pipeline_shader_group_handle_capture_replay,
        b "rayTracingPipelineShaderGroupHandleCaptureReplayMixed" ray_tracing_pipeline_shader_group_handle_capture_replay_mixed,
        b "rayTracingPipelineTraceRaysIndirect" ray_tracing_pipeline_trace_rays_indirect,
        b "rayTraversalPrimitiveCulling" ray_traversal_primitive_culling,
    )));
    put(m, "VkPhysicalDeviceAccelerationStructureFeaturesKHR", f.accel.map(|s| obj!(s;
        b "accelerationStructure" acceleration_structure,
        b "accelerationStructureCaptureReplay" acceleration_structure_capture_replay,
        b "accelerationStructureIndirectBuild" acceleration_structure_indirect_build,
        b "accelerationStructureHostCommands" acceleration_structure_host_commands,
        b "descriptorBindingAccelerationStructureUpdateAfterBind" descriptor_binding_acceleration_structure_update_after_bind,
    )));
    put(
        m,
        "VkPhysicalDeviceRayQueryFeaturesKHR",
        f.ray_query.map(|s| obj!(s; b "rayQuery" ray_query)),
    );
    put(
        m,
        "VkPhysicalDeviceRayTracingMaintenance1FeaturesKHR",
        f.rt_maintenance1.map(|s| {
            obj!(s;
                b "rayTracingMaintenance1" ray_tracing_maintenance1,
                b "rayTracingPipelineTraceRaysIndirect2" ray_tracing_pipeline_trace_rays_indirect2,
            )
        }),
    );
    put(
        m,
        "VkPhysicalDeviceRayTracingPositionFetchFeaturesKHR",
        f.position_fetch.map(|s| {
            obj!(s;
        b "rayTracingPositionFetch" ray_tracing_position_fetch)
        }),
    );
}

/// Descriptor buffer and heap, untyped pointers, robustness2, device fault, maintenance5 and 6.
fn descriptor_and_device_features(f: &Features, m: &mut Map<String, Value>) {
    put(m, "VkPhysicalDeviceDescriptorBufferFeaturesEXT", f.descriptor_buffer.map(|s| obj!(s;
        b "descriptorBuffer" descriptor_buffer, b "descriptorBufferCaptureReplay" descriptor_buffer_capture_replay,
        b "descriptorBufferImageLayoutIgnored" descriptor_buffer_image_layout_ignored,
        b "descriptorBufferPushDescriptors" descriptor_buffer_push_descriptors,
    )));
    put(m, "VkPhysicalDeviceDescriptorHeapFeaturesEXT", f.descriptor_heap.map(|s| obj!(s;
        b "descriptorHeap" descriptor_heap, b "descriptorHeapCaptureReplay" descriptor_heap_capture_replay)));
    put(
        m,
        "VkPhysicalDeviceShaderUntypedPointersFeaturesKHR",
        f.untyped_pointers.map(|s| {
            obj!(s;
        b "shaderUntypedPointers" shader_untyped_pointers)
        }),
    );
    put(m, "VkPhysicalDeviceRobustness2FeaturesEXT", f.robustness2.map(|s| obj!(s;
        b "robustBufferAccess2" robust_buffer_access2, b "robustImageAccess2" robust_image_access2, b "nullDescriptor" null_descriptor)));
    put(
        m,
        "VkPhysicalDeviceFaultFeaturesEXT",
        f.fault.map(|s| {
            obj!(s;
        b "deviceFault" device_fault, b "deviceFaultVendorBinary" device_fault_vendor_binary)
        }),
    );
    put(
        m,
        "VkPhysicalDeviceMaintenance5FeaturesKHR",
        f.maintenance5.map(|s| obj!(s; b "maintenance5" maintenance5)),
    );
    put(
        m,
        "VkPhysicalDeviceMaintenance6FeaturesKHR",
        f.maintenance6.map(|s| obj!(s; b "maintenance6" maintenance6)),
    );
}

/// The ray tracing extensions beyond what rtprobe's matrix uses: pipeline libraries, validation,
/// invocation reorder, cluster and partitioned AS (the geometry kinds and micromaps are in
/// [`rt_geometry_features`]).
fn rt_extension_features(f: &Features, m: &mut Map<String, Value>) {
    put(
        m,
        "VkPhysicalDevicePipelineLibraryGroupHandlesFeaturesEXT",
        f.pipeline_library_group_handles.map(|s| {
            obj!(s;
        b "pipelineLibraryGroupHandles" pipeline_library_group_handles)
        }),
    );
    put(
        m,
        "VkPhysicalDevicePipelineBinaryFeaturesKHR",
        f.pipeline_binary.map(|s| obj!(s; b "pipelineBinaries" pipeline_binaries)),
    );
    put(
        m,
        "VkPhysicalDeviceRayTracingValidationFeaturesNV",
        f.rt_validation.map(|s| obj!(s; b "rayTracingValidation" ray_tracing_validation)),
    );
    put(
        m,
        "VkPhysicalDeviceRayTracingInvocationReorderFeaturesNV",
        f.invocation_reorder_nv.map(|s| {
            obj!(s;
        b "rayTracingInvocationReorder" ray_tracing_invocation_reorder)
        }),
    );
    put(
        m,
        "VkPhysicalDeviceRayTracingInvocationReorderFeaturesEXT",
        f.invocation_reorder_ext.map(|s| {
            obj!(s;
        b "rayTracingInvocationReorder" ray_tracing_invocation_reorder)
        }),
    );
    put(
        m,
        "VkPhysicalDeviceClusterAccelerationStructureFeaturesNV",
        f.cluster_accel.map(|s| {
            obj!(s;
        b "clusterAccelerationStructure" cluster_acceleration_structure)
        }),
    );
    put(
        m,
        "VkPhysicalDevicePartitionedAccelerationStructureFeaturesNV",
        f.partitioned_accel.map(|s| {
            obj!(s;
        b "partitionedAccelerationStructure" partitioned_acceleration_structure)
        }),
    );
}

/// The ray tracing geometry kinds beyond triangles and AABBs (dense geometry, motion blur, swept
/// spheres) and micromaps.
fn rt_geometry_features(f: &Features, m: &mut Map<String, Value>) {
    put(
        m,
        "VkPhysicalDeviceDenseGeometryFormatFeaturesAMDX",
        f.dense_geometry_format.map(|s| obj!(s; b "denseGeometryFormat" dense_geometry_format)),
    );
    put(m, "VkPhysicalDeviceRayTracingMotionBlurFeaturesNV", f.motion_blur.map(|s| obj!(s;
        b "rayTracingMotionBlur" ray_tracing_motion_blur,
        b "rayTracingMotionBlurPipelineTraceRaysIndirect" ray_tracing_motion_blur_pipeline_trace_rays_indirect)));
    put(
        m,
        "VkPhysicalDeviceRayTracingLinearSweptSpheresFeaturesNV",
        f.linear_swept_spheres.map(|s| {
            obj!(s;
        b "spheres" spheres, b "linearSweptSpheres" linear_swept_spheres)
        }),
    );
    put(m, "VkPhysicalDeviceOpacityMicromapFeaturesEXT", f.opacity_micromap.map(|s| obj!(s;
        b "micromap" micromap, b "micromapCaptureReplay" micromap_capture_replay, b "micromapHostCommands" micromap_host_commands)));
    put(
        m,
        "VkPhysicalDeviceOpacityMicromapFeaturesKHR",
        f.opacity_micromap_khr.map(|s| obj!(s; b "micromap" micromap)),
    );
    put(
        m,
        "VkPhysicalDevicePipelineOpacityMicromapFeaturesARM",
        f.pipeline_opacity_micromap.map(|s| {
            obj!(s;
        b "pipelineOpacityMicromap" pipeline_opacity_micromap)
        }),
    );
    put(
        m,
        "VkPhysicalDeviceDisplacementMicromapFeaturesNV",
        f.displacement_micromap.map(|s| obj!(s; b "displacementMicromap" displacement_micromap)),
    );
}

/// Properties of the ray tracing extensions listed in [`rt_extension_features`] and
/// [`rt_geometry_features`], and of the legacy VK_NV_ray_tracing.
fn rt_extension_properties(info: &DeviceInfo, m: &mut Map<String, Value>) {
    let p = &info.properties;
    put(m, "VkPhysicalDeviceRayTracingPropertiesNV", p.rt_nv.map(|s| obj!(s;
        n "shaderGroupHandleSize" shader_group_handle_size, n "maxRecursionDepth" max_recursion_depth,
        n "maxShaderGroupStride" max_shader_group_stride, n "shaderGroupBaseAlignment" shader_group_base_alignment,
        n "maxGeometryCount" max_geometry_count, n "maxInstanceCount" max_instance_count, n "maxTriangleCount" max_triangle_count,
        n "maxDescriptorSetAccelerationStructures" max_descriptor_set_acceleration_structures)));
    put(m, "VkPhysicalDeviceRayTracingInvocationReorderPropertiesNV", p.invocation_reorder_nv.map(|s| obj!(s;
        reorder "rayTracingInvocationReorderReorderingHint" ray_tracing_invocation_reorder_reordering_hint)));
    put(m, "VkPhysicalDeviceRayTracingInvocationReorderPropertiesEXT", p.invocation_reorder_ext.map(|s| obj!(s;
        reorder "rayTracingInvocationReorderReorderingHint" ray_tracing_invocation_reorder_reordering_hint,
        n "maxShaderBindingTableRecordIndex" max_shader_binding_table_record_index)));
    put(m, "VkPhysicalDeviceClusterAccelerationStructurePropertiesNV", p.cluster_accel.map(|s| obj!(s;
        n "maxVerticesPerCluster" max_vertices_per_cluster, n "maxTrianglesPerCluster" max_triangles_per_cluster,
        n "clusterScratchByteAlignment" cluster_scratch_byte_alignment, n "clusterByteAlignment" cluster_byte_alignment,
        n "clusterTemplateByteAlignment" cluster_template_byte_alignment,
        n "clusterBottomLevelByteAlignment" cluster_bottom_level_byte_alignment,
        n "clusterTemplateBoundsByteAlignment" cluster_template_bounds_byte_alignment,
        n "maxClusterGeometryIndex" max_cluster_geometry_index)));
    put(
        m,
        "VkPhysicalDevicePartitionedAccelerationStructurePropertiesNV",
        p.partitioned_accel.map(|s| {
            obj!(s;
        n "maxPartitionCount" max_partition_count)
        }),
    );
    put(
        m,
        "VkPhysicalDeviceOpacityMicromapPropertiesEXT",
        p.opacity_micromap.map(|s| {
            obj!(s;
        n "maxOpacity2StateSubdivisionLevel" max_opacity2_state_subdivision_level,
        n "maxOpacity4StateSubdivisionLevel" max_opacity4_state_subdivision_level)
        }),
    );
    put(
        m,
        "VkPhysicalDeviceOpacityMicromapPropertiesKHR",
        p.opacity_micromap_khr.map(|s| {
            obj!(s;
        n "maxOpacity2StateSubdivisionLevel" max_opacity2_state_subdivision_level,
        n "maxOpacity4StateSubdivisionLevel" max_opacity4_state_subdivision_level,
        n "maxOpacityLossy4StateSubdivisionLevel" max_opacity_lossy4_state_subdivision_level,
        n "maxMicromapTriangles" max_micromap_triangles)
        }),
    );
    put(
        m,
        "VkPhysicalDeviceDisplacementMicromapPropertiesNV",
        p.displacement_micromap.map(|s| {
            obj!(s;
        n "maxDisplacementMicromapSubdivisionLevel" max_displacement_micromap_subdivision_level)
        }),
    );
}

/// Properties and limits, one object per Vulkan struct the device has.
pub fn properties(info: &DeviceInfo) -> Map<String, Value> {
    let p = &info.properties;
    let mut m = Map::new();
    core_properties(p, &mut m);
    pipeline_and_accel_properties(p, &mut m);
    descriptor_properties(p, &mut m);
    rt_extension_properties(info, &mut m);
    m
}

/// The core limits rtprobe relies on, and Vulkan 1.2's descriptor-indexing properties.
fn core_properties(p: &Properties, m: &mut Map<String, Value>) {
    let limits = obj!(p.core.limits;
        n "maxBoundDescriptorSets" max_bound_descriptor_sets, n "maxPushConstantsSize" max_push_constants_size,
        n "maxPerStageDescriptorStorageBuffers" max_per_stage_descriptor_storage_buffers,
        n "maxPerStageDescriptorUniformBuffers" max_per_stage_descriptor_uniform_buffers,
        n "maxPerStageDescriptorSampledImages" max_per_stage_descriptor_sampled_images,
        n "maxPerStageDescriptorStorageImages" max_per_stage_descriptor_storage_images,
        n "maxPerStageResources" max_per_stage_resources,
        n "maxDescriptorSetStorageBuffers" max_descriptor_set_storage_buffers,
        n "maxDescriptorSetSampledImages" max_descriptor_set_sampled_images,
        n "maxStorageBufferRange" max_storage_buffer_range, n "maxUniformBufferRange" max_uniform_buffer_range,
        n "maxImageDimension2D" max_image_dimension2_d,
        n "maxComputeWorkGroupInvocations" max_compute_work_group_invocations,
        n "maxComputeWorkGroupSize" max_compute_work_group_size,
        n "minStorageBufferOffsetAlignment" min_storage_buffer_offset_alignment,
        n "minUniformBufferOffsetAlignment" min_uniform_buffer_offset_alignment,
        n "nonCoherentAtomSize" non_coherent_atom_size, n "timestampPeriod" timestamp_period,
    );
    m.insert("VkPhysicalDeviceProperties".into(), json!({ "limits": limits }));
    put(m, "VkPhysicalDeviceVulkan12Properties", p.v12.map(|s| obj!(s;
        n "maxUpdateAfterBindDescriptorsInAllPools" max_update_after_bind_descriptors_in_all_pools,
        b "shaderUniformBufferArrayNonUniformIndexingNative" shader_uniform_buffer_array_non_uniform_indexing_native,
        b "shaderSampledImageArrayNonUniformIndexingNative" shader_sampled_image_array_non_uniform_indexing_native,
        b "shaderStorageBufferArrayNonUniformIndexingNative" shader_storage_buffer_array_non_uniform_indexing_native,
        b "shaderStorageImageArrayNonUniformIndexingNative" shader_storage_image_array_non_uniform_indexing_native,
        b "robustBufferAccessUpdateAfterBind" robust_buffer_access_update_after_bind,
        n "maxPerStageDescriptorUpdateAfterBindUniformBuffers" max_per_stage_descriptor_update_after_bind_uniform_buffers,
        n "maxPerStageDescriptorUpdateAfterBindStorageBuffers" max_per_stage_descriptor_update_after_bind_storage_buffers,
        n "maxPerStageDescriptorUpdateAfterBindSampledImages" max_per_stage_descriptor_update_after_bind_sampled_images,
        n "maxPerStageDescriptorUpdateAfterBindStorageImages" max_per_stage_descriptor_update_after_bind_storage_images,
        n "maxPerStageUpdateAfterBindResources" max_per_stage_update_after_bind_resources,
        n "maxDescriptorSetUpdateAfterBindUniformBuffers" max_descriptor_set_update_after_bind_uniform_buffers,
        n "maxDescriptorSetUpdateAfterBindStorageBuffers" max_descriptor_set_update_after_bind_storage_buffers,
        n "maxDescriptorSetUpdateAfterBindSampledImages" max_descriptor_set_update_after_bind_sampled_images,
        n "maxDescriptorSetUpdateAfterBindStorageImages" max_descriptor_set_update_after_bind_storage_images,
    )));
}

/// The ray tracing pipeline's and acceleration structures' properties.
fn pipeline_and_accel_properties(p: &Properties, m: &mut Map<String, Value>) {
    put(m, "VkPhysicalDeviceRayTracingPipelinePropertiesKHR", p.rt_pipeline.map(|s| obj!(s;
        n "shaderGroupHandleSize" shader_group_handle_size, n "maxRayRecursionDepth" max_ray_recursion_depth,
        n "maxShaderGroupStride" max_shader_group_stride, n "shaderGroupBaseAlignment" shader_group_base_alignment,
        n "shaderGroupHandleCaptureReplaySize" shader_group_handle_capture_replay_size,
        n "maxRayDispatchInvocationCount" max_ray_dispatch_invocation_count,
        n "shaderGroupHandleAlignment" shader_group_handle_alignment, n "maxRayHitAttributeSize" max_ray_hit_attribute_size,
    )));
    put(m, "VkPhysicalDeviceAccelerationStructurePropertiesKHR", p.accel.map(|s| obj!(s;
        n "maxGeometryCount" max_geometry_count, n "maxInstanceCount" max_instance_count,
        n "maxPrimitiveCount" max_primitive_count,
        n "maxPerStageDescriptorAccelerationStructures" max_per_stage_descriptor_acceleration_structures,
        n "maxPerStageDescriptorUpdateAfterBindAccelerationStructures" max_per_stage_descriptor_update_after_bind_acceleration_structures,
        n "maxDescriptorSetAccelerationStructures" max_descriptor_set_acceleration_structures,
        n "maxDescriptorSetUpdateAfterBindAccelerationStructures" max_descriptor_set_update_after_bind_acceleration_structures,
        n "minAccelerationStructureScratchOffsetAlignment" min_acceleration_structure_scratch_offset_alignment,
    )));
}

/// Descriptor buffer, descriptor heap, pipeline binary and robustness2 properties.
fn descriptor_properties(p: &Properties, m: &mut Map<String, Value>) {
    put(m, "VkPhysicalDeviceDescriptorBufferPropertiesEXT", p.descriptor_buffer.map(|s| obj!(s;
        b "combinedImageSamplerDescriptorSingleArray" combined_image_sampler_descriptor_single_array,
        b "bufferlessPushDescriptors" bufferless_push_descriptors,
        n "descriptorBufferOffsetAlignment" descriptor_buffer_offset_alignment,
        n "maxDescriptorBufferBindings" max_descriptor_buffer_bindings,
        n "maxResourceDescriptorBufferBindings" max_resource_descriptor_buffer_bindings,
        n "maxSamplerDescriptorBufferBindings" max_sampler_descriptor_buffer_bindings,
        n "samplerDescriptorSize" sampler_descriptor_size, n "combinedImageSamplerDescriptorSize" combined_image_sampler_descriptor_size,
        n "sampledImageDescriptorSize" sampled_image_descriptor_size, n "storageImageDescriptorSize" storage_image_descriptor_size,
        n "uniformBufferDescriptorSize" uniform_buffer_descriptor_size, n "storageBufferDescriptorSize" storage_buffer_descriptor_size,
        n "robustUniformBufferDescriptorSize" robust_uniform_buffer_descriptor_size,
        n "robustStorageBufferDescriptorSize" robust_storage_buffer_descriptor_size,
        n "accelerationStructureDescriptorSize" acceleration_structure_descriptor_size,
        n "maxSamplerDescriptorBufferRange" max_sampler_descriptor_buffer_range,
        n "maxResourceDescriptorBufferRange" max_resource_descriptor_buffer_range,
        n "resourceDescriptorBufferAddressSpaceSize" resource_descriptor_buffer_address_space_size,
        n "descriptorBufferAddressSpaceSize" descriptor_buffer_address_space_size,
    )));
    put(m, "VkPhysicalDeviceDescriptorHeapPropertiesEXT", p.descriptor_heap.map(|s| obj!(s;
        n "samplerHeapAlignment" sampler_heap_alignment, n "resourceHeapAlignment" resource_heap_alignment,
        n "maxSamplerHeapSize" max_sampler_heap_size, n "maxResourceHeapSize" max_resource_heap_size,
        n "imageDescriptorSize" image_descriptor_size, n "bufferDescriptorSize" buffer_descriptor_size,
        n "samplerDescriptorSize" sampler_descriptor_size,
        n "samplerDescriptorAlignment" sampler_descriptor_alignment, n "imageDescriptorAlignment" image_descriptor_alignment,
        n "bufferDescriptorAlignment" buffer_descriptor_alignment,
        n "minSamplerHeapReservedRange" min_sampler_heap_reserved_range,
        n "minSamplerHeapReservedRangeWithEmbedded" min_sampler_heap_reserved_range_with_embedded,
        n "minResourceHeapReservedRange" min_resource_heap_reserved_range,
        n "maxPushDataSize" max_push_data_size,
    )));
    put(m, "VkPhysicalDevicePipelineBinaryPropertiesKHR", p.pipeline_binary.map(|s| obj!(s;
        b "pipelineBinaryInternalCache" pipeline_binary_internal_cache,
        b "pipelineBinaryInternalCacheControl" pipeline_binary_internal_cache_control,
        b "pipelineBinaryPrefersInternalCache" pipeline_binary_prefers_internal_cache,
        b "pipelineBinaryPrecompiledInternalCache" pipeline_binary_precompiled_internal_cache,
        b "pipelineBinaryCompressedData" pipeline_binary_compressed_data,
    )));
    put(m, "VkPhysicalDeviceRobustness2PropertiesEXT", p.robustness2.map(|s| obj!(s;
        n "robustStorageBufferAccessSizeAlignment" robust_storage_buffer_access_size_alignment,
        n "robustUniformBufferAccessSizeAlignment" robust_uniform_buffer_access_size_alignment,
    )));
}
