//! Every cell's attempts as bisection sees them: the report's, then its own, and what each
//! cell's verdict says (fault, pass, error, unknown).
use crate::model::{Attempt, Cell, CellReport, Halt, Outcome, RunReport};
use crate::runner::oracle::Event;
use std::collections::HashMap;

/// What a cell's verdict says, for bisection.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum State {
    Fault,
    Pass,
    /// rtprobe could not run it (`error`): no evidence about the driver either way, so it is
    /// neither a faulting cell nor a passing one, and is not run again.
    Error,
    /// Never ran (or unsupported).
    Unknown,
}

/// Every cell's attempts, keyed by id: the report's, then bisection's own.
#[derive(Clone, Debug, Default)]
pub struct Verdicts {
    cells: HashMap<String, CellReport>,
    /// Attempts bisection added.
    pub runs: usize,
    /// A run of bisection's that halted (no cell can run): bisection stops with it.
    pub halt: Option<Halt>,
}

impl Verdicts {
    pub fn from_report(r: &RunReport) -> Self {
        let cells = r
            .cells
            .iter()
            .filter(|c| !c.attempts.is_empty())
            .map(|c| (c.id.clone(), c.clone()))
            .collect();
        Verdicts { cells, runs: 0, halt: None }
    }

    pub fn record(&mut self, cell: &Cell, attempt: Attempt) {
        self.runs += 1;
        match self.cells.get_mut(&cell.id()) {
            Some(c) => {
                c.attempts.push(attempt);
                c.refresh();
            }
            None => {
                self.cells.insert(cell.id(), CellReport::new(cell, attempt));
            }
        }
    }

    /// Record an oracle's attempt, or its halt (its other events say nothing about a cell).
    pub fn on_event(&mut self, ev: Event) {
        match ev {
            Event::Attempt { cell, attempt } => self.record(&cell, attempt),
            Event::Halt(h) => self.halt = Some(h),
            Event::WorkerReady { .. }
            | Event::Prebuilt { .. }
            | Event::CacheSaved(_)
            | Event::Worker(_) => {}
        }
    }

    pub fn get(&self, c: &Cell) -> Option<&CellReport> {
        self.cells.get(&c.id())
    }

    /// Every attempt made, evidence or not (what caps the repeats of a cell).
    pub fn attempts(&self, c: &Cell) -> u32 {
        self.get(c).map(|r| r.attempts.len() as u32).unwrap_or(0)
    }

    /// The evidence: (faulted, attempts) over the attempts whose cell ran and that the driver
    /// decided — not a worker that never got its device up (`Attempt::not_run`), not an `error`
    /// (rtprobe could not run the cell). Rate bounds and miss probabilities rest on these.
    pub fn counts(&self, c: &Cell) -> (u32, u32) {
        let evidence = |a: &&Attempt| !a.not_run() && a.outcome != Outcome::Error;
        let Some(r) = self.get(c) else { return (0, 0) };
        let n = r.attempts.iter().filter(evidence).count() as u32;
        let k =
            r.attempts.iter().filter(evidence).filter(|a| a.outcome.is_finding()).count() as u32;
        (k, n)
    }

    /// Attempts that count as evidence (see [`Verdicts::counts`]).
    pub fn evidence(&self, c: &Cell) -> u32 {
        self.counts(c).1
    }

    /// The cell's fault rate bound: one-sided Clopper–Pearson at [`crate::model::stats::CONFIDENCE`].
    pub fn rate_bound(&self, c: &Cell) -> f64 {
        let (k, n) = self.counts(c);
        crate::model::stats::rate_bound(k, n)
    }

    pub fn state(&self, c: &Cell) -> State {
        match self.get(c).filter(|r| !r.attempts.is_empty()) {
            None => State::Unknown,
            Some(r) => match r.outcome {
                Outcome::Error => State::Error,
                Outcome::Mismatch | Outcome::DeviceLost | Outcome::Crash | Outcome::Timeout => {
                    State::Fault
                }
                Outcome::Pass => State::Pass,
                Outcome::Unsupported | Outcome::NotImplemented => State::Unknown,
            },
        }
    }
}
