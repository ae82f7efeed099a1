//! Which worker runs which cells: the supervisor's slots (up to `-j` of them, each a queue of
//! cells and at most one worker at a time), the job of the next worker of a slot (all of its
//! queue, or its first cell alone when cells are isolated), the cells later workers must build at
//! their turn (an earlier worker died or hung prebuilding them), and the slot's count of fruitless
//! workers in a row (failed setups, deaths before the first cell): at two, the slot gives up on
//! the last one's cells; and a halted run, which starts no worker again. No processes: `W` is
//! whatever the supervisor keeps of a running worker.
use crate::model::Cell;
use std::collections::{HashSet, VecDeque};

pub(super) struct Slot<W> {
    queue: VecDeque<Cell>,
    pub worker: Option<W>,
    /// Workers in a row that ended without producing an attempt.
    fruitless: u32,
    /// Cells a worker died or hung prebuilding: later workers build them at their turn only.
    serial: HashSet<String>,
}

pub(super) struct Schedule<W> {
    pub slots: Vec<Slot<W>>,
    /// One worker per cell (`--isolation process-per-cell`, or a re-run alone).
    per_cell: bool,
    /// A worker halted the run ([`Schedule::halt`]).
    halted: bool,
}

/// A worker's job: its cells, and those of them it must not prebuild.
pub(super) struct Job {
    pub cells: Vec<Cell>,
    pub serial: Vec<String>,
}

impl<W> Schedule<W> {
    /// `cells` split in order over at most `jobs` slots of equal size (the last may be shorter).
    pub fn new(cells: &[Cell], jobs: usize, per_cell: bool) -> Self {
        let jobs = jobs.max(1).min(cells.len().max(1));
        let chunk = cells.len().div_ceil(jobs).max(1);
        let slots = cells
            .chunks(chunk)
            .map(|c| Slot {
                queue: c.iter().copied().collect(),
                worker: None,
                fruitless: 0,
                serial: HashSet::new(),
            })
            .collect();
        Schedule { slots, per_cell, halted: false }
    }

    pub fn per_cell(&self) -> bool {
        self.per_cell
    }

    /// No cell left and no worker running.
    pub fn finished(&self) -> bool {
        self.slots.iter().all(|s| s.worker.is_none() && s.queue.is_empty())
    }

    /// Slots with cells left and no worker.
    pub fn idle(&self) -> Vec<usize> {
        (0..self.slots.len())
            .filter(|&i| self.slots[i].worker.is_none() && !self.slots[i].queue.is_empty())
            .collect()
    }

    /// The job of slot `i`'s next worker: a prefix of its queue.
    pub fn job(&self, i: usize) -> Job {
        let s = &self.slots[i];
        let cells: Vec<Cell> = if self.per_cell {
            s.queue.iter().take(1).copied().collect()
        } else {
            s.queue.iter().copied().collect()
        };
        let serial = cells.iter().map(Cell::id).filter(|id| s.serial.contains(id)).collect();
        Job { cells, serial }
    }

    pub fn workers(&self) -> impl Iterator<Item = &W> {
        self.slots.iter().filter_map(|s| s.worker.as_ref())
    }

    /// Slot `i`'s worker produced an attempt of `cell`: it leaves the queue, and the slot's run
    /// of fruitless workers ends.
    pub fn ran(&mut self, i: usize, cell: &Cell) {
        let s = &mut self.slots[i];
        if let Some(pos) = s.queue.iter().position(|c| c == cell) {
            s.queue.remove(pos);
        }
        s.fruitless = 0;
    }

    /// Later workers of slot `i` build `cells` at their turn only.
    pub fn serial(&mut self, i: usize, cells: Vec<String>) {
        self.slots[i].serial.extend(cells);
    }

    /// Slot `i`'s worker, given `batch` cells, ended without an attempt. The first time the
    /// cells go to a fresh worker; the second in a row, the slot gives up on them: they are
    /// returned, to be recorded as not run (its job is a prefix of the queue).
    pub fn fruitless(&mut self, i: usize, batch: usize) -> Vec<Cell> {
        let s = &mut self.slots[i];
        s.fruitless += 1;
        if s.fruitless < 2 {
            return vec![];
        }
        s.fruitless = 0;
        let n = batch.min(s.queue.len());
        s.queue.drain(..n).collect()
    }

    /// A worker found what no cell can get past: every slot's cells are dropped, without an
    /// attempt, so that no worker starts again; stopping the running ones is the supervisor's.
    pub fn halt(&mut self) {
        self.halted = true;
        for s in &mut self.slots {
            s.queue.clear();
        }
    }

    pub fn halted(&self) -> bool {
        self.halted
    }

    /// No worker can start for slot `i`: every cell it has left, to be recorded as not run.
    pub fn abandon(&mut self, i: usize) -> Vec<Cell> {
        self.slots[i].queue.drain(..).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{DescriptorModel, IndexSource, Resource, Stage};

    fn cells(n: usize) -> Vec<Cell> {
        let stages = [
            Stage::Raygen,
            Stage::ClosestHit,
            Stage::AnyHit,
            Stage::Miss,
            Stage::Intersection,
            Stage::Callable,
            Stage::Compute,
        ];
        let out: Vec<Cell> = stages
            .iter()
            .map(|&s| {
                Cell::new(
                    s,
                    Resource::StorageBuffer,
                    IndexSource::Literal,
                    DescriptorModel::DescriptorIndexing,
                )
            })
            .take(n)
            .collect();
        assert_eq!(out.len(), n);
        out
    }

    #[test]
    fn cells_split_in_order_over_at_most_jobs_slots() {
        let c = cells(5);
        let s: Schedule<()> = Schedule::new(&c, 2, false);
        assert_eq!(s.slots.len(), 2);
        assert_eq!(s.job(0).cells, c[..3]);
        assert_eq!(s.job(1).cells, c[3..]);
        let one: Schedule<()> = Schedule::new(&c, 9, false);
        assert_eq!(one.slots.len(), 5);
        let none: Schedule<()> = Schedule::new(&[], 4, false);
        assert!(none.finished() && none.idle().is_empty());
    }

    #[test]
    fn isolated_cells_get_a_worker_each() {
        let c = cells(3);
        let mut s: Schedule<()> = Schedule::new(&c, 1, true);
        assert_eq!(s.job(0).cells, c[..1]);
        s.ran(0, &c[0]);
        assert_eq!(s.job(0).cells, c[1..2]);
    }

    #[test]
    fn an_attempt_takes_the_cell_off_the_queue_and_ends_a_fruitless_run() {
        let c = cells(3);
        let mut s: Schedule<()> = Schedule::new(&c, 1, false);
        assert!(s.fruitless(0, 3).is_empty());
        s.ran(0, &c[1]);
        assert_eq!(s.job(0).cells, [c[0], c[2]]);
        // The count started again: one more fruitless worker is a retry, not a give-up.
        assert!(s.fruitless(0, 2).is_empty());
        assert_eq!(s.job(0).cells.len(), 2);
    }

    #[test]
    fn a_failed_setup_is_retried_once_then_its_cells_are_given_up() {
        let c = cells(4);
        let mut s: Schedule<()> = Schedule::new(&c, 1, true);
        assert!(s.fruitless(0, 1).is_empty(), "the first failure is retried");
        assert_eq!(s.fruitless(0, 1), c[..1], "the second gives up on that worker's job only");
        assert_eq!(s.job(0).cells, c[1..2]);
        assert!(s.fruitless(0, 1).is_empty(), "the count starts again for the next job");
    }

    #[test]
    fn cells_that_broke_a_prebuild_build_at_their_turn() {
        let c = cells(3);
        let mut s: Schedule<()> = Schedule::new(&c, 1, false);
        assert!(s.job(0).serial.is_empty());
        s.serial(0, vec![c[0].id(), c[2].id(), "not-in-this-slot".into()]);
        assert_eq!(s.job(0).serial, [c[0].id(), c[2].id()]);
    }

    #[test]
    fn a_halt_drops_every_cell_left_and_starts_no_worker() {
        let c = cells(4);
        let mut s: Schedule<u8> = Schedule::new(&c, 2, false);
        s.slots[1].worker = Some(7);
        assert!(!s.halted());
        s.halt();
        assert!(s.halted());
        assert!(s.idle().is_empty(), "no worker starts again");
        assert!(s.job(0).cells.is_empty() && s.job(1).cells.is_empty());
        assert!(s.fruitless(1, 2).is_empty() && s.fruitless(1, 2).is_empty(), "nothing given up");
        assert!(!s.finished(), "a worker still runs: the supervisor stops it");
        s.slots[1].worker = None;
        assert!(s.finished());
    }

    #[test]
    fn a_slot_with_a_worker_is_not_idle_and_not_finished() {
        let c = cells(2);
        let mut s: Schedule<u8> = Schedule::new(&c, 2, false);
        assert_eq!(s.idle(), [0, 1]);
        s.slots[0].worker = Some(7);
        assert_eq!(s.idle(), [1]);
        assert_eq!(s.abandon(1), c[1..]);
        s.ran(0, &c[0]);
        assert!(!s.finished(), "its worker still runs");
        assert_eq!(s.workers().collect::<Vec<_>>(), [&7]);
        s.slots[0].worker = None;
        assert!(s.finished());
    }
}
