//! What the commands that run or re-run cells share: the report they start from and its device,
//! workers and threads per device type, the supervisor options of a re-run, and the
//! supervisor-backed oracle that `run`'s rounds and `bisect` run cells through.
use super::commands::{open_instance, Globals};
use super::exit::{self, coded};
use super::out::errln;
use crate::model::Cell;
use crate::model::{Injection, Isolation, RunReport, SceneParams};
use crate::runner::oracle::{Event, Mode, Oracle};
use crate::runner::supervisor::{Supervisor, SupervisorOptions};
use crate::vk::{features, DeviceInfo, Instance};
use anyhow::Result;
use std::path::Path;
use std::sync::Arc;
use std::time::Duration;

pub fn load_report(path: &Path) -> Result<RunReport> {
    RunReport::load(path).map_err(|e| coded(exit::BAD_INPUT, e))
}

/// The device the report was made on, on this machine: the same card (device UUID) if it is here,
/// else a card of the same name and driver build (name, driver version, driver UUID) — another
/// machine of a fleet, or the same model leased again, reproduces a driver's fault as well. The
/// third value is the device UUID of the card used when it is not the report's (a one-line
/// warning says so on stderr; bisect records it as `device_uuid_rerun`).
pub(crate) fn report_device(
    g: &Globals,
    r: &RunReport,
) -> Result<(Arc<Instance>, DeviceInfo, Option<String>)> {
    let inst = open_instance(g)?;
    let all = features::query_all(&inst)?;
    let same = |d: &DeviceInfo, keys: &[&str]| {
        let j = crate::caps::device_json(d);
        keys.iter().all(|k| j[*k] == r.device[*k])
    };
    const DRIVER: [&str; 3] = ["name", "driver_version", "driver_uuid"];
    let card = all.iter().find(|d| same(d, &DRIVER) && same(d, &["device_uuid"]));
    let other = card.is_none();
    let info = card.or_else(|| all.iter().find(|d| same(d, &DRIVER))).cloned().ok_or_else(|| {
        coded(
            exit::BAD_DEVICE_SELECTION,
            format!(
                "the report was made on {} (driver {}), which is not on this machine; `rtprobe bisect --offline` uses the report's verdicts alone",
                r.device["name"].as_str().unwrap_or("?"),
                r.device["driver_version"]["decoded"].as_str().unwrap_or("?")
            ),
        )
    })?;
    let rerun = other.then(|| {
        let j = crate::caps::device_json(&info);
        let uuid = j["device_uuid"].as_str().unwrap_or("?").to_string();
        errln!(
            "rtprobe: warning: the report's card (UUID {}) is not here; re-running on {} UUID {uuid} of the same driver build",
            r.device["device_uuid"].as_str().unwrap_or("?"),
            j["name"].as_str().unwrap_or("?")
        );
        uuid
    });
    Ok((inst, info, rerun))
}

/// One worker per core on CPU implementations (lavapipe JITs each pipeline on one thread), one
/// on GPUs (the driver parallelises; several processes only contend for one device).
pub(crate) fn default_jobs(info: &crate::vk::DeviceInfo) -> usize {
    if info.properties.core.device_type == ash::vk::PhysicalDeviceType::CPU {
        std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1).clamp(1, 8)
    } else {
        1
    }
}

/// Fresh workers at once when cells are re-run alone (confirm, repeats, verifying repeats,
/// GPU-AV, bisect's repeats), each still alone in its own process: on CPU devices `jobs`, at
/// most one per core (lavapipe JITs each pipeline on one thread, so two processes use two
/// cores); on GPUs one, whatever `-j` says: a device loss or hang in one process can take the
/// other processes' contexts on the same GPU with it, and its fault would then be theirs too.
pub(crate) fn rerun_jobs(info: &crate::vk::DeviceInfo, jobs: usize) -> usize {
    if info.properties.core.device_type == ash::vk::PhysicalDeviceType::CPU {
        let cores = std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1);
        jobs.clamp(1, cores.max(1))
    } else {
        1
    }
}

/// `--pipelines` for `info`: `auto` resolved (linked on GPUs with VK_KHR_pipeline_library, whole
/// on CPU devices); `linked` on a device without the extension is an error.
pub(crate) fn pipeline_mode(
    mode: crate::model::PipelineMode,
    info: &crate::vk::DeviceInfo,
) -> Result<crate::model::PipelineMode, String> {
    use crate::model::PipelineMode;
    let has = info.has_extension(ash::khr::pipeline_library::NAME);
    let cpu = info.properties.core.device_type == ash::vk::PhysicalDeviceType::CPU;
    match mode {
        PipelineMode::Auto if has && !cpu => Ok(PipelineMode::Linked),
        PipelineMode::Auto | PipelineMode::Whole => Ok(PipelineMode::Whole),
        PipelineMode::Linked if has => Ok(PipelineMode::Linked),
        PipelineMode::Linked => Err(format!(
            "--pipelines linked: {} lacks VK_KHR_pipeline_library; use --pipelines whole",
            info.name()
        )),
    }
}

/// Pipeline-creation threads per worker: the cores (at most 16) on GPUs, where creating
/// pipelines is most of a cell's time; 1 on CPU devices, whose workers already take one core
/// each and which compile at the first trace (measured on lavapipe: docs/performance.md).
pub(crate) fn default_threads(info: &crate::vk::DeviceInfo) -> usize {
    if info.properties.core.device_type == ash::vk::PhysicalDeviceType::CPU {
        1
    } else {
        std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1).clamp(1, 16)
    }
}

/// The supervisor options of a run (also used by `bisect`): no dump, the job files under the temp
/// dir, one thread, and no persisted pipeline cache: a re-run of a report's cells starts cold, so
/// that a cached binary cannot stand in for the cell's own compile (`run` sets its own folder),
/// and no binding stages: a caller re-running a report's cells sets the report's.
pub(crate) fn supervisor_options(
    device_index: usize,
    scene: SceneParams,
    jobs: usize,
    isolation: Isolation,
    timeout_s: f64,
    validate: bool,
    inject: Vec<Injection>,
) -> SupervisorOptions {
    SupervisorOptions {
        device_index,
        scene,
        jobs,
        // One at a time unless the caller knows the device ([`rerun_jobs`]).
        rerun_jobs: 1,
        isolation,
        timeout: Duration::from_secs_f64(timeout_s),
        setup_timeout: Duration::from_secs(120),
        grace: Duration::from_millis(500),
        kill_wait: Duration::from_secs(5),
        validate,
        gpu_av: false,
        inject,
        dump: None,
        spirv_dir: None,
        threads: 1,
        pipeline_cache: None,
        binding_stages: None,
        lane_evidence: crate::model::LaneMode::Auto,
        fresh: true,
        internal_cache_control: false,
        linked: false,
    }
}

/// What a report's run set that changes results, applied to the supervisor options of a re-run
/// of its cells (`bisect`, the validated run): binding stages, lane evidence, and how
/// ray tracing pipelines were made (a linked pipeline can fault where a whole one does not; a
/// report from before `--pipelines` made them whole).
pub(crate) fn as_the_report_ran(
    opts: &mut SupervisorOptions,
    r: &crate::model::options::RunOptions,
) {
    opts.binding_stages = r.binding_stages.clone();
    opts.lane_evidence = r.lane_evidence;
    opts.linked = r.pipelines == Some(crate::model::PipelineMode::Linked);
}

/// The supervisor-backed [`Oracle`] of `run` and `bisect`. Under GPU-AV (`run
/// --validate=gpu-av`'s findings) each batch gets a fresh supervisor with validation and GPU-AV
/// on, one thread, no pipeline cache and its own job folder.
pub(crate) struct SupervisorOracle {
    opts: SupervisorOptions,
    /// `run`'s one supervisor for all its other batches; `None` (`bisect`): a fresh one per batch,
    /// so that nothing a worker of an earlier batch sent late reaches a later one (bisection runs
    /// many small batches).
    shared: Option<Supervisor>,
    /// `bisect`: say each batch on stderr (through tracing when stderr is not a terminal).
    announce: bool,
    /// Attempts so far (what the announcements count).
    attempts: usize,
}

impl SupervisorOracle {
    pub(crate) fn for_run(opts: SupervisorOptions) -> Self {
        SupervisorOracle {
            shared: Some(Supervisor::new(opts.clone())),
            opts,
            announce: false,
            attempts: 0,
        }
    }

    pub(crate) fn for_bisect(opts: SupervisorOptions) -> Self {
        SupervisorOracle { opts, shared: None, announce: true, attempts: 0 }
    }

    fn say(&self, cells: usize, mode: Mode) {
        let msg = format!(
            "bisect: running {}{} ({} run so far)",
            crate::model::plural(cells, "cell"),
            if mode == Mode::Shared { "" } else { ", each alone" },
            self.attempts
        );
        if std::io::IsTerminal::is_terminal(&std::io::stderr()) {
            errln!("{msg}");
        } else {
            tracing::info!("{msg}");
        }
    }
}

impl Oracle for SupervisorOracle {
    fn run(&mut self, cells: &[Cell], mode: Mode, on: &mut dyn FnMut(Event)) {
        if self.announce {
            self.say(cells.len(), mode);
        }
        let attempts = &mut self.attempts;
        let on = &mut |ev: Event| {
            *attempts += matches!(ev, Event::Attempt { .. }) as usize;
            on(ev)
        };
        let isolated = mode != Mode::Shared;
        match (mode, &mut self.shared) {
            (Mode::GpuAv, _) => {
                let o = SupervisorOptions {
                    validate: true,
                    gpu_av: true,
                    threads: 1,
                    pipeline_cache: None,
                    fresh: true,
                    ..self.opts.clone()
                };
                Supervisor::new(o).run(cells, true, on)
            }
            (_, Some(sup)) => sup.run(cells, isolated, on),
            (_, None) => Supervisor::new(self.opts.clone()).run(cells, isolated, on),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::options::RunOptions;
    use crate::model::PipelineMode;

    /// Re-runs alone on a CPU device run side by side, up to `-j` and the cores; on a GPU one
    /// at a time whatever `-j` says (a device loss in one process can take the others').
    #[test]
    fn reruns_run_side_by_side_on_cpu_devices_only() {
        let device = |t: ash::vk::PhysicalDeviceType| {
            let mut info = crate::vk::features::blank_device();
            info.properties.core.device_type = t;
            info
        };
        let cores = std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1);
        let cpu = device(ash::vk::PhysicalDeviceType::CPU);
        assert_eq!(rerun_jobs(&cpu, 64), cores, "at most one per core");
        assert_eq!(rerun_jobs(&cpu, 1), 1, "-j 1 is one at a time");
        assert_eq!(rerun_jobs(&cpu, 2), 2.min(cores));
        let gpu = device(ash::vk::PhysicalDeviceType::DISCRETE_GPU);
        assert_eq!(rerun_jobs(&gpu, 8), 1);
        assert_eq!(rerun_jobs(&device(ash::vk::PhysicalDeviceType::INTEGRATED_GPU), 4), 1);
    }

    /// A re-run of a report's cells (bisect, the validated run) makes its ray tracing
    /// pipelines as the report's run did; whole where the report says whole or says nothing (it
    /// predates `--pipelines`), whatever the caller's options held.
    #[test]
    fn a_rerun_makes_pipelines_the_way_the_report_did() {
        let rerun = |mode: Option<PipelineMode>, before: bool| {
            let mut o = supervisor_options(
                0,
                SceneParams::default(),
                1,
                Isolation::Worker,
                5.0,
                false,
                vec![],
            );
            o.linked = before;
            let r = RunOptions {
                pipelines: mode,
                binding_stages: Some("rgen".into()),
                ..RunOptions::for_tests()
            };
            as_the_report_ran(&mut o, &r);
            assert_eq!(o.binding_stages.as_deref(), Some("rgen"));
            o.linked
        };
        assert!(rerun(Some(PipelineMode::Linked), false));
        assert!(!rerun(Some(PipelineMode::Whole), true));
        assert!(!rerun(None, true));
    }
}
