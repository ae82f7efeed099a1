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
        let known: std::collections::HashSet<String> =
            report.cells.iter().map(|c| c.id.clone()).collect();
        for pc in &plan.cells {
            let not_run = match &pc.status {
                PlanStatus::Run => None,
                PlanStatus::Unsupported { reason } => Some((Outcome::Unsupported, reason)),
                PlanStatus::NotImplemented { reason } => Some((Outcome::NotImplemented, reason)),
            };
            if let Some((outcome, reason)) = not_run {
                if !known.contains(&pc.cell.id()) {
                    report.cells.push(CellReport::unrun(&pc.cell, outcome, reason.clone()));
                }
            }
        }
        let mut w = ReportWriter { path, report, order };
        w.sort();
        w
    }

    /// Where a cell sits: its plan position (a workaround variant: its plain cell's), then its
    /// patch, so variants sit right after their plain cell.
    fn key(&self, cell: &Cell, id: &str) -> (usize, usize) {
        let patch = cell.patch.map(|p| 1 + p as usize).unwrap_or(0);
        let at = self.order.get(id).or_else(|| self.order.get(&cell.base().id()));
        (at.copied().unwrap_or(usize::MAX), patch)
    }

    /// Every entry in [`Self::key`] order (once, at the start; [`Self::record`] keeps it).
    fn sort(&mut self) {
        let mut cells = std::mem::take(&mut self.report.cells);
        cells.sort_by_cached_key(|c| self.key(&c.cell, &c.id));
        self.report.cells = cells;
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
            t.readback_ms += tm.readback_ms;
            t.pipeline_wait_ms += tm.pipeline_wait_ms;
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
        // The entries are in key order: the cell's entry, if any, is among those of its key
        // (binary search, not a scan or a sort per attempt: linear in the cells over a run).
        let key = self.key(cell, &id);
        let cells = &self.report.cells;
        let from = cells.partition_point(|c| self.key(&c.cell, &c.id) < key);
        let to = from + cells[from..].partition_point(|c| self.key(&c.cell, &c.id) <= key);
        match (from..to).find(|&i| cells[i].id == id) {
            // An unsupported entry of an older plan (resume) is replaced by what ran.
            Some(i) if cells[i].attempts.is_empty() => {
                self.report.count_cell(i, false);
                self.report.cells[i] = CellReport::new(cell, attempt);
                self.report.count_cell(i, true);
            }
            Some(i) => {
                // The counts change by this cell's share alone (not a recount of every cell:
                // that made a run quadratic in its cells).
                self.report.count_cell(i, false);
                let existing = &mut self.report.cells[i];
                existing.attempts.push(attempt);
                existing.refresh();
                self.report.count_cell(i, true);
            }
            None => {
                let mut c = CellReport::new(cell, attempt);
                // Not in the plan: a round's retry (a workaround variant, a recommended pattern).
                c.retry = cell.canary.is_none() && !self.order.contains_key(&id);
                self.report.cells.insert(to, c);
                self.report.count_cell(to, true);
            }
        }
    }

    pub fn record_worker(&mut self, event: WorkerEvent) {
        self.report.workers.push(event);
        self.report.count_worker_event(self.report.workers.len() - 1);
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

    fn cell(stage: Stage, index: IndexSource) -> Cell {
        Cell::new(stage, Resource::StorageBuffer, index, DescriptorModel::DescriptorIndexing)
    }

    /// Attempts arrive in any order (workers, confirmations, workaround variants); the entries
    /// stay in plan order, each cell once, its variants right after it — the order a full sort
    /// after every attempt gave.
    #[test]
    fn entries_stay_in_plan_order_whatever_order_attempts_arrive_in() {
        let cells: Vec<Cell> = [Stage::Raygen, Stage::Miss, Stage::ClosestHit, Stage::AnyHit]
            .iter()
            .flat_map(|&s| [cell(s, IndexSource::Literal), cell(s, IndexSource::Dynamic)])
            .collect();
        let mut planned: Vec<PlannedCell> =
            cells.iter().map(|&cell| PlannedCell { cell, status: PlanStatus::Run }).collect();
        planned[3].status = PlanStatus::Unsupported { reason: "x".into() };
        let plan = RunPlan { generated: 8, cells: planned, not_generated: vec![], filtered_out: 0 };
        let dir = crate::tempdir::tempdir().unwrap();
        let mut w =
            ReportWriter::new(dir.path().join("r.json"), RunReport::for_tests(vec![]), &plan);
        let variant = Cell { patch: Some(Workaround::PinIndex), ..cells[1] };
        let pass = || Attempt::for_tests(Outcome::Pass, false);
        for i in [7, 0, 5, 1, 2, 6, 4] {
            w.record(&cells[i], pass());
        }
        w.record(&variant, pass());
        w.record(&cells[5], pass());
        let ids: Vec<&str> = w.report.cells.iter().map(|c| c.id.as_str()).collect();
        let mut want: Vec<String> = cells.iter().map(Cell::id).collect();
        want.insert(2, variant.id());
        assert_eq!(ids, want);
        assert_eq!(w.report.cells[6].attempts.len(), 2, "a second attempt joins its cell");
        // (the workaround variant is a retry, counted apart from the plan's cells)
        assert_eq!((w.report.summary["pass"], w.report.retries["pass"]), (7, 1));
        assert_eq!(w.report.summary["unsupported"], 1);
    }

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

    /// The counts kept incrementally equal a recount of every cell after each of thousands of
    /// random attempts on a 5,000-cell report: planned cells, workaround variants (retries),
    /// canaries, repeated attempts that make a cell flaky, worker events. Its twin: a writer
    /// that added a cell's new share without taking out its old one would count a cell once per
    /// attempt, and the first repeated attempt would fail the comparison.
    #[test]
    fn incremental_counts_match_a_full_recount_on_a_5000_cell_report() {
        use crate::model::{Canary, Phase};
        let stages = [Stage::Raygen, Stage::Miss, Stage::ClosestHit, Stage::AnyHit];
        let cells: Vec<Cell> = (0..1250u32)
            .flat_map(|copy| stages.map(|s| Cell { copy, ..cell(s, IndexSource::Dynamic) }))
            .collect();
        assert_eq!(cells.len(), 5000);
        let planned = cells.iter().map(|&cell| PlannedCell { cell, status: PlanStatus::Run });
        let plan = RunPlan {
            generated: 5000,
            cells: planned.collect(),
            not_generated: vec![],
            filtered_out: 0,
        };
        let mut w = ReportWriter::new(PathBuf::from("r.json"), RunReport::for_tests(vec![]), &plan);
        let outcomes = [
            Outcome::Pass,
            Outcome::Pass,
            Outcome::Mismatch,
            Outcome::Crash,
            Outcome::Timeout,
            Outcome::Error,
        ];
        // A fixed xorshift: the same sequence every run, no dependency.
        let mut x: u64 = 0x9e37_79b9_7f4a_7c15;
        let mut next = move |n: usize| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x % n as u64) as usize
        };
        let mut repeated = 0;
        for k in 0..6000 {
            let mut c = cells[next(cells.len())];
            match next(20) {
                0 => c.patch = Some(Workaround::PinIndex),
                1 => c.canary = Some(Canary::InfiniteLoop),
                _ => {}
            }
            repeated += usize::from(w.report.cells.iter().any(|e| e.cell == c));
            w.record(&c, Attempt::for_tests(outcomes[next(outcomes.len())], false));
            if next(50) == 0 {
                let outcome = outcomes[next(outcomes.len())];
                w.record_worker(WorkerEvent {
                    worker: k,
                    phase: Phase::BetweenCells,
                    outcome,
                    detail: None,
                    cells: 1,
                    wall_ms: 1.0,
                    device_features: vec![],
                    worker_exit: None,
                    halt: None,
                    overlapped_cell: None,
                    fault: None,
                });
            }
            if k % 97 == 0 || k == 5999 {
                let mut full = w.report.clone();
                full.recount();
                assert_eq!(w.report.summary, full.summary, "after {k} attempts");
                assert_eq!(w.report.retries, full.retries, "after {k} attempts");
                assert_eq!(w.report.tally, full.tally, "after {k} attempts");
            }
        }
        // The sequence did what the comparison needs: repeated cells, flaky findings, retries,
        // canaries and worker faults all counted.
        let r = &w.report;
        assert!(repeated > 1000 && r.tally.flaky > 100, "{repeated} repeats, {:?}", r.tally);
        assert!(r.tally.worker_faults > 10 && !r.retries.is_empty());
        assert!(r.tally.canaries_detected + r.tally.canaries_undetected > 100);
        assert_eq!(
            r.summary.values().sum::<usize>(),
            r.cells
                .iter()
                .filter(|c| c.canary_check.is_none() && !c.is_retry(r.options.patches))
                .count()
        );
    }
}
