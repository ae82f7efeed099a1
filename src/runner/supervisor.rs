//! The supervisor: the only part that decides deadlines and kills. It starts workers (`rtprobe
//! __worker`, stdin null, stdout/stderr piped, each in its own process group), reads their
//! messages, and turns silence past a deadline into `timeout`, a worker that dies mid-cell into
//! `crash` (with signal and stderr tail), then starts a fresh worker for the remaining cells.
//! Kills are SIGTERM to the process group, a grace period, then SIGKILL.
use super::protocol::{WorkerJob, WorkerMsg};
use crate::matrix::Cell;
use crate::outcome::{CellResult, Outcome};
use crate::scene::SceneParams;
use serde::{Deserialize, Serialize};
use std::collections::VecDeque;
use std::io::{BufRead, BufReader, Read};
use std::os::unix::process::{CommandExt, ExitStatusExt};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc::{channel, Receiver, RecvTimeoutError, Sender};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum Isolation {
    /// One worker runs many cells and is replaced after a fault.
    Worker,
    /// Every cell runs in a fresh worker process.
    ProcessPerCell,
}

#[derive(Clone, Debug)]
pub struct SupervisorOptions {
    pub device_index: usize,
    pub scene: SceneParams,
    pub jobs: usize,
    pub isolation: Isolation,
    /// Hard deadline for one cell.
    pub timeout: Duration,
    /// Hard deadline for a worker to create its device and reference.
    pub setup_timeout: Duration,
    pub grace: Duration,
    pub validate: bool,
    /// `--inject-fault`, passed to every worker.
    pub inject: Vec<crate::matrix::inject::Injection>,
    pub dump: Option<PathBuf>,
    pub job_dir: PathBuf,
}

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct WorkerExit {
    #[serde(skip_serializing_if = "Option::is_none")]
    pub code: Option<i32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub signal: Option<i32>,
    #[serde(skip_serializing_if = "String::is_empty", default)]
    pub stderr_tail: String,
}

/// One run of one cell.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Attempt {
    pub outcome: Outcome,
    /// Ran alone in a fresh worker (a `--confirm` re-run, or process-per-cell isolation).
    pub isolated: bool,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub detail: Option<String>,
    /// The worker's own report (absent when the worker died or hung).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub result: Option<CellResult>,
    /// How the worker ended, when it ended during this cell.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub worker_exit: Option<WorkerExit>,
    /// The fault `--inject-fault` put into this attempt (recorded even when the worker died).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub injected: Option<crate::matrix::inject::InjectedFault>,
    pub wall_ms: f64,
}

/// Events for the report writer and progress display.
pub enum Event<'a> {
    WorkerReady { device_ms: f64, reference_ms: f64 },
    Attempt { cell: &'a Cell, attempt: Attempt },
}

enum Line {
    Msg(WorkerMsg),
    Garbage(String),
    Eof,
}

struct Worker {
    child: Child,
    pid: i32,
    generation: u64,
    stderr: Arc<Mutex<String>>,
    ready: bool,
    /// The cell it is running, since when.
    current: Option<(Cell, Instant)>,
    spawned: Instant,
}

struct Slot {
    queue: VecDeque<Cell>,
    worker: Option<Worker>,
    setup_failures: u32,
}

const STDERR_TAIL: usize = 4000;

fn kill_group(w: &mut Worker, grace: Duration) -> WorkerExit {
    unsafe { libc::kill(-w.pid, libc::SIGTERM) };
    let until = Instant::now() + grace;
    let mut status = None;
    while Instant::now() < until {
        if let Ok(Some(s)) = w.child.try_wait() {
            status = Some(s);
            break;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    if status.is_none() {
        unsafe { libc::kill(-w.pid, libc::SIGKILL) };
        status = w.child.wait().ok();
    }
    // Anything else left in the group.
    unsafe { libc::kill(-w.pid, libc::SIGKILL) };
    exit_of(status, &w.stderr)
}

fn exit_of(status: Option<std::process::ExitStatus>, stderr: &Arc<Mutex<String>>) -> WorkerExit {
    let tail = stderr.lock().map(|s| s.clone()).unwrap_or_default();
    WorkerExit { code: status.and_then(|s| s.code()), signal: status.and_then(|s| s.signal()), stderr_tail: tail }
}

pub struct Supervisor {
    opts: SupervisorOptions,
    /// The dice seed of the worker each cell was last sent to (`--inject-fault flaky`).
    seeds: std::rc::Rc<std::cell::RefCell<std::collections::HashMap<String, u64>>>,
    tx: Sender<(usize, u64, Line)>,
    rx: Receiver<(usize, u64, Line)>,
    generation: u64,
}

impl Supervisor {
    pub fn new(opts: SupervisorOptions) -> Self {
        let (tx, rx) = channel();
        Supervisor { opts, tx, rx, generation: 0, seeds: Default::default() }
    }

    fn spawn(&mut self, slot: usize, cells: Vec<Cell>) -> std::io::Result<Worker> {
        self.generation += 1;
        let gen = self.generation;
        let seed = inject_seed(gen);
        for c in &cells {
            self.seeds.borrow_mut().insert(c.id(), seed);
        }
        let job = WorkerJob {
            device_index: self.opts.device_index,
            scene: self.opts.scene,
            fence_timeout_ms: (self.opts.timeout.as_millis() as u64 * 8 / 10).max(100),
            validate: self.opts.validate,
            inject: self.opts.inject.clone(),
            inject_seed: seed,
            dump: self.opts.dump.clone(),
            cells,
        };
        std::fs::create_dir_all(&self.opts.job_dir)?;
        let path = self.opts.job_dir.join(format!("job-{}-{gen}.json", std::process::id()));
        std::fs::write(&path, serde_json::to_vec(&job).map_err(std::io::Error::other)?)?;
        let exe = std::env::current_exe()?;
        let mut child = Command::new(exe)
            .arg("__worker")
            .arg(&path)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .process_group(0)
            .spawn()?;
        let pid = child.id() as i32;
        let stdout = child.stdout.take().expect("piped stdout");
        let tx = self.tx.clone();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines() {
                let Ok(line) = line else { break };
                let msg = match serde_json::from_str::<WorkerMsg>(&line) {
                    Ok(m) => Line::Msg(m),
                    Err(_) => Line::Garbage(line),
                };
                if tx.send((slot, gen, msg)).is_err() {
                    return;
                }
            }
            let _ = tx.send((slot, gen, Line::Eof));
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
        Ok(Worker { child, pid, generation: gen, stderr, ready: false, current: None, spawned: Instant::now() })
    }

    /// Run `cells`, calling `on` for each attempt as it finishes. `isolated` forces one fresh
    /// worker per cell.
    pub fn run(&mut self, cells: &[Cell], isolated: bool, on: &mut dyn FnMut(Event)) {
        // Every attempt records what was injected into it, worked out as the worker did.
        let inject = self.opts.inject.clone();
        let seeds = self.seeds.clone();
        let mut tagged = |ev: Event| match ev {
            Event::Attempt { cell, mut attempt } => {
                if let Some(seed) = seeds.borrow().get(&cell.id()).copied() {
                    attempt.injected = crate::matrix::inject::roll(&inject, cell, seed);
                }
                on(Event::Attempt { cell, attempt })
            }
            other => on(other),
        };
        let on: &mut dyn FnMut(Event) = &mut tagged;
        let per_cell = isolated || self.opts.isolation == Isolation::ProcessPerCell;
        let jobs = self.opts.jobs.max(1).min(cells.len().max(1));
        let chunk = cells.len().div_ceil(jobs).max(1);
        let mut slots: Vec<Slot> = cells.chunks(chunk).map(|c| Slot { queue: c.iter().copied().collect(), worker: None, setup_failures: 0 }).collect();
        loop {
            // Start workers where cells wait.
            for i in 0..slots.len() {
                if slots[i].worker.is_none() && !slots[i].queue.is_empty() {
                    let batch: Vec<Cell> = if per_cell { vec![slots[i].queue[0]] } else { slots[i].queue.iter().copied().collect() };
                    match self.spawn(i, batch) {
                        Ok(w) => slots[i].worker = Some(w),
                        Err(e) => {
                            let msg = format!("cannot start a worker: {e}");
                            for c in slots[i].queue.drain(..) {
                                on(Event::Attempt { cell: &c, attempt: Attempt { outcome: Outcome::Error, isolated: per_cell, detail: Some(msg.clone()), result: None, worker_exit: None, injected: None, wall_ms: 0.0 } });
                            }
                        }
                    }
                }
            }
            if slots.iter().all(|s| s.worker.is_none() && s.queue.is_empty()) {
                break;
            }
            // Nearest deadline.
            let now = Instant::now();
            let deadline = slots
                .iter()
                .filter_map(|s| s.worker.as_ref())
                .map(|w| match &w.current {
                    Some((_, since)) => *since + self.opts.timeout,
                    None if !w.ready => w.spawned + self.opts.setup_timeout,
                    None => now + Duration::from_secs(3600),
                })
                .min()
                .unwrap_or(now + Duration::from_millis(50));
            let wait = deadline.saturating_duration_since(now);
            match self.rx.recv_timeout(wait) {
                Ok((i, gen, line)) => {
                    let Some(w) = slots[i].worker.as_mut() else { continue };
                    if w.generation != gen {
                        continue;
                    }
                    self.handle(&mut slots[i], line, per_cell, on);
                }
                Err(RecvTimeoutError::Timeout) => self.expire(&mut slots, per_cell, on),
                Err(RecvTimeoutError::Disconnected) => break,
            }
        }
    }

    fn handle(&mut self, slot: &mut Slot, line: Line, per_cell: bool, on: &mut dyn FnMut(Event)) {
        let w = slot.worker.as_mut().expect("checked by caller");
        match line {
            Line::Msg(WorkerMsg::Ready { device_ms, reference_ms }) => {
                w.ready = true;
                slot.setup_failures = 0;
                on(Event::WorkerReady { device_ms, reference_ms });
            }
            Line::Msg(WorkerMsg::Start { cell }) => {
                if let Some(c) = slot.queue.iter().find(|c| c.id() == cell) {
                    w.current = Some((*c, Instant::now()));
                }
            }
            Line::Msg(WorkerMsg::Result { cell, result }) => {
                let since = w.current.take().map(|(_, t)| t).unwrap_or_else(Instant::now);
                if let Some(pos) = slot.queue.iter().position(|c| c.id() == cell) {
                    let c = slot.queue.remove(pos).expect("position is valid");
                    let ends = result.outcome.ends_worker();
                    let attempt = Attempt {
                        outcome: result.outcome,
                        isolated: per_cell,
                        detail: result.detail.clone(),
                        result: Some(result),
                        worker_exit: None,
                        injected: None,
                        wall_ms: since.elapsed().as_secs_f64() * 1e3,
                    };
                    on(Event::Attempt { cell: &c, attempt });
                    if ends || per_cell {
                        // The worker exits by itself; make sure of it.
                        let mut w = slot.worker.take().expect("present");
                        let grace = if per_cell && !ends { Duration::from_secs(10) } else { self.opts.grace };
                        wait_or_kill(&mut w, grace);
                    }
                }
            }
            Line::Msg(WorkerMsg::Fatal { message }) => {
                let mut w = slot.worker.take().expect("present");
                let exit = kill_group(&mut w, self.opts.grace);
                for c in slot.queue.drain(..) {
                    on(Event::Attempt {
                        cell: &c,
                        attempt: Attempt { outcome: Outcome::Error, isolated: per_cell, detail: Some(format!("worker could not start: {message}")), result: None, worker_exit: Some(exit.clone()), injected: None, wall_ms: 0.0 },
                    });
                }
            }
            Line::Garbage(text) => tracing::debug!("worker said: {text}"),
            Line::Eof => {
                let mut w = slot.worker.take().expect("present");
                let status = w.child.wait().ok();
                // Give the stderr reader a moment to drain.
                std::thread::sleep(Duration::from_millis(20));
                let exit = exit_of(status, &w.stderr);
                if let Some((cell, since)) = w.current.take() {
                    if let Some(pos) = slot.queue.iter().position(|c| *c == cell) {
                        slot.queue.remove(pos);
                    }
                    let outcome = if exit.signal.is_some() || exit.code.is_some_and(|c| c != 0) { Outcome::Crash } else { Outcome::Error };
                    let detail = match (exit.signal, exit.code) {
                        (Some(s), _) => format!("worker killed by signal {s} ({})", signal_name(s)),
                        (None, Some(c)) => format!("worker exited with code {c} mid-cell"),
                        (None, None) => "worker vanished mid-cell".into(),
                    };
                    on(Event::Attempt { cell: &cell, attempt: Attempt { outcome, isolated: per_cell, detail: Some(detail), result: None, worker_exit: Some(exit), injected: None, wall_ms: since.elapsed().as_secs_f64() * 1e3 } });
                } else if !w.ready {
                    slot.setup_failures += 1;
                    if slot.setup_failures >= 2 {
                        let detail = format!("worker died during setup twice (exit {:?}, signal {:?})", exit.code, exit.signal);
                        for c in slot.queue.drain(..) {
                            on(Event::Attempt { cell: &c, attempt: Attempt { outcome: Outcome::Error, isolated: per_cell, detail: Some(detail.clone()), result: None, worker_exit: Some(exit.clone()), injected: None, wall_ms: 0.0 } });
                        }
                    }
                }
            }
        }
    }

    fn expire(&mut self, slots: &mut [Slot], per_cell: bool, on: &mut dyn FnMut(Event)) {
        let now = Instant::now();
        for slot in slots.iter_mut() {
            let Some(w) = slot.worker.as_mut() else { continue };
            match &w.current {
                Some((cell, since)) if now >= *since + self.opts.timeout => {
                    let (cell, since) = (*cell, *since);
                    let mut w = slot.worker.take().expect("present");
                    let exit = kill_group(&mut w, self.opts.grace);
                    if let Some(pos) = slot.queue.iter().position(|c| *c == cell) {
                        slot.queue.remove(pos);
                    }
                    let detail = format!("no result within {:?}; worker process group killed", self.opts.timeout);
                    on(Event::Attempt { cell: &cell, attempt: Attempt { outcome: Outcome::Timeout, isolated: per_cell, detail: Some(detail), result: None, worker_exit: Some(exit), injected: None, wall_ms: since.elapsed().as_secs_f64() * 1e3 } });
                }
                None if !w.ready && now >= w.spawned + self.opts.setup_timeout => {
                    let mut w = slot.worker.take().expect("present");
                    let exit = kill_group(&mut w, self.opts.grace);
                    let detail = format!("worker setup took longer than {:?}", self.opts.setup_timeout);
                    for c in slot.queue.drain(..) {
                        on(Event::Attempt { cell: &c, attempt: Attempt { outcome: Outcome::Error, isolated: per_cell, detail: Some(detail.clone()), result: None, worker_exit: Some(exit.clone()), injected: None, wall_ms: 0.0 } });
                    }
                }
                _ => {}
            }
        }
    }
}

fn wait_or_kill(w: &mut Worker, grace: Duration) {
    let until = Instant::now() + grace;
    while Instant::now() < until {
        if let Ok(Some(_)) = w.child.try_wait() {
            return;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    kill_group(w, Duration::from_millis(200));
}

/// A fresh seed for each worker's flaky-injection dice (recorded in every injected result).
fn inject_seed(generation: u64) -> u64 {
    let nanos = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map(|d| d.as_nanos() as u64).unwrap_or(0);
    nanos ^ (u64::from(std::process::id()) << 32) ^ generation.wrapping_mul(0x9e37_79b9_7f4a_7c15)
}

pub fn signal_name(sig: i32) -> &'static str {
    match sig {
        libc::SIGSEGV => "SIGSEGV",
        libc::SIGBUS => "SIGBUS",
        libc::SIGABRT => "SIGABRT",
        libc::SIGILL => "SIGILL",
        libc::SIGFPE => "SIGFPE",
        libc::SIGKILL => "SIGKILL",
        libc::SIGTERM => "SIGTERM",
        _ => "signal",
    }
}
