//! One cell's turn: built (or taken from the prebuild), its push constants, the records buffer
//! filled with the sentinel, the work recorded and submitted with a deadline, the records read
//! back and judged; the phases told to the caller, and every failure made the cell's result.
use super::built::{Bound, Seen};
use super::check::World;
use super::error::CellError;
use super::executor::{Executor, PhaseHook};
use super::record::{self, Work};
use crate::model::comparison::HeapDetail;
use crate::model::inject::{self, FaultKind};
use crate::model::{Canary, Cell, CellResult, InjectedFault, Phase, Timings};
use crate::probe::spec::ProbeSpec;
use crate::probe::{self, Record, RECORD_SIZE};
use crate::reference::ExpectedMemo;
use crate::vk::submit::Waited;
use std::time::Instant;

/// An address no driver maps: the invalid-address canary reads there.
pub const CANARY_BAD_ADDRESS: u64 = 0xdead_0000_0000;

/// A cell whose device work is over, its records read back: what judging it needs
/// ([`World::finish`]), on the cell thread or a checker's.
pub struct Traced {
    pub(super) cell: Cell,
    pub(super) records: Vec<Record>,
    pub(super) seen: Seen,
    /// A heap cell's descriptors, read from the executor's bindings before the hand-off.
    pub(super) heap: Option<HeapDetail>,
    pub(super) timings: Timings,
    /// Milliseconds from the cell's start to its readback's end.
    pub(super) device_part_ms: f64,
    pub(super) validation_errors: u64,
}

#[cfg(test)]
impl Traced {
    /// `cell` traced with no records, for tests of what carries traced cells.
    pub fn for_tests(cell: Cell) -> Traced {
        let seen = Seen { heap_capability: false, dropped: false, lanes: Default::default() };
        Traced {
            cell,
            records: vec![],
            seen,
            heap: None,
            timings: Timings::default(),
            device_part_ms: 0.0,
            validation_errors: 0,
        }
    }

    pub fn cell(&self) -> &Cell {
        &self.cell
    }
}

/// A cell's turn up to its check: its result already (a failure before the check), or its records
/// to judge.
// One per cell, moved once: boxing the large variant would buy nothing.
#[allow(clippy::large_enum_variant)]
pub enum Ran {
    Done(CellResult),
    Traced(Traced),
}

impl World<'_> {
    /// The traced cell's result: judged against the reference (`expected` kept from cell to
    /// cell), its total time its device part's and its check's. The records' vector comes back
    /// for reuse.
    pub(super) fn finish(
        &self,
        t: Traced,
        expected: &mut ExpectedMemo,
    ) -> (CellResult, Vec<Record>) {
        let Traced { cell, records, seen, heap, mut timings, device_part_ms, validation_errors } =
            t;
        let started = Instant::now();
        let mut out = self.judge(&cell, (&records, expected), (seen, heap), &mut timings);
        out.timings.total_ms = device_part_ms + started.elapsed().as_secs_f64() * 1e3;
        out.validation_errors = validation_errors;
        (out, records)
    }
}

impl Executor {
    /// Run one cell. Never panics on driver misbehaviour; every failure is an outcome.
    pub fn run(&mut self, cell: &Cell, on_phase: PhaseHook) -> CellResult {
        match self.run_traced(cell, on_phase) {
            Ran::Done(r) => r,
            Ran::Traced(t) => self.judge_traced(t),
        }
    }

    /// A traced cell's result, judged on this thread.
    pub fn judge_traced(&mut self, t: Traced) -> CellResult {
        let mut expected = std::mem::take(&mut self.scratch.expected);
        let (out, records) = self.world().finish(t, &mut expected);
        (self.scratch.records, self.scratch.expected) = (records, expected);
        out
    }

    /// Run one cell up to its check (phase `check` entered): its records to judge, or its result
    /// where it failed before. Never panics on driver misbehaviour.
    pub fn run_traced(&mut self, cell: &Cell, on_phase: PhaseHook) -> Ran {
        let start = Instant::now();
        let validation_before = crate::vk::instance::validation_error_count();
        let mut timings = Timings::default();
        let injected = inject::roll(&self.opts.inject, cell, self.opts.inject_seed);
        let result = self
            .try_run(cell, injected.as_ref(), &mut timings, on_phase)
            .and_then(|done| on_phase(Phase::Check).map(|()| done).map_err(CellError::from));
        let validation_errors = crate::vk::instance::validation_error_count() - validation_before;
        match result {
            Ok((records, seen)) => Ran::Traced(Traced {
                cell: *cell,
                records,
                seen,
                // (a canary's check never reads it)
                heap: cell.canary.is_none().then(|| self.heap_detail(cell)).flatten(),
                timings,
                device_part_ms: start.elapsed().as_secs_f64() * 1e3,
                validation_errors,
            }),
            Err(e) => {
                let mut out = e.result(&self.gpu, self.opts.timeout, timings.clone());
                out.timings.total_ms = start.elapsed().as_secs_f64() * 1e3;
                out.validation_errors = validation_errors;
                Ran::Done(out)
            }
        }
    }

    /// A records vector a checker is done with, kept for the next cell's readback.
    pub fn reuse_records(&mut self, records: Vec<Record>) {
        if self.scratch.records.capacity() < records.capacity() {
            self.scratch.records = records;
        }
    }

    /// The cell's push constants (layout: probe::PushConstants, then the patches' table address).
    fn push_constants(&self, cell: &Cell, injected: Option<&InjectedFault>, b: &Bound) -> Vec<u8> {
        let (w, h) = (self.scene.params.width, self.scene.params.height);
        let spec = ProbeSpec::of(cell);
        let fault = injected.map(|i| i.fault);
        let injected_bad =
            injected.is_some_and(|i| i.fault.reads_bad_address() && i.armed != Some(false));
        probe::PushConstants {
            loop_forever: u32::from(
                spec.canary == Some(Canary::InfiniteLoop) || fault == Some(FaultKind::Hang),
            ),
            as_table: b.addresses.as_table,
            base_address: b.addresses.base,
            scene_desc: b.addresses.scene_desc,
            bad_address: if spec.canary == Some(Canary::InvalidAddress) || injected_bad {
                CANARY_BAD_ADDRESS
            } else {
                0
            },
            inject_salt: fault.map(|f| inject::value_salt(f, &cell.id())).unwrap_or(0),
            ..probe::push_constants(w, h, self.scene.params.instances, spec.resource)
        }
        .to_bytes(b.addresses.patched_table)
    }

    /// The cell's records (in the scratch's vector, taken: [`Executor::run`] gives it back), and
    /// what the driver saw of the cell's shape.
    fn try_run(
        &mut self,
        cell: &Cell,
        injected: Option<&InjectedFault>,
        timings: &mut Timings,
        on_phase: PhaseHook,
    ) -> Result<(Vec<Record>, Seen), CellError> {
        let bound = self.build(cell, injected, timings, on_phase)?;
        on_phase(Phase::Record)?;
        let pc = self.push_constants(cell, injected, &bound);
        let gpu = &self.gpu;
        let work = Work {
            pipe: &self.pipelines[&bound.pkey],
            binding: &self.bindings[&bound.key],
            stages: bound.key.stages,
            pc: &pc,
            color: self.color.as_ref(),
            size: (self.scene.params.width, self.scene.params.height),
        };
        // Sentinel: a record no probe wrote reads as flags 0xffffffff. Written from the host
        // (the buffer is mapped): a vkCmdFillBuffer is an internal compute dispatch on some
        // drivers and must not disturb the state this cell binds.
        self.records.fill(0, self.scene.params.pixels() * RECORD_SIZE, 0xff);
        let mut entered_trace = Ok(());
        let waited = self.submitter.run(gpu, self.opts.timeout, |cmd| unsafe {
            work.record(gpu, cmd);
            record::to_host(gpu, cmd);
            // Recorded: what follows is the submission and the fence wait.
            entered_trace = on_phase(Phase::Trace);
        })?;
        entered_trace?;
        match waited {
            Waited::TimedOut => return Err(CellError::Timeout("the cell's submission")),
            Waited::Done(d) => timings.trace_ms = d.as_secs_f64() * 1e3,
        }
        on_phase(Phase::Readback)?;
        let t = Instant::now();
        let mut recs = std::mem::take(&mut self.scratch.records);
        let bytes = self.records.mapped(self.scene.params.pixels() * RECORD_SIZE);
        Record::decode_all(bytes, &mut recs);
        timings.readback_ms = t.elapsed().as_secs_f64() * 1e3;
        timings.check_ms = timings.readback_ms;
        Ok((recs, bound.seen))
    }
}
