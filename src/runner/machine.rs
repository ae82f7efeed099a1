//! A worker as the supervisor sees it, as a pure state machine: [`step`] takes the worker's state
//! and one input (a parsed line of its output, the end of its output, a deadline that passed, or
//! how its process ended) and gives the next state and the [`Effect`]s the supervisor must carry
//! out (report an [`Event`]: an attempt or a worker event; kill or reap the process, send cells
//! back). No
//! processes and no clock of its own: `now` comes with each input, and the supervisor alone
//! decides that a deadline passed (it compares [`Worker::deadline`] with its clock and feeds
//! [`Input::Deadline`]), as nextest's runner decides for its executors.
//!
//! A worker's states: `Setup` until `ready`, then `Between` cells, `Prebuild` while it builds a
//! batch ahead of the cells' turns (each step of progress restarts the deadline), `Cell` from a
//! `start` to its `result`, and `Teardown` after its last result or a result that ends it (a
//! worker that then says `exiting` is `Ended` at once, its process reaped in the background). A
//! worker that must go (end of output, a deadline, a fatal message) is `Dying` until the
//! supervisor feeds how it ended, then `Ended`. What is recorded is decided there, from the state
//! it died in: a cell's attempt (`crash` or `timeout` mid-cell, with the phase), the prebuild's
//! worker event (its batch then builds cell by cell), or a worker event outside any cell; a
//! fatal message that halts the run (no shader compiler) is the worker's event, then the halt.
use super::event::Event;
use super::protocol::WorkerMsg;
use crate::model::{signal_name, Attempt, Cell, Halt, Outcome, Phase, WorkerEvent, WorkerExit};
use std::time::{Duration, Instant};

/// Lines that are not protocol messages logged per worker (a worker can flood them).
pub(super) const GARBAGE_LOGGED: u64 = 20;

/// How long each state may last (the supervisor's options).
#[derive(Clone, Copy, Debug)]
pub(super) struct Limits {
    /// A cell, the gap between two cells, a prebuild's step, teardown.
    pub timeout: Duration,
    /// Setup, from the process start to `ready`.
    pub setup_timeout: Duration,
}

#[derive(Clone, Debug, PartialEq)]
pub(super) enum State {
    Setup,
    Cell {
        cell: Cell,
        since: Instant,
    },
    /// After `ready` or a result, before the next `start`.
    Between {
        since: Instant,
    },
    /// Building `cells` ahead of their turns; `since` restarts at each step of progress;
    /// `overlapped` is the last cell told of by an overlapped step (`cell ID: phase`); `fault`:
    /// the VK_EXT_device_fault data an overlapped cell's device loss sent before its `fatal`.
    Prebuild {
        cells: Vec<String>,
        since: Instant,
        overlapped: Option<String>,
        fault: Option<Box<crate::model::FaultInfo>>,
    },
    /// After its last result, or a result that ends it: it must exit.
    Teardown {
        since: Instant,
    },
    /// Being killed or reaped; `was` is the state it was in.
    Dying {
        was: Box<State>,
        cause: Cause,
    },
    /// Gone, recorded: the supervisor drops it.
    Ended,
}

/// Why a worker is dying.
#[derive(Clone, Debug, PartialEq)]
pub(super) enum Cause {
    /// Its output ended.
    Eof,
    /// Its state's deadline passed.
    Deadline,
    /// It said it cannot go on (a failed setup; a device loss or hung fence while prebuilding);
    /// `halt`: nor can the run.
    Fatal { message: String, outcome: Outcome, halt: Option<Halt> },
}

// One message per line, moved once: boxing the large variant would buy nothing.
#[allow(clippy::large_enum_variant)]
#[derive(Debug)]
pub(super) enum Input {
    Msg(WorkerMsg),
    /// A line that is not a protocol message.
    Garbage(String),
    Eof,
    /// The supervisor found the state's deadline passed.
    Deadline,
    /// How the process ended, after [`Effect::Kill`] or [`Effect::Reap`].
    Exited(WorkerExit),
}

#[derive(Debug, PartialEq)]
pub(super) enum Effect {
    /// A line for the debug log.
    Log(String),
    /// Kill the process group (SIGTERM, grace, SIGKILL, bounded wait), then feed `Exited`.
    Kill,
    /// Its output ended: wait for the exit (bounded; one that does not exit is killed), then feed
    /// `Exited`.
    Reap,
    /// It said `exiting` after its last result: it owes nothing more. Reap it in the background
    /// (killed if it is still there after the teardown deadline), without waiting for its exit.
    Release,
    /// An event for the rounds above: its setup, a prebuild, the pipeline cache saved, the
    /// worker's own record (its setup, or a fault outside any cell), or an attempt of one of its
    /// cells (the cell leaves the queue).
    Report(Event),
    /// Cells it died or hung prebuilding: later workers build them at their turn only.
    Serial(Vec<String>),
    /// It ended without an attempt; should the slot give up on its `batch` cells, each is
    /// recorded as `not_run`.
    Fruitless { batch: usize, not_run: Attempt },
}

#[derive(Clone, Debug)]
pub(super) struct Worker {
    pub id: u64,
    pub state: State,
    pub phase: Phase,
    /// The step of the phase it last named (`vkCreateDevice`, `pipelines 3/8`).
    pub step: Option<String>,
    pub device_features: Vec<String>,
    /// Cells of its job without a result yet, in order.
    pub pending: Vec<Cell>,
    /// Cells it was given.
    pub batch: usize,
    /// It produced at least one attempt.
    pub progressed: bool,
    /// Lines that were not protocol messages.
    pub garbage: u64,
    pub spawned: Instant,
    /// It runs its cells alone (recorded in each attempt).
    pub isolated: bool,
}

impl Worker {
    pub fn new(id: u64, cells: Vec<Cell>, isolated: bool, spawned: Instant) -> Worker {
        Worker {
            id,
            state: State::Setup,
            phase: Phase::Setup,
            step: None,
            device_features: vec![],
            batch: cells.len(),
            pending: cells,
            progressed: false,
            garbage: 0,
            spawned,
            isolated,
        }
    }

    /// When its state's time is up (`None`: dying or ended, nothing to wait for).
    pub fn deadline(&self, limits: &Limits) -> Option<Instant> {
        match self.state {
            State::Setup => Some(self.spawned + limits.setup_timeout),
            State::Cell { since, .. }
            | State::Between { since }
            | State::Prebuild { since, .. }
            | State::Teardown { since } => Some(since + limits.timeout),
            State::Dying { .. } | State::Ended => None,
        }
    }

    pub fn ended(&self) -> bool {
        self.state == State::Ended
    }

    fn where_(&self) -> String {
        match &self.step {
            Some(s) => format!("{} ({s})", self.phase),
            None => self.phase.to_string(),
        }
    }

    fn enter(&mut self, state: State, phase: Phase) {
        self.state = state;
        self.phase = phase;
        self.step = None;
    }
}

/// One input: the worker's next state and what the supervisor must do.
pub(super) fn step(
    mut w: Worker,
    input: Input,
    now: Instant,
    limits: &Limits,
) -> (Worker, Vec<Effect>) {
    let mut fx = Vec::new();
    match input {
        Input::Msg(msg) if alive(&w.state) => message(&mut w, msg, now, &mut fx),
        Input::Garbage(text) if alive(&w.state) => garbage(&mut w, text, &mut fx),
        Input::Eof => dying(&mut w, Cause::Eof, &mut fx),
        Input::Deadline => dying(&mut w, Cause::Deadline, &mut fx),
        Input::Exited(exit) => exited(&mut w, exit, now, limits, &mut fx),
        Input::Msg(_) | Input::Garbage(_) => {}
    }
    (w, fx)
}

fn alive(s: &State) -> bool {
    !matches!(s, State::Dying { .. } | State::Ended)
}

fn message(w: &mut Worker, msg: WorkerMsg, now: Instant, fx: &mut Vec<Effect>) {
    match msg {
        WorkerMsg::Ready { .. } if w.state != State::Setup => {
            // Only once, at the end of setup: it must not restart any clock.
            fx.push(Effect::Log(format!("worker {} sent ready again; ignored", w.id)));
        }
        ready @ WorkerMsg::Ready { .. } => setup_done(w, ready, now, fx),
        WorkerMsg::Phase { phase, step } => phase_told(w, phase, step, now),
        WorkerMsg::Prebuild { cells, threads } if matches!(w.state, State::Between { .. }) => {
            fx.push(Effect::Log(format!(
                "worker {} prebuilds {} cells on {threads} threads",
                w.id,
                cells.len()
            )));
            let state = State::Prebuild { cells, since: now, overlapped: None, fault: None };
            w.enter(state, Phase::Prebuild);
        }
        WorkerMsg::Prebuild { .. } => fx.push(Effect::Log(format!(
            "worker {} sent prebuild while not between cells; ignored",
            w.id
        ))),
        WorkerMsg::Prebuilt { wall_ms, pipelines, threads, overlapped, checked_apart } => {
            if matches!(w.state, State::Prebuild { .. }) {
                w.enter(State::Between { since: now }, Phase::BetweenCells);
                let ev = Event::Prebuilt { wall_ms, pipelines, threads, overlapped, checked_apart };
                fx.push(Effect::Report(ev));
            }
        }
        WorkerMsg::CacheSaved { bytes, error } => fx.push(Effect::Report(Event::CacheSaved(
            bytes.ok_or_else(|| error.unwrap_or_else(|| "not saved".into())),
        ))),
        WorkerMsg::Exiting if matches!(w.state, State::Teardown { .. }) && w.pending.is_empty() => {
            // Everything is in: how the process ends (it skips its Vulkan teardown) is nobody's
            // record, so nothing waits for it.
            fx.push(Effect::Release);
            w.state = State::Ended;
        }
        WorkerMsg::Exiting => fx.push(Effect::Log(format!(
            "worker {} said exiting with cells left; waiting for its exit",
            w.id
        ))),
        WorkerMsg::Start { cell } => start(w, cell, now, fx),
        WorkerMsg::Result { cell, result } => finished(w, &cell, result, now, fx),
        WorkerMsg::DeviceFault { cell, fault } => match &mut w.state {
            State::Prebuild { fault: kept, .. } => *kept = Some(Box::new(fault)),
            _ => fx.push(Effect::Log(format!(
                "worker {} sent a device fault of {cell} outside a prebuild; ignored",
                w.id
            ))),
        },
        WorkerMsg::Fatal { message, outcome, halt } => {
            dying(w, Cause::Fatal { message, outcome, halt }, fx)
        }
    }
}

/// The worker's `ready`: setup done, its figures reported and its setup recorded.
fn setup_done(w: &mut Worker, msg: WorkerMsg, now: Instant, fx: &mut Vec<Effect>) {
    let WorkerMsg::Ready {
        device_ms,
        create_ms,
        reference_ms,
        as_build_ms,
        setup_wait_ms,
        device_features,
        pipeline_cache,
        driver_cache,
    } = msg
    else {
        return;
    };
    w.enter(State::Between { since: now }, Phase::BetweenCells);
    w.device_features = device_features;
    fx.push(Effect::Report(Event::WorkerReady {
        device_ms,
        create_ms,
        reference_ms,
        as_build_ms,
        setup_wait_ms,
        pipeline_cache,
        driver_cache,
    }));
    fx.push(record(w, Phase::Setup, Outcome::Pass, None, None, now));
}

/// A `phase` line: prebuild progress (GLSL, a cell compiled and bound, a pipeline) restarts its
/// clock and names the overlapped cell it is at.
fn phase_told(w: &mut Worker, phase: Phase, step: Option<String>, now: Instant) {
    if let (Phase::Prebuild, State::Prebuild { since, overlapped, .. }) = (phase, &mut w.state) {
        *since = now;
        if let Some(cell) = step.as_deref().and_then(super::protocol::overlapped_cell) {
            *overlapped = Some(cell.to_string());
        }
    }
    w.phase = phase;
    w.step = step;
}

fn start(w: &mut Worker, cell: String, now: Instant, fx: &mut Vec<Effect>) {
    // Only between cells: a repeated `start` must not restart the running cell's clock.
    if !matches!(w.state, State::Between { .. }) {
        fx.push(Effect::Log(format!(
            "worker {} sent start {cell} while not between cells; ignored",
            w.id
        )));
    } else if let Some(c) = w.pending.iter().find(|c| c.id() == cell) {
        w.enter(State::Cell { cell: *c, since: now }, Phase::Compile);
    }
}

/// A cell's result: its attempt; then the next cell, or teardown after the last one or after an
/// outcome that ends the worker (it exits by itself).
fn finished(
    w: &mut Worker,
    cell: &str,
    result: crate::model::CellResult,
    now: Instant,
    fx: &mut Vec<Effect>,
) {
    let since = match w.state {
        State::Cell { since, .. } => since,
        _ => now,
    };
    let Some(pos) = w.pending.iter().position(|c| c.id() == cell) else {
        return;
    };
    let c = w.pending.remove(pos);
    let ends = result.outcome.ends_worker();
    // A cell that overlapped a prebuild sends its lines after `prebuilt`, together: its wall
    // time is the worker's own measure then, never less.
    let wall_ms = ms(since, now).max(result.timings.total_ms);
    let attempt = attempt(w, result.outcome).with_result(result).with_wall_ms(wall_ms);
    w.progressed = true;
    if ends || w.pending.is_empty() {
        w.enter(State::Teardown { since: now }, Phase::Teardown);
    } else {
        w.enter(State::Between { since: now }, Phase::BetweenCells);
    }
    fx.push(Effect::Report(Event::Attempt { cell: c, attempt }));
}

fn garbage(w: &mut Worker, text: String, fx: &mut Vec<Effect>) {
    w.garbage += 1;
    if w.garbage <= GARBAGE_LOGGED {
        fx.push(Effect::Log(format!("worker {} said: {text}", w.id)));
    } else if w.garbage == GARBAGE_LOGGED + 1 {
        fx.push(Effect::Log(format!("worker {} keeps printing; further lines not logged", w.id)));
    }
}

fn dying(w: &mut Worker, cause: Cause, fx: &mut Vec<Effect>) {
    if !alive(&w.state) {
        return;
    }
    fx.push(if cause == Cause::Eof { Effect::Reap } else { Effect::Kill });
    let was = Box::new(std::mem::replace(&mut w.state, State::Ended));
    w.state = State::Dying { was, cause };
}

/// The process ended: record it by the state it died in and why.
fn exited(w: &mut Worker, exit: WorkerExit, now: Instant, limits: &Limits, fx: &mut Vec<Effect>) {
    let State::Dying { was, cause } = std::mem::replace(&mut w.state, State::Ended) else {
        w.state = State::Ended;
        return;
    };
    let (died_as, what) = died(&exit);
    let at = w.where_();
    // A fatal message mid-cell is the worker's: the cell was not what failed, and runs again.
    let (fatal, halt) = match &cause {
        Cause::Fatal { halt, .. } => (true, *halt),
        _ => (false, None),
    };
    let (outcome, detail) = match (&*was, cause) {
        (State::Teardown { .. }, Cause::Eof) if exit.code == Some(0) => return, // exited cleanly
        (State::Cell { .. }, Cause::Eof) => (died_as, format!("{what} mid-cell, in {at}")),
        (State::Cell { .. }, Cause::Deadline) => (
            Outcome::Timeout,
            format!("no result within {:?}, in {at}; worker process group killed", limits.timeout),
        ),
        (State::Prebuild { .. }, Cause::Fatal { message, outcome, .. }) => {
            (outcome, format!("worker failed in {at}: {message}"))
        }
        (_, Cause::Fatal { message, outcome, .. }) => {
            (outcome, format!("worker setup failed in {at}: {message}"))
        }
        (State::Prebuild { .. }, Cause::Deadline) => (
            Outcome::Timeout,
            format!(
                "no progress within {:?}, in {at}; worker process group killed",
                limits.timeout
            ),
        ),
        (State::Setup, Cause::Deadline) => (
            Outcome::Timeout,
            format!("worker setup took longer than {:?}, in {at}; killed", limits.setup_timeout),
        ),
        (State::Between { .. }, Cause::Deadline) => (
            Outcome::Timeout,
            format!("no next cell within {:?} after the last result; killed", limits.timeout),
        ),
        (State::Teardown { .. }, Cause::Deadline) => (
            Outcome::Timeout,
            format!(
                "did not exit within {:?} after its last cell, in {at}; killed",
                limits.timeout
            ),
        ),
        (_, Cause::Eof | Cause::Deadline) => (died_as, format!("{what} in {at}")),
    };
    match *was {
        State::Cell { cell, since } if !fatal => {
            let attempt = attempt(w, outcome)
                .with_detail(detail)
                .with_exit(exit)
                .with_wall_ms(ms(since, now));
            fx.push(Effect::Report(Event::Attempt { cell, attempt }));
        }
        State::Prebuild { cells, overlapped, fault, .. } if halt.is_none() => {
            let fault = fault.map(|f| *f);
            prebuild_failed(w, (cells, overlapped, fault), outcome, detail, exit, now, fx)
        }
        _ => worker_failed(w, outcome, detail, exit, halt, now, fx),
    }
}

/// A worker died, hung or lost its device while prebuilding: no one cell can be blamed, so it
/// is the worker's record (phase `prebuild`), and the batch's cells go back to the sequential
/// path: later workers build each at its turn, where a fault is exactly one cell's verdict.
fn prebuild_failed(
    w: &Worker,
    (cells, overlapped, fault): (Vec<String>, Option<String>, Option<crate::model::FaultInfo>),
    outcome: Outcome,
    detail: String,
    exit: WorkerExit,
    now: Instant,
    fx: &mut Vec<Effect>,
) {
    fx.push(Effect::Serial(cells));
    let detail = format!("{detail}; its batch runs again, each cell building at its turn");
    let mut event = worker_event(w, Phase::Prebuild, outcome, Some(detail), Some(exit), now);
    event.overlapped_cell = overlapped;
    event.fault = fault;
    fx.push(Effect::Report(Event::Worker(event)));
}

/// A worker failed outside any cell: in setup, between cells or in teardown. Its own event;
/// then its `halt`, which stops the run (its cells stay without an attempt), or, without an
/// attempt, it is fruitless too, with what its cells get should the slot give up.
fn worker_failed(
    w: &Worker,
    outcome: Outcome,
    detail: String,
    exit: WorkerExit,
    halt: Option<Halt>,
    now: Instant,
    fx: &mut Vec<Effect>,
) {
    let why = format!(
        "not run: two workers in a row failed before running a cell; the last: {} in {}: {detail}",
        outcome.as_str(),
        w.phase
    );
    let mut event = record(w, w.phase, outcome, Some(detail), Some(exit.clone()), now);
    if let Effect::Report(Event::Worker(e)) = &mut event {
        e.halt = halt;
    }
    fx.push(event);
    if let Some(h) = halt {
        fx.push(Effect::Report(Event::Halt(h)));
    } else if !w.progressed {
        fx.push(Effect::Fruitless {
            batch: w.batch,
            not_run: attempt(w, outcome).with_detail(why).with_exit(exit),
        });
    }
}

/// An attempt by this worker, in its current phase.
fn attempt(w: &Worker, outcome: Outcome) -> Attempt {
    Attempt::new(outcome, w.isolated).with_worker(w.id, w.phase, w.device_features.clone())
}

/// The worker's own record, to report.
fn record(
    w: &Worker,
    phase: Phase,
    outcome: Outcome,
    detail: Option<String>,
    worker_exit: Option<WorkerExit>,
    now: Instant,
) -> Effect {
    Effect::Report(Event::Worker(worker_event(w, phase, outcome, detail, worker_exit, now)))
}

fn worker_event(
    w: &Worker,
    phase: Phase,
    outcome: Outcome,
    detail: Option<String>,
    worker_exit: Option<WorkerExit>,
    now: Instant,
) -> WorkerEvent {
    WorkerEvent {
        worker: w.id,
        phase,
        outcome,
        detail,
        cells: w.batch,
        wall_ms: ms(w.spawned, now),
        device_features: w.device_features.clone(),
        worker_exit,
        halt: None,
        overlapped_cell: None,
        fault: None,
    }
}

fn ms(since: Instant, now: Instant) -> f64 {
    now.saturating_duration_since(since).as_secs_f64() * 1e3
}

/// How a worker that ended unasked is classified: a signal or a non-zero code is a crash.
pub(super) fn died(exit: &WorkerExit) -> (Outcome, String) {
    match (exit.signal, exit.code) {
        (Some(s), _) => {
            (Outcome::Crash, format!("worker killed by signal {s} ({})", signal_name(s)))
        }
        (None, Some(c)) if c != 0 => (Outcome::Crash, format!("worker exited with code {c}")),
        (None, Some(_)) => (Outcome::Error, "worker exited (code 0) early".into()),
        (None, None) => (Outcome::Error, "worker vanished".into()),
    }
}

#[cfg(test)]
mod tests;
