//! A run report's counts — the outcome counts of the planned probe cells (`summary`, every
//! outcome present), retries counted apart (`retries`) and the tally (findings, flaky cells,
//! canaries, injections that ran and passed, worker faults) — as a sum of what each cell adds.
//! [`RunReport::recount`] adds every cell's share; the report writer takes one cell's share out
//! before an attempt changes it and puts it back after ([`RunReport::count_cell`]), so recording
//! an attempt costs the same whatever the report's size.
use super::report::{CellReport, RunReport};
use crate::model::{Outcome, PatchMode};
use std::collections::BTreeMap;

/// Where a cell is counted.
enum Bucket {
    Canary { detected: bool },
    Retry,
    Planned,
}

fn bucket(c: &CellReport, patches: PatchMode) -> Bucket {
    match &c.canary_check {
        Some(chk) => Bucket::Canary { detected: chk.detected },
        None if c.is_retry(patches) => Bucket::Retry,
        None => Bucket::Planned,
    }
}

/// `n + 1` or `n - 1`; a count never goes below zero (taking out what was never put in is a
/// caller's bug, and `recount` would correct it).
fn bump(n: &mut usize, add: bool) {
    *n = if add { *n + 1 } else { n.saturating_sub(1) };
}

impl RunReport {
    /// The counts afresh from every cell and worker event.
    pub fn recount(&mut self) {
        self.summary = Outcome::ALL.iter().map(|o| (o.as_str().to_string(), 0)).collect();
        self.retries = BTreeMap::new();
        self.tally = Default::default();
        for i in 0..self.cells.len() {
            self.count_cell(i, true);
        }
        self.tally.worker_faults = self.workers.iter().filter(|w| w.is_fault()).count();
    }

    /// Adds (`add`) or takes out cell `i`'s share of the counts. The writer takes it out before
    /// the cell changes and adds it back after; both must see the same `options.patches`.
    pub fn count_cell(&mut self, i: usize, add: bool) {
        let c = &self.cells[i];
        let t = &mut self.tally;
        match bucket(c, self.options.patches) {
            Bucket::Canary { detected: true } => bump(&mut t.canaries_detected, add),
            Bucket::Canary { detected: false } => bump(&mut t.canaries_undetected, add),
            Bucket::Retry => {
                let key = c.outcome.as_str();
                let n = self.retries.entry(key.to_string()).or_default();
                bump(n, add);
                if *n == 0 {
                    self.retries.remove(key);
                }
            }
            Bucket::Planned => {
                bump(self.summary.entry(c.outcome.as_str().into()).or_default(), add)
            }
        }
        if c.is_finding() {
            bump(&mut t.findings, add);
            if c.flaky {
                bump(&mut t.flaky, add);
            }
        }
        if c.injection_undetected {
            bump(&mut t.injections_undetected, add);
        }
    }

    /// A worker event was added: counted if it is a fault.
    pub fn count_worker_event(&mut self, i: usize) {
        if self.workers[i].is_fault() {
            self.tally.worker_faults += 1;
        }
    }
}
