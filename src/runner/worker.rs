//! The worker: `rtprobe __worker JOB.json`. Setup first: one device with exactly what its cells
//! need, then the scene's acceleration structures and every resource the cells use, before it
//! says `ready` (a fault there is the setup's, never a cell's). Then it runs the cells in order,
//! telling the supervisor each phase it enters, and reports each cell on stdout. After a device
//! loss, a timeout or a crash the device is unusable, so it reports and exits at once (`_exit`,
//! skipping destructors that could block on a hung queue). The supervisor kills it if the
//! supervisor dies (PR_SET_PDEATHSIG, set at spawn). A setup failure that no worker can get past
//! (the shader compiler cannot start) says so in its `fatal` message (`halt`): the run stops.
use super::misbehave::{Misbehave, SetupStep};
use super::overlap;
use super::protocol::{WorkerJob, WorkerMsg};
use super::worker_io::{halt_of, send};
use crate::exec::{CellError, ExecOptions, Executor, Ran};
use crate::model::Phase;
use crate::model::{Cell, DescriptorModel, Resource, Stage};
use crate::model::{Halt, Outcome};
use crate::probe::spec::{ArrayAt, ProbeSpec};
use crate::shadergen::compile::CompileError;
use crate::vk::{features, Gpu, Instance, InstanceOptions, Requirements, VkError};
use std::collections::HashSet;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// What the device must enable for `cells` (as their probe specs say).
pub fn requirements(info: &crate::vk::DeviceInfo, cells: &[Cell]) -> Requirements {
    let specs: Vec<ProbeSpec> = cells.iter().map(ProbeSpec::of).collect();
    let any = |f: &dyn Fn(&ProbeSpec) -> bool| specs.iter().any(f);
    let fragment = any(&|s| s.stage == Stage::Fragment);
    Requirements {
        rt_pipeline: any(&|s| s.stage.is_ray_tracing()),
        ray_query: any(&|s| {
            s.resource == Resource::AccelerationStructure && !s.stage.can_trace_ray()
        }),
        buffer_device_address: true,
        descriptor_indexing: true,
        descriptor_buffer: any(&|s| s.model == DescriptorModel::DescriptorBuffer),
        descriptor_heap: any(&|s| s.model == DescriptorModel::DescriptorHeap),
        untyped_pointers: any(&|s| s.array == ArrayAt::Heap),
        device_fault: info.features.fault.is_some_and(|f| f.device_fault == ash::vk::TRUE),
        int64: any(&ProbeSpec::int64),
        fragment_stores: fragment,
        dynamic_rendering: fragment,
        invocation_reorder: any(&|s| s.reorder.is_some()),
        scalar_block_layout: false,
        timeline_semaphore: false,
        pipeline_library: false,
        disable_internal_cache: false,
        // The matrix's cells run without robustness: their reads are in bounds by design.
        robustness: crate::vk::Robustness::default(),
        // Generated GLSL declares no SPV_GOOGLE extension.
        google: crate::vk::GoogleHlsl::default(),
        // Generated GLSL uses no capability beyond the fields above.
        shader: crate::vk::ShaderFeatures::default(),
    }
}

/// How the worker's pipelines are made, on top of what its cells need: ray tracing pipelines
/// linked from group libraries (`job.linked`, where the device has VK_KHR_pipeline_library); in
/// a worker that compiles afresh, the driver's own cache off with `disableInternalCache` where
/// the run saw `pipelineBinaryInternalCacheControl` ([`env_switch`] otherwise).
fn pipeline_creation(info: &crate::vk::DeviceInfo, job: &WorkerJob, req: &mut Requirements) {
    req.pipeline_library =
        job.linked && req.rt_pipeline && info.has_extension(ash::khr::pipeline_library::NAME);
    req.disable_internal_cache =
        job.fresh && job.internal_cache_control && crate::vk::device::internal_cache_control(info);
}

/// Whether a worker sets the drivers' documented cache switches ([`FRESH_ENV`]): it compiles
/// afresh on a device without `pipelineBinaryInternalCacheControl`. Set before the driver loads
/// (it reads them at instance or device creation); on NVIDIA they also hide that property.
fn env_switch(job: &WorkerJob) -> bool {
    job.fresh && !job.internal_cache_control
}

/// NVIDIA's `__GL_SHADER_DISK_CACHE=0` and Mesa's `MESA_SHADER_CACHE_DISABLE=true`.
const FRESH_ENV: &[(&str, &str)] =
    &[("__GL_SHADER_DISK_CACHE", "0"), ("MESA_SHADER_CACHE_DISABLE", "true")];

/// Where the worker keeps GLSL compiles: the job's folder, unless a cell is a mutant (a mutant
/// rewrites the SPIR-V, and its round is about what the compiled code does, so it compiles its
/// own). A re-run alone reads it too: the rule that re-runs compile afresh is about the driver's
/// pipeline compile, which [`pipeline_creation`] and [`env_switch`] keep afresh.
fn glsl_cache(job: &WorkerJob) -> Option<std::path::PathBuf> {
    job.glsl_cache.clone().filter(|_| job.cells.iter().all(|c| c.mutant.is_none()))
}

/// What the report records of the driver's own cache for this worker.
fn driver_cache(exec: &Executor, job: &WorkerJob) -> crate::model::DriverCache {
    let gpu = &exec.gpu;
    crate::model::DriverCache {
        properties: gpu.info.properties.pipeline_binary.map(|p| p.by_name()).unwrap_or_default(),
        fresh: job.fresh,
        internal_cache_disabled: gpu.enabled.disable_internal_cache,
        env_switch: env_switch(job),
        glsl_cache: glsl_cache(job).is_some(),
    }
}

/// Tells the supervisor each phase, then runs the test hook (if any) for it.
struct Phases {
    hook: Option<Misbehave>,
}

impl Phases {
    fn enter(&self, phase: Phase, step: Option<(SetupStep, &str)>) -> Result<(), VkError> {
        send(&WorkerMsg::Phase { phase, step: step.map(|(_, s)| s.to_string()) });
        match &self.hook {
            Some(h) => h.at(phase, step.map(|(s, _)| s)),
            None => Ok(()),
        }
    }

    /// An overlapped cell enters `phase` (`runner::overlap`): told as a `prebuild` step naming
    /// the cell, then the test hook's turn.
    fn enter_overlapped(&self, cell: &str, phase: Phase) -> Result<(), VkError> {
        super::worker_io::send_overlapped(cell, phase);
        self.hook.as_ref().map_or(Ok(()), |h| h.at_overlapped(phase))
    }

    /// The test hook's turn as the setup starts the shader compiler (`setup:no_compiler`).
    fn compiler(&self) -> Result<(), CompileError> {
        self.hook.as_ref().map_or(Ok(()), Misbehave::compiler)
    }
}

/// A setup that failed, classified; `halt` when no worker could get past it.
struct SetupFailure {
    outcome: Outcome,
    message: String,
    halt: Option<Halt>,
}

impl From<CellError> for SetupFailure {
    fn from(e: CellError) -> Self {
        SetupFailure { outcome: e.outcome(), message: e.to_string(), halt: halt_of(&e) }
    }
}

impl From<CompileError> for SetupFailure {
    fn from(e: CompileError) -> Self {
        CellError::Compile(e).into()
    }
}

impl From<VkError> for SetupFailure {
    fn from(e: VkError) -> Self {
        CellError::Vk(e).into()
    }
}

/// The worker's executor, and the milliseconds its instance and device creation took.
fn setup(job: &WorkerJob, phases: &Phases) -> Result<(Executor, f64), SetupFailure> {
    if env_switch(job) {
        for (k, v) in FRESH_ENV {
            // Single-threaded here: no other thread reads the environment yet.
            std::env::set_var(k, v);
        }
    }
    phases.enter(Phase::Setup, Some((SetupStep::CreateInstance, "vkCreateInstance")))?;
    let t = Instant::now();
    let inst =
        Arc::new(Instance::new(&InstanceOptions { validate: job.validate, gpu_av: job.gpu_av })?);
    let all = features::query_all(&inst)?;
    let mut create_ms = t.elapsed().as_secs_f64() * 1e3;
    let info = all
        .get(job.device_index)
        .ok_or_else(|| SetupFailure {
            outcome: Outcome::Error,
            message: format!("device {} vanished", job.device_index),
            halt: None,
        })?
        .clone();
    let mut req = requirements(&info, &job.cells);
    // Injected invalid-address loads need 64-bit integers, as the address probes do.
    req.int64 |= job.cells.iter().any(|c| {
        crate::model::inject::for_cell(&job.inject, c).is_some_and(|i| i.fault.reads_bad_address())
    });
    pipeline_creation(&info, job, &mut req);
    phases.enter(Phase::Setup, Some((SetupStep::CreateDevice, "vkCreateDevice")))?;
    let t = Instant::now();
    let gpu = Gpu::new(inst, info, req)?;
    create_ms += t.elapsed().as_secs_f64() * 1e3;
    let opts = ExecOptions {
        timeout: Duration::from_millis(job.fence_timeout_ms),
        setup_timeout: Duration::from_millis(job.setup_fence_timeout_ms.max(job.fence_timeout_ms)),
        inject: job.inject.clone(),
        inject_seed: job.inject_seed,
        dump: job.dump.clone(),
        pipeline_cache: job.pipeline_cache.clone(),
        glsl_cache: glsl_cache(job),
        spirv_dir: job.spirv_dir.clone(),
        all_stages: job.binding_stages.as_deref() == Some("all"),
        lanes: job.lane_evidence,
    };
    phases.enter(Phase::Setup, Some((SetupStep::Compiler, "shader compiler (shaderc)")))?;
    phases.compiler()?;
    let mut exec = Executor::new(gpu, &job.scene, opts)?;
    phases
        .enter(Phase::Setup, Some((SetupStep::Scene, "acceleration structures and resources")))?;
    exec.prepare(&job.cells)?;
    Ok((exec, create_ms))
}

/// Cells prebuilt at once: bounds the batch a fault in the prebuild sends back to the sequential
/// path and the driver's live pipelines (each chunk's are destroyed before the next). 1,024
/// makes the default matrix one chunk: at 512 its two chunks cost the H200's cell thread 0.3 s
/// of own time destroying the first (reports/nvidia-h200/perf/s33/: own 0.97-1.03 s at 512,
/// 0.63-0.67 s at 1,024; `--patches all` 3.0-3.2 s against 2.6-2.8 s).
const PREBUILD_CHUNK: usize = 1024;

/// Runs the job; returns the process exit code (the process may also `_exit` early).
pub fn main(job_path: &std::path::Path) -> u8 {
    crate::native_crash::install();
    let hook = match Misbehave::from_env() {
        Ok(h) => h,
        Err(message) => {
            send(&WorkerMsg::Fatal { message, outcome: Outcome::Error, halt: None });
            return 2;
        }
    };
    let phases = Phases { hook };
    let job: WorkerJob = match std::fs::read(job_path)
        .map_err(|e| e.to_string())
        .and_then(|b| serde_json::from_slice(&b).map_err(|e| e.to_string()))
    {
        Ok(j) => j,
        Err(e) => {
            send(&WorkerMsg::Fatal {
                message: format!("cannot read job {}: {e}", job_path.display()),
                outcome: Outcome::Error,
                halt: None,
            });
            return 2;
        }
    };
    // Read: the supervisor keeps no use for it, and an interrupted run leaves nothing behind.
    let _ = std::fs::remove_file(job_path);
    let t = Instant::now();
    let (mut exec, create_ms) = match setup(&job, &phases) {
        Ok(e) => e,
        Err(SetupFailure { outcome, message, halt }) => {
            send(&WorkerMsg::Fatal { message, outcome, halt });
            return 3;
        }
    };
    send(&WorkerMsg::Ready {
        device_ms: t.elapsed().as_secs_f64() * 1e3 - exec.reference_ms,
        create_ms,
        reference_ms: exec.reference_ms,
        as_build_ms: exec.as_build_ms(),
        setup_wait_ms: exec.fence_wait_ms(),
        device_features: exec.gpu.enabled_names.clone(),
        pipeline_cache: exec.cache_status.clone(),
        driver_cache: Some(driver_cache(&exec, &job)),
    });
    let serial: HashSet<&str> = job.serial.iter().map(String::as_str).collect();
    let chunks = job.cells.len().div_ceil(PREBUILD_CHUNK);
    for (k, chunk) in job.cells.chunks(PREBUILD_CHUNK).enumerate() {
        let overlap = job.overlaps();
        let hook = phases.hook.as_ref();
        let mut batch = overlap::start(&mut exec, chunk, &serial, job.threads, overlap, hook);
        for (i, cell) in chunk.iter().enumerate() {
            let last = i + 1 == chunk.len();
            run_cell(
                &mut exec,
                cell,
                serial.contains(cell.id().as_str()),
                &phases,
                &mut batch,
                last,
            );
            let next = if k * PREBUILD_CHUNK + i + 1 < job.cells.len() {
                Phase::BetweenCells
            } else {
                Phase::Teardown
            };
            // A loss injected here has nothing to fail; hang, crash and spam act by themselves.
            let _ = phases.enter(next, None);
        }
        if let Some(b) = batch {
            b.end(&mut exec);
        }
        // The chunk's cells ran: its pipelines go, so the live ones stay a chunk's whatever
        // the job's size (a later cell that shares one makes it again, from the cache). The
        // last chunk's go with the process, but under validation.
        if k + 1 < chunks || job.validate {
            exec.release_pipelines();
        }
    }
    finish(exec, job.validate)
}

/// One cell's turn: its `start`, phases and `result`, or, while the batch's pipelines are still
/// being made (`runner::overlap`), its phases as prebuild steps and its lines held back for
/// `prebuilt`. The batch's `prebuilt` goes out after the chunk's `last` cell at the latest.
fn run_cell(
    exec: &mut Executor,
    cell: &Cell,
    serial: bool,
    phases: &Phases,
    batch: &mut Option<overlap::Batch>,
    last: bool,
) {
    let id = cell.id();
    let overlapped = batch.as_mut().is_some_and(|b| b.before(exec, cell, serial));
    match batch.as_mut().filter(|_| overlapped) {
        Some(b) => {
            b.hold(WorkerMsg::Start { cell: id.clone() });
            match exec.run_traced(cell, &mut |p| phases.enter_overlapped(&id, p)) {
                Ran::Done(result) => {
                    if result.outcome.ends_worker() {
                        b.ended(&id, &result);
                    }
                    b.hold(WorkerMsg::Result { cell: id, result });
                }
                Ran::Traced(traced) => b.judge(exec, id, traced),
            }
        }
        None => {
            send(&WorkerMsg::Start { cell: id.clone() });
            let result = exec.run(cell, &mut |p| phases.enter(p, None));
            let ends = result.outcome.ends_worker();
            send(&WorkerMsg::Result { cell: id, result });
            if ends {
                // The device is lost or hung: do not run destructors that may wait on it.
                unsafe { libc::_exit(0) };
            }
        }
    }
    if let Some(b) = batch {
        b.after(exec, overlapped, last);
    }
}

/// After the last cell: the pipeline cache saved (`cache_saved`), then the exit — with every
/// object destroyed under validation, else at once ([`exit_without_teardown`]).
fn finish(exec: Executor, validate: bool) -> u8 {
    if let Some(saved) = exec.save_pipeline_cache() {
        let (bytes, error) = match saved {
            Ok(b) => (Some(b), None),
            Err(e) => {
                tracing::warn!("pipeline cache not saved: {e}");
                (None, Some(e))
            }
        };
        send(&WorkerMsg::CacheSaved { bytes, error });
    }
    if validate {
        // The layers check every object is destroyed before its device: destroy properly.
        drop(exec);
        return 0;
    }
    exit_without_teardown(exec)
}

/// The worker's work is done (every result sent, the pipeline cache saved): it says `exiting`
/// and ends the process without destroying its Vulkan objects, which on the H200 took 0.66 s
/// (528 pipelines, 660 libraries, the device) after the last result.
///
/// Safe: nothing of the device is used again, and the OS reclaims a process's memory and its
/// driver handles at exit (the kernel driver frees the GPU context when the device file closes).
/// The Vulkan spec (1.4.360, Vulkan-Docs HEAD) asks destruction only of an application that
/// destroys a parent: "All child objects created on device that can be destroyed or freed must
/// have been destroyed or freed prior to destroying device" (VUID-vkDestroyDevice-device-05137;
/// likewise VUID-vkDestroyInstance-instance-00629); its Device Destruction note says freeing
/// them explicitly is "to avoid resource leaks". No rule requires `vkDestroyDevice` or
/// `vkDestroyInstance` before a process exits, and neither is called here, so none is broken.
/// Under `--validate` the worker destroys everything instead (the layers report objects left at
/// `vkDestroyDevice`), and a lost or hung device already `_exit`s the same way.
fn exit_without_teardown(exec: Executor) -> ! {
    send(&WorkerMsg::Exiting);
    std::mem::forget(exec);
    // `_exit`, not `exit`: the driver's atexit handlers would tear down what `forget` kept.
    unsafe { libc::_exit(0) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_compiler_that_cannot_start_halts_the_run_and_other_setup_failures_do_not() {
        let f = SetupFailure::from(CompileError::Init);
        assert_eq!((f.outcome, f.halt), (Outcome::Error, Some(Halt::NoShaderCompiler)));
        assert_eq!(f.message, "the shader compiler (shaderc) could not be started");
        // The test hook fails the setup the same way, through the same conversion.
        let hooked = Phases { hook: Some(Misbehave::parse("setup:no_compiler").unwrap()) };
        assert_eq!(SetupFailure::from(hooked.compiler().unwrap_err()).halt, f.halt);
        assert!(Phases { hook: None }.compiler().is_ok());
        // The twins: a cell's GLSL error or a device loss stops this worker only.
        let glsl = CompileError::Glsl { file: "probe.rgen".into(), message: "bad".into() };
        assert_eq!(SetupFailure::from(glsl).halt, None);
        let lost = SetupFailure::from(VkError::DeviceLost { call: "vkQueueSubmit" });
        assert_eq!((lost.outcome, lost.halt), (Outcome::DeviceLost, None));
    }
    fn job(cells: &[Cell], glsl: Option<&str>) -> WorkerJob {
        serde_json::from_value(serde_json::json!({
            "device_index": 0,
            "scene": crate::model::SceneParams::default(),
            "fence_timeout_ms": 100,
            "validate": false,
            "dump": null,
            "cells": cells,
            "fresh": true,
            "glsl_cache": glsl,
        }))
        .unwrap()
    }

    /// A re-run alone (fresh: the driver's cache switched off) runs the SPIR-V kept in
    /// rtprobe's own GLSL cache, and keeps the driver afresh; a mutant compiles its own, and a
    /// job without the folder compiles the GLSL too.
    #[test]
    fn a_fresh_worker_reads_kept_spirv_but_not_the_drivers_cache_and_a_mutant_neither() {
        use crate::model::{DescriptorModel, IndexSource, Mutant, Resource, Stage};
        let cell = Cell::new(
            Stage::ClosestHit,
            Resource::StorageBuffer,
            IndexSource::Dynamic,
            DescriptorModel::DescriptorIndexing,
        );
        let rerun = job(&[cell], Some("/cache"));
        assert_eq!(glsl_cache(&rerun).as_deref(), Some(std::path::Path::new("/cache")));
        assert!(env_switch(&rerun), "the driver's own cache is still bypassed");
        let mutant = Cell { mutant: Some(Mutant::IndexZero), ..cell };
        assert_eq!(glsl_cache(&job(&[cell, mutant], Some("/cache"))), None);
        assert_eq!(glsl_cache(&job(&[cell], None)), None);
    }
}
