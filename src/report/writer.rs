//! The run report's writer: cell entries built as attempts arrive, kept in plan order, saved
//! atomically (`cli::run`: at once after a fault, passes at most every 100 ms).
use crate::model::{
    Attempt, Cell, CellReport, Outcome, PlanStatus, RunPlan, RunReport, WorkerEvent,
};
use std::collections::BTreeMap;
use std::path::PathBuf;

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
                    report.cells.push(CellReport::unrun(&pc.cell, outcome, reason.clone()));
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

    /// Cells already run (for --resume): every cell with an attempt that ran it (not only failed
    /// setups). Follow-ups (confirmation, repeats, workarounds) are chosen from the report's
    /// state, so a resumed run finishes them.
    pub fn done(&self) -> std::collections::HashSet<String> {
        self.report
            .cells
            .iter()
            .filter(|c| c.attempts.iter().any(|a| !a.not_run()))
            .map(|c| c.id.clone())
            .collect()
    }

    pub fn record(&mut self, cell: &Cell, attempt: Attempt) {
        let id = cell.id();
        let t = &mut self.report.timing;
        // Timing statistics only from cells that ran to completion (a hung fence wait or a crash
        // says nothing about per-cell cost).
        if let Some(r) = attempt
            .result
            .as_ref()
            .filter(|r| matches!(r.outcome, Outcome::Pass | Outcome::Mismatch))
        {
            let tm = &r.timings;
            t.compile_ms += tm.compile_ms;
            t.pipeline_ms += tm.pipeline_ms;
            t.setup_ms += tm.setup_ms;
            t.trace_ms += tm.trace_ms;
            t.check_ms += tm.check_ms;
            t.overhead_ms += (attempt.wall_ms - tm.total_ms).max(0.0)
                + (tm.total_ms
                    - tm.compile_ms
                    - tm.pipeline_ms
                    - tm.setup_ms
                    - tm.trace_ms
                    - tm.check_ms)
                    .max(0.0);
            t.cells_timed += 1;
        }
        match self.report.cells.iter_mut().find(|c| c.id == id) {
            // An unsupported entry of an older plan (resume) is replaced by what ran.
            Some(existing) if existing.attempts.is_empty() => {
                *existing = CellReport::new(cell, attempt)
            }
            Some(existing) => {
                existing.attempts.push(attempt);
                existing.refresh();
            }
            None => {
                let mut c = CellReport::new(cell, attempt);
                // Not in the plan: a round's retry (a workaround variant, a recommended pattern).
                c.retry = cell.canary.is_none() && !self.order.contains_key(&id);
                self.report.cells.push(c);
            }
        }
        self.sort();
    }

    pub fn record_worker(&mut self, event: WorkerEvent) {
        self.report.workers.push(event);
    }

    /// Save (compact while running, pretty when final).
    pub fn save(&self, pretty: bool) -> Result<(), crate::atomic::WriteError> {
        let bytes = if pretty {
            serde_json::to_vec_pretty(&self.report)
        } else {
            serde_json::to_vec(&self.report)
        }
        .expect("report serializes");
        crate::atomic::write_atomic_with(&self.path, &bytes, pretty)
    }
}

/// Attach to each finding what the report holds about it beyond its own attempts: its
/// workaround variants and its recommended pattern (`report::recommended`).
pub fn annotate_findings(report: &mut RunReport) {
    report.annotate_workarounds();
    super::recommended::annotate(report);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{DescriptorModel, IndexSource, PlannedCell, Resource, Stage, Workaround};

    #[test]
    fn cells_outside_the_plan_are_retries_counted_apart() {
        let planned = Cell::new(
            Stage::ClosestHit,
            Resource::StorageBuffer,
            IndexSource::Dynamic,
            DescriptorModel::DescriptorIndexing,
        );
        let plan = RunPlan {
            generated: 1,
            cells: vec![PlannedCell { cell: planned, status: PlanStatus::Run }],
            not_generated: vec![],
            filtered_out: 0,
        };
        let mut w = ReportWriter::new(PathBuf::from("r.json"), RunReport::for_tests(vec![]), &plan);
        w.record(&planned, Attempt::for_tests(Outcome::Crash, false));
        let variant = Cell { patch: Some(Workaround::PinIndex), ..planned };
        let pattern = Cell { index: IndexSource::DynamicElement, ..planned };
        w.record(&variant, Attempt::for_tests(Outcome::Error, false));
        w.record(&pattern, Attempt::for_tests(Outcome::Crash, false));
        let r = &w.report;
        let retry = |id: String| r.cells.iter().find(|c| c.id == id).unwrap().retry;
        assert!(!retry(planned.id()) && retry(variant.id()) && retry(pattern.id()));
        // The plan's one cell is the plan's count; the two retries are counted apart, and the
        // pattern's crash is no finding of its own.
        assert_eq!(r.summary.values().sum::<usize>(), 1);
        assert_eq!((r.summary["crash"], r.retries["error"], r.retries["crash"]), (1, 1, 1));
        assert_eq!(r.findings().count(), 1);
        // Its twin: had the plan held the pattern, it would be a planned cell and a finding.
        let plan2 = RunPlan {
            cells: vec![
                PlannedCell { cell: planned, status: PlanStatus::Run },
                PlannedCell { cell: pattern, status: PlanStatus::Run },
            ],
            ..plan
        };
        let mut w =
            ReportWriter::new(PathBuf::from("r.json"), RunReport::for_tests(vec![]), &plan2);
        w.record(&planned, Attempt::for_tests(Outcome::Crash, false));
        w.record(&pattern, Attempt::for_tests(Outcome::Crash, false));
        assert_eq!(w.report.findings().count(), 2);
        assert!(w.report.retries.is_empty());
    }
}
