//! One run of one cell (`Attempt`), how a worker ended, its own records, what in a worker stops
//! the whole run (`Halt`), and how cells are isolated: what the supervisor records and every
//! report keeps.
use crate::model::{CellResult, Outcome, Phase};
use serde::{Deserialize, Serialize};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Isolation {
    /// One worker runs many cells and is replaced after a fault.
    Worker,
    /// Every cell runs in a fresh worker process.
    ProcessPerCell,
}

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct WorkerExit {
    #[serde(skip_serializing_if = "Option::is_none")]
    pub code: Option<i32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub signal: Option<i32>,
    #[serde(skip_serializing_if = "String::is_empty", default)]
    pub stderr_tail: String,
    /// Set when the process did not die after SIGKILL within the bound (stuck in the kernel,
    /// e.g. uninterruptible sleep in the driver): it was left behind, and this says so.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub abandoned: Option<String>,
}

/// One run of one cell.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Attempt {
    pub outcome: Outcome,
    /// Ran alone in a fresh worker (a `--confirm` re-run, or process-per-cell isolation).
    pub isolated: bool,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub detail: Option<String>,
    /// The worker's own report (absent when the worker died or hung).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub result: Option<CellResult>,
    /// How the worker ended, when it ended during this cell.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub worker_exit: Option<WorkerExit>,
    /// The fault `--inject-fault` put into this attempt (recorded even when the worker died).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub injected: Option<crate::model::InjectedFault>,
    pub wall_ms: f64,
    /// The worker's last phase when the attempt ended (`setup`: the cell never ran because its
    /// worker's setup failed).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub phase: Option<Phase>,
    /// The worker that ran it (`worker` of the report's `workers` entries; 0 in older reports).
    #[serde(default)]
    pub worker: u64,
    /// What the worker's device was created with (extensions, then feature bits).
    #[serde(skip_serializing_if = "Vec::is_empty", default)]
    pub device_features: Vec<String>,
}

impl Attempt {
    /// The one constructor: an attempt that ended with `outcome`, nothing else known yet; the
    /// `with_*` methods add what the recorder knows (the worker and its phase, the worker's own
    /// result, how the worker ended, the detail, the time).
    pub fn new(outcome: Outcome, isolated: bool) -> Attempt {
        Attempt {
            outcome,
            isolated,
            detail: None,
            result: None,
            worker_exit: None,
            injected: None,
            wall_ms: 0.0,
            phase: None,
            worker: 0,
            device_features: vec![],
        }
    }

    /// Who ran it: the worker (0: none started), its last phase and what its device enabled.
    pub fn with_worker(self, worker: u64, phase: Phase, device_features: Vec<String>) -> Attempt {
        Attempt { worker, phase: Some(phase), device_features, ..self }
    }

    pub fn with_detail(self, detail: impl Into<String>) -> Attempt {
        Attempt { detail: Some(detail.into()), ..self }
    }

    /// The worker's own report; its detail becomes the attempt's.
    pub fn with_result(self, result: CellResult) -> Attempt {
        Attempt { detail: result.detail.clone(), result: Some(result), ..self }
    }

    pub fn with_exit(self, exit: WorkerExit) -> Attempt {
        Attempt { worker_exit: Some(exit), ..self }
    }

    pub fn with_wall_ms(self, wall_ms: f64) -> Attempt {
        Attempt { wall_ms, ..self }
    }

    /// An attempt with only an outcome (unit tests of reporters and fleet tools).
    #[cfg(test)]
    pub fn for_tests(outcome: Outcome, isolated: bool) -> Attempt {
        Attempt::new(outcome, isolated)
            .with_detail(format!("{} happened", outcome.as_str()))
            .with_wall_ms(1.0)
    }

    /// The cell never ran: its worker's setup failed.
    pub fn not_run(&self) -> bool {
        self.phase == Some(Phase::Setup)
    }

    /// Evidence about the driver: the cell ran (not a failed setup, [`Attempt::not_run`]) and the
    /// driver decided the outcome — not `error`, where rtprobe could not run the cell. A cell's
    /// incidence, bisection's rate bounds and every miss probability rest on these alone.
    pub fn is_evidence(&self) -> bool {
        !self.not_run() && self.outcome != Outcome::Error
    }

    /// Evidence of a driver fault ([`Attempt::is_evidence`] and a finding).
    pub fn faulted(&self) -> bool {
        self.is_evidence() && self.outcome.is_finding()
    }
}

/// A worker's own record: its setup (`pass` once it is ready) or a fault outside any cell
/// (between two cells, in teardown).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct WorkerEvent {
    pub worker: u64,
    pub phase: Phase,
    pub outcome: Outcome,
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub detail: Option<String>,
    /// Cells the worker was given.
    pub cells: usize,
    pub wall_ms: f64,
    #[serde(skip_serializing_if = "Vec::is_empty", default)]
    pub device_features: Vec<String>,
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub worker_exit: Option<WorkerExit>,
    /// Set when this failure stopped the run ([`Halt`]): the machine's state, not the driver's,
    /// so it is no driver fault — a baseline, the exit code and the summary's worker faults leave
    /// it out, and a `--resume` after the cause is fixed passes clean.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub halt: Option<Halt>,
    /// A worker that ended before `prebuilt` while cells overlapped the prebuild: the last
    /// overlapped cell it told of (its `cell ID: phase` steps). The batch runs again serially,
    /// where that cell's own fault, if it repeats, is its verdict; a baseline counts this entry
    /// as that cell's ([`WorkerEvent::explained_by`]).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub overlapped_cell: Option<String>,
    /// VK_EXT_device_fault's data of that overlapped cell's device loss, when it ended the
    /// worker itself (queried by the worker before its `fatal`; its serial re-run queries its
    /// own).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub fault: Option<crate::model::FaultInfo>,
}

impl WorkerEvent {
    /// The cell this worker fault is that cell's own, once re-run alone: the overlapped cell it
    /// ran, when that cell's verdict is itself a fault that ends a worker (a crash, a device loss
    /// or a timeout). A fault that did not repeat is explained by no cell.
    pub fn explained_by(&self, verdict: impl Fn(&str) -> Option<Outcome>) -> bool {
        self.overlapped_cell.as_deref().and_then(verdict).is_some_and(Outcome::ends_worker)
    }

    /// A fault of the driver outside any cell: a failing outcome that did not halt the run.
    pub fn is_fault(&self) -> bool {
        self.outcome.is_finding() && self.halt.is_none()
    }
}

/// What a worker found that no cell of the run can get past: the run stops (its cells left
/// without an attempt, for a later `--resume`), and the CLI exits with the halt's own code.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Halt {
    /// The shader compiler (shaderc) could not be started: no cell can be compiled (exit 12).
    NoShaderCompiler,
}

pub fn signal_name(sig: i32) -> &'static str {
    match sig {
        libc::SIGSEGV => "SIGSEGV",
        libc::SIGBUS => "SIGBUS",
        libc::SIGABRT => "SIGABRT",
        libc::SIGILL => "SIGILL",
        libc::SIGFPE => "SIGFPE",
        libc::SIGKILL => "SIGKILL",
        libc::SIGTERM => "SIGTERM",
        _ => "signal",
    }
}
