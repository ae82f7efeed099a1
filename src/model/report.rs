//! The run report (`"schema": "rtprobe.report/1"`): what ran, on what, with which scene, and per
//! cell its axes, outcome, attempts (timings, mismatch and fault details, worker exit). Cells are
//! kept in plan order, so reports of the same plan diff cleanly. Written atomically as the run
//! goes (`cli::run`: at once after a fault, passes at most every 100 ms); `--resume` reads it back.
use super::load::LoadError;
pub use super::options::{ResultOption, RunOptions};
use crate::model::NotGenerated;
use crate::model::Outcome;
use crate::model::SceneParams;
use crate::model::{Attempt, WorkerEvent};
use crate::model::{Canary, Cell};
use serde::{Deserialize, Serialize};
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::Path;

pub const SCHEMA: &str = "rtprobe.report/1";

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct CanaryCheck {
    /// Outcomes that prove detection works.
    pub expected: Vec<Outcome>,
    pub detected: bool,
}

pub fn canary_expectation(c: Canary) -> Vec<Outcome> {
    match c {
        Canary::InvalidAddress => vec![Outcome::Crash, Outcome::DeviceLost],
        Canary::InfiniteLoop => vec![Outcome::Timeout, Outcome::DeviceLost],
    }
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct CellReport {
    pub id: String,
    #[serde(flatten)]
    pub cell: Cell,
    /// The verdict: the worst outcome of all attempts (a fault seen once stays a finding).
    pub outcome: Outcome,
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub reason: Option<String>,
    /// With several attempts: `Some(true)` when the verdict's fault was seen more than once.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub confirmed: Option<bool>,
    /// How often the cell faulted, for a cell with a finding.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub incidence: Option<Incidence>,
    /// The attempts disagree (some faulted, some did not, or they faulted differently).
    #[serde(skip_serializing_if = "std::ops::Not::not", default)]
    pub flaky: bool,
    /// The `--inject-fault` argument that made this cell misbehave on purpose.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub injected: Option<String>,
    /// A dynamic descriptor index without `nonuniformEXT`: the rule it breaks (the spec
    /// guarantees nothing about which element it reads); the reads are counted per attempt in
    /// `comparison.element_reads`.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub outside_spec: Option<String>,
    /// An attempt ran with its injected fault and still passed: `--inject-fault` could not make
    /// this cell misbehave, so detection on this driver is unproven (the run exits 11 when
    /// nothing else is wrong).
    #[serde(skip_serializing_if = "std::ops::Not::not", default)]
    pub injection_undetected: bool,
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub canary_check: Option<CanaryCheck>,
    /// For a cell with a finding: each workaround tried and its outcome.
    #[serde(skip_serializing_if = "Vec::is_empty", default)]
    pub workarounds: Vec<WorkaroundResult>,
    /// For a cell with a finding: whether the engines' recommended pattern nearest to it works
    /// (`report::recommended`).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub recommended: Option<crate::model::PatternResult>,
    /// For a cell with a finding, with `--validate=gpu-av`: whether GPU-AV masks it
    /// (`report::gpu_av`; those attempts are not among `attempts`).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub gpu_av: Option<crate::model::GpuAvResult>,
    /// Not a planned cell: a round added it to test a finding (a workaround variant, or a
    /// recommended pattern the plan lacked). Counted apart from the plan (`RunReport::retries`),
    /// never a finding or a baseline regression of its own. Reports before this field mark
    /// nothing: their workaround variants are retries where the run did not plan them
    /// ([`CellReport::is_retry`]).
    #[serde(skip_serializing_if = "std::ops::Not::not", default)]
    pub retry: bool,
    #[serde(default)]
    pub attempts: Vec<Attempt>,
}

/// `faulted` of `attempts` attempts were findings.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Incidence {
    pub faulted: u32,
    pub attempts: u32,
    /// Whether any attempt that ran alone in a fresh worker faulted (None: none ran alone).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub reproduced_alone: Option<bool>,
    /// The chance that a fault of the observed rate (faulted / attempts) would pass all of
    /// `attempts` attempts: `(1 - faulted/attempts)^attempts` (binomial, independent attempts).
    pub miss_probability: f64,
}

impl Incidence {
    pub fn rate(&self) -> f64 {
        self.faulted as f64 / self.attempts.max(1) as f64
    }

    /// `1 of 2 attempts; not reproduced alone`
    pub fn label(&self) -> String {
        let mut s = format!("{} of {} attempts", self.faulted, self.attempts);
        if let Some(false) = self.reproduced_alone {
            s += "; not reproduced alone"
        }
        if self.faulted < self.attempts {
            s += &format!(
                "; {:.2}% chance that {} attempts miss a fault of this rate",
                100.0 * self.miss_probability,
                self.attempts
            );
        }
        s
    }
}

impl CellReport {
    /// Whether the cell is a round's retry rather than a planned cell ([`CellReport::retry`]; a
    /// workaround variant of a run that did not plan them, `patches` not `all`).
    /// A finding: a planned probe cell (no canary, no workaround variant, no other retry) whose
    /// worst attempt faulted or mismatched.
    pub fn is_finding(&self) -> bool {
        self.cell.canary.is_none()
            && self.cell.patch.is_none()
            && !self.retry
            && self.outcome.is_finding()
    }

    pub fn is_retry(&self, patches: crate::model::PatchMode) -> bool {
        self.retry || (self.cell.patch.is_some() && patches != crate::model::PatchMode::All)
    }

    /// The own/other/neither element reads of each attempt that compared (cells without
    /// `nonuniformEXT` on a dynamic descriptor index).
    pub fn element_reads(&self) -> impl Iterator<Item = &crate::model::ElementReads> {
        self.attempts
            .iter()
            .filter_map(|a| a.result.as_ref()?.comparison.as_ref()?.element_reads.as_ref())
    }

    /// Whether an attempt of this cell, which lacks `nonuniformEXT`, mismatched where its read is
    /// defined all the same: on a subgroup the device's lane evidence proves uniform
    /// (`ElementReads::uniform_mismatched`, `VUID-RuntimeSpirv-subgroupSize-10149`), or on lane
    /// words whose subgroup's records contradict each other (subgroup ballot the device supports
    /// in the stage is defined). Such a fault is settled evidence, not an undefined read's.
    pub fn defined_mismatch(&self) -> bool {
        self.attempts.iter().filter(|a| a.outcome == crate::model::Outcome::Mismatch).any(|a| {
            a.result.as_ref().and_then(|r| r.comparison.as_ref()).is_some_and(|c| {
                c.element_reads.as_ref().is_some_and(|e| e.uniform_mismatched > 0)
                    || (c.lane_contradictions > 0
                        && c.lane_evidence == crate::model::LaneEvidence::Supported)
            })
        })
    }

    /// A cell with its first attempt.
    pub fn new(cell: &Cell, attempt: Attempt) -> Self {
        let mut c = CellReport::unrun(cell, attempt.outcome, String::new());
        c.attempts.push(attempt);
        c.refresh();
        c
    }

    /// A planned cell that did not run (`unsupported`, with the device's reason).
    pub fn unrun(cell: &Cell, outcome: Outcome, reason: String) -> Self {
        CellReport {
            id: cell.id(),
            cell: *cell,
            outcome,
            reason: Some(reason),
            confirmed: None,
            incidence: None,
            flaky: false,
            injected: None,
            outside_spec: None,
            injection_undetected: false,
            canary_check: None,
            workarounds: vec![],
            recommended: None,
            gpu_av: None,
            retry: false,
            attempts: vec![],
        }
    }

    /// (faulted, attempts) over the attempts that are evidence about the driver
    /// ([`Attempt::is_evidence`]): what the incidence and bisection count.
    pub fn evidence_counts(&self) -> (u32, u32) {
        let n = self.attempts.iter().filter(|a| a.is_evidence()).count() as u32;
        let k = self.attempts.iter().filter(|a| a.faulted()).count() as u32;
        (k, n)
    }

    /// Recompute the verdict from every attempt: the worst outcome, its incidence, whether the
    /// attempts disagree, and (for a canary) whether the fault was detected.
    ///
    /// Attempts that never ran the cell (its worker's setup failed: `Attempt::not_run`) decide
    /// the verdict only while the cell has no other attempt: the setup's fault is then the cell's
    /// outcome (the worker's own record carries it too), but it never counts towards a rate.
    pub fn refresh(&mut self) {
        let ran: Vec<&Attempt> = self.attempts.iter().filter(|a| !a.not_run()).collect();
        let counted: Vec<&Attempt> =
            if ran.is_empty() { self.attempts.iter().collect() } else { ran };
        let Some(worst) = counted.iter().max_by_key(|a| a.outcome.severity()) else {
            return;
        };
        let (outcome, detail) = (worst.outcome, worst.detail.clone());
        let (k, n) = self.evidence_counts();
        let alone: Vec<&&Attempt> =
            counted.iter().skip(1).filter(|a| a.isolated && a.is_evidence()).collect();
        self.outcome = outcome;
        self.flaky = counted.iter().any(|a| a.outcome != outcome);
        self.confirmed =
            (n > 1).then(|| counted.iter().filter(|a| a.outcome == outcome).count() > 1);
        // An injected fault that an attempt ran with (armed, for flaky) and that still passed:
        // detection is unproven there, as with an undetected canary.
        self.injection_undetected = self.attempts.iter().any(|a| {
            a.outcome == Outcome::Pass
                && a.injected.as_ref().is_some_and(|i| i.armed != Some(false))
        });
        // Incidence is over the evidence only (`Attempt::is_evidence`), as bisection counts it: an
        // `error` verdict, or one no attempt that ran decided, has none.
        self.incidence = (outcome.is_finding() && n > 0).then(|| Incidence {
            faulted: k,
            attempts: n,
            reproduced_alone: (!alone.is_empty())
                .then(|| alone.iter().any(|a| a.outcome.is_finding())),
            miss_probability: crate::model::stats::miss(k as f64 / n as f64, n),
        });
        self.injected =
            self.attempts.iter().find_map(|a| a.injected.as_ref()).map(|i| i.spec.clone());
        // Labelled from the cell's shape, so a cell that crashed (no comparison) carries it too,
        // or from a comparison judged so (the compiler dropped a nonuniformEXT: `exec::seen`).
        let judged_undefined = self.attempts.iter().any(|a| {
            a.result
                .as_ref()
                .and_then(|r| r.comparison.as_ref())
                .is_some_and(|c| c.element_reads.is_some())
        });
        self.outside_spec = (crate::model::undefined_descriptor_read(&self.cell)
            || judged_undefined)
            .then(|| crate::model::NO_NONUNIFORM_VUID.to_string());
        self.reason = match (&self.incidence, detail) {
            (Some(inc), d) if n > 1 => {
                Some(format!("{} ({})", d.unwrap_or_else(|| outcome.as_str().into()), inc.label()))
            }
            (_, d) => d,
        };
        self.canary_check = self.cell.canary.map(|c| {
            let expected = canary_expectation(c);
            CanaryCheck { detected: expected.contains(&outcome), expected }
        });
    }
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct WorkaroundResult {
    pub patch: crate::model::Workaround,
    pub cell: String,
    pub outcome: Outcome,
    /// The patched cell passed where the plain one did not, on enough attempts that a fault as
    /// frequent as the finding's would have shown (`miss_probability` below
    /// `bisect::DEFAULT_MAX_MISS`): a verified workaround. Fewer passes are reported as passes,
    /// not as verified.
    pub verified: bool,
    /// Attempts of the patched cell that ran, and (when it passed against a finding) the chance
    /// they would all have missed a fault as frequent as the finding's
    /// (`model::stats::pass_miss`).
    #[serde(default)]
    pub attempts: u32,
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub miss_probability: Option<f64>,
}

impl WorkaroundResult {
    /// `interleave → not proven (2 passes; need 19 for 99%)` / `interleave → crash`.
    pub fn tried(&self) -> String {
        match self.outcome {
            Outcome::Pass => format!(
                "{} → {}",
                self.patch.as_str(),
                crate::model::stats::passes_text(
                    self.attempts,
                    self.attempts,
                    self.miss_probability
                )
            ),
            o => format!("{} → {}", self.patch.as_str(), o.as_str()),
        }
    }
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct PlanSummary {
    /// Cells of the full matrix (before filters and support checks).
    pub generated: usize,
    pub filtered_out: usize,
    pub planned: usize,
    pub to_run: usize,
    pub unsupported: usize,
    /// Planned cells rtprobe cannot run yet (outcome `not_implemented`, with the reason).
    #[serde(default)]
    pub not_implemented: usize,
    pub not_generated: Vec<NotGenerated>,
    /// Cells left to the other shards (`--shard I/N`).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub sharded_out: usize,
}

fn is_zero(n: &usize) -> bool {
    *n == 0
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct SceneSummary {
    pub params: SceneParams,
    pub instances: usize,
    pub blas: usize,
    pub triangles: usize,
    /// Pixels skipped by the comparison because their primary hit lies within the margin.
    pub ambiguous_pixels: usize,
    /// Cells the scene cannot discriminate, by why (`run --scene`; `reference::limits`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub limits: Vec<crate::model::SceneLimit>,
    /// The scene's CPU cost before any cell (absent in reports before it was measured).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cost: Option<crate::model::SceneCost>,
}

/// What the run found, beside the outcome counts.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct Tally {
    /// Probe cells with a finding (their worst attempt faulted or mismatched).
    pub findings: usize,
    /// Findings whose attempts disagree.
    pub flaky: usize,
    pub canaries_detected: usize,
    pub canaries_undetected: usize,
    /// Cells whose `--inject-fault` ran and still passed.
    #[serde(default)]
    pub injections_undetected: usize,
    /// Worker faults outside any cell (failed setups, crashes between cells, hung teardowns).
    #[serde(default)]
    pub worker_faults: usize,
}

#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct TimingSummary {
    pub wall_ms: f64,
    pub workers_started: usize,
    /// Mean device setup time of the workers (instance, device, the scene's acceleration
    /// structures, resources; the AS build below is part of it).
    pub device_ms_mean: f64,
    /// Workers that built the scene's acceleration structures in their setup, and the build's
    /// host-side wall time (geometry upload, BLAS and TLAS builds, the fence wait): mean and
    /// slowest worker. Part of `device_ms_mean`.
    #[serde(default)]
    pub as_builds: usize,
    #[serde(default)]
    pub as_build_ms_mean: f64,
    #[serde(default)]
    pub as_build_ms_max: f64,
    /// Sums over cells of the worker-side split.
    pub compile_ms: f64,
    pub pipeline_ms: f64,
    pub setup_ms: f64,
    pub trace_ms: f64,
    pub check_ms: f64,
    /// Of `check_ms`, the records' readback (0 in older reports).
    #[serde(default)]
    pub readback_ms: f64,
    /// Supervisor-observed wall time of all attempts minus the worker-side split: process,
    /// protocol and bookkeeping overhead.
    pub overhead_ms: f64,
    pub cells_timed: usize,
    /// Wall time of the workers' prebuilds (pipelines created on `--threads` threads ahead of
    /// the cells' turns), summed over workers; the cells' `pipeline_ms` is each pipeline's time
    /// on its thread.
    #[serde(default)]
    pub prebuild_ms: f64,
    /// Pipelines those prebuilds created.
    #[serde(default)]
    pub prebuilt_pipelines: usize,
    /// Cells that ran while their prebuild's pipelines were still being made (overlapped).
    #[serde(default)]
    pub overlapped_cells: usize,
    /// Of those, the cells whose records were judged on a checker thread while the cell thread
    /// went on (`exec::checker`; 0 in older reports).
    #[serde(default)]
    pub checked_apart: usize,
    /// The workers' instance and device creation, summed (part of `device_ms_mean`'s workers'
    /// setup; 0 in older reports).
    #[serde(default)]
    pub device_create_ms: f64,
    /// Sum over timed cells of `Timings::pipeline_wait_ms`: the cell thread blocked on, or
    /// creating, a pipeline (0 in older reports).
    #[serde(default)]
    pub pipeline_wait_ms: f64,
    /// The workers' setup time blocked on the queue (fence waits of the scene's AS build and
    /// the uploads), summed (part of `device_ms_mean`'s workers' setup; 0 in older reports).
    #[serde(default)]
    pub setup_wait_ms: f64,
    /// rtprobe's own time: `wall_ms` less the driver's time on the critical path (device
    /// creation, the setup's queue waits, pipeline waits, the cells' fence waits); see
    /// [`own_ms`] and docs/performance.md. `None` in older reports.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub own_ms: Option<f64>,
}

/// The driver's time on a run's critical path, each part summed over workers.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DriverMs {
    /// The workers' instance and device creation.
    pub create: f64,
    /// The workers' setup blocked on the queue (AS build, uploads).
    pub setup_wait: f64,
    /// The cell thread's pipeline waits.
    pub pipeline_wait: f64,
    /// The cells' submit-to-fence time (the timed cells' `trace_ms`).
    pub fence: f64,
}

impl DriverMs {
    /// The parts a report's timing holds.
    pub fn of(t: &TimingSummary) -> Self {
        DriverMs {
            create: t.device_create_ms,
            setup_wait: t.setup_wait_ms,
            pipeline_wait: t.pipeline_wait_ms,
            fence: t.trace_ms,
        }
    }
}

/// rtprobe's own time in a run of `wall_ms`: the wall less the driver's time on the critical
/// path ([`DriverMs`]: device creation, the setup's queue waits, the cell thread's pipeline
/// waits, the cells' queue waits), summed over workers and divided by the `slots` that ran at
/// once (exact for one slot; with several an estimate that assumes the driver's time spread
/// evenly). Never below 0.
pub fn own_ms(wall_ms: f64, d: DriverMs, slots: usize) -> f64 {
    let driver = (d.create + d.setup_wait + d.pipeline_wait + d.fence) / slots.max(1) as f64;
    (wall_ms - driver).max(0.0)
}

#[cfg(test)]
mod own_tests {
    use super::{own_ms, DriverMs, TimingSummary};

    fn d(create: f64, setup_wait: f64, pipeline_wait: f64, fence: f64) -> DriverMs {
        DriverMs { create, setup_wait, pipeline_wait, fence }
    }

    #[test]
    fn own_time_is_the_wall_less_the_driver_on_the_critical_path() {
        // The H200's warm run's shape: 2.4 s wall, 0.38 s device, 0.9 s waits, 0.1 s fences.
        assert!((own_ms(2400.0, d(380.0, 0.0, 900.0, 100.0), 1) - 1020.0).abs() < 1e-9);
        // Two slots at once: the driver's sums are shared between them.
        assert!((own_ms(2400.0, d(760.0, 0.0, 1800.0, 200.0), 2) - 1020.0).abs() < 1e-9);
        // No slot recorded (a run with no worker): counted as one.
        assert_eq!(own_ms(10.0, d(4.0, 0.0, 0.0, 0.0), 0), 6.0);
        // Garbage in (driver sums beyond the wall, NaN-free): never negative.
        assert_eq!(own_ms(100.0, d(80.0, 0.0, 50.0, 0.0), 1), 0.0);
    }

    #[test]
    fn the_setups_queue_waits_are_the_drivers_not_rtprobes() {
        // s31's H200 warm run: 1.9 s wall, device 0.35 s, pipeline waits 0.29 s, fences 0.12 s;
        // a setup that waited 0.08 s on its AS build and uploads: own 1.14 s, not 1.22 s.
        let t = TimingSummary {
            device_create_ms: 350.0,
            setup_wait_ms: 80.0,
            pipeline_wait_ms: 290.0,
            trace_ms: 120.0,
            ..Default::default()
        };
        let with = own_ms(1980.0, DriverMs::of(&t), 1);
        assert!((with - 1140.0).abs() < 1e-9, "{with}");
        // Its twin: the same run without the setup's waits counts them as rtprobe's.
        let without = own_ms(1980.0, DriverMs { setup_wait: 0.0, ..DriverMs::of(&t) }, 1);
        assert!((without - with - 80.0).abs() < 1e-9, "{without} against {with}");
        // An older report's timing (no `setup_wait_ms`) still loads, with 0 for it.
        let old: TimingSummary = serde_json::from_str(
            r#"{"wall_ms":1,"workers_started":1,"device_ms_mean":1,"compile_ms":0,
               "pipeline_ms":0,"setup_ms":0,"trace_ms":0,"check_ms":0,"overhead_ms":0,
               "cells_timed":0}"#,
        )
        .expect("an old timing loads");
        assert_eq!(old.setup_wait_ms, 0.0);
    }
}

/// The persisted pipeline cache of a run (`--pipeline-cache`): what the workers loaded and saved.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct PipelineCacheSummary {
    pub file: Option<std::path::PathBuf>,
    /// Workers that started from stored bytes, and the most bytes one of them loaded.
    pub workers_loaded: usize,
    pub loaded_bytes: u64,
    /// Why stored files were ignored (corrupt, truncated, another device or driver).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub ignored: Vec<String>,
    /// Saves made, and the bytes of the last one.
    pub saves: usize,
    pub saved_bytes: u64,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub save_errors: Vec<String>,
}

/// One `--resume` of a report.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Resumed {
    /// When the resumed run started (RFC 3339, UTC).
    pub at: String,
    /// Cells with an attempt that ran, kept from before (not run again).
    pub kept: usize,
    /// Cells of the plan it still had to run.
    pub to_run: usize,
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct RunReport {
    pub schema: String,
    pub tool: Value,
    pub command_line: Vec<String>,
    pub started: String,
    #[serde(default)]
    pub finished: Option<String>,
    pub complete: bool,
    /// Why `complete` is false though every run in the report finished: `merge --force` joined
    /// reports of different runs (another device, scene or result-changing option), so no
    /// cell set or verdict of one run can be read from it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub incomplete: Option<String>,
    pub device: Value,
    /// The caps file's `matrix` object for this device, as informational data no reader
    /// interprets; its shape is that of the caps schema named in `matrix_support_schema`.
    pub matrix_support: Value,
    /// The caps schema `matrix_support` follows (absent: `rtprobe.caps/1`'s, which had
    /// `nonuniform_by_resource` where `/2` has one key per registry axis).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub matrix_support_schema: Option<String>,
    pub scene: SceneSummary,
    pub options: RunOptions,
    pub plan: PlanSummary,
    /// Verdicts of the planned probe cells, every outcome present (canaries are in `tally`;
    /// retries in `retries`): they add up to `plan.planned`.
    pub summary: BTreeMap<String, usize>,
    /// Verdicts of the retries (workaround variants and recommended patterns a round added, not
    /// planned), by outcome; empty when there were none.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub retries: BTreeMap<String, usize>,
    /// Each `--resume` of this report: when, and how many cells it kept (not run again).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub resumed: Vec<Resumed>,
    #[serde(default)]
    pub tally: Tally,
    pub timing: TimingSummary,
    /// With `--baseline`: how the run compared with its expectations.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub baseline: Option<crate::model::BaselineCheck>,
    /// Each worker's setup (`pass` once ready) and its faults outside any cell.
    #[serde(default)]
    pub workers: Vec<WorkerEvent>,
    /// The persisted pipeline cache (absent: `--pipeline-cache off`, or an older report).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pipeline_cache: Option<PipelineCacheSummary>,
    /// With `--mutants`: the kill matrix (each cell's mutant attempts are not among its
    /// `attempts`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mutants: Option<crate::model::MutantReport>,
    /// The driver's own pipeline cache: its pipeline-binary properties and how fresh re-runs
    /// bypassed it (absent in older reports).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub driver_cache: Option<super::driver_cache::DriverCacheSummary>,
    pub cells: Vec<CellReport>,
}

impl RunReport {
    /// A minimal complete report holding `cells` (unit tests of reporters and fleet tools).
    #[cfg(test)]
    pub fn for_tests(cells: Vec<CellReport>) -> RunReport {
        let mut r = RunReport {
            schema: SCHEMA.into(),
            tool: serde_json::json!({ "name": "rtprobe", "version": "test" }),
            command_line: vec![],
            started: String::new(),
            finished: None,
            complete: true,
            incomplete: None,
            device: serde_json::json!({ "name": "test device" }),
            matrix_support: serde_json::json!({}),
            matrix_support_schema: None,
            scene: SceneSummary {
                params: SceneParams::default(),
                instances: 16,
                blas: 4,
                triangles: 0,
                ambiguous_pixels: 0,
                limits: vec![],
                cost: None,
            },
            options: RunOptions::for_tests(),
            plan: PlanSummary {
                generated: 0,
                filtered_out: 0,
                planned: cells.len(),
                to_run: cells.len(),
                unsupported: 0,
                not_implemented: 0,
                not_generated: vec![],
                sharded_out: 0,
            },
            summary: Default::default(),
            retries: Default::default(),
            resumed: vec![],
            tally: Default::default(),
            timing: TimingSummary::default(),
            baseline: None,
            workers: vec![],
            pipeline_cache: None,
            mutants: None,
            driver_cache: None,
            cells,
        };
        r.recount();
        r
    }

    /// Canaries whose fault rtprobe did not classify as expected: detection is unproven.
    pub fn undetected_canaries(&self) -> impl Iterator<Item = &CellReport> {
        self.cells.iter().filter(|c| c.canary_check.as_ref().is_some_and(|k| !k.detected))
    }

    /// Cells with a finding (canaries, workaround variants and other retries excluded).
    pub fn findings(&self) -> impl Iterator<Item = &CellReport> {
        self.cells.iter().filter(|c| c.is_finding())
    }

    /// Attach to each finding the outcome of its workaround variants present in the report.
    pub fn annotate_workarounds(&mut self) {
        let variants: Vec<(Cell, String, Outcome, u32)> = self
            .cells
            .iter()
            .filter(|c| c.cell.patch.is_some())
            .map(|c| {
                (
                    c.cell,
                    c.id.clone(),
                    c.outcome,
                    c.attempts.iter().filter(|a| !a.not_run()).count() as u32,
                )
            })
            .collect();
        for c in self.cells.iter_mut().filter(|c| c.cell.patch.is_none() && c.cell.canary.is_none())
        {
            let incidence = c.incidence.clone();
            let finding = c.outcome.is_finding();
            c.workarounds = variants
                .iter()
                .filter(|(v, _, _, _)| v.base() == c.cell)
                .map(|(v, id, o, n)| {
                    let miss_probability = incidence
                        .as_ref()
                        .filter(|_| *o == Outcome::Pass)
                        .map(|i| crate::model::stats::pass_miss(i.faulted, i.attempts, *n));
                    WorkaroundResult {
                        patch: v.patch.expect("filtered"),
                        cell: id.clone(),
                        outcome: *o,
                        verified: finding
                            && miss_probability
                                .is_some_and(|m| m < crate::model::stats::DEFAULT_MAX_MISS),
                        attempts: *n,
                        miss_probability,
                    }
                })
                .collect();
        }
    }

    /// Read a report back. Its counts are recomputed from its cells, so that a report written
    /// before retries were counted apart (its `summary` held them) reads as one written now.
    pub fn load(path: &Path) -> Result<RunReport, LoadError> {
        let mut r: RunReport = super::load::read_json(path, "run report")?;
        super::load::check_schema(path, &r.schema, SCHEMA)?;
        r.recount();
        Ok(r)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{DescriptorModel, IndexSource, Resource, Stage};

    fn cell() -> Cell {
        Cell::new(
            Stage::ClosestHit,
            Resource::StorageBuffer,
            IndexSource::Dynamic,
            DescriptorModel::DescriptorIndexing,
        )
    }

    fn attempt(outcome: Outcome, isolated: bool) -> Attempt {
        Attempt::for_tests(outcome, isolated)
    }

    #[test]
    fn a_fault_that_does_not_repeat_alone_stays_the_verdict() {
        let mut c = CellReport::new(&cell(), attempt(Outcome::DeviceLost, false));
        c.attempts.push(attempt(Outcome::Pass, true));
        c.refresh();
        assert_eq!(c.outcome, Outcome::DeviceLost);
        assert!(c.flaky);
        assert_eq!(c.confirmed, Some(false));
        let inc = c.incidence.clone().unwrap();
        assert_eq!((inc.faulted, inc.attempts, inc.reproduced_alone), (1, 2, Some(false)));
        assert!((inc.miss_probability - 0.25).abs() < 1e-12);
        assert!(
            c.reason.as_deref().unwrap().contains("1 of 2 attempts; not reproduced alone"),
            "{:?}",
            c.reason
        );
    }

    #[test]
    fn the_worst_attempt_wins_in_any_order_and_repeats_confirm() {
        for order in [[Outcome::Pass, Outcome::Mismatch], [Outcome::Mismatch, Outcome::Pass]] {
            let mut c = CellReport::new(&cell(), attempt(order[0], false));
            c.attempts.push(attempt(order[1], true));
            c.refresh();
            assert_eq!(c.outcome, Outcome::Mismatch);
            assert!(c.flaky);
        }
        let mut c = CellReport::new(&cell(), attempt(Outcome::Crash, false));
        c.attempts.push(attempt(Outcome::Crash, true));
        c.refresh();
        assert_eq!((c.outcome, c.flaky, c.confirmed), (Outcome::Crash, false, Some(true)));
        assert_eq!(c.incidence.as_ref().unwrap().miss_probability, 0.0);
        assert_eq!(c.incidence.as_ref().unwrap().reproduced_alone, Some(true));
        let pass = CellReport::new(&cell(), attempt(Outcome::Pass, false));
        assert!(pass.incidence.is_none() && !pass.flaky && pass.confirmed.is_none());
    }

    /// Issue 21, item 6: `error` attempts (rtprobe could not run the cell) are no evidence about
    /// the driver, for the incidence as for bisection: a mismatch among two errors is 1 of 1, a
    /// cell of errors only has no incidence, and a failed setup counts neither.
    #[test]
    fn the_incidence_counts_what_bisection_counts() {
        let mut c = CellReport::new(&cell(), attempt(Outcome::Mismatch, false));
        c.attempts.push(attempt(Outcome::Error, true));
        c.attempts.push(attempt(Outcome::Error, false));
        c.refresh();
        assert_eq!(c.outcome, Outcome::Mismatch);
        let inc = c.incidence.clone().unwrap();
        assert_eq!((inc.faulted, inc.attempts), (1, 1));
        assert_eq!(inc.reproduced_alone, None, "the error that ran alone reproduced nothing");
        assert_eq!(c.evidence_counts(), (1, 1));
        let mut errors = CellReport::new(&cell(), attempt(Outcome::Error, false));
        errors.attempts.push(attempt(Outcome::Error, true));
        errors.refresh();
        assert_eq!((errors.outcome, errors.incidence.clone()), (Outcome::Error, None));
        let mut setup = CellReport::new(&cell(), attempt(Outcome::Pass, false));
        setup.attempts.push(Attempt::for_tests(Outcome::Crash, false).with_worker(
            1,
            crate::model::Phase::Setup,
            vec![],
        ));
        setup.attempts.push(attempt(Outcome::Crash, true));
        setup.refresh();
        let inc = setup.incidence.clone().unwrap();
        assert_eq!((inc.faulted, inc.attempts, inc.reproduced_alone), (1, 2, Some(true)));
    }

    #[test]
    fn miss_probability_is_binomial() {
        assert!((crate::model::stats::miss(0.5, 8) - 1.0 / 256.0).abs() < 1e-15);
        assert_eq!(crate::model::stats::miss(1.0, 3), 0.0);
        assert_eq!(crate::model::stats::miss(0.0, 3), 1.0);
    }
}
