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
    /// The expected verdict (never `pass`: passing cells are not listed). Matched exactly, but
    /// for crash and device loss (one fault: a GPU fault may end the worker either way):
    /// `error` (rtprobe could not run the cell) and `mismatch` (wrong values) are different.
    pub outcome: Outcome,
    /// A known flake: a pass, `outcome` and any of `also` are tolerated, at a fault rate its
    /// `rate` explains.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub flake: bool,
    /// Other outcomes the cell has shown, also accepted (a deqp `Fail` line: mismatch or error).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub also: Vec<Outcome>,
    /// The failure rate seen when the entry was written, `K of N attempts` ([`Self::recorded`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rate: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bug: Option<String>,
}

/// What a flake's rate is held to without a recorded one: deqp-runner calls a test a flake when
/// it fails and then passes its re-run, one fault in two attempts.
pub const DEQP_FLAKE_RATE: (u32, u32) = (1, 2);

impl Expectation {
    /// The recorded rate as (faulted, attempts); `None` without one. `Err` with the text when it
    /// is not `K of N attempts` with K <= N, N >= 1.
    pub fn recorded(&self) -> Result<Option<(u32, u32)>, String> {
        let Some(r) = &self.rate else { return Ok(None) };
        let bad =
            || format!("rate {r:?} of {} is not `K of N attempts` (K <= N, N >= 1)", self.cell);
        let words: Vec<&str> = r.split_whitespace().collect();
        match words[..] {
            [k, "of", n, "attempts" | "attempt"] => {
                let (k, n) = (k.parse().map_err(|_| bad())?, n.parse().map_err(|_| bad())?);
                if n == 0 || k > n {
                    return Err(bad());
                }
                Ok(Some((k, n)))
            }
            _ => Err(bad()),
        }
    }
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
    /// A fault was expected and the cell did not run: unsupported or not implemented here, or
    /// planned by neither this run nor another shard of it (fails the run: a cell that stops
    /// running hides whatever it would show).
    Missing,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CellCheck {
    pub cell: String,
    pub status: Status,
    pub expected: Outcome,
    /// The cell's verdict; `not_implemented` for a [`Status::Missing`] cell the run did not plan.
    pub actual: Outcome,
    /// Why, where the outcomes alone do not say (a flake's rate, a missing cell).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub why: Option<String>,
}

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct BaselineCheck {
    pub source: String,
    /// Only the cells that were not simply expected.
    pub cells: Vec<CellCheck>,
    pub expected: usize,
    pub known_flakes: usize,
    /// Baseline entries for cells this run left to another shard or its `--filter` excluded.
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
    pub fn missing(&self) -> impl Iterator<Item = &CellCheck> {
        self.cells.iter().filter(|c| c.status == Status::Missing)
    }
    /// Whether the baseline expects the verdict of `cell` (a finding it lists, a known flake, or
    /// a pass): it is not among the regressions, missing cells and unexpected passes.
    pub fn expects(&self, cell: &str) -> bool {
        !self.cells.iter().any(|c| {
            c.cell == cell
                && matches!(c.status, Status::Regression | Status::Improvement | Status::Missing)
        })
    }
    /// Whether the run is as expected (improvements count unless allowed).
    pub fn ok(&self, allow_improvements: bool) -> bool {
        self.regressions().next().is_none()
            && self.missing().next().is_none()
            && self.performance.is_empty()
            && self.worker_faults.is_empty()
            && (allow_improvements || self.improvements().next().is_none())
    }
}
