//! One cell's turn: built (or taken from the prebuild), its push constants, the records buffer
//! filled with the sentinel, the work recorded and submitted with a deadline, the records read
//! back and judged; the phases told to the caller, and every failure made the cell's result.
use super::built::{Bound, Seen};
use super::error::CellError;
use super::executor::{Executor, PhaseHook};
use super::record::{self, Work};
use crate::model::inject::{self, FaultKind};
use crate::model::{Canary, Cell, CellResult, InjectedFault, Phase, Timings};
use crate::probe::spec::ProbeSpec;
use crate::probe::{self, Record, RECORD_SIZE};
use crate::vk::submit::Waited;
use std::time::Instant;

/// An address no driver maps: the invalid-address canary reads there.
pub const CANARY_BAD_ADDRESS: u64 = 0xdead_0000_0000;

impl Executor {
    /// Run one cell. Never panics on driver misbehaviour; every failure is an outcome.
    pub fn run(&mut self, cell: &Cell, on_phase: PhaseHook) -> CellResult {
        let start = Instant::now();
        let validation_before = crate::vk::instance::validation_error_count();
        let mut timings = Timings::default();
        let injected = inject::roll(&self.opts.inject, cell, self.opts.inject_seed);
        let result = self
            .try_run(cell, injected.as_ref(), &mut timings, on_phase)
            .and_then(|done| on_phase(Phase::Check).map(|()| done).map_err(CellError::from));
        let mut out = match result {
            Ok((records, seen)) => {
                let mut expected = std::mem::take(&mut self.scratch.expected);
                let out = self.judge(cell, (&records, &mut expected), seen, &mut timings);
                (self.scratch.records, self.scratch.expected) = (records, expected);
                out
            }
            Err(e) => e.result(&self.gpu, self.opts.timeout, timings.clone()),
        };
        out.timings.total_ms = start.elapsed().as_secs_f64() * 1e3;
        out.validation_errors = crate::vk::instance::validation_error_count() - validation_before;
        out
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
