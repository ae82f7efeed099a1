//! A run's rounds as a library: the matrix, then confirmation, repeats, workarounds, recommended
//! patterns (and the repeats that verify them), GPU-AV and canaries, each deciding which cells
//! to run again from the report so far and recording what comes back. Cells run through an
//! [`Oracle`] (`runner::oracle`: the CLI's wraps the supervisor; `bisect` uses the same trait;
//! tests script outcomes), events reach the report through a [`Recorder`], [`Progress`] shows
//! them, and [`Policy`] says which rounds run, from the run's options. [`start`] builds the report a run starts from (fresh or resumed)
//! and finishes it.
//!
//! The order is the run's contract (ARCHITECTURE.md, "A run, end to end"): every probe cell,
//! then faults confirmed alone, then `--repeat`, then workarounds and patterns with their
//! verifying repeats, then `--mutants` (each cell's emulated driver bugs, kept apart), then GPU-AV (attempts kept apart from the cells' own), canaries last (they
//! may wedge a real GPU), then the findings are annotated with what the rounds found.
mod policy;
pub mod progress;
pub mod record;
mod rounds;
pub mod start;
#[cfg(test)]
mod tests;

pub use crate::runner::oracle::{Event, Mode, Oracle};
pub use policy::{Campaign, MutantPolicy, Policy};
pub use progress::Progress;
pub use record::Recorder;
pub use rounds::{confirm_cells, repeat_cells, verify_cells, workaround_cells};

use crate::model::Cell;

impl Campaign<'_> {
    /// Every round `policy` asks for, in the run's order: `cells` first, `canaries` last.
    pub fn run(&mut self, policy: &Policy, cells: &[Cell], canaries: &[Cell]) {
        self.rec.progress.scheduled((cells.len() + canaries.len()) as u64);
        self.matrix(cells);
        if policy.confirm {
            self.confirm();
        }
        if let Some(n) = policy.repeat {
            self.repeat(n);
        }
        if policy.workarounds {
            self.workarounds();
            self.patterns();
            self.verify();
        }
        if let Some(m) = &policy.mutants {
            self.mutants(m);
        }
        if let Some(layer) = policy.gpu_av {
            self.gpu_av(layer);
        }
        self.canaries(canaries);
        crate::report::writer::annotate_findings(&mut self.rec.writer.report);
    }
}
