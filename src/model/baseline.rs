//! Baselines (what a run is expected to give) and a run checked against one (the data;
//! `fleet::baseline` reads the formats and checks).
use crate::model::Outcome;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

pub const SCHEMA: &str = "rtprobe.baseline/1";

/// What a cell is expected to do.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Expectation {
    pub cell: String,
    /// The expected verdict (never `pass`: passing cells are not listed).
    pub outcome: Outcome,
    /// A known flake: a pass, `outcome` and any of `also` (each by deqp class) are tolerated.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub flake: bool,
    /// Other outcomes a flaky cell has shown.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub also: Vec<Outcome>,
    /// The failure rate seen when the entry was written, e.g. `3 of 8 attempts`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rate: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bug: Option<String>,
}

/// Per-cell time bound of one phase: a run fails when its mean exceeds
/// `mean_ms * factor + slack_ms`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PerfBound {
    pub mean_ms: f64,
    pub factor: f64,
    pub slack_ms: f64,
}

impl PerfBound {
    pub fn limit(&self) -> f64 {
        self.mean_ms * self.factor + self.slack_ms
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Baseline {
    pub schema: String,
    /// Header: the device and driver the expectations were taken on.
    #[serde(default)]
    pub device: String,
    #[serde(default)]
    pub driver_version: String,
    /// The report it was made from.
    #[serde(default)]
    pub source: String,
    pub expected: Vec<Expectation>,
    /// Worker faults outside any cell the run is known to have (a driver that aborts in
    /// teardown after its faulting cells, say), by phase and outcome.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub worker_faults: Vec<WorkerFault>,
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub performance: BTreeMap<String, PerfBound>,
}

#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
pub struct WorkerFault {
    pub phase: String,
    pub outcome: Outcome,
}

/// How one cell compared with its expectation.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    /// As expected (pass, or the expected fault).
    Expected,
    /// A listed flake showed one of its outcomes.
    KnownFlake,
    /// Not as expected: a new fault, or another fault than the expected one.
    Regression,
    /// Passes where a fault was expected: update the baseline.
    Improvement,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CellCheck {
    pub cell: String,
    pub status: Status,
    pub expected: Outcome,
    pub actual: Outcome,
}

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct BaselineCheck {
    pub source: String,
    /// Only the cells that were not simply expected.
    pub cells: Vec<CellCheck>,
    pub expected: usize,
    pub known_flakes: usize,
    /// Baseline entries for cells this run did not plan (another shard, filter or device).
    pub not_run: usize,
    /// Those entries' cells (`merge` keeps the ones no shard ran; absent in older reports).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub not_run_cells: Vec<String>,
    /// Phases over their bound: `phase: actual ms/cell > limit`.
    pub performance: Vec<String>,
    /// Worker faults outside cells the baseline does not list (each fails the run).
    #[serde(default)]
    pub worker_faults: Vec<String>,
    /// Worker faults outside cells the baseline lists.
    #[serde(default)]
    pub expected_worker_faults: usize,
}

impl BaselineCheck {
    pub fn regressions(&self) -> impl Iterator<Item = &CellCheck> {
        self.cells.iter().filter(|c| c.status == Status::Regression)
    }
    pub fn improvements(&self) -> impl Iterator<Item = &CellCheck> {
        self.cells.iter().filter(|c| c.status == Status::Improvement)
    }
    /// Whether the baseline expects the verdict of `cell` (a finding it lists, a known flake, or
    /// a pass): it is not among the regressions and unexpected passes.
    pub fn expects(&self, cell: &str) -> bool {
        !self
            .cells
            .iter()
            .any(|c| c.cell == cell && matches!(c.status, Status::Regression | Status::Improvement))
    }

    /// Whether the run is as expected (improvements count unless allowed).
    pub fn ok(&self, allow_improvements: bool) -> bool {
        self.regressions().next().is_none()
            && self.performance.is_empty()
            && self.worker_faults.is_empty()
            && (allow_improvements || self.improvements().next().is_none())
    }
}
