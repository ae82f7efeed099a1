//! The supervisor: the only part that decides deadlines and kills. It starts workers (`rtprobe
//! __worker`, stdin null, stdout/stderr piped, each in its own process group, dying with the
//! supervisor: see [`super::groups`]), reads their messages and keeps each worker's state and last
//! [`Phase`]. Every state has a deadline: setup, a cell, the gap between two cells, teardown after
//! the last cell. Deadlines are checked before every wait, so a worker that keeps printing cannot
//! hold one off. Silence past a deadline is `timeout` (the process group is killed), a worker that
//! dies mid-cell is `crash` (with signal and stderr tail), both with the phase they happened in.
//! A failed setup (device, scene AS, resources) is its own record and is retried once in a fresh
//! worker; then the cells it would have run are recorded as not run, with the setup's outcome. A
//! setup that no worker can get past (the shader compiler cannot start) halts the run instead:
//! every worker is killed, nothing more starts, and the cells left stay without an attempt. A
//! fault between cells or in teardown is recorded for the worker, not blamed on a cell. Kills
//! are SIGTERM to the group, a grace period, SIGKILL, and a bounded wait: a process that will not
//! die (uninterruptible sleep in the driver) is reported and abandoned.
//!
//! Here is the loop and the I/O: job files, processes ([`super::process`]), the clock and the
//! deadlines. What a worker's lines mean is [`super::machine`] (a pure state machine whose effects
//! are carried out here), which worker runs which cells is [`super::schedule`], and the faults
//! injected into each attempt are [`super::injection`].
use super::event::Event;
use super::injection::Injections;
use super::machine::{self, Effect, Input, Limits};
use super::process::{Line, Proc};
use super::protocol::WorkerJob;
use super::schedule::{Job, Schedule};
use crate::model::Cell;
use crate::model::Outcome;
use crate::model::Phase;
use crate::model::SceneParams;
use crate::model::{Attempt, Isolation};
use std::path::PathBuf;
use std::sync::mpsc::{channel, Receiver, RecvTimeoutError, Sender};
use std::time::{Duration, Instant};

#[derive(Clone, Debug)]
pub struct SupervisorOptions {
    pub device_index: usize,
    pub scene: SceneParams,
    pub jobs: usize,
    /// Fresh workers at once when cells are re-run alone (each still alone in its process):
    /// the cores on CPU devices, whose JIT is single-threaded; 1 on GPUs, where a device loss
    /// in one process can take the other processes' contexts with it (`cli::shared::rerun_jobs`).
    pub rerun_jobs: usize,
    pub isolation: Isolation,
    /// Hard deadline for one cell; also for the gap between two cells and for teardown.
    pub timeout: Duration,
    /// Hard deadline for a worker's setup (device, scene AS, resources, reference).
    pub setup_timeout: Duration,
    /// Between SIGTERM and SIGKILL.
    pub grace: Duration,
    /// How long to wait for a SIGKILLed worker to be reaped before abandoning it.
    pub kill_wait: Duration,
    pub validate: bool,
    /// Workers turn GPU-Assisted Validation on (`report::gpu_av`).
    pub gpu_av: bool,
    /// `--inject-fault`, passed to every worker.
    pub inject: Vec<crate::model::Injection>,
    pub dump: Option<PathBuf>,
    /// A repro bundle's `shaders/` (`run --cell-spec`): workers run its SPIR-V.
    pub spirv_dir: Option<PathBuf>,
    /// Threads a worker creates pipelines on, ahead of the cells' turns (1: no prebuild).
    pub threads: usize,
    /// Folder of the persisted pipeline caches (`None`: off). Used only by workers of a
    /// non-isolated [`Supervisor::run`] (the matrix, and the first run of workaround and pattern
    /// cells): re-runs alone (`--confirm`, `--repeat`, the repeats that verify a workaround) start
    /// cold, so that a cached binary cannot stand in for the cell's own compile.
    pub pipeline_cache: Option<PathBuf>,
    /// `RTPROBE_BINDING_STAGES` of the run, written into each worker's job file.
    pub binding_stages: Option<String>,
    /// `--lane-evidence` of the run, written into each worker's job file.
    pub lane_evidence: crate::model::LaneMode,
    /// Every worker compiles afresh (`bisect`, `run --cell-spec`, the GPU-AV re-runs), as
    /// re-runs alone always do: no pipeline cache, the driver's own cache bypassed.
    pub fresh: bool,
    /// The device offers `pipelineBinaryInternalCacheControl` (fresh workers turn the driver's
    /// cache off with it rather than with the environment switches).
    pub internal_cache_control: bool,
    /// Ray tracing pipelines are linked from group libraries (`--pipelines`).
    pub linked: bool,
}

/// A worker's own fence deadline for `deadline` of the supervisor's: shorter, so that the worker
/// reports a hung submission before the supervisor kills it (at least 100 ms).
fn fence_ms(deadline: Duration) -> u64 {
    (deadline.as_millis() as u64 * 8 / 10).max(100)
}

/// A worker the supervisor runs: its process, and its state as [`machine`] keeps it.
struct Running {
    process: Proc,
    worker: machine::Worker,
}

pub struct Supervisor {
    opts: SupervisorOptions,
    injections: Injections,
    tx: Sender<Line>,
    rx: Receiver<Line>,
    generation: u64,
    /// The current `run` re-runs cells alone: its workers load no persisted pipeline cache.
    rerun: bool,
    /// This supervisor's job files' folder (`rtprobe-jobs-<pid>-…`, made afresh at the first
    /// worker's start, removed with the supervisor or by the interrupt handler).
    jobs: Option<super::groups::JobFolder>,
}

impl Supervisor {
    pub fn new(opts: SupervisorOptions) -> Self {
        super::groups::install_handlers();
        let (tx, rx) = channel();
        let injections = Injections::new(opts.inject.clone());
        Supervisor { opts, injections, tx, rx, generation: 0, rerun: false, jobs: None }
    }

    fn limits(&self) -> Limits {
        Limits { timeout: self.opts.timeout, setup_timeout: self.opts.setup_timeout }
    }

    /// Run `cells`, calling `on` for each attempt as it finishes. `isolated` forces one fresh
    /// worker per cell, without the persisted pipeline cache (a re-run), `rerun_jobs` of them at
    /// once.
    pub fn run(&mut self, cells: &[Cell], isolated: bool, on: &mut dyn FnMut(Event)) {
        self.rerun = isolated;
        let per_cell = isolated || self.opts.isolation == Isolation::ProcessPerCell;
        let jobs = if isolated { self.opts.rerun_jobs } else { self.opts.jobs };
        let mut schedule: Schedule<Running> = Schedule::new(cells, jobs, per_cell);
        loop {
            if schedule.halted() {
                self.stop(&mut schedule);
                break;
            }
            self.start_workers(&mut schedule, on);
            if schedule.finished() {
                break;
            }
            // Deadlines first, before every wait: a worker that keeps printing cannot hold one off.
            if self.expire(&mut schedule, on) {
                continue;
            }
            let now = Instant::now();
            let limits = self.limits();
            let deadline = schedule
                .workers()
                .filter_map(|r| r.worker.deadline(&limits))
                .min()
                .unwrap_or(now + Duration::from_millis(50));
            match self.rx.recv_timeout(deadline.saturating_duration_since(now)) {
                Ok((i, id, input)) => {
                    // Worker ids are unique per supervisor; a late line from a worker of an
                    // earlier `run` (more slots, or a slot since reused) matches no worker here.
                    if schedule
                        .slots
                        .get(i)
                        .and_then(|s| s.worker.as_ref())
                        .is_some_and(|r| r.worker.id == id)
                    {
                        self.feed(&mut schedule, i, input, on);
                    }
                }
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => break,
            }
        }
    }

    /// A worker for every slot with cells left and none running; a slot whose worker cannot
    /// start records its cells as not run.
    fn start_workers(&mut self, schedule: &mut Schedule<Running>, on: &mut dyn FnMut(Event)) {
        for i in schedule.idle() {
            match self.spawn(i, schedule.job(i), schedule.per_cell()) {
                Ok(r) => schedule.slots[i].worker = Some(r),
                Err(e) => {
                    let msg = format!("cannot start a worker: {e}");
                    for c in schedule.abandon(i) {
                        let attempt = Attempt::new(Outcome::Error, schedule.per_cell())
                            .with_worker(0, Phase::Setup, vec![])
                            .with_detail(msg.clone());
                        self.record(c, attempt, on);
                    }
                }
            }
        }
    }

    /// Whether workers started now compile afresh: re-runs alone, and every worker of a fresh
    /// supervisor.
    fn fresh(&self) -> bool {
        self.rerun || self.opts.fresh
    }

    /// The folder of this supervisor's job files, made at the first call.
    fn job_folder(&mut self) -> std::io::Result<&std::path::Path> {
        if self.jobs.is_none() {
            // (its error names the temporary folder and says to set TMPDIR)
            self.jobs = Some(super::groups::JobFolder::new()?);
        }
        Ok(self.jobs.as_ref().expect("made above").path())
    }

    /// Writes worker `id`'s job file and starts it.
    fn spawn(&mut self, slot: usize, job: Job, per_cell: bool) -> std::io::Result<Running> {
        self.generation += 1;
        let id = self.generation;
        let seed = self.injections.deal(id, &job.cells);
        let job = WorkerJob {
            device_index: self.opts.device_index,
            scene: self.opts.scene.clone(),
            fence_timeout_ms: fence_ms(self.opts.timeout),
            setup_fence_timeout_ms: fence_ms(self.opts.setup_timeout),
            validate: self.opts.validate,
            gpu_av: self.opts.gpu_av,
            inject: self.injections.list().to_vec(),
            inject_seed: seed,
            dump: self.opts.dump.clone(),
            spirv_dir: self.opts.spirv_dir.clone(),
            serial: job.serial,
            cells: job.cells,
            threads: self.opts.threads.max(1),
            pipeline_cache: self.opts.pipeline_cache.clone().filter(|_| !self.fresh()),
            // rtprobe's own GLSL cache, for re-runs alone too; a fresh supervisor (bisect, repro,
            // GPU-AV) compiles its GLSL as well.
            glsl_cache: self.opts.pipeline_cache.clone().filter(|_| !self.opts.fresh),
            binding_stages: self.opts.binding_stages.clone(),
            lane_evidence: self.opts.lane_evidence,
            fresh: self.fresh(),
            internal_cache_control: self.opts.internal_cache_control,
            linked: self.opts.linked,
        };
        let path = self.job_folder()?.join(format!("job-{id}.json"));
        std::fs::write(&path, serde_json::to_vec(&job).map_err(std::io::Error::other)?)?;
        let process = Proc::start(&path, slot, id, self.tx.clone())?;
        Ok(Running {
            process,
            worker: machine::Worker::new(id, job.cells, per_cell, Instant::now()),
        })
    }

    /// Kill every worker past its deadline; true when one was.
    fn expire(&mut self, schedule: &mut Schedule<Running>, on: &mut dyn FnMut(Event)) -> bool {
        let now = Instant::now();
        let limits = self.limits();
        let due: Vec<usize> = (0..schedule.slots.len())
            .filter(|&i| {
                schedule.slots[i]
                    .worker
                    .as_ref()
                    .and_then(|r| r.worker.deadline(&limits))
                    .is_some_and(|d| now >= d)
            })
            .collect();
        for &i in &due {
            self.feed(schedule, i, Input::Deadline, on);
        }
        !due.is_empty()
    }

    /// The run halted: every worker still running is killed; what it was doing is not recorded
    /// (the run stops, its cells left without an attempt).
    fn stop(&self, schedule: &mut Schedule<Running>) {
        for slot in &mut schedule.slots {
            if let Some(mut r) = slot.worker.take() {
                tracing::debug!("worker {} stopped: the run halted", r.worker.id);
                r.process.kill(self.opts.grace, self.opts.kill_wait);
            }
        }
    }

    /// Steps slot `i`'s worker with `input` and carries out the effects; a kill or reap feeds how
    /// the process ended back in. An ended worker leaves its slot.
    fn feed(
        &mut self,
        schedule: &mut Schedule<Running>,
        i: usize,
        input: Input,
        on: &mut dyn FnMut(Event),
    ) {
        let Some(mut r) = schedule.slots[i].worker.take() else {
            return;
        };
        let limits = self.limits();
        let mut next = Some(input);
        while let Some(input) = next.take() {
            // The worker's timeline (RUST_LOG=rtprobe::runner::supervisor=trace): each line as
            // it arrives, cut short.
            if tracing::enabled!(tracing::Level::TRACE) {
                let line: String = format!("{input:?}").chars().take(120).collect();
                tracing::trace!("worker {}: {line}", r.worker.id);
            }
            let (worker, effects) = machine::step(r.worker, input, Instant::now(), &limits);
            r.worker = worker;
            for effect in effects {
                if let Some(exited) = self.apply(schedule, i, &mut r.process, effect, on) {
                    next = Some(exited);
                }
            }
        }
        if !r.worker.ended() {
            schedule.slots[i].worker = Some(r);
        }
    }

    /// Carries out one effect of slot `i`'s worker; a kill or a reap returns how it ended.
    fn apply(
        &self,
        schedule: &mut Schedule<Running>,
        i: usize,
        process: &mut Proc,
        effect: Effect,
        on: &mut dyn FnMut(Event),
    ) -> Option<Input> {
        match effect {
            Effect::Log(line) => tracing::debug!("{line}"),
            Effect::Kill => {
                return Some(Input::Exited(process.kill(self.opts.grace, self.opts.kill_wait)))
            }
            Effect::Reap => {
                return Some(Input::Exited(process.reap(self.opts.grace, self.opts.kill_wait)))
            }
            Effect::Release => process.release(self.opts.timeout, self.opts.kill_wait),
            Effect::Report(Event::Attempt { cell, attempt }) => {
                schedule.ran(i, &cell);
                self.record(cell, attempt, on);
            }
            Effect::Report(Event::Halt(halt)) => {
                schedule.halt();
                on(Event::Halt(halt))
            }
            Effect::Report(event) => on(event),
            Effect::Serial(cells) => schedule.serial(i, cells),
            Effect::Fruitless { batch, not_run } => {
                for c in schedule.fruitless(i, batch) {
                    self.record(c, not_run.clone(), on);
                }
            }
        }
        None
    }

    /// Every attempt records what was injected into it, worked out as the worker did.
    fn record(&self, cell: Cell, mut attempt: Attempt, on: &mut dyn FnMut(Event)) {
        self.injections.tag(&cell, &mut attempt);
        on(Event::Attempt { cell, attempt });
    }
}

#[cfg(test)]
mod tests {
    use super::fence_ms;
    use std::time::Duration;

    #[test]
    fn the_setup_waits_on_the_setup_deadline_not_a_cells() {
        // Before, the worker's setup (the scene's AS build) waited at most the cell's fence
        // deadline (16 s of --timeout 20) though the supervisor allowed it 120 s.
        assert_eq!(fence_ms(Duration::from_secs(20)), 16_000);
        assert_eq!(fence_ms(Duration::from_secs(120)), 96_000);
        assert_eq!(fence_ms(Duration::from_millis(50)), 100);
    }
}
