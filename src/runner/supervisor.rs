//! The supervisor: the only part that decides deadlines and kills. It starts workers (`rtprobe
//! __worker`, stdin null, stdout/stderr piped, each in its own process group, dying with the
//! supervisor: see [`super::groups`]), reads their messages and keeps each worker's state and last
//! [`Phase`]. Every state has a deadline: setup, a cell, the gap between two cells, teardown after
//! the last cell. Deadlines are checked before every wait, so a worker that keeps printing cannot
//! hold one off. Silence past a deadline is `timeout` (the process group is killed), a worker that
//! dies mid-cell is `crash` (with signal and stderr tail), both with the phase they happened in.
//! A failed setup (device, scene AS, resources) is its own record and is retried once in a fresh
//! worker; then the cells it would have run are recorded as not run, with the setup's outcome. A
//! fault between cells or in teardown is recorded for the worker, not blamed on a cell. Kills
//! are SIGTERM to the group, a grace period, SIGKILL, and a bounded wait: a process that will not
//! die (uninterruptible sleep in the driver) is reported and abandoned.
use super::groups;
use super::process::{died, exit_of, kill_group, poll_exit};
use crate::model::Phase;
use super::protocol::{WorkerJob, WorkerMsg};
use crate::model::Cell;
use crate::model::Outcome;
use crate::model::SceneParams;
use std::collections::VecDeque;
use std::io::{BufRead, BufReader, Read};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc::{channel, Receiver, RecvTimeoutError, Sender};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use crate::model::{Attempt, Isolation, WorkerEvent, WorkerExit};

#[derive(Clone, Debug)]
pub struct SupervisorOptions {
    pub device_index: usize,
    pub scene: SceneParams,
    pub jobs: usize,
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
    pub job_dir: PathBuf,
    /// Threads a worker creates pipelines on, ahead of the cells' turns (1: no prebuild).
    pub threads: usize,
    /// Folder of the persisted pipeline caches (`None`: off). Used only by workers of a
    /// non-isolated [`Supervisor::run`] (the matrix, and the first run of workaround and pattern
    /// cells): re-runs alone (`--confirm`, `--repeat`, the repeats that verify a workaround) start
    /// cold, so that a cached binary cannot stand in for the cell's own compile.
    pub pipeline_cache: Option<PathBuf>,
    /// `RTPROBE_BINDING_STAGES` of the run, written into each worker's job file.
    pub binding_stages: Option<String>,
}

/// Events for the report writer and progress display.
pub enum Event<'a> {
    WorkerReady { device_ms: f64, reference_ms: f64, pipeline_cache: Option<crate::exec::pipeline_cache::Loaded> },
    /// A worker built a batch of cells ahead of their turns.
    Prebuilt { wall_ms: f64, pipelines: usize, threads: usize },
    /// A worker wrote the pipeline cache back (`Err`: why not).
    CacheSaved(Result<u64, String>),
    /// A worker's setup finished or failed, or it faulted outside a cell.
    Worker(WorkerEvent),
    Attempt { cell: &'a Cell, attempt: Attempt },
}

enum Line {
    Msg(WorkerMsg),
    Garbage(String),
    Eof,
}

enum State {
    Setup,
    Cell { cell: Cell, since: Instant },
    /// After `ready` or a result, before the next `start`.
    Between { since: Instant },
    /// Building `cells` ahead of their turns; `since` restarts at each step of progress.
    Prebuild { cells: Vec<String>, since: Instant },
    /// After its last result: it must exit.
    Teardown { since: Instant },
}

struct Worker {
    child: Child,
    pid: i32,
    id: u64,
    stderr: Arc<Mutex<String>>,
    spawned: Instant,
    state: State,
    phase: Phase,
    step: Option<String>,
    device_features: Vec<String>,
    /// Cells of its job without a result yet.
    batch_left: usize,
    /// Cells it was given.
    batch: usize,
    /// It produced at least one attempt.
    progressed: bool,
    /// Lines that were not protocol messages (logged up to a limit: a worker can flood them).
    garbage: u64,
}

impl Worker {
    fn deadline(&self, o: &SupervisorOptions) -> Instant {
        match self.state {
            State::Setup => self.spawned + o.setup_timeout,
            State::Cell { since, .. } | State::Between { since } | State::Prebuild { since, .. } | State::Teardown { since } => since + o.timeout,
        }
    }

    fn where_(&self) -> String {
        match &self.step {
            Some(s) => format!("{} ({s})", self.phase),
            None => self.phase.to_string(),
        }
    }
}

struct Slot {
    queue: VecDeque<Cell>,
    worker: Option<Worker>,
    /// Workers in a row that ended without producing an attempt (failed setups, deaths before
    /// the first cell): two of them give up on the slot's cells.
    fruitless: u32,
    /// Cells a worker died or hung prebuilding: later workers build them at their turn only.
    serial: std::collections::HashSet<String>,
}

const STDERR_TAIL: usize = 4000;
const GARBAGE_LOGGED: u64 = 20;

pub struct Supervisor {
    opts: SupervisorOptions,
    /// The dice seed of the worker each cell was last sent to (`--inject-fault flaky`).
    seeds: std::rc::Rc<std::cell::RefCell<std::collections::HashMap<String, u64>>>,
    tx: Sender<(usize, u64, Line)>,
    rx: Receiver<(usize, u64, Line)>,
    generation: u64,
    /// The current `run` re-runs cells alone: its workers load no persisted pipeline cache.
    rerun: bool,
}

impl Supervisor {
    pub fn new(opts: SupervisorOptions) -> Self {
        groups::install_handlers();
        let (tx, rx) = channel();
        Supervisor { opts, tx, rx, generation: 0, seeds: Default::default(), rerun: false }
    }

    fn spawn(&mut self, slot: usize, cells: Vec<Cell>, serial: &std::collections::HashSet<String>) -> std::io::Result<Worker> {
        self.generation += 1;
        let id = self.generation;
        let batch = cells.len();
        let seed = inject_seed(id);
        for c in &cells {
            self.seeds.borrow_mut().insert(c.id(), seed);
        }
        let job = WorkerJob {
            device_index: self.opts.device_index,
            scene: self.opts.scene,
            fence_timeout_ms: (self.opts.timeout.as_millis() as u64 * 8 / 10).max(100),
            validate: self.opts.validate,
            gpu_av: self.opts.gpu_av,
            inject: self.opts.inject.clone(),
            inject_seed: seed,
            dump: self.opts.dump.clone(),
            spirv_dir: self.opts.spirv_dir.clone(),
            serial: cells.iter().map(Cell::id).filter(|id| serial.contains(id)).collect(),
            cells,
            threads: self.opts.threads.max(1),
            pipeline_cache: self.opts.pipeline_cache.clone().filter(|_| !self.rerun),
            binding_stages: self.opts.binding_stages.clone(),
        };
        std::fs::create_dir_all(&self.opts.job_dir)?;
        let path = self.opts.job_dir.join(format!("job-{}-{id}.json", std::process::id()));
        std::fs::write(&path, serde_json::to_vec(&job).map_err(std::io::Error::other)?)?;
        let exe = std::env::current_exe()?;
        let mut cmd = Command::new(exe);
        cmd.arg("__worker").arg(&path).stdin(Stdio::null()).stdout(Stdio::piped()).stderr(Stdio::piped());
        groups::harden(&mut cmd);
        let mut child = cmd.spawn()?;
        let pid = child.id() as i32;
        groups::register(pid);
        let stdout = child.stdout.take().expect("piped stdout");
        let tx = self.tx.clone();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines() {
                let Ok(line) = line else { break };
                let msg = match serde_json::from_str::<WorkerMsg>(&line) {
                    Ok(m) => Line::Msg(m),
                    Err(_) => Line::Garbage(line),
                };
                if tx.send((slot, id, msg)).is_err() {
                    return;
                }
            }
            let _ = tx.send((slot, id, Line::Eof));
        });
        let stderr = Arc::new(Mutex::new(String::new()));
        let mut err_pipe = child.stderr.take().expect("piped stderr");
        let sink = stderr.clone();
        std::thread::spawn(move || {
            let mut buf = [0u8; 4096];
            while let Ok(n) = err_pipe.read(&mut buf) {
                if n == 0 {
                    break;
                }
                if let Ok(mut s) = sink.lock() {
                    s.push_str(&String::from_utf8_lossy(&buf[..n]));
                    if s.len() > 2 * STDERR_TAIL {
                        let cut = s.len() - STDERR_TAIL;
                        let cut = (cut..s.len()).find(|i| s.is_char_boundary(*i)).unwrap_or(cut);
                        s.drain(..cut);
                    }
                }
            }
        });
        Ok(Worker {
            child,
            pid,
            id,
            stderr,
            spawned: Instant::now(),
            state: State::Setup,
            phase: Phase::Setup,
            step: None,
            device_features: vec![],
            batch_left: batch,
            batch,
            progressed: false,
            garbage: 0,
        })
    }

    /// Run `cells`, calling `on` for each attempt as it finishes. `isolated` forces one fresh
    /// worker per cell, without the persisted pipeline cache (a re-run).
    pub fn run(&mut self, cells: &[Cell], isolated: bool, on: &mut dyn FnMut(Event)) {
        self.rerun = isolated;
        // Every attempt records what was injected into it, worked out as the worker did.
        let inject = self.opts.inject.clone();
        let seeds = self.seeds.clone();
        let mut tagged = |ev: Event| match ev {
            Event::Attempt { cell, mut attempt } => {
                if let Some(seed) = seeds.borrow().get(&cell.id()).copied() {
                    attempt.injected = crate::model::inject::roll(&inject, cell, seed);
                }
                on(Event::Attempt { cell, attempt })
            }
            other => on(other),
        };
        let on: &mut dyn FnMut(Event) = &mut tagged;
        let per_cell = isolated || self.opts.isolation == Isolation::ProcessPerCell;
        let jobs = self.opts.jobs.max(1).min(cells.len().max(1));
        let chunk = cells.len().div_ceil(jobs).max(1);
        let mut slots: Vec<Slot> = cells.chunks(chunk).map(|c| Slot { queue: c.iter().copied().collect(), worker: None, fruitless: 0, serial: Default::default() }).collect();
        loop {
            self.start_workers(&mut slots, per_cell, on);
            if slots.iter().all(|s| s.worker.is_none() && s.queue.is_empty()) {
                break;
            }
            // Deadlines first, before every wait: a worker that keeps printing cannot hold one off.
            if self.expire(&mut slots, per_cell, on) {
                continue;
            }
            let now = Instant::now();
            let deadline = slots.iter().filter_map(|s| s.worker.as_ref()).map(|w| w.deadline(&self.opts)).min().unwrap_or(now + Duration::from_millis(50));
            match self.rx.recv_timeout(deadline.saturating_duration_since(now)) {
                Ok((i, id, line)) => {
                    // Worker ids are unique per supervisor; a late line from a worker of an
                    // earlier `run` (more slots, or a slot since reused) matches no worker here.
                    if let Some(slot) = slots.get_mut(i).filter(|s| s.worker.as_ref().is_some_and(|w| w.id == id)) {
                        self.handle(slot, line, per_cell, on);
                    }
                }
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => break,
            }
        }
    }

    fn start_workers(&mut self, slots: &mut [Slot], per_cell: bool, on: &mut dyn FnMut(Event)) {
        for i in 0..slots.len() {
            if slots[i].worker.is_some() || slots[i].queue.is_empty() {
                continue;
            }
            let batch: Vec<Cell> = if per_cell { vec![slots[i].queue[0]] } else { slots[i].queue.iter().copied().collect() };
            match self.spawn(i, batch, &slots[i].serial) {
                Ok(w) => slots[i].worker = Some(w),
                Err(e) => {
                    let msg = format!("cannot start a worker: {e}");
                    for c in slots[i].queue.drain(..) {
                        let attempt = Attempt { outcome: Outcome::Error, isolated: per_cell, detail: Some(msg.clone()), result: None, worker_exit: None, injected: None, wall_ms: 0.0, phase: Some(Phase::Setup), worker: 0, device_features: vec![] };
                        on(Event::Attempt { cell: &c, attempt });
                    }
                }
            }
        }
    }

    fn handle(&mut self, slot: &mut Slot, line: Line, per_cell: bool, on: &mut dyn FnMut(Event)) {
        let w = slot.worker.as_mut().expect("checked by caller");
        match line {
            Line::Msg(WorkerMsg::Ready { .. }) if !matches!(w.state, State::Setup) => {
                // Only once, at the end of setup: it must not restart any clock.
                tracing::debug!("worker {} sent ready again; ignored", w.id);
            }
            Line::Msg(WorkerMsg::Ready { device_ms, reference_ms, device_features, pipeline_cache }) => {
                w.state = State::Between { since: Instant::now() };
                w.phase = Phase::BetweenCells;
                w.step = None;
                w.device_features = device_features;
                on(Event::WorkerReady { device_ms, reference_ms, pipeline_cache });
                on(Event::Worker(WorkerEvent {
                    worker: w.id,
                    phase: Phase::Setup,
                    outcome: Outcome::Pass,
                    detail: None,
                    cells: w.batch,
                    wall_ms: ms(w.spawned),
                    device_features: w.device_features.clone(),
                    worker_exit: None,
                }));
            }
            Line::Msg(WorkerMsg::Phase { phase, step }) => {
                // Prebuild progress (GLSL, a cell compiled and bound, a pipeline) restarts its clock.
                if let (Phase::Prebuild, State::Prebuild { since, .. }) = (phase, &mut w.state) {
                    *since = Instant::now();
                }
                w.phase = phase;
                w.step = step;
            }
            Line::Msg(WorkerMsg::Prebuild { cells, threads }) => {
                if matches!(w.state, State::Between { .. }) {
                    tracing::debug!("worker {} prebuilds {} cells on {threads} threads", w.id, cells.len());
                    w.state = State::Prebuild { cells, since: Instant::now() };
                    w.phase = Phase::Prebuild;
                    w.step = None;
                } else {
                    tracing::debug!("worker {} sent prebuild while not between cells; ignored", w.id);
                }
            }
            Line::Msg(WorkerMsg::Prebuilt { wall_ms, pipelines, threads }) => {
                if matches!(w.state, State::Prebuild { .. }) {
                    w.state = State::Between { since: Instant::now() };
                    w.phase = Phase::BetweenCells;
                    w.step = None;
                    on(Event::Prebuilt { wall_ms, pipelines, threads });
                }
            }
            Line::Msg(WorkerMsg::CacheSaved { bytes, error }) => {
                on(Event::CacheSaved(bytes.ok_or_else(|| error.unwrap_or_else(|| "not saved".into()))));
            }
            Line::Msg(WorkerMsg::Start { cell }) => {
                // Only between cells: a repeated `start` must not restart the running cell's clock.
                if !matches!(w.state, State::Between { .. }) {
                    tracing::debug!("worker {} sent start {cell} while not between cells; ignored", w.id);
                } else if let Some(c) = slot.queue.iter().find(|c| c.id() == cell) {
                    w.state = State::Cell { cell: *c, since: Instant::now() };
                    w.phase = Phase::Compile;
                    w.step = None;
                }
            }
            Line::Msg(WorkerMsg::Result { cell, result }) => {
                let since = match w.state {
                    State::Cell { since, .. } => since,
                    _ => Instant::now(),
                };
                let Some(pos) = slot.queue.iter().position(|c| c.id() == cell) else { return };
                let c = slot.queue.remove(pos).expect("position is valid");
                let ends = result.outcome.ends_worker();
                let attempt = Attempt {
                    outcome: result.outcome,
                    isolated: per_cell,
                    detail: result.detail.clone(),
                    result: Some(result),
                    worker_exit: None, injected: None,
                    wall_ms: ms(since),
                    phase: Some(w.phase),
                    worker: w.id,
                    device_features: w.device_features.clone(),
                };
                w.batch_left = w.batch_left.saturating_sub(1);
                w.progressed = true;
                slot.fruitless = 0;
                let now = Instant::now();
                // After a fault the worker exits by itself; after its last cell it tears down.
                if ends || w.batch_left == 0 {
                    w.state = State::Teardown { since: now };
                    w.phase = Phase::Teardown;
                } else {
                    w.state = State::Between { since: now };
                    w.phase = Phase::BetweenCells;
                }
                w.step = None;
                on(Event::Attempt { cell: &c, attempt });
            }
            Line::Msg(WorkerMsg::Fatal { message, outcome }) => {
                let mut w = slot.worker.take().expect("present");
                let exit = kill_group(&mut w.child, w.pid, w.id, &w.stderr, self.opts.grace, self.opts.kill_wait);
                if matches!(w.state, State::Prebuild { .. }) {
                    let detail = format!("worker failed in {}: {message}", w.where_());
                    self.prebuild_failed(slot, &w, outcome, detail, exit, on);
                } else {
                    let detail = format!("worker setup failed in {}: {message}", w.where_());
                    self.worker_failed(slot, &w, outcome, detail, exit, per_cell, on);
                }
            }
            Line::Garbage(text) => {
                w.garbage += 1;
                if w.garbage <= GARBAGE_LOGGED {
                    tracing::debug!("worker {} said: {text}", w.id);
                } else if w.garbage == GARBAGE_LOGGED + 1 {
                    tracing::debug!("worker {} keeps printing; further lines not logged", w.id);
                }
            }
            Line::Eof => {
                let mut w = slot.worker.take().expect("present");
                let exit = match poll_exit(&mut w.child, self.opts.grace) {
                    Some(status) => {
                        groups::unregister(w.pid);
                        exit_of(Some(status), &w.stderr)
                    }
                    // Closed its output but does not exit: treat as hung.
                    None => kill_group(&mut w.child, w.pid, w.id, &w.stderr, Duration::ZERO, self.opts.kill_wait),
                };
                let (outcome, what) = died(&exit);
                match w.state {
                    State::Cell { cell, since } => {
                        if let Some(pos) = slot.queue.iter().position(|c| *c == cell) {
                            slot.queue.remove(pos);
                        }
                        let detail = format!("{what} mid-cell, in {}", w.where_());
                        self.cell_ended(slot, &w, &cell, outcome, detail, exit, since, per_cell, on);
                    }
                    State::Teardown { .. } if exit.code == Some(0) => {} // exited cleanly
                    State::Prebuild { .. } => {
                        let detail = format!("{what} in {}", w.where_());
                        self.prebuild_failed(slot, &w, outcome, detail, exit, on);
                    }
                    State::Setup | State::Between { .. } | State::Teardown { .. } => {
                        let detail = format!("{what} in {}", w.where_());
                        self.worker_failed(slot, &w, outcome, detail, exit, per_cell, on);
                    }
                }
            }
        }
    }

    /// Kill every worker past its deadline; true when one was.
    fn expire(&mut self, slots: &mut [Slot], per_cell: bool, on: &mut dyn FnMut(Event)) -> bool {
        let now = Instant::now();
        let mut any = false;
        for slot in slots.iter_mut() {
            if !slot.worker.as_ref().is_some_and(|w| now >= w.deadline(&self.opts)) {
                continue;
            }
            any = true;
            let mut w = slot.worker.take().expect("present");
            let exit = kill_group(&mut w.child, w.pid, w.id, &w.stderr, self.opts.grace, self.opts.kill_wait);
            match w.state {
                State::Cell { cell, since } => {
                    if let Some(pos) = slot.queue.iter().position(|c| *c == cell) {
                        slot.queue.remove(pos);
                    }
                    let detail = format!("no result within {:?}, in {}; worker process group killed", self.opts.timeout, w.where_());
                    self.cell_ended(slot, &w, &cell, Outcome::Timeout, detail, exit, since, per_cell, on);
                }
                State::Setup => {
                    let detail = format!("worker setup took longer than {:?}, in {}; killed", self.opts.setup_timeout, w.where_());
                    self.worker_failed(slot, &w, Outcome::Timeout, detail, exit, per_cell, on);
                }
                State::Prebuild { .. } => {
                    let detail = format!("no progress within {:?}, in {}; worker process group killed", self.opts.timeout, w.where_());
                    self.prebuild_failed(slot, &w, Outcome::Timeout, detail, exit, on);
                }
                State::Between { .. } => {
                    let detail = format!("no next cell within {:?} after the last result; killed", self.opts.timeout);
                    self.worker_failed(slot, &w, Outcome::Timeout, detail, exit, per_cell, on);
                }
                State::Teardown { .. } => {
                    let detail = format!("did not exit within {:?} after its last cell, in {}; killed", self.opts.timeout, w.where_());
                    self.worker_failed(slot, &w, Outcome::Timeout, detail, exit, per_cell, on);
                }
            }
        }
        any
    }

    #[allow(clippy::too_many_arguments)]
    fn cell_ended(&self, slot: &mut Slot, w: &Worker, cell: &Cell, outcome: Outcome, detail: String, exit: WorkerExit, since: Instant, per_cell: bool, on: &mut dyn FnMut(Event)) {
        slot.fruitless = 0;
        let attempt = Attempt {
            outcome,
            isolated: per_cell,
            detail: Some(detail),
            result: None,
            worker_exit: Some(exit), injected: None,
            wall_ms: ms(since),
            phase: Some(w.phase),
            worker: w.id,
            device_features: w.device_features.clone(),
        };
        on(Event::Attempt { cell, attempt });
    }

    /// A worker died, hung or lost its device while prebuilding: no one cell can be blamed, so it
    /// is the worker's record (phase `prebuild`), and the batch's cells go back to the sequential
    /// path: later workers build each at its turn, where a fault is exactly one cell's verdict.
    fn prebuild_failed(&self, slot: &mut Slot, w: &Worker, outcome: Outcome, detail: String, exit: WorkerExit, on: &mut dyn FnMut(Event)) {
        if let State::Prebuild { cells, .. } = &w.state {
            slot.serial.extend(cells.iter().cloned());
        }
        on(Event::Worker(WorkerEvent {
            worker: w.id,
            phase: Phase::Prebuild,
            outcome,
            detail: Some(format!("{detail}; its batch runs again, each cell building at its turn")),
            cells: w.batch,
            wall_ms: ms(w.spawned),
            device_features: w.device_features.clone(),
            worker_exit: Some(exit),
        }));
    }

    /// A worker failed outside any cell: in setup, between cells or in teardown. Recorded as its
    /// own event; when two workers in a row fail without running a cell, the cells of the last
    /// one's job are recorded as not run, with its outcome.
    #[allow(clippy::too_many_arguments)]
    fn worker_failed(&self, slot: &mut Slot, w: &Worker, outcome: Outcome, detail: String, exit: WorkerExit, per_cell: bool, on: &mut dyn FnMut(Event)) {
        on(Event::Worker(WorkerEvent {
            worker: w.id,
            phase: w.phase,
            outcome,
            detail: Some(detail.clone()),
            cells: w.batch,
            wall_ms: ms(w.spawned),
            device_features: w.device_features.clone(),
            worker_exit: Some(exit.clone()),
        }));
        if w.progressed {
            return;
        }
        slot.fruitless += 1;
        if slot.fruitless < 2 {
            return;
        }
        slot.fruitless = 0;
        let why = format!("not run: two workers in a row failed before running a cell; the last: {} in {}: {detail}", outcome.as_str(), w.phase);
        // Its job is a prefix of the queue (all of it, or one cell in process-per-cell).
        let n = w.batch.min(slot.queue.len());
        for c in slot.queue.drain(..n) {
            let attempt = Attempt {
                outcome,
                isolated: per_cell,
                detail: Some(why.clone()),
                result: None,
                worker_exit: Some(exit.clone()), injected: None,
                wall_ms: 0.0,
                phase: Some(w.phase),
                worker: w.id,
                device_features: w.device_features.clone(),
            };
            on(Event::Attempt { cell: &c, attempt });
        }
    }
}

fn ms(since: Instant) -> f64 {
    since.elapsed().as_secs_f64() * 1e3
}

/// A fresh seed for each worker's flaky-injection dice (recorded in every injected result).
fn inject_seed(generation: u64) -> u64 {
    let nanos = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map(|d| d.as_nanos() as u64).unwrap_or(0);
    nanos ^ (u64::from(std::process::id()) << 32) ^ generation.wrapping_mul(0x9e37_79b9_7f4a_7c15)
}
