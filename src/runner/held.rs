//! An overlapped batch's held lines ([`Held`]): the `start` and `result` lines of the cells that
//! ran while the prebuild's pipelines were still being made, kept in order until `prebuilt`
//! (`runner::overlap`), with the results of the cells whose records the checker thread judges
//! (`exec::checker`) filled in as they come back.
//!
//! Fault attribution stays the inline check's: the supervisor blames a death during the overlap
//! on the last cell an overlapped step named (`protocol::overlapped_step`). So before the cell
//! thread waits for a cell's check (the queue full, or `prebuilt` due), and before a check's panic
//! is resumed, that cell is named again (`cell ID: check`): a check that hangs or panics is
//! pinned on its own cell, not on a later one the cell thread ran meanwhile. At most
//! [`QUEUE`] cells wait for their checks, so a hang is found within that many cells.
use super::protocol::WorkerMsg;
use crate::exec::checker::{Checker, QUEUE};
use crate::exec::{Executor, Traced};
use crate::model::Phase;
use crate::probe::Record;
use std::collections::VecDeque;

/// One held line: a message, or the place of a `result` whose check has not come back yet.
// One per overlapped cell, moved once, as `WorkerMsg` itself.
#[allow(clippy::large_enum_variant)]
enum Line {
    Msg(WorkerMsg),
    Checking,
}

/// Names a cell to the supervisor (its overlapped `check` step).
pub(super) type Tell = Box<dyn Fn(&str)>;

/// The held lines and the checker thread of one overlapped batch.
pub(super) struct Held {
    lines: Vec<Line>,
    /// The cells handed to `checker` and where in `lines` their results go, oldest first.
    checking: VecDeque<(usize, String)>,
    /// Started at the first cell handed over (`None` before, or where no thread could start).
    checker: Option<Checker>,
    /// Cells judged on the checker thread (`prebuilt`'s `checked_apart`).
    checked_apart: usize,
    tell: Tell,
}

/// The worker's [`Tell`]: a `phase prebuild` step `cell ID: check`.
pub(super) fn tell_supervisor() -> Tell {
    Box::new(|cell| super::worker_io::send_overlapped(cell, Phase::Check))
}

impl Held {
    pub(super) fn new(tell: Tell) -> Held {
        Held { lines: vec![], checking: VecDeque::new(), checker: None, checked_apart: 0, tell }
    }

    /// A line held back as it is.
    pub(super) fn push(&mut self, msg: WorkerMsg) {
        self.lines.push(Line::Msg(msg));
    }

    /// `cell`'s records, judged on the checker thread (started at the first; where it cannot
    /// start, here, at once); its `result` held in its place. With [`QUEUE`] cells waiting, the
    /// oldest is waited for first.
    pub(super) fn judge(&mut self, exec: &mut Executor, cell: String, traced: Traced) {
        if self.checker.is_none() {
            self.checker = Checker::start(exec)
                .inspect_err(|e| tracing::warn!("no checker thread ({e}): checks inline"))
                .ok();
        }
        if self.checker.is_none() {
            let result = exec.judge_traced(traced);
            return self.push(WorkerMsg::Result { cell, result });
        }
        self.hand_over(cell, traced, &mut |r| exec.reuse_records(r));
    }

    /// `traced` to the checker (which exists), its place kept; with [`QUEUE`] cells waiting, the
    /// oldest waited for first.
    fn hand_over(&mut self, cell: String, traced: Traced, reuse: &mut dyn FnMut(Vec<Record>)) {
        if self.checking.len() >= QUEUE {
            self.collect_one(reuse, true);
        }
        if let Some(c) = self.checker.as_mut() {
            c.submit(traced);
            self.checking.push_back((self.lines.len(), cell));
            self.lines.push(Line::Checking);
        }
    }

    /// The results come back so far put in their places (`wait`: every one, waited for); each
    /// records vector to `reuse`.
    pub(super) fn collect(&mut self, reuse: &mut dyn FnMut(Vec<Record>), wait: bool) {
        while self.collect_one(reuse, wait) {}
    }

    /// The oldest waiting cell's result put in its place, if it is back (`wait`: waited for,
    /// the cell named first); its check's panic resumed after naming the cell. Whether one was.
    fn collect_one(&mut self, reuse: &mut dyn FnMut(Vec<Record>), wait: bool) -> bool {
        let (Some((_, cell)), Some(c)) = (self.checking.front(), self.checker.as_mut()) else {
            return false;
        };
        if wait {
            (self.tell)(cell);
        }
        let Some(judged) = (if wait { Some(c.take()) } else { c.try_take() }) else {
            return false;
        };
        let Some((at, cell)) = self.checking.pop_front() else { return false };
        let (result, records) = judged.unwrap_or_else(|payload| {
            (self.tell)(&cell);
            std::panic::resume_unwind(payload)
        });
        reuse(records);
        self.lines[at] = Line::Msg(WorkerMsg::Result { cell, result });
        self.checked_apart += 1;
        true
    }

    /// Every held line in order, every check waited for first; the checker thread ended. With
    /// the number of cells judged on it.
    pub(super) fn drain(&mut self, reuse: &mut dyn FnMut(Vec<Record>)) -> (Vec<WorkerMsg>, usize) {
        self.collect(reuse, true);
        self.checker = None;
        let lines = std::mem::take(&mut self.lines).into_iter().map(|l| match l {
            Line::Msg(m) => m,
            Line::Checking => unreachable!("every check was waited for"),
        });
        (lines.collect(), std::mem::take(&mut self.checked_apart))
    }
}

#[cfg(test)]
mod tests;
