//! What cells are run through above the supervisor: an [`Oracle`] takes a batch of cells and a
//! [`Mode`] and reports what happens as [`Event`]s (the runner's one vocabulary, from
//! `super::event`). `campaign`'s rounds and `bisect` share it; the CLI's implementation wraps
//! [`super::supervisor::Supervisor`], tests script outcomes per cell, `bisect --offline`'s runs
//! nothing.
pub use super::event::Event;
use crate::model::Cell;

/// How a batch of cells runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// As the plan runs: cells share workers (per `--isolation`), with the persisted pipeline
    /// cache (the matrix, the first run of workaround and pattern cells, canaries).
    Shared,
    /// Each cell alone in a fresh worker, its pipeline compiled cold (the SPIR-V may be kept:
    /// `runner::protocol::WorkerJob::glsl_cache`), several side by side on CPU devices
    /// (`SupervisorOptions::rerun_jobs`) (confirmation, repeats, verifying workarounds and
    /// patterns, bisection's repeats).
    Alone,
    /// Alone, under the validation layer with GPU-AV on, one thread, no pipeline cache
    /// (`report::gpu_av`); its attempts never join the cells' own.
    GpuAv,
}

/// Runs cells. Every attempt comes back as an [`Event::Attempt`], in the order they end; an
/// oracle may also report worker events (`WorkerReady`, `Worker`, ...). A cell it could not run
/// may come back with no attempt at all: callers never loop on a batch that added nothing.
pub trait Oracle {
    /// Run each of `cells` once more, as `mode` says, reporting every event to `on`.
    fn run(&mut self, cells: &[Cell], mode: Mode, on: &mut dyn FnMut(Event));
    /// Whether it runs anything (`bisect --offline`'s runs nothing).
    fn can_run(&self) -> bool {
        true
    }
}
