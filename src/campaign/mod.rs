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
//! verifying repeats, then GPU-AV (attempts kept apart from the cells' own), canaries last (they
//! may wedge a real GPU), then the findings are annotated with what the rounds found.
pub mod progress;
pub mod record;
mod rounds;
pub mod start;
#[cfg(test)]
mod tests;

pub use crate::runner::oracle::{Event, Mode, Oracle};
pub use progress::Progress;
pub use record::Recorder;
pub use rounds::{confirm_cells, repeat_cells, verify_cells, workaround_cells};

use crate::model::report::RunOptions;
use crate::model::{Cell, Isolation, PatchMode};

/// Which rounds a run makes after its matrix.
#[derive(Clone, Debug, PartialEq)]
pub struct Policy {
    /// Re-run each fault alone once (`--no-confirm` off, under `--isolation worker` only: with
    /// a process per cell every attempt already ran alone).
    pub confirm: bool,
    /// `--repeat N`: every faulting cell gets N attempts in all.
    pub repeat: Option<u32>,
    /// `--patches faults`: retry findings with each applicable workaround and their recommended
    /// pattern, then verify the passing ones.
    pub workarounds: bool,
    /// `--validate=gpu-av`: re-run findings under GPU-AV; `Some(layer)`, the installed
    /// validation layer's spec version (`None`: not installed).
    pub gpu_av: Option<Option<u32>>,
}

impl Policy {
    /// The rounds `options` ask for; `layer` is asked only under `--validate=gpu-av`.
    pub fn of(options: &RunOptions, layer: impl FnOnce() -> Option<u32>) -> Policy {
        Policy {
            confirm: options.confirm && options.isolation == Isolation::Worker,
            repeat: options.repeat,
            workarounds: options.patches == PatchMode::Faults,
            gpu_av: options.gpu_av.then(layer),
        }
    }
}

/// What the rounds run with: the oracle, the recorder of the report, and which cells the device
/// can run (workaround and pattern cells outside the plan are checked here).
pub struct Campaign<'a> {
    pub oracle: &'a mut dyn Oracle,
    pub rec: &'a mut Recorder,
    pub supported: &'a dyn Fn(&Cell) -> bool,
}

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
        if let Some(layer) = policy.gpu_av {
            self.gpu_av(layer);
        }
        self.canaries(canaries);
        crate::report::writer::annotate_findings(&mut self.rec.writer.report);
    }
}
