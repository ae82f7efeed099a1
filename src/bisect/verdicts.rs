//! Every cell's attempts as bisection sees them: the report's, then its own, and what each
//! cell's verdict says (fault, pass, error, unknown).
use crate::model::{Attempt, Cell, CellReport, Halt, IndexSource, Outcome, RunReport};
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
    /// Evidence rtprobe itself doubts ([`Doubt`]): used neither as a fault nor as a pass, and not
    /// run again (another attempt would not settle it).
    Doubtful(Doubt),
    /// Never ran (or unsupported).
    Unknown,
}

/// Why a verdict is no evidence for bisection.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Doubt {
    /// A fault of a read the spec leaves undefined (a dynamic set/binding index without
    /// `nonuniformEXT` in a module without `DescriptorHeapEXT`: `model::NO_NONUNIFORM_VUID`):
    /// whatever it read, it is no driver bug by the spec. Not where a mismatch fell on a subgroup
    /// the device's lane evidence proves uniform (`CellReport::defined_mismatch`): that read was
    /// defined (`VUID-RuntimeSpirv-subgroupSize-10149`), and its fault is settled.
    UndefinedFault,
    /// A pass judged leniently whose pixels read what another lane's index gives while a sibling
    /// with a defined index faults (`isolation::suspect`): the lenient read may be that fault.
    SuspectPass,
}

impl Doubt {
    pub fn why(self) -> &'static str {
        match self {
            Doubt::UndefinedFault => "a fault of a read the spec leaves undefined (no nonuniformEXT on a set/binding index)",
            Doubt::SuspectPass => "a lenient pass whose other-lane reads a faulting sibling with a defined index may explain",
        }
    }
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
        self.get(c).map(CellReport::evidence_counts).unwrap_or((0, 0))
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

    /// For a cell judged leniently (its dynamic index lacks `nonuniformEXT`, or the compiler dropped
    /// it) whose attempts read other elements (the most in one attempt), a faulting sibling that
    /// differs only in a defined index (another index source, or `nonuniformEXT`): the read of
    /// "another element" may be that fault.
    pub fn suspect(&self, cell: &Cell) -> Option<(Cell, usize)> {
        let other = self.get(cell)?.element_reads().map(|e| e.other).max().filter(|o| *o > 0)?;
        let defined = IndexSource::ALL
            .iter()
            .filter(|i| **i != IndexSource::Dynamic)
            .map(|i| Cell { index: *i, nonuniform: false, ..*cell })
            .chain(std::iter::once(Cell { nonuniform: true, ..*cell }));
        defined
            .into_iter()
            .filter(|s| s != cell)
            .find(|s| self.state(s) == State::Fault)
            .map(|s| (s, other))
    }

    pub fn state(&self, c: &Cell) -> State {
        match self.get(c).filter(|r| !r.attempts.is_empty()) {
            None => State::Unknown,
            Some(r) => match r.outcome {
                Outcome::Error => State::Error,
                Outcome::Mismatch | Outcome::DeviceLost | Outcome::Crash | Outcome::Timeout
                    if r.outside_spec.is_some() && !r.defined_mismatch() =>
                {
                    State::Doubtful(Doubt::UndefinedFault)
                }
                Outcome::Mismatch | Outcome::DeviceLost | Outcome::Crash | Outcome::Timeout => {
                    State::Fault
                }
                Outcome::Pass if self.suspect(c).is_some() => State::Doubtful(Doubt::SuspectPass),
                Outcome::Pass => State::Pass,
                Outcome::Unsupported | Outcome::NotImplemented => State::Unknown,
            },
        }
    }
}
