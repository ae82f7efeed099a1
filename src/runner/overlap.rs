//! The worker's side of a prebuild ([`Batch`]): the chunk's cells (but the serial ones) staged
//! and their pipelines handed to `--threads` threads (`exec::prebuild`), then each cell run as
//! soon as its pipeline is made, while later pipelines are still being made: the cells overlap
//! the prebuild.
//!
//! Fault attribution: while pipelines are still being made on other threads, a crash, hang or
//! device loss cannot be pinned on the cell that was running (the driver was also busy
//! elsewhere). So a cell that runs before the last pipeline of the batch is made (an
//! *overlapped* cell) is run inside the prebuild, as the supervisor sees it: its phases go out
//! as `prebuild` steps (`cell ID: trace`, each restarting the supervisor's deadline), and its
//! `start` and `result` lines are held back and sent right after `prebuilt`, once every pipeline
//! is made. A worker that dies or hangs before `prebuilt` is therefore a prebuild death, blamed on
//! no cell (the worker's record, phase `prebuild`), and the batch's unfinished cells go to the
//! next worker as `serial`, where a real fault recurs with nothing else running and is pinned on
//! its cell. An overlapped cell whose own result ends the worker (a lost device, a fence past
//! the worker's deadline) is reported the same way: as the worker's `fatal` message in
//! `prebuild`, never as the cell's result. A hang ends in a timeout either way: the worker's
//! fence deadline, or the supervisor's prebuild deadline once the pool is silent.
//!
//! An overlapped cell's records are judged on a checker thread (`exec::checker`) while the cell
//! thread goes on to the next cell: its `result` is held back anyway; `prebuilt` waits for every
//! check, and the held lines go out in order (`runner::held`, which also keeps a check's hang or
//! panic pinned on its own cell). A cell after `prebuilt` is judged on the cell thread, between its
//! `start` and `result`.
//!
//! `--validate` (and GPU-AV) keep the batch unoverlapped: every pipeline is made before the
//! first cell runs, so each cell's validation messages are its own. A serial cell never runs
//! overlapped either: the batch's pipelines are all made before its turn.
use super::held::Held;
use super::misbehave::Misbehave;
use super::protocol::WorkerMsg;
use super::worker_io::{halt_of, send};
use crate::exec::prebuild::{Prebuild, Step};
use crate::exec::{CellError, Executor, Traced};
use crate::model::{Cell, Halt, Phase};
use std::collections::HashSet;
use std::sync::Arc;
use std::time::Instant;

/// A chunk's prebuild under way, as the worker runs its cells.
pub(super) struct Batch {
    pb: Prebuild,
    /// `start` and `result` lines of the overlapped cells, sent right after `prebuilt`; their
    /// checks on the checker thread (`runner::held`).
    held: Held,
    /// `prebuilt` sent: every pipeline made, no cell overlaps any more.
    announced: bool,
    started: Instant,
    threads: usize,
    overlapped: usize,
}

/// Start building `chunk`'s cells (but the serial ones) ahead of their turns on `threads`
/// threads: `None` where it is not worth it (one thread, or fewer than two cells: each cell
/// builds at its turn). `overlap`: cells may run while pipelines are still being made (not
/// under validation). The `prebuild` message, then every unit of work as a `phase prebuild`
/// step (`glsl k/n`, `compiled k/n`, `pipelines k/n`): each restarts the supervisor's deadline.
/// An error that ends the worker (a device loss, a hung fence, or the test hook's) is the
/// worker's: it reports it as fatal and exits, and the supervisor runs these cells again
/// without prebuilding.
pub(super) fn start(
    exec: &mut Executor,
    chunk: &[Cell],
    serial: &HashSet<&str>,
    threads: usize,
    overlap: bool,
    hook: Option<&Misbehave>,
) -> Option<Batch> {
    let cells: Vec<Cell> =
        chunk.iter().filter(|c| !serial.contains(c.id().as_str())).copied().collect();
    if threads <= 1 || cells.len() < 2 {
        return None;
    }
    send(&WorkerMsg::Prebuild { cells: cells.iter().map(Cell::id).collect(), threads });
    let started = Instant::now();
    send(&WorkerMsg::Phase { phase: Phase::Prebuild, step: None });
    let progress: crate::exec::prebuild::Progress = Arc::new(|step: Step| {
        send(&WorkerMsg::Phase { phase: Phase::Prebuild, step: Some(step.to_string()) })
    });
    let held = overlap && hook.is_some_and(|h| h.overlap);
    let pb = hook
        .map_or(Ok(()), |h| h.at(Phase::Prebuild, None))
        .map_err(CellError::from)
        .and_then(|()| exec.prebuild(&cells, threads, held, progress))
        .unwrap_or_else(|e| fatal(threads, &e.to_string(), e.outcome(), halt_of(&e)));
    let mut b = Batch {
        pb,
        held: Held::new(super::held::tell_supervisor()),
        announced: false,
        started,
        threads,
        overlapped: 0,
    };
    if !overlap {
        b.finish(exec);
    }
    Some(b)
}

impl Batch {
    /// Before `cell`'s turn: its pipeline waited for; `prebuilt` sent if every pipeline is made
    /// (first waited for when the cell is serial). Whether the cell runs overlapped.
    pub(super) fn before(&mut self, exec: &mut Executor, cell: &Cell, serial: bool) -> bool {
        if serial {
            self.finish(exec);
        }
        let polled = exec.turn(&mut self.pb, cell).and_then(|()| exec.poll(&mut self.pb));
        // `prebuilt` goes out once per batch: after it, every later cell runs as usual.
        if self.check(polled) && !self.announced {
            self.announce(exec);
        }
        !self.announced
    }

    /// An overlapped cell's `start` or `result`, held back until `prebuilt`.
    pub(super) fn hold(&mut self, msg: WorkerMsg) {
        self.held.push(msg);
    }

    /// An overlapped cell's records, judged on the checker thread; its `result` held back until
    /// `prebuilt` as another's (`runner::held`).
    pub(super) fn judge(&mut self, exec: &mut Executor, cell: String, traced: Traced) {
        self.held.judge(exec, cell, traced);
    }

    /// After an overlapped cell whose result ends the worker: the worker's fatal message (the
    /// cell cannot be blamed while pipelines were being made), then its exit.
    pub(super) fn ended(&self, cell: &str, r: &crate::model::CellResult) -> ! {
        if let Some(fault) = r.fault.clone() {
            send(&WorkerMsg::DeviceFault { cell: cell.to_string(), fault });
        }
        let what = format!(
            "cell {cell} ended {} while pipelines were still being made ({}); it runs again \
             with nothing else running",
            r.outcome.as_str(),
            r.detail.as_deref().unwrap_or("no detail")
        );
        fatal(self.threads, &what, r.outcome, None)
    }

    /// After a cell: the held pool let go (the test hook's hold lasts one cell); `prebuilt`
    /// sent if every pipeline is made, or, after the chunk's `last` cell, once they are.
    pub(super) fn after(&mut self, exec: &mut Executor, overlapped: bool, last: bool) {
        self.overlapped += usize::from(overlapped);
        self.pb.release();
        self.held.collect(&mut |r| exec.reuse_records(r), false);
        if last {
            self.finish(exec);
        } else if !self.announced {
            let polled = exec.poll(&mut self.pb);
            if self.check(polled) {
                self.announce(exec);
            }
        }
    }

    /// The batch over: its pipelines all made and kept, `prebuilt` sent, the threads joined.
    pub(super) fn end(mut self, exec: &mut Executor) {
        self.finish(exec);
        exec.end(self.pb);
    }

    /// Every pipeline waited for, then `prebuilt` (once).
    fn finish(&mut self, exec: &mut Executor) {
        if !self.announced {
            let waited = exec.wait_all(&mut self.pb).map(|()| true);
            self.check(waited);
            self.announce(exec);
        }
    }

    fn check(&self, r: Result<bool, CellError>) -> bool {
        r.unwrap_or_else(|e| fatal(self.threads, &e.to_string(), e.outcome(), halt_of(&e)))
    }

    /// `prebuilt`, then the overlapped cells' held lines in order (their checks waited for).
    fn announce(&mut self, exec: &mut Executor) {
        let (held, checked_apart) = self.held.drain(&mut |r| exec.reuse_records(r));
        self.announced = true;
        send(&WorkerMsg::Prebuilt {
            wall_ms: self.started.elapsed().as_secs_f64() * 1e3,
            pipelines: self.pb.stats.pipelines,
            threads: self.pb.stats.threads,
            overlapped: self.overlapped,
            checked_apart,
        });
        for m in held {
            send(&m);
        }
    }
}

/// The prebuild failed in a way that ends the worker: its fatal message, then its exit (a lost
/// or hung device: no destructor runs).
fn fatal(threads: usize, what: &str, outcome: crate::model::Outcome, halt: Option<Halt>) -> ! {
    send(&WorkerMsg::Fatal {
        message: format!("building a batch of cells on {threads} threads: {what}"),
        outcome,
        halt,
    });
    unsafe { libc::_exit(0) }
}
