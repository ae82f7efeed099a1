//! `rtprobe __verify JOB.json`: `patch --verify`'s device work in a process of its own, started
//! by `rtprobe patch` through `runner::process::run_to_end` as the supervisor starts workers (own
//! process group, dying with its parent, killed when silent past its deadline). It opens the
//! job's device, runs the unpatched and the patched pipeline ([`super::verify_with`]), saying
//! each step on stdout before taking it, and writes a [`VerifyOutput`] to the job's result file
//! (tmp + rename). A driver that crashes or hangs on a user's shader kills or stalls this process
//! only: the parent turns that into the verification's outcome.
//!
//! Test hook: `RTPROBE_VERIFY_FAULT=<crash|hang>` raises SIGSEGV or sleeps forever where the
//! patched pipeline would be traced, `crash-unpatched` raises SIGSEGV where the unpatched one
//! would, `swap` swaps the push-constant offsets of the contract's first two addresses (a wrong
//! patch: `tests/patch_corpus.rs`).
use super::{Compared, HarnessError, UserModule};
use crate::model::contract::HostContract;
use crate::vk::{features, Gpu, Instance, InstanceOptions};
use serde::{Deserialize, Serialize};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

pub const FAULT_ENV: &str = "RTPROBE_VERIFY_FAULT";

/// One module of a job: its name for messages and its SPIR-V.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct JobModule {
    pub name: String,
    pub words: Vec<u32>,
    /// `--hit-group`'s ray type for this hit shader (`UserModule::ray_type`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ray_type: Option<u32>,
}

impl JobModule {
    /// The module as the harness holds it, with its ray type.
    pub fn user_module(&self) -> Result<UserModule, HarnessError> {
        let mut m = UserModule::new(&self.name, &self.words)?;
        m.ray_type = self.ray_type;
        Ok(m)
    }
}

/// What the parent asks of the child.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct VerifyJob {
    /// The device's index in `features::query_all`.
    pub device_index: usize,
    /// With the validation layer (messages are counted and handed back).
    pub validate: bool,
    /// The modules' blocks need scalar layout.
    pub scalar: bool,
    pub before: Vec<JobModule>,
    pub after: Vec<JobModule>,
    pub contract: HostContract,
    /// The fence deadline of one submission.
    pub timeout_ms: u64,
    /// Where the child writes its [`VerifyOutput`].
    pub result: PathBuf,
}

/// What a failure of the harness was, for the parent's exit code.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FailKind {
    DeviceLost,
    /// A Vulkan error, a failed scene build or a fence timeout.
    Vulkan,
    /// Modules the harness cannot run, or that disagree with each other or the contract.
    Input,
}

/// What the child hands back.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum VerifyOutput {
    Ran { device: String, compared: Vec<Compared>, validation_errors: u64 },
    Failed { kind: FailKind, message: String },
}

impl From<HarnessError> for VerifyOutput {
    fn from(e: HarnessError) -> VerifyOutput {
        let kind = match &e {
            HarnessError::Vk(v) if v.is_device_lost() => FailKind::DeviceLost,
            HarnessError::Vk(_) | HarnessError::Build(_) | HarnessError::Timeout(_) => {
                FailKind::Vulkan
            }
            HarnessError::Unsupported(_) | HarnessError::Interface(_) => FailKind::Input,
        };
        VerifyOutput::Failed { kind, message: e.to_string() }
    }
}

/// One line of progress on stdout.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Step {
    pub step: String,
}

fn say(step: &str) {
    let mut out = std::io::stdout().lock();
    let _ = serde_json::to_writer(&mut out, &Step { step: step.into() });
    let _ = out.write_all(b"\n");
    let _ = out.flush();
}

/// The test hook, where the pipeline it names is traced.
fn misbehave(step: &str) {
    let fault = std::env::var(FAULT_ENV).unwrap_or_default();
    let (fault, at) = match fault.as_str() {
        "crash-unpatched" => ("crash", "trace unpatched"),
        f => (f, "trace patched"),
    };
    if step != at {
        return;
    }
    match fault {
        "crash" => unsafe {
            // Rust's own SIGSEGV handler ignores a raised signal; restore the default first.
            libc::signal(libc::SIGSEGV, libc::SIG_DFL);
            libc::raise(libc::SIGSEGV);
        },
        "hang" => loop {
            std::thread::sleep(Duration::from_secs(3600));
        },
        _ => {}
    }
}

/// The contract as the test hook leaves it: `swap` swaps the offsets of its first two addresses.
fn wrong_contract(c: &HostContract) -> HostContract {
    let mut c = c.clone();
    if std::env::var(FAULT_ENV).as_deref() == Ok("swap") && c.addresses.len() >= 2 {
        let (a, b) = (c.addresses[0].offset, c.addresses[1].offset);
        c.addresses[0].offset = b;
        c.addresses[1].offset = a;
    }
    c
}

fn modules(list: &[JobModule]) -> Result<Vec<UserModule>, HarnessError> {
    list.iter().map(JobModule::user_module).collect()
}

fn run(job: &VerifyJob) -> Result<VerifyOutput, HarnessError> {
    say("setup");
    let (before, after) = (modules(&job.before)?, modules(&job.after)?);
    let inst = Arc::new(Instance::new(&InstanceOptions { validate: job.validate, gpu_av: false })?);
    let all = features::query_all(&inst)?;
    let info = all
        .get(job.device_index)
        .ok_or_else(|| HarnessError::Unsupported("the device vanished".into()))?
        .clone();
    let mut req = super::requirements(job.scalar);
    super::enable_needs(before.iter().chain(&after).map(|m| m.words.as_slice()), &mut req)?;
    let gpu = Gpu::new(inst, info, req)?;
    let messages = crate::vk::instance::validation_error_count();
    let timeout = Duration::from_millis(job.timeout_ms);
    let contract = wrong_contract(&job.contract);
    let (device, compared) =
        super::verify_with(gpu, &before, &after, &contract, timeout, &mut |s: &str| {
            say(s);
            misbehave(s);
        })?;
    let validation_errors = crate::vk::instance::validation_error_count() - messages;
    Ok(VerifyOutput::Ran { device, compared, validation_errors })
}

/// The child's entry: 0 when it wrote its result, 2 otherwise.
pub fn main(job_path: &Path) -> u8 {
    crate::native_crash::install();
    let read = std::fs::read(job_path)
        .map_err(|e| e.to_string())
        .and_then(|b| serde_json::from_slice::<VerifyJob>(&b).map_err(|e| e.to_string()));
    let job = match read {
        Ok(j) => j,
        Err(e) => {
            eprintln!("rtprobe __verify: cannot read job {}: {e}", job_path.display());
            return 2;
        }
    };
    let out = run(&job).unwrap_or_else(VerifyOutput::from);
    let bytes = serde_json::to_vec(&out).expect("a verify result serializes");
    match crate::atomic::write_atomic(&job.result, &bytes) {
        Ok(()) => 0,
        Err(e) => {
            eprintln!("rtprobe __verify: writing {}: {e}", job.result.display());
            2
        }
    }
}
