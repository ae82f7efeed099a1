//! One stress case in a worker process: `rtprobe __stress JOB.json`, started by `supervised`.
//! It opens the device the job names with what the stress pipeline needs, traces the case's
//! parts (a progress line before each, so the parent's deadline follows the device work), then
//! judges them on the CPU (a heartbeat line every few seconds, and only then: a hang in the driver
//! stays silent) and writes a [`CaseOutput`] to the job's result file (tmp + rename). A driver
//! crash kills this process and nothing else: the parent records it as the case's outcome.
//!
//! Test hook: `RTPROBE_STRESS_FAULT=<case>:<crash|hang>` makes that case's worker raise SIGSEGV
//! or sleep forever where its first part would be traced (`tests/stress.rs`).
use super::gpu::{GpuTracer, Mode};
use super::result::{CaseResult, Verdict};
use super::{CaseKind, Part, StressOptions, TraceError, Traced, Tracer};
use crate::vk::{features, Gpu, Instance, InstanceOptions};
use serde::{Deserialize, Serialize};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
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

/// One line of progress on stdout: `setup`, `ready`, `trace PART`, `check` (a heartbeat).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Progress {
    pub step: String,
}

fn say(step: impl Into<String>) {
    let mut out = std::io::stdout().lock();
    let _ = serde_json::to_writer(&mut out, &Progress { step: step.into() });
    let _ = out.write_all(b"\n");
    let _ = out.flush();
}

/// `RTPROBE_STRESS_FAULT`: the case whose first trace misbehaves, and how.
fn hook(case: &str) -> Option<&'static str> {
    let v = std::env::var("RTPROBE_STRESS_FAULT").ok()?;
    let (c, how) = v.split_once(':')?;
    (c == case).then_some(match how {
        "crash" => "crash",
        "hang" => "hang",
        _ => return None,
    })
}

/// The device tracer, saying each part before tracing it.
struct Announced {
    inner: GpuTracer,
    hook: Option<&'static str>,
}

impl Tracer for Announced {
    fn name(&self) -> String {
        self.inner.name()
    }
    fn trace(&mut self, part: &Part) -> Result<Vec<Traced>, TraceError> {
        say(format!("trace {}", part.label));
        match self.hook.take() {
            Some("crash") => unsafe {
                // Rust's own SIGSEGV handler ignores a raised signal; restore the default first.
                libc::signal(libc::SIGSEGV, libc::SIG_DFL);
                libc::raise(libc::SIGSEGV);
            },
            Some(_) => loop {
                std::thread::sleep(Duration::from_secs(3600));
            },
            None => {}
        }
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

/// Prints `check` every few seconds while the CPU judges the case (stops when dropped).
struct Heartbeat(Arc<AtomicBool>);

impl Heartbeat {
    fn start() -> Heartbeat {
        let on = Arc::new(AtomicBool::new(true));
        let flag = on.clone();
        std::thread::spawn(move || {
            while flag.load(Ordering::Relaxed) {
                say("check");
                std::thread::sleep(Duration::from_secs(2));
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
    let mut tracer = Announced { inner, hook: hook(kind.as_str()) };
    let opts = StressOptions { cases: vec![kind], seed: job.seed, full: job.full };
    let start = std::time::Instant::now();
    let trace = super::trace_case(&mut tracer, kind, &opts);
    let _beat = Heartbeat::start();
    let mut r = super::judge(kind, &trace);
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
