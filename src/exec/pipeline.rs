//! Pipelines of a cell: ray tracing (with its shader binding table), graphics (fragment probes,
//! dynamic rendering, one quad per tile) or compute. The group layout of every RT pipeline is
//! fixed: raygen; miss 0 (primary), miss 1 (AS probe ray); hit group 0 triangles, hit group 1
//! procedural (intersection); callable 0 when the callable stage is probed. Heap pipelines (see
//! [`super::heap`]) have no layout, the descriptor-heap create flag, the set/binding mapping on
//! every stage, and shader record data after each SBT handle where their mapping reads it.
use super::heap::PipelineMapping;
use crate::model::DescriptorModel;
use crate::probe;
use crate::shadergen::{CellShaders, PipelineKind, Role};
use crate::vk::memory::{Buffer, Location};
use crate::vk::{Gpu, VkError};
use ash::vk;
use std::ffi::CStr;

pub const COLOR_FORMAT: vk::Format = vk::Format::R8G8B8A8_UNORM;

pub struct Sbt {
    buffer: Buffer,
    pub raygen: vk::StridedDeviceAddressRegionKHR,
    pub miss: vk::StridedDeviceAddressRegionKHR,
    pub hit: vk::StridedDeviceAddressRegionKHR,
    pub callable: vk::StridedDeviceAddressRegionKHR,
}

pub struct Pipeline {
    pub raw: vk::Pipeline,
    pub kind: PipelineKind,
    pub sbt: Option<Sbt>,
}

fn align(x: u64, a: u64) -> u64 {
    x.div_ceil(a.max(1)) * a.max(1)
}

const MAIN: &CStr = c"main";

fn stage_flag(role: Role) -> vk::ShaderStageFlags {
    match role {
        Role::Raygen => vk::ShaderStageFlags::RAYGEN_KHR,
        Role::Miss | Role::ProbeMiss => vk::ShaderStageFlags::MISS_KHR,
        Role::ClosestHitTriangles | Role::ClosestHitProcedural => {
            vk::ShaderStageFlags::CLOSEST_HIT_KHR
        }
        Role::Intersection => vk::ShaderStageFlags::INTERSECTION_KHR,
        Role::AnyHit => vk::ShaderStageFlags::ANY_HIT_KHR,
        Role::Callable => vk::ShaderStageFlags::CALLABLE_KHR,
        Role::Vertex => vk::ShaderStageFlags::VERTEX,
        Role::Fragment => vk::ShaderStageFlags::FRAGMENT,
        Role::Compute => vk::ShaderStageFlags::COMPUTE,
    }
}

/// The shader record data after each SBT group's handle: the two hit groups', and the one every
/// other group (raygen, miss, callable) carries. All the same length, or all empty.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ShaderRecords {
    pub other: Vec<u8>,
    pub hit_triangles: Vec<u8>,
    pub hit_procedural: Vec<u8>,
}

/// The shader record data of `cell`'s ray tracing pipeline ([`probe::ShaderRecordData`] after
/// every handle): the probed array's heap index where the heap mapping reads it
/// (`heap_access=mapped_shader_record_index`, `heap` laid out so; the same in every record) and
/// the runtime base where the probe reads it (`base=shader_record`; the hit groups' bases differ
/// from each other and from the other groups', `probe::RECORD_BASE_*`); no data when neither does.
pub fn shader_records(
    spec: &crate::probe::spec::ProbeSpec,
    heap: Option<&super::heap::HeapLayout>,
) -> ShaderRecords {
    let mapped = spec.heap == Some(crate::model::HeapAccess::MappedShaderRecordIndex);
    let base = spec.base == crate::probe::spec::Base::ShaderRecord;
    if !mapped && !base {
        return ShaderRecords::default();
    }
    let heap_index = if mapped { heap.map(|l| l.probe_index()).unwrap_or(0) } else { 0 };
    let record = |dyn_base: u32| probe::ShaderRecordData { heap_index, dyn_base }.to_bytes();
    ShaderRecords {
        other: record(probe::RECORD_BASE_OTHER),
        hit_triangles: record(probe::RECORD_BASE_TRIANGLES),
        hit_procedural: record(probe::RECORD_BASE_PROCEDURAL),
    }
}

/// One `VkShaderModule` per SPIR-V module, all or none.
pub fn shader_modules(gpu: &Gpu, spirv: &[&[u32]]) -> Result<Vec<vk::ShaderModule>, VkError> {
    let d = &gpu.device;
    let mut modules = Vec::new();
    for words in spirv {
        match unsafe {
            d.create_shader_module(&vk::ShaderModuleCreateInfo::default().code(words), None)
        } {
            Ok(m) => modules.push(m),
            Err(e) => {
                for m in &modules {
                    unsafe { d.destroy_shader_module(*m, None) };
                }
                return Err(VkError::from_result("vkCreateShaderModule", e));
            }
        }
    }
    Ok(modules)
}

/// Create the pipeline for `shaders` (SPIR-V in `spirv`, same order), specializing constant 0 to
/// `probe::SPEC_SLOT` in every stage. `heap` (the set/binding → heap mapping chained to each
/// stage) is `Some` exactly for the descriptor_heap model; `records` is the shader record data
/// written after each SBT handle (ray tracing pipelines).
#[allow(clippy::too_many_arguments)]
pub fn create(
    gpu: &Gpu,
    cache: vk::PipelineCache,
    shaders: &CellShaders,
    spirv: &[std::sync::Arc<Vec<u32>>],
    layout: vk::PipelineLayout,
    model: DescriptorModel,
    heap: Option<&PipelineMapping>,
    records: &ShaderRecords,
) -> Result<Pipeline, VkError> {
    let d = &gpu.device;
    let words: Vec<&[u32]> = spirv.iter().map(|w| w.as_slice()).collect();
    let modules = shader_modules(gpu, &words)?;
    let spec_data = probe::SPEC_SLOT.to_le_bytes();
    let spec_entries = [vk::SpecializationMapEntry { constant_id: 0, offset: 0, size: 4 }];
    let spec = vk::SpecializationInfo::default().map_entries(&spec_entries).data(&spec_data);
    let stages: Vec<vk::PipelineShaderStageCreateInfo> = shaders
        .shaders
        .iter()
        .zip(&modules)
        .map(|(s, m)| {
            let mut st = vk::PipelineShaderStageCreateInfo::default()
                .stage(stage_flag(s.role))
                .module(*m)
                .name(MAIN)
                .specialization_info(&spec);
            if let Some(h) = heap {
                st.p_next = h.stage_next();
            }
            st
        })
        .collect();
    let flags = if model == DescriptorModel::DescriptorBuffer {
        vk::PipelineCreateFlags::DESCRIPTOR_BUFFER_EXT
    } else {
        vk::PipelineCreateFlags::empty()
    };
    // Heap pipelines: VK_PIPELINE_CREATE_2_DESCRIPTOR_HEAP_BIT_EXT, which only the flags2 struct carries.
    let mut flags2 = vk::PipelineCreateFlags2CreateInfoKHR::default()
        .flags(crate::vk::heap::PIPELINE_CREATE_2_DESCRIPTOR_HEAP);
    let flags2 = heap.is_some().then_some(&mut flags2);
    let result = match shaders.kind {
        PipelineKind::RayTracing => {
            create_rt(gpu, cache, shaders, &stages, layout, flags, flags2, records)
        }
        PipelineKind::Compute => {
            let mut ci = vk::ComputePipelineCreateInfo::default()
                .stage(stages[0])
                .layout(layout)
                .flags(flags);
            if let Some(f2) = flags2 {
                ci = ci.push_next(f2);
            }
            unsafe { d.create_compute_pipelines(cache, &[ci], None) }
                .map_err(|(_, e)| VkError::from_result("vkCreateComputePipelines", e))
                .map(|p| Pipeline { raw: p[0], kind: PipelineKind::Compute, sbt: None })
        }
        PipelineKind::Graphics => create_graphics(gpu, cache, &stages, layout, flags, flags2),
    };
    for m in &modules {
        unsafe { d.destroy_shader_module(*m, None) };
    }
    result
}

fn create_graphics(
    gpu: &Gpu,
    cache: vk::PipelineCache,
    stages: &[vk::PipelineShaderStageCreateInfo],
    layout: vk::PipelineLayout,
    flags: vk::PipelineCreateFlags,
    flags2: Option<&mut vk::PipelineCreateFlags2CreateInfoKHR>,
) -> Result<Pipeline, VkError> {
    let formats = [COLOR_FORMAT];
    let mut rendering =
        vk::PipelineRenderingCreateInfo::default().color_attachment_formats(&formats);
    let vi = vk::PipelineVertexInputStateCreateInfo::default();
    let ia = vk::PipelineInputAssemblyStateCreateInfo::default()
        .topology(vk::PrimitiveTopology::TRIANGLE_LIST);
    let vp = vk::PipelineViewportStateCreateInfo::default().viewport_count(1).scissor_count(1);
    let rs = vk::PipelineRasterizationStateCreateInfo::default()
        .polygon_mode(vk::PolygonMode::FILL)
        .cull_mode(vk::CullModeFlags::NONE)
        .line_width(1.0);
    let ms = vk::PipelineMultisampleStateCreateInfo::default()
        .rasterization_samples(vk::SampleCountFlags::TYPE_1);
    let att = [vk::PipelineColorBlendAttachmentState::default()
        .color_write_mask(vk::ColorComponentFlags::RGBA)];
    let cb = vk::PipelineColorBlendStateCreateInfo::default().attachments(&att);
    let dyn_states = [vk::DynamicState::VIEWPORT, vk::DynamicState::SCISSOR];
    let ds = vk::PipelineDynamicStateCreateInfo::default().dynamic_states(&dyn_states);
    let mut ci = vk::GraphicsPipelineCreateInfo::default()
        .flags(flags)
        .stages(stages)
        .vertex_input_state(&vi)
        .input_assembly_state(&ia)
        .viewport_state(&vp)
        .rasterization_state(&rs)
        .multisample_state(&ms)
        .color_blend_state(&cb)
        .dynamic_state(&ds)
        .layout(layout)
        .push_next(&mut rendering);
    if let Some(f2) = flags2 {
        ci = ci.push_next(f2);
    }
    unsafe { gpu.device.create_graphics_pipelines(cache, &[ci], None) }
        .map_err(|(_, e)| VkError::from_result("vkCreateGraphicsPipelines", e))
        .map(|p| Pipeline { raw: p[0], kind: PipelineKind::Graphics, sbt: None })
}

/// The shader groups in SBT order: raygen, miss, probe miss, the triangle and procedural hit
/// groups, then the callable (when the cell has one).
fn rt_groups(shaders: &CellShaders) -> Vec<vk::RayTracingShaderGroupCreateInfoKHR<'static>> {
    let idx = |r: Role| {
        shaders
            .shaders
            .iter()
            .position(|s| s.role == r)
            .map(|i| i as u32)
            .unwrap_or(vk::SHADER_UNUSED_KHR)
    };
    let general = |r: Role| {
        vk::RayTracingShaderGroupCreateInfoKHR::default()
            .ty(vk::RayTracingShaderGroupTypeKHR::GENERAL)
            .general_shader(idx(r))
            .closest_hit_shader(vk::SHADER_UNUSED_KHR)
            .any_hit_shader(vk::SHADER_UNUSED_KHR)
            .intersection_shader(vk::SHADER_UNUSED_KHR)
    };
    let mut groups = vec![
        general(Role::Raygen),
        general(Role::Miss),
        general(Role::ProbeMiss),
        vk::RayTracingShaderGroupCreateInfoKHR::default()
            .ty(vk::RayTracingShaderGroupTypeKHR::TRIANGLES_HIT_GROUP)
            .general_shader(vk::SHADER_UNUSED_KHR)
            .closest_hit_shader(idx(Role::ClosestHitTriangles))
            .any_hit_shader(idx(Role::AnyHit))
            .intersection_shader(vk::SHADER_UNUSED_KHR),
        vk::RayTracingShaderGroupCreateInfoKHR::default()
            .ty(vk::RayTracingShaderGroupTypeKHR::PROCEDURAL_HIT_GROUP)
            .general_shader(vk::SHADER_UNUSED_KHR)
            .closest_hit_shader(idx(Role::ClosestHitProcedural))
            .any_hit_shader(idx(Role::AnyHit))
            .intersection_shader(idx(Role::Intersection)),
    ];
    if shaders.get(Role::Callable).is_some() {
        groups.push(general(Role::Callable));
    }
    groups
}

// One RT pipeline's inputs, each a distinct Vulkan object or table.
#[allow(clippy::too_many_arguments)]
fn create_rt(
    gpu: &Gpu,
    cache: vk::PipelineCache,
    shaders: &CellShaders,
    stages: &[vk::PipelineShaderStageCreateInfo],
    layout: vk::PipelineLayout,
    flags: vk::PipelineCreateFlags,
    flags2: Option<&mut vk::PipelineCreateFlags2CreateInfoKHR>,
    records: &ShaderRecords,
) -> Result<Pipeline, VkError> {
    let groups = rt_groups(shaders);
    // Group order: raygen, miss, probe miss, triangle hits, procedural hits, callable.
    let record = |g: usize| match g {
        3 => records.hit_triangles.as_slice(),
        4 => records.hit_procedural.as_slice(),
        _ => records.other.as_slice(),
    };
    let counts = sbt_counts(shaders);
    let rt = RtPipeline { stages, groups: &groups, counts, depth: shaders.recursion_depth, layout };
    create_rt_pipeline(gpu, cache, &rt, flags, flags2, &record)
}

/// The groups of a cell's SBT after raygen: miss and probe miss, the two hit groups, and the
/// callable where the cell has one ([`rt_groups`]'s order).
pub fn sbt_counts(shaders: &CellShaders) -> SbtCounts {
    SbtCounts { miss: 2, hit: 2, callable: shaders.get(Role::Callable).is_some() as u32 }
}

/// How many groups each SBT region holds after the raygen group (groups in that order).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SbtCounts {
    pub miss: u32,
    pub hit: u32,
    pub callable: u32,
}

/// A ray tracing pipeline's parts: stages, groups (raygen, misses, hits, callables, as
/// `counts` says), recursion depth and layout.
pub struct RtPipeline<'a> {
    pub stages: &'a [vk::PipelineShaderStageCreateInfo<'a>],
    pub groups: &'a [vk::RayTracingShaderGroupCreateInfoKHR<'a>],
    pub counts: SbtCounts,
    pub depth: u32,
    pub layout: vk::PipelineLayout,
}

/// Create the RT pipeline `p` and its SBT, each group's record its handle then `record(group)`
/// (all records the same length). Used by the cells' pipelines and the user-shader harness.
pub fn create_rt_pipeline<'r>(
    gpu: &Gpu,
    cache: vk::PipelineCache,
    p: &RtPipeline,
    flags: vk::PipelineCreateFlags,
    flags2: Option<&mut vk::PipelineCreateFlags2CreateInfoKHR>,
    record: &dyn Fn(usize) -> &'r [u8],
) -> Result<Pipeline, VkError> {
    let rt = gpu.rt.as_ref().expect("ray tracing pipeline enabled");
    let mut ci = vk::RayTracingPipelineCreateInfoKHR::default()
        .flags(flags)
        .stages(p.stages)
        .groups(p.groups)
        .max_pipeline_ray_recursion_depth(p.depth)
        .layout(p.layout);
    if let Some(f2) = flags2 {
        ci = ci.push_next(f2);
    }
    let raw = unsafe {
        rt.create_ray_tracing_pipelines(vk::DeferredOperationKHR::null(), cache, &[ci], None)
    }
    .map_err(|(_, e)| VkError::from_result("vkCreateRayTracingPipelinesKHR", e))?[0];
    let sbt = shader_binding_table(gpu, raw, p.counts, record)?;
    Ok(Pipeline { raw, kind: PipelineKind::RayTracing, sbt: Some(sbt) })
}

/// Where an SBT's regions sit (bytes from its base), as [`sbt_layout`] computes them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SbtLayout {
    /// Every record's stride: the handle and its shader record data, aligned to
    /// `shaderGroupHandleAlignment`.
    pub stride: u64,
    /// The raygen region's size (and stride): one record aligned to `shaderGroupBaseAlignment`.
    pub raygen_size: u64,
    pub miss_off: u64,
    pub hit_off: u64,
    pub call_off: u64,
    /// The buffer's size, with room to align its base.
    pub total: u64,
}

/// The SBT layout of `counts` groups after the raygen group, each record a `handle`-byte handle
/// then `record` bytes of shader record data, for the device's handle and base alignments (`ha`,
/// `ba`): what the worker writes, and what the vendor issue says it wrote.
pub fn sbt_layout(counts: SbtCounts, handle: u64, ha: u64, ba: u64, record: u64) -> SbtLayout {
    let rec = handle + record;
    let stride = align(rec, ha);
    let raygen_size = align(rec, ba);
    let miss_off = align(raygen_size, ba);
    let hit_off = align(miss_off + counts.miss as u64 * stride, ba);
    let call_off = align(hit_off + counts.hit as u64 * stride, ba);
    let total = call_off + counts.callable.max(1) as u64 * stride + ba;
    SbtLayout { stride, raygen_size, miss_off, hit_off, call_off, total }
}

/// The SBT of pipeline `raw`: the raygen group, then `counts` miss, hit and callable groups, each
/// record the group's handle then `record(group)`. The pipeline is destroyed when its handles
/// cannot be read.
fn shader_binding_table<'r>(
    gpu: &Gpu,
    raw: vk::Pipeline,
    counts: SbtCounts,
    record: &dyn Fn(usize) -> &'r [u8],
) -> Result<Sbt, VkError> {
    let rt = gpu.rt.as_ref().expect("ray tracing pipeline enabled");
    let props = gpu.info.properties.rt_pipeline.expect("RT pipeline properties");
    let h = props.shader_group_handle_size as u64;
    let ha = props.shader_group_handle_alignment as u64;
    let ba = props.shader_group_base_alignment as u64;
    let n = 1 + counts.miss + counts.hit + counts.callable;
    let handles = match unsafe {
        rt.get_ray_tracing_shader_group_handles(raw, 0, n, (n as u64 * h) as usize)
    } {
        Ok(h) => h,
        Err(e) => {
            unsafe { gpu.device.destroy_pipeline(raw, None) };
            return Err(VkError::from_result("vkGetRayTracingShaderGroupHandlesKHR", e));
        }
    };
    let SbtLayout { stride, raygen_size: rg_size, miss_off, hit_off, call_off, total } =
        sbt_layout(counts, h, ha, ba, record(0).len() as u64);
    let buffer = Buffer::new(
        gpu,
        total,
        vk::BufferUsageFlags::SHADER_BINDING_TABLE_KHR
            | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS,
        Location::Host,
        "shader binding table",
    )?;
    let base = align(buffer.address, ba);
    let shift = (base - buffer.address) as usize;
    let handle = |g: usize| &handles[g * h as usize..(g + 1) * h as usize];
    let put = |off: u64, g: usize| {
        buffer.write(shift + off as usize, handle(g));
        buffer.write(shift + (off + h) as usize, record(g));
    };
    put(0, 0);
    let mut g = 1;
    for (off, count) in
        [(miss_off, counts.miss), (hit_off, counts.hit), (call_off, counts.callable)]
    {
        for k in 0..count as u64 {
            put(off + k * stride, g);
            g += 1;
        }
    }
    let region = |off: u64, count: u32| match count {
        0 => vk::StridedDeviceAddressRegionKHR::default(),
        n => vk::StridedDeviceAddressRegionKHR {
            device_address: base + off,
            stride,
            size: n as u64 * stride,
        },
    };
    Ok(Sbt {
        raygen: vk::StridedDeviceAddressRegionKHR {
            device_address: base,
            stride: rg_size,
            size: rg_size,
        },
        miss: region(miss_off, counts.miss),
        hit: region(hit_off, counts.hit),
        callable: region(call_off, counts.callable),
        buffer,
    })
}

impl Pipeline {
    pub fn destroy(&self, gpu: &Gpu) {
        unsafe { gpu.device.destroy_pipeline(self.raw, None) };
        if let Some(s) = &self.sbt {
            s.buffer.destroy(gpu);
        }
    }
}
