//! One stress case in a worker process: `rtprobe __stress JOB.json`, started by `supervised`.
//! It opens the device the job names with what the stress pipeline needs, traces the case's
//! parts (a progress line before each part and after each submission of its rays, with the rays
//! traced so far: the parent's deadline follows the device work), then judges them on the CPU (a
//! heartbeat line every [`BEAT`] in which the check moved — triangles placed in the reference's
//! grid (`index`), rays judged (`check`), rays' facing found (`facing`) — and only then: a hang
//! in the driver or a stalled check stays silent and is killed at the parent's deadline) and
//! writes a [`CaseOutput`] to the job's result file (tmp + rename). A driver crash kills this
//! process and nothing else: the parent records it as the case's outcome.
//!
//! Test hook: `RTPROBE_STRESS_FAULT=<case>:<crash|hang>` makes that case's worker raise SIGSEGV
//! or sleep forever where its first part would be traced; `<case>:stall` holds the case's first
//! submission on the device until its fence wait has run out (a GPU slower than any deadline:
//! the driver's own wait times out), `<case>:stall_forever` for good (a hung GPU: the worker
//! must still write its result and exit); `<case>:slow_<step>:SECS` makes the
//! check's step (`index`, `check` or `facing`) take SECS more, spread over its units (slow,
//! progressing), and `<case>:stalled_<step>:SECS` stalls it SECS at its first unit, heartbeat
//! running (`tests/stress.rs`).
use super::gpu::{GpuTracer, Mode};
use super::result::{CaseResult, Verdict};
use super::{CaseKind, Part, StressOptions, TraceError, Traced, Tracer, Work};
use crate::vk::{features, Gpu, Instance, InstanceOptions};
use serde::{Deserialize, Serialize};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::Duration;

/// What the parent asks of one worker.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct CaseJob {
    pub device_index: usize,
    /// The case's name (`CaseKind::as_str`).
    pub case: String,
    pub seed: u64,
    pub full: bool,
    /// Fence deadline of one submission.
    pub timeout: Duration,
    pub ray_query: bool,
    pub validate: bool,
    /// Where the worker writes its [`CaseOutput`].
    pub result: PathBuf,
}

/// What the worker hands back.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct CaseOutput {
    pub result: CaseResult,
    /// Validation messages the layer reported in this worker.
    pub validation_errors: u64,
}

/// One line of progress on stdout: `setup`, `ready`, `trace PART` (before a part, and after
/// each submission with the part's rays traced: `done` of `total`), and the check's heartbeat:
/// `index` (the case's triangles placed in the reference's grids), `check` (its rays judged),
/// `facing` (its rays' facing found), each `done` of `total` `unit`s.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Progress {
    pub step: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub done: Option<u64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub total: Option<u64>,
    /// What `done` counts: `rays` where absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub unit: Option<String>,
}

/// How often the check's heartbeat speaks.
pub const BEAT: Duration = Duration::from_secs(2);

fn say(step: impl Into<String>) {
    tell(Progress { step: step.into(), done: None, total: None, unit: None });
}

fn tell(p: Progress) {
    let mut out = std::io::stdout().lock();
    let _ = serde_json::to_writer(&mut out, &p);
    let _ = out.write_all(b"\n");
    let _ = out.flush();
}

/// `RTPROBE_STRESS_FAULT`: how the case's worker misbehaves.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Hook {
    Crash,
    Hang,
    /// The first submission is held on the device past its deadline, then released (`false`:
    /// never, `stall_forever`).
    Stall {
        release: bool,
    },
    /// The check's step takes this much longer, spread over its units.
    Slow(Work, Duration),
    /// The check's step stalls this long at its first unit, the heartbeat running.
    Stalled(Work, Duration),
}

/// The heartbeat's name of each step of the check, and its unit.
fn step_of(w: Work) -> (usize, &'static str, &'static str) {
    match w {
        Work::Indexed => (0, "index", "triangles"),
        Work::Judged => (1, "check", "rays"),
        Work::Faced => (2, "facing", "rays"),
    }
}

const STEPS: [Work; 3] = [Work::Indexed, Work::Judged, Work::Faced];

fn hook(case: &str) -> Option<Hook> {
    let v = std::env::var("RTPROBE_STRESS_FAULT").ok()?;
    let (c, how) = v.split_once(':')?;
    if c != case {
        return None;
    }
    let secs = |s: &str| s.parse::<f64>().ok().filter(|s| s.is_finite() && *s >= 0.0);
    let step = |name: &str| STEPS.into_iter().find(|&w| step_of(w).1 == name);
    Some(match how.split_once(':') {
        None if how == "crash" => Hook::Crash,
        None if how == "hang" => Hook::Hang,
        None if how == "stall" => Hook::Stall { release: true },
        None if how == "stall_forever" => Hook::Stall { release: false },
        Some((h, s)) => {
            let d = Duration::from_secs_f64(secs(s)?);
            match h.split_once('_')? {
                ("slow", w) => Hook::Slow(step(w)?, d),
                ("stalled", w) => Hook::Stalled(step(w)?, d),
                _ => return None,
            }
        }
        None => return None,
    })
}

/// The device tracer, saying each part before tracing it.
struct Announced {
    inner: GpuTracer,
    hook: Option<Hook>,
}

impl Tracer for Announced {
    fn name(&self) -> String {
        self.inner.name()
    }
    fn trace(&mut self, part: &Part) -> Result<Vec<Traced>, TraceError> {
        say(format!("trace {}", part.label));
        match self.hook.take() {
            Some(Hook::Crash) => unsafe {
                // Rust's own SIGSEGV handler ignores a raised signal; restore the default first.
                libc::signal(libc::SIGSEGV, libc::SIG_DFL);
                libc::raise(libc::SIGSEGV);
            },
            Some(Hook::Hang) => loop {
                std::thread::sleep(Duration::from_secs(3600));
            },
            Some(Hook::Stall { .. } | Hook::Slow(..) | Hook::Stalled(..)) | None => {}
        }
        let step = format!("trace {}", part.label);
        self.inner.on_chunk(Box::new(move |done, total| {
            tell(Progress {
                step: step.clone(),
                done: Some(done as u64),
                total: Some(total as u64),
                unit: None,
            })
        }));
        self.inner.trace(part)
    }
}

/// Opens the job's device and the stress pipeline on it; `stall`: its first submission held,
/// then released or not (the device opened with `timelineSemaphore`).
fn open(job: &CaseJob, stall: Option<bool>) -> Result<GpuTracer, String> {
    let inst = Arc::new(
        Instance::new(&InstanceOptions { validate: job.validate, gpu_av: false })
            .map_err(|e| e.to_string())?,
    );
    let all = features::query_all(&inst).map_err(|e| e.to_string())?;
    let info = all.get(job.device_index).ok_or("the device vanished")?.clone();
    let mode = if job.ray_query { Mode::RayQuery } else { Mode::Pipeline };
    let req =
        crate::vk::Requirements { timeline_semaphore: stall.is_some(), ..mode.requirements() };
    let gpu = Gpu::new(inst, info, req).map_err(|e| e.to_string())?;
    let mut tracer = GpuTracer::new(gpu, job.timeout, mode).map_err(|e| e.to_string())?;
    if let Some(release) = stall {
        tracer.hold_first_submission(release).map_err(|e| e.to_string())?;
    }
    Ok(tracer)
}

/// What the check has done: per step (`step_of`) the units done and their total, and the step
/// it is in.
struct Counters {
    step: AtomicUsize,
    done: [AtomicU64; 3],
    total: [u64; 3],
}

impl Counters {
    /// The counters of judging `trace`'s parts: their triangles, rays, and rays again where the
    /// case finds facing (`transform`).
    fn of(kind: CaseKind, trace: &super::CaseTrace) -> Counters {
        let parts: &[Part] = match trace {
            super::CaseTrace::Traced(parts, _) => parts,
            _ => &[],
        };
        let rays: u64 = parts.iter().map(|p| p.rays.len() as u64).sum();
        let triangles = parts
            .iter()
            .flat_map(|p| p.scene.instances.iter().map(|i| &p.scene.meshes[i.mesh]))
            .map(|m| m.indices.len() as u64)
            .sum();
        let facing = if kind == CaseKind::Transform { rays } else { 0 };
        Counters {
            step: AtomicUsize::new(0),
            done: Default::default(),
            total: [triangles, rays, facing],
        }
    }
}

/// Prints the check's step with its units done when it starts and then every [`BEAT`] in which
/// it moved (more units done, or the next step begun): a check that stops moving goes silent,
/// and the parent's deadline kills it (stops when dropped).
struct Heartbeat(Arc<AtomicBool>);

impl Heartbeat {
    fn start(c: Arc<Counters>) -> Heartbeat {
        let on = Arc::new(AtomicBool::new(true));
        let flag = on.clone();
        std::thread::spawn(move || {
            let mut told = None;
            while flag.load(Ordering::Relaxed) {
                let k = c.step.load(Ordering::Relaxed);
                let now = (k, c.done[k].load(Ordering::Relaxed));
                if Some(now) != told {
                    let (_, step, unit) = step_of(STEPS[k]);
                    tell(Progress {
                        step: step.into(),
                        done: Some(now.1),
                        total: Some(c.total[k]),
                        unit: Some(unit.into()),
                    });
                    told = Some(now);
                }
                std::thread::sleep(BEAT);
            }
        });
        Heartbeat(on)
    }
}

impl Drop for Heartbeat {
    fn drop(&mut self) {
        self.0.store(false, Ordering::Relaxed);
    }
}

/// Judges `trace`, the heartbeat counting each unit of work and the test hook slowing or
/// stalling its step.
fn judge(kind: CaseKind, trace: &super::CaseTrace, hook: Option<Hook>) -> CaseResult {
    let c = Arc::new(Counters::of(kind, trace));
    let _beat = Heartbeat::start(c.clone());
    let stalled = AtomicBool::new(false);
    let on_work = |w: Work| {
        let (k, _, _) = step_of(w);
        c.step.store(k, Ordering::Relaxed);
        match hook {
            Some(Hook::Slow(h, d)) if h == w => {
                std::thread::sleep(d / c.total[k].max(1) as u32);
            }
            Some(Hook::Stalled(h, d)) if h == w && !stalled.swap(true, Ordering::Relaxed) => {
                std::thread::sleep(d);
            }
            Some(
                Hook::Crash | Hook::Hang | Hook::Stall { .. } | Hook::Slow(..) | Hook::Stalled(..),
            )
            | None => {}
        }
        c.done[k].fetch_add(1, Ordering::Relaxed);
    };
    super::judge_counting(kind, trace, &on_work)
}

/// The case's result, and whether its device was left as it was (a submission timed out or the
/// device was lost): the process must then end without the driver's teardown.
fn run(job: &CaseJob, kind: CaseKind) -> (CaseResult, bool) {
    say("setup");
    let hook = hook(kind.as_str());
    let stall = match hook {
        Some(Hook::Stall { release }) => Some(release),
        Some(Hook::Crash | Hook::Hang | Hook::Slow(..) | Hook::Stalled(..)) | None => None,
    };
    let inner = match open(job, stall) {
        Ok(t) => t,
        Err(e) => {
            let detail = format!("setting up the stress pipeline: {e}");
            return (CaseResult::without_results(kind, Verdict::Error, detail, 0), false);
        }
    };
    say("ready");
    let mut tracer = Announced { inner, hook };
    let opts = StressOptions { cases: vec![kind], seed: job.seed, full: job.full };
    let start = std::time::Instant::now();
    let trace = super::trace_case(&mut tracer, kind, &opts);
    let broken = tracer.inner.is_broken();
    if broken {
        // A timed-out or lost submission may still run: destroying the device would wait for
        // it (a hung driver hangs the worker before its result is written) or free what it
        // uses. The process `_exit`s after the result (`main`); the OS reclaims it all then.
        std::mem::forget(tracer);
    }
    let mut r = judge(kind, &trace, hook);
    r.ms = start.elapsed().as_secs_f64() * 1e3;
    (r, broken)
}

/// The worker's entry: 0 when it wrote its result, 2 for a job it cannot read.
pub fn main(job_path: &Path) -> u8 {
    crate::native_crash::install();
    let read = std::fs::read(job_path)
        .map_err(|e| e.to_string())
        .and_then(|b| serde_json::from_slice::<CaseJob>(&b).map_err(|e| e.to_string()));
    let _ = std::fs::remove_file(job_path);
    let job = match read {
        Ok(j) => j,
        Err(e) => {
            eprintln!("rtprobe __stress: cannot read job {}: {e}", job_path.display());
            return 2;
        }
    };
    let Some(kind) = CaseKind::parse(&job.case) else {
        eprintln!("rtprobe __stress: unknown case {:?}", job.case);
        return 2;
    };
    let (result, broken) = run(&job, kind);
    let out =
        CaseOutput { result, validation_errors: crate::vk::instance::validation_error_count() };
    let bytes = serde_json::to_vec(&out).expect("a case result serializes");
    let code = match crate::atomic::write_atomic(&job.result, &bytes) {
        Ok(()) => 0,
        Err(e) => {
            eprintln!("rtprobe __stress: writing {}: {e}", job.result.display());
            2
        }
    };
    if broken {
        // `_exit`, not a return: the driver's atexit handlers would tear down the device the
        // worker left, waiting for its hung work (as `run`'s worker does, `runner::worker`).
        unsafe { libc::_exit(code.into()) }
    }
    code
}
