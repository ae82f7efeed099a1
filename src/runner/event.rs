//! What running cells reports, in one vocabulary from the worker's state machine up: the machine
//! ([`super::machine`]) emits each [`Event`] as an effect, the supervisor passes it on (an
//! attempt tagged with what was injected into it), and the rounds above record it through
//! [`super::oracle::Oracle`]. A new event is a variant here, emitted by the machine and recorded
//! by its consumers: nothing translates one event type into another.
use crate::model::{Attempt, Cell, Halt, WorkerEvent};

/// Events for the report writer and progress display.
// One message per line, moved once: boxing the large variant would buy nothing.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, PartialEq)]
pub enum Event {
    /// A worker finished its setup.
    WorkerReady {
        device_ms: f64,
        /// Of `device_ms`, the instance and device creation.
        create_ms: f64,
        reference_ms: f64,
        /// The scene AS build within `device_ms`, when the worker built one.
        as_build_ms: Option<f64>,
        /// Of `device_ms`, the time blocked on the queue (fence waits of the AS build, uploads).
        setup_wait_ms: f64,
        pipeline_cache: Option<crate::exec::pipeline_cache::Loaded>,
        driver_cache: Option<crate::model::DriverCache>,
    },
    /// A worker built a batch of cells ahead of their turns.
    /// `overlapped`: cells that ran while its pipelines were still being made; `checked_apart`:
    /// those judged on the checker thread.
    Prebuilt {
        wall_ms: f64,
        pipelines: usize,
        threads: usize,
        overlapped: usize,
        checked_apart: usize,
    },
    /// A worker wrote the pipeline cache back (`Err`: why not).
    CacheSaved(Result<u64, String>),
    /// A worker's setup finished or failed, or it faulted outside a cell.
    Worker(WorkerEvent),
    /// An attempt of one cell.
    Attempt { cell: Cell, attempt: Attempt },
    /// A worker found what no cell of the run can get past: the supervisor stops its workers
    /// and runs nothing more, and the rounds above stop (after the worker's own record).
    Halt(Halt),
}
