//! What the matrix can run on a device, per axis value, decided from the queried features only.
//! `Unsupported` is said only when the device's features or extensions say so; `NotImplemented`
//! marks what rtprobe itself cannot do yet, which is never blamed on the device.
use crate::model::registry::AxisId;
use crate::model::{
    AsAccess, BaseSource, Canary, DescriptorModel, HeapAccess, IndexSource, Mutant, Reorder,
    Resource, SamplerIndex, SceneLayout, Stage, Workaround,
};
use crate::vk::{heap, DeviceInfo};
use ash::{ext, khr, nv, vk};
use serde::Serialize;

#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
#[serde(tag = "status", rename_all = "snake_case")]
pub enum Support {
    Supported,
    Unsupported { reason: String },
    NotImplemented { reason: String },
}

impl Support {
    pub fn is_supported(&self) -> bool {
        matches!(self, Support::Supported)
    }

    fn require(checks: &[(bool, &str)]) -> Support {
        let missing: Vec<&str> =
            checks.iter().filter(|(ok, _)| !ok).map(|(_, what)| *what).collect();
        if missing.is_empty() {
            Support::Supported
        } else {
            Support::Unsupported { reason: format!("device lacks {}", missing.join(", ")) }
        }
    }

    /// The first non-supported of several, or `Supported`.
    pub fn all(items: impl IntoIterator<Item = Support>) -> Support {
        items.into_iter().find(|s| !s.is_supported()).unwrap_or(Support::Supported)
    }
}

fn on(b: vk::Bool32) -> bool {
    b == vk::TRUE
}

pub fn stage(info: &DeviceInfo, s: Stage) -> Support {
    match s {
        Stage::Raygen
        | Stage::ClosestHit
        | Stage::AnyHit
        | Stage::Miss
        | Stage::Intersection
        | Stage::Callable => {
            let missing = info.rt_pipeline_missing();
            if missing.is_empty() {
                Support::Supported
            } else {
                Support::Unsupported { reason: format!("device lacks {}", missing.join(", ")) }
            }
        }
        Stage::Fragment => Support::require(&[
            (info.universal_queue_family().is_some(), "a graphics queue"),
            (on(info.features.core.fragment_stores_and_atomics), "fragmentStoresAndAtomics"),
            (info.features.v13.is_some_and(|v| on(v.dynamic_rendering)), "dynamicRendering"),
        ]),
        // Compute shaders and storage buffers are core Vulkan 1.0.
        Stage::Compute => Support::Supported,
    }
}

pub fn resource(info: &DeviceInfo, r: Resource) -> Support {
    let fmt = info.probe_image_format.optimal_tiling_features;
    match r {
        Resource::StorageBuffer | Resource::UniformBuffer => Support::Supported,
        Resource::SampledImage => Support::require(&[(
            fmt.contains(vk::FormatFeatureFlags::SAMPLED_IMAGE),
            "sampled R32G32B32A32_SFLOAT images",
        )]),
        Resource::StorageImage => Support::require(&[(
            fmt.contains(vk::FormatFeatureFlags::STORAGE_IMAGE),
            "storage R32G32B32A32_SFLOAT images",
        )]),
        Resource::AccelerationStructure => Support::require(&[(
            info.features.accel.is_some_and(|a| on(a.acceleration_structure)),
            "accelerationStructure (VK_KHR_acceleration_structure)",
        )]),
    }
}

/// Dynamic (runtime) indexing of an array of `r`, with or without `nonuniformEXT`.
pub fn dynamic_index(info: &DeviceInfo, r: Resource, nonuniform: bool) -> Support {
    let c = &info.features.core;
    let v12 = info.features.v12.unwrap_or_default();
    let (dynamic, nu, name) = match r {
        Resource::StorageBuffer => (
            c.shader_storage_buffer_array_dynamic_indexing,
            v12.shader_storage_buffer_array_non_uniform_indexing,
            "StorageBuffer",
        ),
        Resource::UniformBuffer => (
            c.shader_uniform_buffer_array_dynamic_indexing,
            v12.shader_uniform_buffer_array_non_uniform_indexing,
            "UniformBuffer",
        ),
        Resource::SampledImage => (
            c.shader_sampled_image_array_dynamic_indexing,
            v12.shader_sampled_image_array_non_uniform_indexing,
            "SampledImage",
        ),
        Resource::StorageImage => (
            c.shader_storage_image_array_dynamic_indexing,
            v12.shader_storage_image_array_non_uniform_indexing,
            "StorageImage",
        ),
        // Arrays of acceleration structures: dynamic indexing is always allowed; non-uniform
        // indexing has no feature bit of its own in VK_KHR_acceleration_structure.
        Resource::AccelerationStructure => (vk::TRUE, vk::TRUE, "AccelerationStructure"),
    };
    let dyn_name = format!("shader{name}ArrayDynamicIndexing");
    let nu_name = format!("shader{name}ArrayNonUniformIndexing");
    let mut checks = vec![
        (on(v12.runtime_descriptor_array), "runtimeDescriptorArray"),
        (on(dynamic), dyn_name.as_str()),
    ];
    if nonuniform {
        checks.push((on(nu), nu_name.as_str()));
    }
    Support::require(&checks)
}

pub fn index(info: &DeviceInfo, i: IndexSource) -> Support {
    match i {
        // dynamic_element indexes the descriptor array with a spec constant: no dynamic indexing.
        IndexSource::Literal
        | IndexSource::SpecConstant
        | IndexSource::PushConstant
        | IndexSource::DynamicElement => Support::Supported,
        IndexSource::Dynamic => {
            // Supported as an axis value when at least one resource kind can be indexed dynamically.
            let any = Resource::ALL.iter().any(|r| dynamic_index(info, *r, false).is_supported());
            if any {
                Support::Supported
            } else {
                dynamic_index(info, Resource::StorageBuffer, false)
            }
        }
    }
}

/// Loads through a raw device address (`--inject-fault` device/flaky): bufferDeviceAddress and
/// shaderInt64.
pub fn device_address_loads(info: &DeviceInfo) -> Support {
    let v12 = info.features.v12.unwrap_or_default();
    Support::require(&[
        (on(v12.buffer_device_address), "bufferDeviceAddress"),
        (on(info.features.core.shader_int64), "shaderInt64"),
    ])
}

pub fn as_access(info: &DeviceInfo, a: AsAccess) -> Support {
    let accel = info.features.accel.is_some_and(|x| on(x.acceleration_structure));
    let v12 = info.features.v12.unwrap_or_default();
    match a {
        AsAccess::Descriptor => Support::require(&[(accel, "accelerationStructure")]),
        AsAccess::Address | AsAccess::AddressPatched => Support::require(&[
            (accel, "accelerationStructure"),
            (on(v12.buffer_device_address), "bufferDeviceAddress"),
            (on(info.features.core.shader_int64), "shaderInt64"),
        ]),
    }
}

pub fn descriptor_model(info: &DeviceInfo, m: DescriptorModel) -> Support {
    let v12 = info.features.v12.unwrap_or_default();
    match m {
        DescriptorModel::DescriptorIndexing => Support::require(&[
            (on(v12.runtime_descriptor_array), "runtimeDescriptorArray"),
            (on(v12.descriptor_binding_partially_bound), "descriptorBindingPartiallyBound"),
        ]),
        DescriptorModel::DescriptorBuffer => {
            if !info.has_extension(ext::descriptor_buffer::NAME) {
                return Support::Unsupported {
                    reason: "driver does not expose VK_EXT_descriptor_buffer".into(),
                };
            }
            Support::require(&[
                (
                    info.features.descriptor_buffer.is_some_and(|d| on(d.descriptor_buffer)),
                    "descriptorBuffer",
                ),
                (on(v12.buffer_device_address), "bufferDeviceAddress"),
            ])
        }
        DescriptorModel::DescriptorHeap => {
            if !info.has_extension(heap::NAME) {
                return Support::Unsupported {
                    reason: "driver does not expose VK_EXT_descriptor_heap".into(),
                };
            }
            // rtprobe's instance is Vulkan 1.3, so maintenance5 (which heaps need) must be listed.
            Support::require(&[
                (
                    info.features.descriptor_heap.is_some_and(|d| on(d.descriptor_heap)),
                    "descriptorHeap",
                ),
                (info.has_extension(khr::maintenance5::NAME), "VK_KHR_maintenance5"),
                (on(v12.buffer_device_address), "bufferDeviceAddress"),
            ])
        }
    }
}

/// Shader execution reordering in raygen: GL_NV_shader_invocation_reorder needs
/// VK_NV_ray_tracing_invocation_reorder with `rayTracingInvocationReorder`. Both values of the
/// axis need the same; a driver whose hint is `NONE` still runs them (reordering is then a no-op,
/// which the spec allows).
pub fn reorder(info: &DeviceInfo, r: Reorder) -> Support {
    match r {
        Reorder::Reorder | Reorder::ReorderHint => {
            if !info.has_extension(nv::ray_tracing_invocation_reorder::NAME) {
                return Support::Unsupported {
                    reason: "driver does not expose VK_NV_ray_tracing_invocation_reorder".into(),
                };
            }
            Support::require(&[(
                info.features
                    .invocation_reorder_nv
                    .is_some_and(|f| on(f.ray_tracing_invocation_reorder)),
                "rayTracingInvocationReorder (VK_NV_ray_tracing_invocation_reorder)",
            )])
        }
    }
}

/// Where a closest-hit dynamic index's base comes from. The shader record needs nothing beyond the
/// ray tracing pipeline; the buffer is read through a device address (`GL_EXT_buffer_reference`
/// with a `uvec2` address, so no 64-bit integers).
pub fn base(info: &DeviceInfo, b: BaseSource) -> Support {
    match b {
        BaseSource::ShaderRecord => Support::Supported,
        BaseSource::Buffer => Support::require(&[(
            on(info.features.v12.unwrap_or_default().buffer_device_address),
            "bufferDeviceAddress",
        )]),
    }
}

/// How a heap cell's shaders reach the heap. The mapped ways need nothing beyond the heap
/// itself; `direct` (GLSL with `layout(descriptor_heap)`) needs untyped pointers on the device and
/// a GLSL compiler with GL_EXT_descriptor_heap on this machine (its absence is rtprobe's gap here,
/// not the device's).
pub fn heap_access(info: &DeviceInfo, h: HeapAccess) -> Support {
    match h {
        HeapAccess::MappedConstantOffset
        | HeapAccess::MappedPushIndex
        | HeapAccess::MappedIndirectIndex
        | HeapAccess::MappedShaderRecordIndex => Support::Supported,
        HeapAccess::Direct => match Support::require(&[(
            info.features.untyped_pointers.is_some_and(|u| on(u.shader_untyped_pointers)),
            "shaderUntypedPointers (VK_KHR_shader_untyped_pointers)",
        )]) {
            Support::Supported if crate::shadergen::glslang::find().is_none() => {
                Support::NotImplemented { reason: crate::shadergen::glslang::missing_reason() }
            }
            other => other,
        },
    }
}

/// The support of one value of one registry axis (`caps`'s matrix): the device's reasons for the
/// axes whose values need something of it, `Supported` for stand-ins and values that need
/// nothing. `nonuniform=true` is supported when some resource kind can be indexed with it (as
/// `index=dynamic`); `sampler=*` needs what `heap_access=direct` needs, `sampler=dynamic` also
/// dynamic indexing of sampled images. A cell's own support (`matrix::plan::device_support`) is
/// decided per cell.
pub fn value(info: &DeviceInfo, axis: AxisId, v: &str) -> Support {
    let of = |s: Option<Support>| s.unwrap_or(Support::Supported);
    match axis {
        AxisId::Stage => of(Stage::parse(v).map(|s| stage(info, s))),
        AxisId::Resource => of(Resource::parse(v).map(|r| resource(info, r))),
        AxisId::Index => of(IndexSource::parse(v).map(|i| index(info, i))),
        // As `index=dynamic`: supported as a value when some resource kind can be indexed with
        // it (each cell's own support is decided per cell).
        AxisId::Nonuniform => match v {
            "true" => Resource::ALL
                .iter()
                .map(|r| dynamic_index(info, *r, true))
                .find(Support::is_supported)
                .unwrap_or_else(|| dynamic_index(info, Resource::StorageBuffer, true)),
            _ => Support::Supported,
        },
        AxisId::AsAccess => of(AsAccess::parse(v).map(|a| as_access(info, a))),
        AxisId::DescriptorModel => of(DescriptorModel::parse(v).map(|m| descriptor_model(info, m))),
        AxisId::HeapAccess => of(HeapAccess::parse(v).map(|h| {
            Support::all([
                descriptor_model(info, DescriptorModel::DescriptorHeap),
                heap_access(info, h),
            ])
        })),
        AxisId::Canary => match Canary::parse(v) {
            Some(Canary::InvalidAddress) => device_address_loads(info),
            Some(Canary::InfiniteLoop) | None => Support::Supported,
        },
        AxisId::Reorder => of(Reorder::parse(v).map(|r| reorder(info, r))),
        AxisId::Base => of(BaseSource::parse(v).map(|b| base(info, b))),
        // Sampler indices exist only on direct heap cells: the heap_access=direct row's reasons
        // first.
        AxisId::Sampler => {
            let direct = value(info, AxisId::HeapAccess, HeapAccess::Direct.as_str());
            match SamplerIndex::parse(v) {
                Some(SamplerIndex::Constant) => direct,
                Some(SamplerIndex::Dynamic) => {
                    Support::all([direct, dynamic_index(info, Resource::SampledImage, true)])
                }
                None => Support::Supported,
            }
        }
        AxisId::Patch => match Workaround::parse(v) {
            Some(Workaround::AsToAddress | Workaround::SsboToAddress) => {
                as_access(info, AsAccess::Address)
            }
            Some(Workaround::Nonuniform | Workaround::PinIndex) | None => Support::Supported,
        },
        AxisId::Mutant => of(Mutant::parse(v).map(|m| mutant(info, m, None))),
        AxisId::SceneLayout => of(SceneLayout::parse(v).map(|l| scene_layout(info, l))),
    }
}

/// A scene layout: `shared_buffers` loads through device addresses (`uvec2` buffer references, no
/// 64-bit integers), `per_mesh` indexes a storage-buffer array non-uniformly.
pub fn scene_layout(info: &DeviceInfo, l: SceneLayout) -> Support {
    match l {
        SceneLayout::SharedBuffers => base(info, BaseSource::Buffer),
        SceneLayout::PerMesh => dynamic_index(info, Resource::StorageBuffer, true),
    }
}

/// What a mutant needs of the device beyond what its cell needs, in the cell's `stage` (`None`:
/// in some stage, for `caps`'s matrix). Only `index-broadcast` needs something:
/// `OpGroupNonUniformBroadcastFirst` is a subgroup ballot operation, allowed only in the stages
/// the device lists (VUID-RuntimeSpirv-None-06343), and its prediction reads the lane evidence,
/// which needs the same.
pub fn mutant(info: &DeviceInfo, m: Mutant, stage: Option<Stage>) -> Support {
    match m {
        Mutant::IndexBroadcast => {
            let ok = match stage {
                Some(s) => info.subgroup_ballot(s),
                None => Stage::ALL.iter().any(|s| info.subgroup_ballot(*s)),
            };
            let where_ = stage.map(|s| format!("in {s}")).unwrap_or_else(|| "in any stage".into());
            Support::require(&[(
                ok,
                &format!("subgroup ballot {where_} (subgroupSupportedStages, subgroupSupportedOperations BALLOT; {})", crate::model::lanes::SUBGROUP_STAGE_VUID),
            )])
        }
        Mutant::IndexZero
        | Mutant::IndexNext
        | Mutant::BaseDropped
        | Mutant::ElementZero
        | Mutant::StrideDouble
        | Mutant::SamplerNext
        | Mutant::TlasOther
        | Mutant::ValueBits => Support::Supported,
    }
}
