//! The run report (`"schema": "rtprobe.report/1"`): what ran, on what, with which scene, and per
//! cell its axes, outcome, attempts (timings, mismatch and fault details, worker exit). Cells are
//! kept in plan order, so reports of the same plan diff cleanly. Written after every cell,
//! atomically; `--resume` reads it back.
use crate::matrix::plan::{NotGenerated, PlanStatus, RunPlan};
use crate::matrix::{Canary, Cell};
use crate::outcome::Outcome;
use crate::runner::supervisor::Attempt;
use crate::scene::SceneParams;
use serde::{Deserialize, Serialize};
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

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
    pub outcome: Outcome,
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub reason: Option<String>,
    /// `Some(true)` when a re-run alone in a fresh worker gave the same outcome.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub confirmed: Option<bool>,
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub canary_check: Option<CanaryCheck>,
    /// For a cell with a finding: each workaround tried and its outcome.
    #[serde(skip_serializing_if = "Vec::is_empty", default)]
    pub workarounds: Vec<WorkaroundResult>,
    #[serde(default)]
    pub attempts: Vec<Attempt>,
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct WorkaroundResult {
    pub patch: crate::matrix::cell::Workaround,
    pub cell: String,
    pub outcome: Outcome,
    /// The patched cell passed where the plain one did not: a verified workaround.
    pub verified: bool,
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
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct SceneSummary {
    pub params: SceneParams,
    pub instances: usize,
    pub blas: usize,
    pub triangles: usize,
    /// Pixels skipped by the comparison because their primary hit lies within the margin.
    pub ambiguous_pixels: usize,
}

#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct TimingSummary {
    pub wall_ms: f64,
    pub workers_started: usize,
    /// Mean device creation time of the workers.
    pub device_ms_mean: f64,
    /// Sums over cells of the worker-side split.
    pub compile_ms: f64,
    pub pipeline_ms: f64,
    pub setup_ms: f64,
    pub trace_ms: f64,
    pub check_ms: f64,
    /// Supervisor-observed wall time of all attempts minus the worker-side split: process,
    /// protocol and bookkeeping overhead.
    pub overhead_ms: f64,
    pub cells_timed: usize,
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
    pub device: Value,
    pub matrix_support: Value,
    pub scene: SceneSummary,
    pub options: Value,
    pub plan: PlanSummary,
    pub summary: BTreeMap<String, usize>,
    pub timing: TimingSummary,
    pub cells: Vec<CellReport>,
}

impl RunReport {
    /// The outcome counts, every outcome present.
    pub fn recount(&mut self) {
        let mut m = BTreeMap::new();
        for o in Outcome::ALL {
            m.insert(o.as_str().to_string(), 0);
        }
        for c in &self.cells {
            *m.entry(c.outcome.as_str().to_string()).or_default() += 1;
        }
        self.summary = m;
    }

    /// Cells with a finding (canaries and workaround variants excluded).
    pub fn findings(&self) -> impl Iterator<Item = &CellReport> {
        self.cells.iter().filter(|c| c.cell.canary.is_none() && c.cell.patch.is_none() && c.outcome.is_finding())
    }

    /// Attach to each finding the outcome of its workaround variants present in the report.
    pub fn annotate_workarounds(&mut self) {
        let variants: Vec<(Cell, String, Outcome)> = self.cells.iter().filter(|c| c.cell.patch.is_some()).map(|c| (c.cell, c.id.clone(), c.outcome)).collect();
        for c in self.cells.iter_mut().filter(|c| c.cell.patch.is_none() && c.cell.canary.is_none()) {
            c.workarounds = variants
                .iter()
                .filter(|(v, _, _)| v.base() == c.cell)
                .map(|(v, id, o)| WorkaroundResult {
                    patch: v.patch.expect("filtered"),
                    cell: id.clone(),
                    outcome: *o,
                    verified: c.outcome.is_finding() && *o == Outcome::Pass,
                })
                .collect();
        }
    }

    pub fn load(path: &Path) -> Result<RunReport, String> {
        let bytes = std::fs::read(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
        let r: RunReport = serde_json::from_slice(&bytes).map_err(|e| format!("{} is not an rtprobe run report: {e}", path.display()))?;
        if r.schema != SCHEMA {
            return Err(format!("{} has schema {:?}, expected {SCHEMA:?}", path.display(), r.schema));
        }
        Ok(r)
    }
}

/// Builds the cell entries as attempts arrive, keeps them in plan order, and saves the report.
pub struct ReportWriter {
    pub path: PathBuf,
    pub report: RunReport,
    order: BTreeMap<String, usize>,
}

impl ReportWriter {
    pub fn new(path: PathBuf, mut report: RunReport, plan: &RunPlan) -> Self {
        let order = plan.cells.iter().enumerate().map(|(i, c)| (c.cell.id(), i)).collect();
        for pc in &plan.cells {
            let not_run = match &pc.status {
                PlanStatus::Run => None,
                PlanStatus::Unsupported { reason } => Some((Outcome::Unsupported, reason)),
                PlanStatus::NotImplemented { reason } => Some((Outcome::NotImplemented, reason)),
            };
            if let Some((outcome, reason)) = not_run {
                if !report.cells.iter().any(|c| c.id == pc.cell.id()) {
                    report.cells.push(CellReport {
                        id: pc.cell.id(),
                        cell: pc.cell,
                        outcome,
                        reason: Some(reason.clone()),
                        confirmed: None,
                        canary_check: None,
                        workarounds: vec![],
                        attempts: vec![],
                    });
                }
            }
        }
        let mut w = ReportWriter { path, report, order };
        w.sort();
        w
    }

    fn sort(&mut self) {
        let order = &self.order;
        // Workaround variants sit right after their plain cell.
        let key = |c: &CellReport| {
            let base = c.cell.base().id();
            let patch = c.cell.patch.map(|p| 1 + p as usize).unwrap_or(0);
            (order.get(&c.id).or_else(|| order.get(&base)).copied().unwrap_or(usize::MAX), patch)
        };
        self.report.cells.sort_by_key(key);
        self.report.recount();
    }

    /// Cells already finished (for --resume): every cell the report holds.
    pub fn done(&self) -> std::collections::HashSet<String> {
        self.report.cells.iter().map(|c| c.id.clone()).collect()
    }

    pub fn record(&mut self, cell: &Cell, attempt: Attempt) {
        let id = cell.id();
        let t = &mut self.report.timing;
        // Timing statistics only from cells that ran to completion (a hung fence wait or a crash
        // says nothing about per-cell cost).
        if let Some(r) = attempt.result.as_ref().filter(|r| matches!(r.outcome, Outcome::Pass | Outcome::Mismatch)) {
            let tm = &r.timings;
            t.compile_ms += tm.compile_ms;
            t.pipeline_ms += tm.pipeline_ms;
            t.setup_ms += tm.setup_ms;
            t.trace_ms += tm.trace_ms;
            t.check_ms += tm.check_ms;
            t.overhead_ms += (attempt.wall_ms - tm.total_ms).max(0.0) + (tm.total_ms - tm.compile_ms - tm.pipeline_ms - tm.setup_ms - tm.trace_ms - tm.check_ms).max(0.0);
            t.cells_timed += 1;
        }
        match self.report.cells.iter_mut().find(|c| c.id == id) {
            Some(existing) => {
                let first = existing.attempts.first().map(|a| a.outcome);
                existing.confirmed = first.map(|f| f == attempt.outcome);
                existing.outcome = attempt.outcome;
                existing.reason = attempt.detail.clone();
                existing.attempts.push(attempt);
            }
            None => {
                let canary_check = cell.canary.map(|c| {
                    let expected = canary_expectation(c);
                    CanaryCheck { detected: expected.contains(&attempt.outcome), expected }
                });
                self.report.cells.push(CellReport {
                    id,
                    cell: *cell,
                    outcome: attempt.outcome,
                    reason: attempt.detail.clone(),
                    confirmed: None,
                    canary_check,
                    workarounds: vec![],
                    attempts: vec![attempt],
                });
            }
        }
        self.sort();
    }

    /// Save (compact while running, pretty when final).
    pub fn save(&self, pretty: bool) -> Result<(), crate::report::atomic::WriteError> {
        let bytes = if pretty { serde_json::to_vec_pretty(&self.report) } else { serde_json::to_vec(&self.report) }.expect("report serializes");
        crate::report::atomic::write_atomic_with(&self.path, &bytes, pretty)
    }
}
