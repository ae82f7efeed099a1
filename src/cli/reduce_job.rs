//! `rtprobe __interesting JOB CANDIDATE`: spirv-reduce's interestingness test for `rtprobe
//! reduce` (exit 0: interesting). spirv-reduce appends the candidate's path and runs the
//! command through the shell; it validates candidates only as universal SPIR-V 1.6, so this
//! test refuses, before any device run: a candidate `spirv-val --target-env vulkan1.x` (with
//! the module's layout options) fails; one whose descriptor indices are not provably in bounds
//! (`shape::bounds`: an `OpUndef` index, a constant past the array); one where the finding's
//! `--inject-fault` request, applied again, matches no access (the access that faulted is
//! gone); one whose pipeline fails `run --shader`'s interface check (a payload spirv-reduce
//! shrank). Then it runs the pipeline with the candidate as `run --shader` runs a variant (the
//! same `__shader` children, the job's attempts) and says yes only when some attempt faults
//! with one of the finding's outcomes, and no attempt faults otherwise or has validation
//! messages. Each run appends one line to the job's log (`RunLine`).
use super::shader_exec::{self, Ctx};
use crate::harness::child::JobModule;
use crate::harness::inject::{self, Request};
use crate::model::{DescriptorModel, Outcome};
use crate::patches::Validation;
use crate::tools::spirv::{self as spirv_tools, ValOptions};
use serde::{Deserialize, Serialize};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// What `reduce` hands each interestingness run.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct InterestingJob {
    pub device_index: usize,
    pub validate: bool,
    pub scalar: bool,
    pub timeout_ms: u64,
    pub setup_timeout_ms: u64,
    pub model: DescriptorModel,
    pub spec: Vec<crate::harness::spec::SpecValue>,
    pub heap_layout: Option<Vec<crate::harness::heap::Array>>,
    pub sizes: crate::harness::Sizes,
    /// The run's `--fill` bytes and `--profile` setup: the harness the finding ran in.
    #[serde(default)]
    pub fills: crate::harness::fill::Fills,
    #[serde(default)]
    pub profile: crate::harness::profile::ProfileSetup,
    /// The run's `--scene` and the fills that read it: candidates trace the scene the finding did.
    #[serde(default)]
    pub scene: Option<std::path::PathBuf>,
    #[serde(default)]
    pub scene_fills: Vec<crate::harness::scene_data::SceneFill>,
    /// The given modules, unreduced and without the injected fault.
    pub modules: Vec<JobModule>,
    /// Which of them the candidate replaces.
    pub target: usize,
    /// spirv-val's environment and layout options for the target (`None`: no spirv-val).
    pub val_env: Option<String>,
    pub val_scalar: bool,
    pub val_ubo_standard: bool,
    /// `--inject-fault`'s request, applied to every candidate.
    pub injection: Option<String>,
    /// The finding's fault outcomes.
    pub outcomes: Vec<Outcome>,
    pub attempts: u32,
    /// The descriptors of a runtime array the harness writes.
    pub runtime_len: u32,
    /// Scratch folder and the log of runs.
    pub dir: PathBuf,
    pub log: PathBuf,
}

/// One interestingness run, as the log records it.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct RunLine {
    pub interesting: bool,
    /// Refused before any device run.
    pub refused_statically: bool,
    pub why: String,
    pub ms: f64,
}

/// The candidate's modules ready to run, or why it is not interesting before the device.
fn prepare(job: &InterestingJob, candidate: &Path) -> Result<Vec<JobModule>, String> {
    let bytes = std::fs::read(candidate).map_err(|e| format!("reading the candidate: {e}"))?;
    let mut m = crate::patches::load(&bytes).map_err(|e| e.to_string())?;
    let words = crate::patches::assemble(&m);
    let opts = job.val_env.as_ref().map(|env| ValOptions {
        env: env.clone(),
        scalar_block_layout: job.val_scalar,
        uniform_buffer_standard_layout: job.val_ubo_standard,
    });
    let check = |w: &[u32], what: &str| match opts.as_ref().map(|o| spirv_tools::validate(w, o)) {
        None | Some(Validation::Valid) => Ok(()),
        Some(v) => Err(format!("{what} fails spirv-val: {v:?}")),
    };
    check(&words, "the candidate")?;
    crate::shape::bounds::check(&m, job.runtime_len).map_err(|e| e.to_string())?;
    if let Some(spec) = &job.injection {
        let r = Request::parse(spec).map_err(|e| e.to_string())?;
        if inject::inject(&mut m, &r).sites.is_empty() {
            return Err("the injection matches no access of the candidate".into());
        }
    }
    let words = crate::patches::assemble(&m);
    check(&words, "the candidate with the injected fault")?;
    let mut modules = job.modules.clone();
    let target = modules.get_mut(job.target).ok_or("the job's target is not a module")?;
    target.words = words;
    interface(&modules)?;
    Ok(modules)
}

/// Vulkan's least `maxRayHitAttributeSize`: the interface check's limit for candidates.
const MIN_MAX_HIT_ATTRIBUTE: u32 = 32;

/// The candidate pipeline against the harness's layout, as `run --shader` checks it before
/// the device: a candidate whose payload no longer matches the other stages' is refused.
fn interface(modules: &[JobModule]) -> Result<(), String> {
    use crate::harness::{run, UserModule};
    let users = modules
        .iter()
        .map(|m| UserModule::new(&m.name, &m.words))
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| e.to_string())?;
    let full = run::full_pipeline(users).map_err(|e| e.to_string())?;
    run::check_pipeline(&full).map_err(|e| e.to_string())?;
    let desc = run::pipeline_desc(&full, MIN_MAX_HIT_ATTRIBUTE);
    let words: Vec<&[u32]> = full.iter().map(|m| m.words.as_slice()).collect();
    crate::interface::check(&words, &desc).map_err(|e| format!("the interface: {e}"))
}

/// Whether the candidate's attempts reproduce the finding, and why (not).
fn judge(job: &InterestingJob, modules: Vec<JobModule>) -> Result<(bool, String), String> {
    static NEXT: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);
    let n = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let dir = job.dir.join(format!("run-{}-{n}", std::process::id()));
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let ctx = Ctx {
        device_index: job.device_index,
        validate: job.validate,
        scalar: job.scalar,
        unpatched: modules.clone(),
        repeat: job.attempts,
        timeout: Duration::from_millis(job.timeout_ms),
        setup_timeout: Duration::from_millis(job.setup_timeout_ms),
        dir: dir.clone(),
        model: job.model,
        spec: job.spec.clone(),
        heap_layout: job.heap_layout.clone(),
        sizes: job.sizes,
        fills: job.fills.clone(),
        scene: job.scene.clone(),
        scene_fills: job.scene_fills.clone(),
        profile: job.profile,
        gpu_av: false,
    };
    let ran = shader_exec::run_variant(&ctx, "candidate", &modules, None);
    let _ = std::fs::remove_dir_all(&dir);
    let ran = ran.map_err(|e| format!("{e:#}"))?;
    let outcomes: Vec<Outcome> = ran.ran.iter().map(|r| r.attempt.attempt.outcome).collect();
    let messages: u64 = ran.ran.iter().map(|r| r.attempt.validation_messages).sum();
    let faults: Vec<Outcome> = outcomes.iter().copied().filter(|o| is_fault(*o)).collect();
    let same = !faults.is_empty() && faults.iter().all(|o| job.outcomes.contains(o));
    let why = format!(
        "attempts: {}{}",
        outcomes.iter().map(|o| o.as_str()).collect::<Vec<_>>().join(", "),
        if messages > 0 { format!("; {messages} validation messages") } else { String::new() }
    );
    Ok((same && messages == 0, why))
}

fn log(job: &InterestingJob, line: &RunLine) {
    let Ok(text) = serde_json::to_string(line) else { return };
    let file = std::fs::OpenOptions::new().create(true).append(true).open(&job.log);
    if let Ok(mut f) = file {
        let _ = writeln!(f, "{text}");
    }
}

/// The test's entry: 0 when the candidate is interesting, 1 when not, 2 when the job is bad.
pub fn main(job_path: &Path, candidate: &Path) -> u8 {
    let started = std::time::Instant::now();
    let job: InterestingJob = match std::fs::read(job_path)
        .map_err(|e| e.to_string())
        .and_then(|b| serde_json::from_slice(&b).map_err(|e| e.to_string()))
    {
        Ok(j) => j,
        Err(e) => {
            eprintln!("rtprobe __interesting: cannot read job {}: {e}", job_path.display());
            return 2;
        }
    };
    let (interesting, refused_statically, why) = match prepare(&job, candidate) {
        Err(why) => (false, true, why),
        Ok(modules) => match judge(&job, modules) {
            Ok((yes, why)) => (yes, false, why),
            Err(why) => (false, false, why),
        },
    };
    let ms = started.elapsed().as_secs_f64() * 1000.0;
    log(&job, &RunLine { interesting, refused_statically, why, ms });
    u8::from(!interesting)
}

/// The outcomes a fault finding has.
pub fn is_fault(o: Outcome) -> bool {
    match o {
        Outcome::DeviceLost | Outcome::Crash | Outcome::Timeout => true,
        Outcome::Pass
        | Outcome::Mismatch
        | Outcome::Error
        | Outcome::Unsupported
        | Outcome::NotImplemented => false,
    }
}
