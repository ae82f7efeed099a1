//! The supervisor ↔ worker protocol. The supervisor writes a [`WorkerJob`] to a file and starts
//! `rtprobe __worker FILE` with stdin closed; the worker answers with one JSON [`WorkerMsg`] per
//! line on stdout. The worker never decides that it is dead: the supervisor does, from deadlines,
//! end of output and exit status.
use crate::model::Cell;
use crate::model::Phase;
use crate::model::SceneParams;
use crate::model::{CellResult, Halt, Outcome};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct WorkerJob {
    pub device_index: usize,
    pub scene: SceneParams,
    /// Fence deadline inside the worker (shorter than the supervisor's hard deadline).
    pub fence_timeout_ms: u64,
    /// Fence deadline of the setup's submissions (the scene's AS build, image uploads), inside
    /// the supervisor's setup deadline (absent: `fence_timeout_ms`).
    #[serde(default)]
    pub setup_fence_timeout_ms: u64,
    pub validate: bool,
    /// GPU-Assisted Validation on (`--validate=gpu-av`'s re-runs of findings).
    #[serde(default)]
    pub gpu_av: bool,
    /// `--inject-fault` injections (the worker applies the first that matches each cell).
    #[serde(default)]
    pub inject: Vec<crate::model::Injection>,
    /// Seed of the flaky-injection dice.
    #[serde(default)]
    pub inject_seed: u64,
    pub dump: Option<PathBuf>,
    /// A repro bundle's `shaders/`: its SPIR-V replaces the compiled (and patched) modules.
    #[serde(default)]
    pub spirv_dir: Option<PathBuf>,
    pub cells: Vec<Cell>,
    /// Threads creating pipelines ahead of the cells' turns (`--threads`; 1: each cell builds
    /// its own at its turn, the sequential path).
    #[serde(default = "one")]
    pub threads: usize,
    /// Cells never prebuilt (an earlier worker died or hung prebuilding them): they build at
    /// their turn, so a fault in their pipeline creation is theirs alone.
    #[serde(default)]
    pub serial: Vec<String>,
    /// Folder of the persisted pipeline caches (`--pipeline-cache`; `None`: off).
    #[serde(default)]
    pub pipeline_cache: Option<PathBuf>,
    /// Folder whose `glsl/` keeps GLSL → SPIR-V compiles (`shadergen::disk_cache`): rtprobe's
    /// own compiler's cache, not the driver's, so re-runs alone get it too and run the SPIR-V
    /// the matrix compiled while their pipelines still compile afresh; `None` (bisect, repro,
    /// GPU-AV, `--pipeline-cache off`) compiles the GLSL too. Mutant workers never read it.
    #[serde(default)]
    pub glsl_cache: Option<PathBuf>,
    /// `RTPROBE_BINDING_STAGES` of the run (`all`: bindings and push constants for every stage).
    /// It changes results, so it travels in the job, not through the worker's environment.
    #[serde(default)]
    pub binding_stages: Option<String>,
    /// `--lane-evidence` of the run (absent: `auto`).
    #[serde(default)]
    pub lane_evidence: crate::model::LaneMode,
    /// Compile afresh (re-runs of a cell alone, GPU-AV, bisect, repro): no pipeline cache, and
    /// the driver's own cache bypassed: `disableInternalCache` where `internal_cache_control`,
    /// else the drivers' documented environment switches.
    #[serde(default)]
    pub fresh: bool,
    /// The device offers `pipelineBinaryInternalCacheControl` (as the run read it, before any
    /// environment switch could hide it).
    #[serde(default)]
    pub internal_cache_control: bool,
    /// Ray tracing pipelines are linked from group libraries (`--pipelines`).
    #[serde(default)]
    pub linked: bool,
}

fn one() -> usize {
    1
}

impl WorkerJob {
    /// The runner's rule: whether a prebuilding worker may run cells while its batch's pipelines
    /// are still being made. Never under `--validate` or GPU-AV (validation errors are counted
    /// per cell around its own work, so nothing else may run meanwhile), whatever `--threads`;
    /// and only with more than one thread (one thread prebuilds nothing).
    pub fn overlaps(&self) -> bool {
        self.threads > 1 && !(self.validate || self.gpu_av)
    }
}

#[derive(Clone, Debug, Serialize, Deserialize)]
// One message per line, moved once: boxing the large variant would buy nothing.
#[allow(clippy::large_enum_variant)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum WorkerMsg {
    /// Setup finished: device created, scene acceleration structures and resources built, CPU
    /// reference computed. `device_features`: what the device was created with (extensions, then
    /// feature bits), copied into each attempt.
    Ready {
        device_ms: f64,
        /// Of `device_ms`, the instance and device creation (`vkCreateInstance`, the devices'
        /// query, `vkCreateDevice`): the driver's time (0 from older workers).
        #[serde(default)]
        create_ms: f64,
        reference_ms: f64,
        /// The scene's acceleration structures' build within `device_ms` (none: no cell of the
        /// worker traces the scene).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        as_build_ms: Option<f64>,
        /// Of `device_ms`, the time blocked on fences (the scene's AS build, uploads): queue
        /// waits, the driver's time (0 from older workers).
        #[serde(default)]
        setup_wait_ms: f64,
        #[serde(default)]
        device_features: Vec<String>,
        /// The pipeline cache file and what was loaded from it (absent: `--pipeline-cache off`).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        pipeline_cache: Option<crate::exec::pipeline_cache::Loaded>,
        /// The driver's pipeline-binary properties and the cache switch a fresh worker used.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        driver_cache: Option<crate::model::DriverCache>,
    },
    /// The worker builds these cells ahead of their turns (phase `prebuild`): compile and
    /// bindings in order, pipelines on `threads` threads. Progress comes as `phase` messages
    /// (`prebuild`, step `glsl k/n`, `compiled k/n` or `pipelines k/n`), each restarting the
    /// supervisor's deadline; a death or hang now is blamed on no cell.
    Prebuild {
        cells: Vec<String>,
        threads: usize,
    },
    /// The prebuild finished: every pipeline of the batch is made. Each cell's result (or
    /// error) waits for its turn; the `overlapped` cells that ran meanwhile send their held
    /// `start` and `result` lines right after this one (`runner::overlap`).
    Prebuilt {
        wall_ms: f64,
        pipelines: usize,
        threads: usize,
        #[serde(default)]
        overlapped: usize,
        /// Of those, the cells whose records were judged on the checker thread
        /// (`exec::checker`).
        #[serde(default)]
        checked_apart: usize,
    },
    /// After the last cell: the pipeline cache was written (`bytes`) or not (`error`).
    CacheSaved {
        #[serde(default, skip_serializing_if = "Option::is_none")]
        bytes: Option<u64>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        error: Option<String>,
    },
    /// Its last message: every result is sent and the pipeline cache saved, and the worker exits
    /// now without destroying its Vulkan objects (`runner::worker::exit_without_teardown`). The
    /// supervisor owes it nothing more: it reaps the process in the background.
    Exiting,
    /// The worker enters `phase` (`step` names the call, e.g. `vkCreateDevice`, in setup). The
    /// supervisor keeps the last one: a timeout or crash is attributed to it.
    Phase {
        phase: Phase,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        step: Option<String>,
    },
    Start {
        cell: String,
    },
    Result {
        cell: String,
        result: CellResult,
    },
    /// VK_EXT_device_fault's data of an overlapped cell whose device loss ends the worker, sent
    /// right before that `fatal` (`runner::overlap`): the prebuild's death keeps it.
    DeviceFault {
        cell: String,
        fault: crate::model::FaultInfo,
    },
    /// Setup failed: the worker cannot run its cells (or, during a prebuild, an error that ends
    /// the worker: a device loss or a hung fence). `outcome` classifies the failure
    /// (`device_lost`, `timeout` of a fence in an upload or AS build, `error`). `halt`: what
    /// failed stops the whole run, not only this worker (no shader compiler).
    Fatal {
        message: String,
        #[serde(default = "error_outcome")]
        outcome: Outcome,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        halt: Option<Halt>,
    },
}

fn error_outcome() -> Outcome {
    Outcome::Error
}

/// The `prebuild` step an overlapped cell's phase is told as (`runner::overlap`).
pub fn overlapped_step(cell: &str, phase: Phase) -> String {
    format!("cell {cell}: {phase}")
}

/// The cell an [`overlapped_step`] names, else `None` (a pool's step: `glsl k/n`, `compiled k/n`,
/// `pipelines k/n`).
pub fn overlapped_cell(step: &str) -> Option<&str> {
    step.strip_prefix("cell ")?.rsplit_once(": ").map(|(cell, _)| cell)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_are_one_json_object_with_a_type() {
        let m = WorkerMsg::Phase { phase: Phase::Pipeline, step: None };
        assert_eq!(serde_json::to_string(&m).unwrap(), r#"{"type":"phase","phase":"pipeline"}"#);
        let f: WorkerMsg = serde_json::from_str(r#"{"type":"fatal","message":"x"}"#).unwrap();
        assert!(matches!(f, WorkerMsg::Fatal { outcome: Outcome::Error, halt: None, .. }));
        let h = WorkerMsg::Fatal {
            message: "x".into(),
            outcome: Outcome::Error,
            halt: Some(Halt::NoShaderCompiler),
        };
        let line = serde_json::to_string(&h).unwrap();
        assert!(line.ends_with(r#""halt":"no_shader_compiler"}"#), "{line}");
        let back: WorkerMsg = serde_json::from_str(&line).unwrap();
        assert!(matches!(back, WorkerMsg::Fatal { halt: Some(Halt::NoShaderCompiler), .. }));
    }

    fn job() -> WorkerJob {
        WorkerJob {
            device_index: 0,
            scene: SceneParams::default(),
            fence_timeout_ms: 100,
            setup_fence_timeout_ms: 100,
            validate: false,
            gpu_av: false,
            inject: vec![],
            inject_seed: 0,
            dump: None,
            spirv_dir: None,
            cells: vec![],
            threads: 1,
            serial: vec![],
            pipeline_cache: None,
            glsl_cache: None,
            binding_stages: None,
            lane_evidence: crate::model::LaneMode::Force,
            fresh: false,
            internal_cache_control: false,
            linked: false,
        }
    }

    /// The runner's own rule, apart from the CLI (which already runs one thread under
    /// `--validate`): a job with validation or GPU-AV on and several threads never overlaps.
    #[test]
    fn validation_never_overlaps_whatever_the_threads() {
        for threads in [2, 4, 64] {
            let plain = WorkerJob { threads, ..job() };
            assert!(plain.overlaps(), "{threads} threads, no validation: cells overlap");
            assert!(!WorkerJob { validate: true, threads, ..job() }.overlaps(), "{threads}");
            assert!(!WorkerJob { gpu_av: true, threads, ..job() }.overlaps(), "{threads}");
        }
        // One thread prebuilds nothing, so nothing overlaps either.
        assert!(!WorkerJob { threads: 1, ..job() }.overlaps());
    }

    #[test]
    fn the_binding_stages_travel_in_the_job_and_older_jobs_have_none() {
        let job = WorkerJob { binding_stages: Some("all".into()), ..job() };
        let mut v = serde_json::to_value(&job).unwrap();
        assert_eq!(
            serde_json::from_value::<WorkerJob>(v.clone()).unwrap().binding_stages.as_deref(),
            Some("all")
        );
        v.as_object_mut().unwrap().remove("binding_stages");
        assert_eq!(
            serde_json::from_value::<WorkerJob>(v.clone()).unwrap().lane_evidence,
            crate::model::LaneMode::Force
        );
        v.as_object_mut().unwrap().remove("lane_evidence");
        let old = serde_json::from_value::<WorkerJob>(v).unwrap();
        assert_eq!((old.binding_stages, old.lane_evidence), (None, crate::model::LaneMode::Auto));
    }

    #[test]
    fn an_overlapped_step_names_its_cell_and_a_pool_step_none() {
        let id = "closest_hit.storage_buffer.dynamic.descriptor_indexing";
        assert_eq!(overlapped_cell(&overlapped_step(id, Phase::Trace)), Some(id));
        for step in ["pipelines 3/9", "compiled 1/512", "glsl 4/9"] {
            assert_eq!(overlapped_cell(step), None, "{step}");
        }
    }
}
