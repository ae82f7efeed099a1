//! Pipelines of a cell: ray tracing (with its shader binding table), graphics (fragment probes,
//! dynamic rendering, one quad per tile) or compute. The group layout of every RT pipeline is
//! fixed: raygen; miss 0 (primary), miss 1 (AS probe ray); hit group 0 triangles, hit group 1
//! procedural (intersection); callable 0 when the callable stage is probed. Heap pipelines (see
//! [`super::heap`]) have no layout, the descriptor-heap create flag, the set/binding mapping on
//! every stage, and shader record data after each SBT handle where their mapping reads it. A
//! cell's RT pipeline is made whole or linked from one library per group
//! ([`super::pipeline_library`]); [`create_rt_pipeline`] takes any group counts (the user-shader
//! harness).
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

/// The specialization every stage of a cell's pipeline gets: constant 0 is `probe::SPEC_SLOT`.
#[derive(Clone, Debug)]
pub struct Specialization {
    data: Vec<u8>,
    entries: Vec<vk::SpecializationMapEntry>,
}

impl Specialization {
    /// The probes' specialization.
    pub fn probe() -> Specialization {
        Specialization {
            data: probe::SPEC_SLOT.to_le_bytes().to_vec(),
            entries: vec![vk::SpecializationMapEntry { constant_id: 0, offset: 0, size: 4 }],
        }
    }

    /// The bytes the constants are read from (part of a pipeline's identity).
    pub fn data(&self) -> &[u8] {
        &self.data
    }

    fn info(&self) -> vk::SpecializationInfo<'_> {
        vk::SpecializationInfo::default().map_entries(&self.entries).data(&self.data)
    }
}

/// Everything a pipeline is made of.
#[derive(Clone, Copy)]
pub struct Desc<'a> {
    pub shaders: &'a CellShaders,
    /// SPIR-V of `shaders`, same order.
    pub spirv: &'a [std::sync::Arc<Vec<u32>>],
    pub layout: vk::PipelineLayout,
    pub model: DescriptorModel,
    /// The set/binding → heap mapping chained to each stage: `Some` exactly for the
    /// descriptor_heap model.
    pub heap: Option<&'a PipelineMapping>,
    /// The shader record data written after each SBT handle (ray tracing pipelines).
    pub records: &'a ShaderRecords,
    pub specialization: &'a Specialization,
}

/// The create flags of a pipeline under `model` (`heap`: with a heap mapping), as
/// `VkPipelineCreateFlags2` (whose low bits are the `VkPipelineCreateFlags` of the same meaning).
pub fn flags2(model: DescriptorModel, heap: bool) -> vk::PipelineCreateFlags2KHR {
    let mut f = vk::PipelineCreateFlags2KHR::empty();
    if model == DescriptorModel::DescriptorBuffer {
        f |= vk::PipelineCreateFlags2KHR::from_raw(
            vk::PipelineCreateFlags::DESCRIPTOR_BUFFER_EXT.as_raw() as u64,
        );
    }
    if heap {
        f |= crate::vk::heap::PIPELINE_CREATE_2_DESCRIPTOR_HEAP;
    }
    f
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

/// The shader modules of `d`'s shaders at `which`; on an error the ones made are destroyed.
fn modules_of(gpu: &Gpu, d: &Desc, which: &[usize]) -> Result<Vec<vk::ShaderModule>, VkError> {
    let words: Vec<&[u32]> = which.iter().map(|&i| d.spirv[i].as_slice()).collect();
    shader_modules(gpu, &words)
}

/// The flags2 struct of heap pipelines (the descriptor-heap flag exists only there; it needs
/// maintenance5, which heaps enable), `None` for the others.
fn flags2_info(d: &Desc) -> Option<vk::PipelineCreateFlags2CreateInfoKHR<'static>> {
    d.heap.map(|_| vk::PipelineCreateFlags2CreateInfoKHR::default().flags(flags2(d.model, true)))
}

/// The stage create infos of `d`'s shaders at `which` (indices), with `modules` (same order as
/// `which`) and `spec`.
fn stage_infos<'a>(
    d: &Desc<'a>,
    which: &[usize],
    modules: &[vk::ShaderModule],
    spec: &'a vk::SpecializationInfo<'a>,
) -> Vec<vk::PipelineShaderStageCreateInfo<'a>> {
    which
        .iter()
        .zip(modules)
        .map(|(&i, m)| {
            let mut st = vk::PipelineShaderStageCreateInfo::default()
                .stage(stage_flag(d.shaders.shaders[i].role))
                .module(*m)
                .name(MAIN)
                .specialization_info(spec);
            if let Some(h) = d.heap {
                st.p_next = h.stage_next();
            }
            st
        })
        .collect()
}

/// Create the pipeline `d` describes with `cache`, specializing every stage with
/// `d.specialization`.
pub fn create(gpu: &Gpu, cache: vk::PipelineCache, d: &Desc) -> Result<Pipeline, VkError> {
    let all: Vec<usize> = (0..d.shaders.shaders.len()).collect();
    let modules = modules_of(gpu, d, &all)?;
    let spec = d.specialization.info();
    let stages = stage_infos(d, &all, &modules, &spec);
    let flags = if d.model == DescriptorModel::DescriptorBuffer {
        vk::PipelineCreateFlags::DESCRIPTOR_BUFFER_EXT
    } else {
        vk::PipelineCreateFlags::empty()
    };
    let mut extra = flags2_info(d);
    let result = match d.shaders.kind {
        PipelineKind::RayTracing => create_rt(gpu, cache, d, &stages, flags, &mut extra),
        PipelineKind::Compute => {
            let mut ci = vk::ComputePipelineCreateInfo::default()
                .stage(stages[0])
                .layout(d.layout)
                .flags(flags);
            if let Some(f2) = extra.as_mut() {
                ci = ci.push_next(f2);
            }
            unsafe { gpu.device.create_compute_pipelines(cache, &[ci], None) }
                .map_err(|(_, e)| VkError::from_result("vkCreateComputePipelines", e))
                .map(|p| Pipeline { raw: p[0], kind: PipelineKind::Compute, sbt: None })
        }
        PipelineKind::Graphics => create_graphics(gpu, cache, &stages, d.layout, flags, &mut extra),
    };
    for m in &modules {
        unsafe { gpu.device.destroy_shader_module(*m, None) };
    }
    result
}

fn create_graphics(
    gpu: &Gpu,
    cache: vk::PipelineCache,
    stages: &[vk::PipelineShaderStageCreateInfo],
    layout: vk::PipelineLayout,
    flags: vk::PipelineCreateFlags,
    extra: &mut Option<vk::PipelineCreateFlags2CreateInfoKHR<'static>>,
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
    if let Some(f2) = extra.as_mut() {
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

/// The shader record data after group `g`'s handle in a cell's SBT. Group order: raygen, miss,
/// probe miss, triangle hits, procedural hits, callable.
fn cell_record(records: &ShaderRecords, g: usize) -> &[u8] {
    match g {
        3 => records.hit_triangles.as_slice(),
        4 => records.hit_procedural.as_slice(),
        _ => records.other.as_slice(),
    }
}

fn create_rt(
    gpu: &Gpu,
    cache: vk::PipelineCache,
    d: &Desc,
    stages: &[vk::PipelineShaderStageCreateInfo],
    flags: vk::PipelineCreateFlags,
    extra: &mut Option<vk::PipelineCreateFlags2CreateInfoKHR<'static>>,
) -> Result<Pipeline, VkError> {
    let groups = rt_groups(d.shaders);
    let counts = sbt_counts(d.shaders);
    let rt = RtPipeline {
        stages,
        groups: &groups,
        counts,
        depth: d.shaders.recursion_depth,
        layout: d.layout,
    };
    let record = |g: usize| cell_record(d.records, g);
    create_rt_pipeline(gpu, cache, &rt, flags, extra.as_mut(), &record)
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

/// One shader group and the stages it uses (indices into the cell's shaders): what a group's
/// pipeline library holds.
#[derive(Clone, Debug)]
pub struct GroupStages {
    pub ty: vk::RayTracingShaderGroupTypeKHR,
    pub stages: Vec<usize>,
    /// The group with its shader indices renumbered into `stages`.
    group: vk::RayTracingShaderGroupCreateInfoKHR<'static>,
}

/// The groups of [`rt_groups`] with their stages, in SBT order.
pub fn rt_group_stages(shaders: &CellShaders) -> Vec<GroupStages> {
    rt_groups(shaders)
        .into_iter()
        .map(|g| {
            let mut stages = Vec::new();
            let mut local = |i: u32| {
                if i == vk::SHADER_UNUSED_KHR {
                    return i;
                }
                stages.push(i as usize);
                stages.len() as u32 - 1
            };
            let group = vk::RayTracingShaderGroupCreateInfoKHR::default()
                .ty(g.ty)
                .general_shader(local(g.general_shader))
                .closest_hit_shader(local(g.closest_hit_shader))
                .any_hit_shader(local(g.any_hit_shader))
                .intersection_shader(local(g.intersection_shader));
            GroupStages { ty: g.ty, stages, group }
        })
        .collect()
}

/// The flags of a pipeline library under `d`'s model, as flags and (heap pipelines) flags2.
fn library_flags(
    d: &Desc,
) -> (vk::PipelineCreateFlags, Option<vk::PipelineCreateFlags2CreateInfoKHR<'static>>) {
    let lib = vk::PipelineCreateFlags::LIBRARY_KHR;
    let f2 = flags2(d.model, d.heap.is_some())
        | vk::PipelineCreateFlags2KHR::from_raw(lib.as_raw() as u64);
    let flags = vk::PipelineCreateFlags::from_raw(flags2(d.model, false).as_raw() as u32) | lib;
    (flags, d.heap.map(|_| vk::PipelineCreateFlags2CreateInfoKHR::default().flags(f2)))
}

/// A pipeline library of group `g` of `d` (`iface`: the interface every library and the linked
/// pipeline share).
pub fn create_rt_library(
    gpu: &Gpu,
    cache: vk::PipelineCache,
    d: &Desc,
    g: &GroupStages,
    iface: &vk::RayTracingPipelineInterfaceCreateInfoKHR,
) -> Result<vk::Pipeline, VkError> {
    let rt = gpu.rt.as_ref().expect("ray tracing pipeline enabled");
    let modules = modules_of(gpu, d, &g.stages)?;
    let spec = d.specialization.info();
    let stages = stage_infos(d, &g.stages, &modules, &spec);
    let groups = [g.group];
    let (flags, mut f2) = library_flags(d);
    let mut ci = vk::RayTracingPipelineCreateInfoKHR::default()
        .flags(flags)
        .stages(&stages)
        .groups(&groups)
        .max_pipeline_ray_recursion_depth(d.shaders.recursion_depth)
        .library_interface(iface)
        .layout(d.layout);
    if let Some(f2) = f2.as_mut() {
        ci = ci.push_next(f2);
    }
    let r = unsafe {
        rt.create_ray_tracing_pipelines(vk::DeferredOperationKHR::null(), cache, &[ci], None)
    }
    .map_err(|(_, e)| VkError::from_result("vkCreateRayTracingPipelinesKHR (library)", e));
    for m in &modules {
        unsafe { gpu.device.destroy_shader_module(*m, None) };
    }
    Ok(r?[0])
}

/// The ray tracing pipeline `d` linked from `libs` (one per group, in SBT order), and its SBT.
pub fn link_rt(
    gpu: &Gpu,
    cache: vk::PipelineCache,
    d: &Desc,
    libs: &[vk::Pipeline],
    iface: &vk::RayTracingPipelineInterfaceCreateInfoKHR,
) -> Result<Pipeline, VkError> {
    let rt = gpu.rt.as_ref().expect("ray tracing pipeline enabled");
    let info = vk::PipelineLibraryCreateInfoKHR::default().libraries(libs);
    let flags = vk::PipelineCreateFlags::from_raw(flags2(d.model, false).as_raw() as u32);
    let mut f2 = d
        .heap
        .map(|_| vk::PipelineCreateFlags2CreateInfoKHR::default().flags(flags2(d.model, true)));
    let mut ci = vk::RayTracingPipelineCreateInfoKHR::default()
        .flags(flags)
        .library_info(&info)
        .library_interface(iface)
        .max_pipeline_ray_recursion_depth(d.shaders.recursion_depth)
        .layout(d.layout);
    if let Some(f2) = f2.as_mut() {
        ci = ci.push_next(f2);
    }
    let raw = unsafe {
        rt.create_ray_tracing_pipelines(vk::DeferredOperationKHR::null(), cache, &[ci], None)
    }
    .map_err(|(_, e)| VkError::from_result("vkCreateRayTracingPipelinesKHR (link)", e))?[0];
    // One library per group, in SBT order: the linked pipeline's groups are the cell's groups.
    debug_assert_eq!(libs.len(), rt_groups(d.shaders).len());
    let record = |g: usize| cell_record(d.records, g);
    let sbt = shader_binding_table(gpu, raw, sbt_counts(d.shaders), &record)?;
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
