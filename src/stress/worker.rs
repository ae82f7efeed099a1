//! One stress case in a worker process: `rtprobe __stress JOB.json`, started by `supervised`.
//! It opens the device the job names with what the stress pipeline needs, traces the case's
//! parts (a progress line before each part and after each submission of its rays, with the rays
//! traced so far: the parent's deadline follows the device work), then judges them on the CPU (a
//! heartbeat line every [`BEAT`] in which more rays were judged, and only then: a hang in the
//! driver or a stalled check stays silent and is killed at the parent's deadline) and writes a [`CaseOutput`] to the job's result file (tmp + rename). A driver
//! crash kills this process and nothing else: the parent records it as the case's outcome.
//!
//! Test hook: `RTPROBE_STRESS_FAULT=<case>:<crash|hang>` makes that case's worker raise SIGSEGV
//! or sleep forever where its first part would be traced; `<case>:slow_check:SECS` makes its
//! check take SECS more, spread over its rays (slow, progressing), and `<case>:stalled_check:SECS`
//! stalls it SECS before its first ray, heartbeat running (`tests/stress.rs`).
use super::gpu::{GpuTracer, Mode};
use super::result::{CaseResult, Verdict};
use super::{CaseKind, Part, StressOptions, TraceError, Traced, Tracer};
use crate::vk::{features, Gpu, Instance, InstanceOptions};
use serde::{Deserialize, Serialize};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
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
    pub timeout_ms: u64,
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
/// each submission with the part's rays traced: `done` of `total`), `check` (a heartbeat, with
/// the case's rays judged: `done` of `total`).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Progress {
    pub step: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub done: Option<u64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub total: Option<u64>,
}

/// How often the check's heartbeat speaks.
pub const BEAT: Duration = Duration::from_secs(2);

fn say(step: impl Into<String>) {
    tell(Progress { step: step.into(), done: None, total: None });
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
    /// The check takes this much longer, spread over its rays.
    SlowCheck(Duration),
    /// The check stalls this long before its first ray, its heartbeat running.
    StalledCheck(Duration),
}

fn hook(case: &str) -> Option<Hook> {
    let v = std::env::var("RTPROBE_STRESS_FAULT").ok()?;
    let (c, how) = v.split_once(':')?;
    if c != case {
        return None;
    }
    let secs = |s: &str| s.parse::<f64>().ok().filter(|s| s.is_finite() && *s >= 0.0);
    Some(match how.split_once(':') {
        None if how == "crash" => Hook::Crash,
        None if how == "hang" => Hook::Hang,
        Some(("slow_check", s)) => Hook::SlowCheck(Duration::from_secs_f64(secs(s)?)),
        Some(("stalled_check", s)) => Hook::StalledCheck(Duration::from_secs_f64(secs(s)?)),
        _ => return None,
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
            Some(Hook::SlowCheck(_) | Hook::StalledCheck(_)) | None => {}
        }
        let step = format!("trace {}", part.label);
        self.inner.on_chunk(Box::new(move |done, total| {
            tell(Progress {
                step: step.clone(),
                done: Some(done as u64),
                total: Some(total as u64),
            })
        }));
        self.inner.trace(part)
    }
}

/// Opens the job's device and the stress pipeline on it.
fn open(job: &CaseJob) -> Result<GpuTracer, String> {
    let inst = Arc::new(
        Instance::new(&InstanceOptions { validate: job.validate, gpu_av: false })
            .map_err(|e| e.to_string())?,
    );
    let all = features::query_all(&inst).map_err(|e| e.to_string())?;
    let info = all.get(job.device_index).ok_or("the device vanished")?.clone();
    let mode = if job.ray_query { Mode::RayQuery } else { Mode::Pipeline };
    let req = mode.requirements();
    let gpu = Gpu::new(inst, info, req).map_err(|e| e.to_string())?;
    GpuTracer::new(gpu, Duration::from_millis(job.timeout_ms), mode).map_err(|e| e.to_string())
}

/// Prints `check` with the rays judged so far when it starts and then every [`BEAT`] in which
/// more were judged: a check that stops judging goes silent, and the parent's deadline kills
/// it (stops when dropped).
struct Heartbeat(Arc<AtomicBool>);

impl Heartbeat {
    fn start(checked: Arc<AtomicU64>, total: u64) -> Heartbeat {
        let on = Arc::new(AtomicBool::new(true));
        let flag = on.clone();
        std::thread::spawn(move || {
            let mut told = None;
            while flag.load(Ordering::Relaxed) {
                let done = Some(checked.load(Ordering::Relaxed));
                if done != told {
                    tell(Progress { step: "check".into(), done, total: Some(total) });
                    told = done;
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

fn run(job: &CaseJob, kind: CaseKind) -> CaseResult {
    say("setup");
    let inner = match open(job) {
        Ok(t) => t,
        Err(e) => {
            let detail = format!("setting up the stress pipeline: {e}");
            return CaseResult::without_results(kind, Verdict::Error, detail, 0);
        }
    };
    say("ready");
    let hook = hook(kind.as_str());
    let mut tracer = Announced { inner, hook };
    let opts = StressOptions { cases: vec![kind], seed: job.seed, full: job.full };
    let start = std::time::Instant::now();
    let trace = super::trace_case(&mut tracer, kind, &opts);
    let total = match &trace {
        super::CaseTrace::Traced(parts, _) => parts.iter().map(|p| p.rays.len() as u64).sum(),
        _ => 0,
    };
    let checked = Arc::new(AtomicU64::new(0));
    let _beat = Heartbeat::start(checked.clone(), total);
    let pause = match hook {
        Some(Hook::StalledCheck(d)) => {
            std::thread::sleep(d);
            Duration::ZERO
        }
        Some(Hook::SlowCheck(d)) => d / total.max(1) as u32,
        _ => Duration::ZERO,
    };
    let on_ray = || {
        if !pause.is_zero() {
            std::thread::sleep(pause);
        }
        checked.fetch_add(1, Ordering::Relaxed);
    };
    let mut r = super::judge_counting(kind, &trace, &on_ray);
    r.ms = start.elapsed().as_secs_f64() * 1e3;
    r
}

/// The worker's entry: 0 when it wrote its result, 2 for a job it cannot read.
pub fn main(job_path: &Path) -> u8 {
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
    let result = run(&job, kind);
    let out =
        CaseOutput { result, validation_errors: crate::vk::instance::validation_error_count() };
    let bytes = serde_json::to_vec(&out).expect("a case result serializes");
    match crate::atomic::write_atomic(&job.result, &bytes) {
        Ok(()) => 0,
        Err(e) => {
            eprintln!("rtprobe __stress: writing {}: {e}", job.result.display());
            2
        }
    }
}
