//! The stress suite on the device ([`Mode::Pipeline`]; [`Mode::RayQuery`] traces the same rays
//! with ray queries in a compute shader): one RT pipeline (raygen, miss, closest hit, any-hit; push
//! constants only, buffers and the TLAS by device address) and, per part, one BLAS per mesh
//! (one non-opaque geometry with NO_DUPLICATE_ANY_HIT_INVOCATION) and a TLAS. The raygen traces
//! each ray twice: first non-opaque, where any-hit counts every candidate and ignores it (so
//! each intersected primitive is counted once), then with gl_RayFlagsOpaqueEXT for the closest
//! hit. Runs in a stress worker (`worker`); every submission has a fence deadline and a lost
//! device or a timeout ends the case with that verdict.
use super::layout::{self, glsl_header, LAUNCH_WIDTH, PUSH_SIZE, RESULT_WORDS};
use super::{Part, TraceError, Traced, Tracer};
use crate::exec::pipeline::{self, Pipeline};
use crate::model::DescriptorModel;
use crate::scene::gpu::{
    bytemuck_transform, bytes_of, record_builds, triangles, AccelStruct, Pending, SceneGpu,
    INPUT_USAGE,
};
use crate::shadergen::compile::Compiler;
use crate::shadergen::{CellShaders, PipelineKind, Role, ShaderSource};
use crate::vk::memory::{full_barrier, Buffer, Location};
use crate::vk::submit::{Submitter, Waited};
use crate::vk::{Gpu, VkError, VkResultExt};
use ash::vk;
use std::time::Duration;

const HEADER: &str = "#version 460\n#extension GL_EXT_ray_tracing : require\n#extension GL_EXT_buffer_reference : require\n\
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require\n";

const COMMON: &str = r#"
layout(buffer_reference, std430, buffer_reference_align = 16) readonly buffer Rays { vec4 v[]; };
layout(buffer_reference, std430, buffer_reference_align = 4) buffer Results { uint w[]; };
layout(push_constant, std430) uniform Push { uint64_t rays; uint64_t results; uint64_t tlas; uint count; uint width; uint ray_flags; } pc;
"#;

const RT_INDEX: &str =
    "uint ray_index() { return gl_LaunchIDEXT.y * pc.width + gl_LaunchIDEXT.x; }\n";

const RAYGEN: &str = r#"
layout(location = 0) rayPayloadEXT uint pass_;
void main() {
    uint i = ray_index();
    if (i >= pc.count) return;
    Rays r = Rays(pc.rays);
    vec4 a = r.v[2 * i];
    vec4 b = r.v[2 * i + 1];
    pass_ = 1u;
    traceRayEXT(accelerationStructureEXT(pc.tlas), pc.ray_flags, 0xff, 0, 0, 0, a.xyz, a.w, b.xyz, b.w, 0);
    pass_ = 2u;
    traceRayEXT(accelerationStructureEXT(pc.tlas), pc.ray_flags | gl_RayFlagsOpaqueEXT, 0xff, 0, 0, 0, a.xyz, a.w, b.xyz, b.w, 0);
}
"#;

const MISS: &str = r#"
layout(location = 0) rayPayloadInEXT uint pass_;
void main() {
    Results o = Results(pc.results);
    uint i = ray_index();
    o.w[i * RESULT_WORDS + W_PASS] = pass_;
    if (pass_ == 2u) o.w[i * RESULT_WORDS + W_STATUS] = STATUS_MISS;
}
"#;

const CLOSEST_HIT: &str = r#"
layout(location = 0) rayPayloadInEXT uint pass_;
hitAttributeEXT vec2 bary;
void main() {
    Results o = Results(pc.results);
    uint base = ray_index() * RESULT_WORDS;
    o.w[base + W_STATUS] = STATUS_HIT;
    o.w[base + W_T] = floatBitsToUint(gl_HitTEXT);
    o.w[base + W_U] = floatBitsToUint(bary.x);
    o.w[base + W_V] = floatBitsToUint(bary.y);
    o.w[base + W_PRIMITIVE] = uint(gl_PrimitiveID);
    o.w[base + W_INSTANCE] = uint(gl_InstanceCustomIndexEXT);
    o.w[base + W_HIT_KIND] = gl_HitKindEXT;
    for (int k = 0; k < 3; k++) {
        o.w[base + W_OBJ_ORIGIN + k] = floatBitsToUint(gl_ObjectRayOriginEXT[k]);
        o.w[base + W_OBJ_DIR + k] = floatBitsToUint(gl_ObjectRayDirectionEXT[k]);
    }
}
"#;

const ANY_HIT: &str = r#"
layout(location = 0) rayPayloadInEXT uint pass_;
void main() {
    Results o = Results(pc.results);
    uint base = ray_index() * RESULT_WORDS;
    uint k = atomicAdd(o.w[base + W_CANDIDATES], 1u);
    uint id = ((uint(gl_InstanceCustomIndexEXT) << 24) | uint(gl_PrimitiveID)) + 1u;
    if (k < 2u) o.w[base + W_CAND0 + k] = id;
    ignoreIntersectionEXT;
}
"#;

/// The procedural hit group is part of the fixed group layout of `exec::pipeline`; stress scenes
/// have no AABBs, so it is never invoked.
const UNUSED_PROCEDURAL: &str = "void main() {}\n";
const UNUSED_INTERSECTION: &str = "void main() { reportIntersectionEXT(0.0, 0u); }\n";
const UNUSED_PROBE_MISS: &str = "void main() {}\n";

/// The same two traces with a ray query in a compute shader: the first query walks every
/// candidate (none is confirmed: counted like any-hit), the second is opaque and commits the
/// closest hit. Front face maps to the hit kinds of the pipeline (0xFE front, 0xFF back).
const RAY_QUERY: &str = r#"
layout(local_size_x = 64) in;
void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= pc.count) return;
    Rays r = Rays(pc.rays);
    vec4 a = r.v[2 * i];
    vec4 b = r.v[2 * i + 1];
    Results o = Results(pc.results);
    uint base = i * RESULT_WORDS;
    rayQueryEXT q;
    rayQueryInitializeEXT(q, accelerationStructureEXT(pc.tlas), pc.ray_flags, 0xff, a.xyz, a.w, b.xyz, b.w);
    uint n = 0u;
    while (rayQueryProceedEXT(q)) {
        if (rayQueryGetIntersectionTypeEXT(q, false) == gl_RayQueryCandidateIntersectionTriangleEXT) {
            uint id = ((uint(rayQueryGetIntersectionInstanceCustomIndexEXT(q, false)) << 24) | uint(rayQueryGetIntersectionPrimitiveIndexEXT(q, false))) + 1u;
            if (n < 2u) o.w[base + W_CAND0 + n] = id;
            n++;
        }
    }
    o.w[base + W_CANDIDATES] = n;
    o.w[base + W_PASS] = 2u;
    rayQueryEXT c;
    rayQueryInitializeEXT(c, accelerationStructureEXT(pc.tlas), pc.ray_flags | gl_RayFlagsOpaqueEXT, 0xff, a.xyz, a.w, b.xyz, b.w);
    while (rayQueryProceedEXT(c)) {}
    if (rayQueryGetIntersectionTypeEXT(c, true) == gl_RayQueryCommittedIntersectionNoneEXT) {
        o.w[base + W_STATUS] = STATUS_MISS;
        return;
    }
    vec2 bary = rayQueryGetIntersectionBarycentricsEXT(c, true);
    o.w[base + W_STATUS] = STATUS_HIT;
    o.w[base + W_T] = floatBitsToUint(rayQueryGetIntersectionTEXT(c, true));
    o.w[base + W_U] = floatBitsToUint(bary.x);
    o.w[base + W_V] = floatBitsToUint(bary.y);
    o.w[base + W_PRIMITIVE] = uint(rayQueryGetIntersectionPrimitiveIndexEXT(c, true));
    o.w[base + W_INSTANCE] = uint(rayQueryGetIntersectionInstanceCustomIndexEXT(c, true));
    o.w[base + W_HIT_KIND] = rayQueryGetIntersectionFrontFaceEXT(c, true) ? 0xFEu : 0xFFu;
    vec3 oo = rayQueryGetIntersectionObjectRayOriginEXT(c, true);
    vec3 od = rayQueryGetIntersectionObjectRayDirectionEXT(c, true);
    for (int k = 0; k < 3; k++) {
        o.w[base + W_OBJ_ORIGIN + k] = floatBitsToUint(oo[k]);
        o.w[base + W_OBJ_DIR + k] = floatBitsToUint(od[k]);
    }
}
"#;

const RQ_HEADER: &str = "#version 460\n#extension GL_EXT_ray_query : require\n#extension GL_EXT_buffer_reference : require\n\
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require\n";

fn source(role: Role, body: &str) -> ShaderSource {
    ShaderSource { role, glsl: format!("{HEADER}{}{COMMON}{RT_INDEX}{body}", glsl_header()) }
}

/// How rays are traced: `traceRayEXT` in an RT pipeline, or `rayQueryEXT` in a compute shader.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    Pipeline,
    RayQuery,
}

impl Mode {
    /// What the device must have to trace this way: the one set `stress` checks before any
    /// worker starts and each worker then creates its device with.
    pub fn requirements(self) -> crate::vk::Requirements {
        crate::vk::Requirements {
            rt_pipeline: self == Mode::Pipeline,
            ray_query: self == Mode::RayQuery,
            buffer_device_address: true,
            int64: true,
            ..crate::vk::Requirements::default()
        }
    }

    pub fn as_str(self) -> &'static str {
        match self {
            Mode::Pipeline => "pipeline",
            Mode::RayQuery => "ray_query",
        }
    }

    fn stages(self) -> vk::ShaderStageFlags {
        match self {
            Mode::Pipeline => {
                vk::ShaderStageFlags::RAYGEN_KHR
                    | vk::ShaderStageFlags::MISS_KHR
                    | vk::ShaderStageFlags::CLOSEST_HIT_KHR
                    | vk::ShaderStageFlags::ANY_HIT_KHR
            }
            Mode::RayQuery => vk::ShaderStageFlags::COMPUTE,
        }
    }

    fn shaders(self) -> CellShaders {
        let shaders = match self {
            Mode::Pipeline => vec![
                source(Role::Raygen, RAYGEN),
                source(Role::Miss, MISS),
                source(Role::ProbeMiss, UNUSED_PROBE_MISS),
                source(Role::ClosestHitTriangles, CLOSEST_HIT),
                source(Role::AnyHit, ANY_HIT),
                source(Role::ClosestHitProcedural, UNUSED_PROCEDURAL),
                source(Role::Intersection, UNUSED_INTERSECTION),
            ],
            Mode::RayQuery => vec![ShaderSource {
                role: Role::Compute,
                glsl: format!("{RQ_HEADER}{}{COMMON}{RAY_QUERY}", glsl_header()),
            }],
        };
        let kind =
            if self == Mode::Pipeline { PipelineKind::RayTracing } else { PipelineKind::Compute };
        CellShaders {
            kind,
            shaders,
            recursion_depth: 1,
            uses_probe_binding: false,
            uses_scene_tlas: false,
            uses_ray_query: self == Mode::RayQuery,
        }
    }
}

/// The stress shaders of `mode` compiled to SPIR-V (no device needed: `rtprobe stress` checks
/// its compiler this way before it starts a worker).
pub fn spirv(mode: Mode) -> Result<Vec<std::sync::Arc<Vec<u32>>>, TraceError> {
    let mut compiler = Compiler::new().map_err(TraceError::Compile)?;
    let mut spirv = Vec::new();
    for s in &mode.shaders().shaders {
        spirv.push(compiler.compile(s.role, &s.glsl).map_err(TraceError::Compile)?.0);
    }
    Ok(spirv)
}

pub struct GpuTracer {
    gpu: Gpu,
    submitter: Submitter,
    layout: vk::PipelineLayout,
    pipeline: Pipeline,
    timeout: Duration,
    /// Set after a device loss, a timeout or a failed held submission (`submit`, which holds
    /// `&self`): later parts are not traced on this device.
    broken: std::cell::RefCell<Option<String>>,
    mode: Mode,
    /// Told (rays traced, rays in the part) after each submission of a part's trace.
    on_chunk: Option<Box<dyn FnMut(usize, usize)>>,
    /// The gate the next submission is held behind, and whether it is released after the
    /// wait ([`GpuTracer::hold_first_submission`]).
    held: std::cell::Cell<Option<(vk::Semaphore, bool)>>,
}

/// Rays per submission: a part's trace is cut into submissions of this many rays, each fenced
/// on its own, so a long trace (`--full`'s 2.3 million rays on a CPU driver) says how far it got
/// between them and a hung one still stays silent.
pub const CHUNK_RAYS: usize = 1 << 16;

fn vk_err(e: VkError) -> TraceError {
    if e.is_device_lost() {
        TraceError::DeviceLost(e.to_string())
    } else {
        TraceError::Failed(e.to_string())
    }
}

impl GpuTracer {
    /// Calls `f(rays traced, rays in the part)` after each submission of a trace.
    pub fn on_chunk(&mut self, f: Box<dyn FnMut(usize, usize)>) {
        self.on_chunk = Some(f);
    }

    pub fn new(gpu: Gpu, timeout: Duration, mode: Mode) -> Result<Self, TraceError> {
        let shaders = mode.shaders();
        let spirv = spirv(mode)?;
        let submitter = Submitter::new(&gpu).map_err(vk_err)?;
        let range = [vk::PushConstantRange::default().stage_flags(mode.stages()).size(PUSH_SIZE)];
        let layout = unsafe {
            gpu.device.create_pipeline_layout(
                &vk::PipelineLayoutCreateInfo::default().push_constant_ranges(&range),
                None,
            )
        }
        .at("vkCreatePipelineLayout")
        .map_err(vk_err)?;
        let desc = pipeline::Desc {
            shaders: &shaders,
            spirv: &spirv,
            layout,
            model: DescriptorModel::DescriptorIndexing,
            heap: None,
            records: &Default::default(),
            specialization: &pipeline::Specialization::probe(),
        };
        let pipeline = pipeline::create(&gpu, vk::PipelineCache::null(), &desc).map_err(vk_err)?;
        Ok(GpuTracer {
            gpu,
            submitter,
            layout,
            pipeline,
            timeout,
            broken: Default::default(),
            mode,
            on_chunk: None,
            held: Default::default(),
        })
    }

    /// Whether a timeout or a device loss stopped this tracer (or a held submission failed):
    /// its objects may still be in use.
    pub fn is_broken(&self) -> bool {
        self.broken.borrow().is_some()
    }

    /// Holds the next submission until its fence wait has run out (`Submitter::run_held`): the
    /// test hooks' GPU that is slower than any deadline, then released (`stall`), or never
    /// (`stall_forever`: a hung GPU). The device must have been opened with `timelineSemaphore`.
    pub fn hold_first_submission(&mut self, release: bool) -> Result<(), TraceError> {
        self.held.set(Some((Submitter::gate(&self.gpu).map_err(vk_err)?, release)));
        Ok(())
    }

    /// Records with `f`, submits and waits up to the deadline; held behind the gate once where
    /// one is set.
    fn submit(&self, f: impl FnOnce(vk::CommandBuffer)) -> Result<Waited, TraceError> {
        let Some((gate, release)) = self.held.take() else {
            return self.submitter.run(&self.gpu, self.timeout, f).map_err(vk_err);
        };
        let waited = self.submitter.run_held(&self.gpu, self.timeout, (gate, release), f);
        match (&waited, release) {
            // Released and finished: nothing waits on the gate any more.
            (Ok(_), true) => unsafe { self.gpu.device.destroy_semaphore(gate, None) },
            // Still held, a hung GPU: the timeout makes the tracer broken (`trace`).
            (Ok(_), false) => {}
            // Failed, perhaps past its submission: left as it is.
            (Err(e), _) => {
                *self.broken.borrow_mut() = Some(format!("a held submission failed ({e})"))
            }
        }
        waited.map_err(vk_err)
    }

    fn build(
        &self,
        part: &Part,
        keep: &mut Vec<Buffer>,
    ) -> Result<(Vec<AccelStruct>, AccelStruct), TraceError> {
        let gpu = &self.gpu;
        let mut pending = Vec::new();
        for mesh in &part.scene.meshes {
            pending.push(
                triangles(
                    gpu,
                    &mesh.positions,
                    &mesh.indices,
                    vk::GeometryFlagsKHR::NO_DUPLICATE_ANY_HIT_INVOCATION,
                    keep,
                )
                .map_err(vk_err)?,
            );
        }
        let mut scratch = Vec::new();
        let (blas, blas_builds) =
            SceneGpu::prepare_all(gpu, &pending, &mut scratch).map_err(vk_err)?;
        let instances: Vec<vk::AccelerationStructureInstanceKHR> = part
            .scene
            .instances
            .iter()
            .enumerate()
            .map(|(k, i)| vk::AccelerationStructureInstanceKHR {
                transform: vk::TransformMatrixKHR { matrix: bytemuck_transform(&i.transform) },
                instance_custom_index_and_mask: vk::Packed24_8::new(k as u32, 0xff),
                instance_shader_binding_table_record_offset_and_flags: vk::Packed24_8::new(0, 0),
                acceleration_structure_reference: vk::AccelerationStructureReferenceKHR {
                    device_handle: blas[i.mesh].address,
                },
            })
            .collect();
        let ib = Buffer::with_data(gpu, bytes_of(&instances), INPUT_USAGE, "instance buffer")
            .map_err(vk_err)?;
        let data = vk::AccelerationStructureGeometryInstancesDataKHR::default()
            .data(vk::DeviceOrHostAddressConstKHR { device_address: ib.address });
        keep.push(ib);
        let tlas_pending = [Pending {
            geometries: vec![vk::AccelerationStructureGeometryKHR::default()
                .geometry_type(vk::GeometryTypeKHR::INSTANCES)
                .geometry(vk::AccelerationStructureGeometryDataKHR { instances: data })],
            ranges: vec![vk::AccelerationStructureBuildRangeInfoKHR::default()
                .primitive_count(instances.len() as u32)],
            ty: vk::AccelerationStructureTypeKHR::TOP_LEVEL,
        }];
        let (mut tlas, tlas_builds) =
            SceneGpu::prepare_all(gpu, &tlas_pending, &mut scratch).map_err(vk_err)?;
        let waited = self.submit(|cmd| record_builds(gpu, cmd, &[&blas_builds, &tlas_builds]))?;
        let tlas = tlas.pop().expect("one TLAS");
        match waited {
            Waited::Done(_) => {
                for s in &scratch {
                    s.destroy(gpu);
                }
                Ok((blas, tlas))
            }
            // The build may still run: its objects and scratch are leaked, not freed under it.
            Waited::TimedOut => Err(TraceError::Timeout(self.timeout)),
        }
    }

    fn launch(
        &mut self,
        part: &Part,
        tlas: &AccelStruct,
        keep: &mut Vec<Buffer>,
    ) -> Result<Vec<Traced>, TraceError> {
        let gpu = &self.gpu;
        let n = part.rays.len();
        let usage =
            vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS;
        let rays = Buffer::with_data(gpu, &layout::ray_bytes(&part.rays), usage, "stress rays")
            .map_err(vk_err)?;
        let results = Buffer::new(
            gpu,
            (n * RESULT_WORDS * 4) as u64,
            usage,
            Location::Host,
            "stress results",
        )
        .map_err(vk_err)?;
        results.write(0, &vec![0u8; n * RESULT_WORDS * 4]);
        let (rays_at, results_at) = (rays.address, results.address);
        keep.extend([rays, results]);
        let ray_bytes = layout::ray_bytes(&part.rays[..n.min(1)]).len() as u64;
        for first in (0..n).step_by(CHUNK_RAYS) {
            let len = CHUNK_RAYS.min(n - first);
            let mut push = Vec::with_capacity(PUSH_SIZE as usize);
            push.extend((rays_at + first as u64 * ray_bytes).to_le_bytes());
            push.extend((results_at + (first * RESULT_WORDS * 4) as u64).to_le_bytes());
            push.extend(tlas.address.to_le_bytes());
            push.extend((len as u32).to_le_bytes());
            push.extend(LAUNCH_WIDTH.to_le_bytes());
            push.extend(part.ray_flags.to_le_bytes());
            if let Waited::TimedOut = self.submit(|cmd| self.record(cmd, &push, len))? {
                return Err(TraceError::Timeout(self.timeout));
            }
            if let Some(f) = self.on_chunk.as_mut() {
                f(first + len, n);
            }
        }
        let bytes = keep[keep.len() - 1].read(n * RESULT_WORDS * 4);
        let decoded = layout::decode(&bytes, n);
        let lost = decoded.iter().filter(|d| d.is_none()).count();
        if lost > 0 {
            return Err(TraceError::Failed(format!(
                "{lost} of {n} rays ran neither the closest-hit nor the miss shader"
            )));
        }
        Ok(decoded.into_iter().map(|d| d.expect("checked above")).collect())
    }

    /// Records the trace (or dispatch) of `len` rays with `push` into `cmd`.
    fn record(&self, cmd: vk::CommandBuffer, push: &[u8], len: usize) {
        let gpu = &self.gpu;
        unsafe {
            match self.mode {
                Mode::Pipeline => {
                    let rt = gpu.rt.as_ref().expect("ray tracing pipeline enabled");
                    let sbt = self.pipeline.sbt.as_ref().expect("RT pipeline has an SBT");
                    gpu.device.cmd_bind_pipeline(
                        cmd,
                        vk::PipelineBindPoint::RAY_TRACING_KHR,
                        self.pipeline.raw,
                    );
                    gpu.device.cmd_push_constants(cmd, self.layout, self.mode.stages(), 0, push);
                    rt.cmd_trace_rays(
                        cmd,
                        &sbt.raygen,
                        &sbt.miss,
                        &sbt.hit,
                        &sbt.callable,
                        LAUNCH_WIDTH,
                        (len as u32).div_ceil(LAUNCH_WIDTH),
                        1,
                    );
                }
                Mode::RayQuery => {
                    gpu.device.cmd_bind_pipeline(
                        cmd,
                        vk::PipelineBindPoint::COMPUTE,
                        self.pipeline.raw,
                    );
                    gpu.device.cmd_push_constants(cmd, self.layout, self.mode.stages(), 0, push);
                    gpu.device.cmd_dispatch(cmd, (len as u32).div_ceil(64), 1, 1);
                }
            }
        }
        full_barrier(gpu, cmd);
    }
}

fn destroy_accel<'a>(gpu: &Gpu, all: impl Iterator<Item = &'a AccelStruct>) {
    let accel = gpu.accel.as_ref().expect("acceleration structures enabled");
    for a in all {
        unsafe { accel.destroy_acceleration_structure(a.raw, None) };
        a.buffer.destroy(gpu);
    }
}

impl Tracer for GpuTracer {
    fn name(&self) -> String {
        format!(
            "{} ({} {}), {}",
            self.gpu.info.name(),
            self.gpu.info.driver_name(),
            self.gpu.info.driver_version(),
            self.mode.as_str()
        )
    }

    fn trace(&mut self, part: &Part) -> Result<Vec<Traced>, TraceError> {
        if let Some(why) = self.broken.get_mut() {
            return Err(TraceError::Failed(format!("not traced: {why} in an earlier case")));
        }
        let mut keep = Vec::new();
        let result = self.build(part, &mut keep).and_then(|(blas, tlas)| {
            let r = self.launch(part, &tlas, &mut keep);
            if !matches!(r, Err(TraceError::Timeout(_))) {
                destroy_accel(&self.gpu, blas.iter().chain([&tlas]));
            }
            r
        });
        match &result {
            // A hung submission may still use them: leak rather than free under it.
            Err(e @ (TraceError::Timeout(_) | TraceError::DeviceLost(_))) => {
                *self.broken.get_mut() = Some(e.to_string())
            }
            _ => {
                for b in &keep {
                    b.destroy(&self.gpu);
                }
            }
        }
        result
    }
}

impl Drop for GpuTracer {
    fn drop(&mut self) {
        if self.is_broken() {
            return;
        }
        unsafe { self.gpu.device.device_wait_idle().ok() };
        if let Some((gate, _)) = self.held.take() {
            unsafe { self.gpu.device.destroy_semaphore(gate, None) };
        }
        self.pipeline.destroy(&self.gpu);
        unsafe { self.gpu.device.destroy_pipeline_layout(self.layout, None) };
        self.submitter.destroy(&self.gpu);
    }
}
