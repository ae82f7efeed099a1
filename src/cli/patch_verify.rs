//! `rtprobe patch --verify`: the unpatched and the patched pipeline run on the device in a child
//! process (`rtprobe __verify JOB`, `harness::child`), started through
//! `runner::process::run_to_end` like the supervisor's workers: its own process group, dying
//! with this process, killed when silent past its deadline (setup: [`SETUP_SILENCE`] more; each
//! step: twice the fence deadline plus [`STEP_SLACK`]). A child that crashes or hangs on a user's
//! shader is the verification's outcome, one line and a non-zero exit; rtprobe itself never
//! goes down with the driver.
use super::args::PatchArgs;
use super::commands::Globals;
use super::exit::{self, coded};
use super::patch_inputs::Input;
use crate::harness::child::{FailKind, JobModule, Step, VerifyJob, VerifyOutput};
use crate::harness::{self, UserModule, Verdict};
use crate::model::contract::HostContract;
use crate::runner::process::{run_to_end, ChildEnd};
use anyhow::{Context, Result};
use std::path::PathBuf;
use std::time::Duration;

/// Silence allowed before the child's first step, on top of a step's.
const SETUP_SILENCE: Duration = Duration::from_secs(60);
/// Silence allowed per step beyond twice the fence deadline.
const STEP_SLACK: Duration = Duration::from_secs(10);
/// SIGTERM to SIGKILL, and how long a killed child is waited for.
const GRACE: Duration = Duration::from_secs(2);
const KILL_WAIT: Duration = Duration::from_secs(5);

/// Reflect every module here first: one the harness cannot run is refused before any child.
/// Their bindings too: two kinds at one set and binding are refused here, not in the child.
fn reflect(inputs: &[Input], words: &[&[u32]]) -> Result<Vec<JobModule>> {
    let bad = |e: harness::HarnessError| coded(exit::BAD_INPUT, format!("--verify: {e}"));
    let modules: Vec<UserModule> = inputs
        .iter()
        .zip(words)
        .map(|(i, w)| UserModule::new(&i.name, w).map_err(bad))
        .collect::<Result<_>>()?;
    harness::check_bindings(&modules).map_err(bad)?;
    Ok(modules
        .into_iter()
        .map(|m| JobModule { name: m.name, words: m.words, ray_type: m.ray_type })
        .collect())
}

/// The device `--device` names, checked for what the harness needs for `modules`: its index.
fn device(g: &Globals, a: &PatchArgs, scalar: bool, modules: &[&JobModule]) -> Result<usize> {
    let inst = super::commands::open_instance(g)?;
    let all = crate::vk::features::query_all(&inst)?;
    let info = crate::vk::features::select(&all, a.device.as_deref())?;
    let mut req = harness::requirements(scalar);
    harness::enable_needs(modules.iter().map(|m| m.words.as_slice()), &mut req)
        .map_err(|e| coded(exit::BAD_INPUT, format!("--verify: {e}")))?;
    let missing = req.missing_on(info);
    if !missing.is_empty() {
        return Err(coded(
            exit::UNSUPPORTED_DEVICE,
            format!(
                "--verify: {} cannot run the pipelines: missing {}",
                info.name(),
                missing.join(", ")
            ),
        ));
    }
    Ok(info.index)
}

/// `--verify`: the lines saying the outputs are identical, or the error saying why not.
pub fn verify(
    g: &Globals,
    a: &PatchArgs,
    inputs: &[Input],
    patched: &[Vec<u32>],
    contract: &HostContract,
    scalar: bool,
) -> Result<Vec<String>> {
    let before = reflect(inputs, &inputs.iter().map(|i| i.words.as_slice()).collect::<Vec<_>>())?;
    let after = reflect(inputs, &patched.iter().map(|w| w.as_slice()).collect::<Vec<_>>())?;
    let device_index = device(g, a, scalar, &before.iter().chain(&after).collect::<Vec<_>>())?;
    // An interrupt kills the child and removes the work folder; nothing is written yet.
    crate::runner::groups::handle_interrupts(crate::runner::groups::Left::Nothing);
    let work = super::paths::work_dir("rtprobe-verify")?;
    let dir = work.path();
    let job = VerifyJob {
        device_index,
        validate: g.validate,
        scalar,
        before,
        after,
        contract: contract.clone(),
        timeout_ms: a.verify_timeout.clamp(1, 3600) * 1000,
        result: dir.join("result.json"),
    };
    let (out, stderr) = run_child(&job, dir.join("job.json"))?;
    outcome(out, &stderr)
}

/// How the child ended: its output, or the line saying how it died and the step it died at.
type Ended = std::result::Result<VerifyOutput, (String, String)>;

/// Run the child on `job`: how it ended, and the tail of its stderr.
fn run_child(job: &VerifyJob, job_path: PathBuf) -> Result<(Ended, String)> {
    let bytes = serde_json::to_vec(job).context("the --verify job")?;
    crate::atomic::write_atomic(&job_path, &bytes)
        .with_context(|| format!("writing {}", job_path.display()))?;
    let step_silence = Duration::from_millis(job.timeout_ms) * 2 + STEP_SLACK;
    let mut step = String::from("start");
    let end = run_to_end(
        "__verify",
        &job_path,
        step_silence + SETUP_SILENCE,
        (GRACE, KILL_WAIT),
        &mut |line| {
            if let Ok(s) = serde_json::from_str::<Step>(line) {
                step = s.step;
            }
            if step == "setup" || step == "scene" {
                step_silence + SETUP_SILENCE
            } else {
                step_silence
            }
        },
    )
    .context("starting the --verify child")?;
    let out = std::fs::read(&job.result)
        .ok()
        .and_then(|b| serde_json::from_slice::<VerifyOutput>(&b).ok());
    let ended = out.ok_or_else(|| (died(&end, &step, step_silence), step.clone()));
    Ok((ended, end.exit.stderr_tail))
}

/// The line for a child that ended without its result: killed for silence, or dead.
pub fn died(end: &ChildEnd, step: &str, silence: Duration) -> String {
    end.describe("the pipelines' child process", step, silence)
}

/// The error for a child that died at `step`. At `trace unpatched` the input itself faults on the
/// harness's resources, so nothing can be said about the patch (bad input); at `trace patched`,
/// after the unpatched pipeline ran, the patched one faulted: through addresses it may read past
/// a buffer whose descriptor reads the driver bounds-checked (lavapipe does, for descriptors).
fn died_error(line: &str, step: &str) -> anyhow::Error {
    if step.starts_with("trace unpatched") {
        return coded(exit::BAD_INPUT, format!("--verify: {line}: the harness cannot run this input (the unpatched pipeline faults on the harness's scene and resources, so the run says nothing about the patch); nothing written; `rtprobe run --shader` runs the same patches with a check of the shader's descriptor indices, which sizes runtime arrays to the harness's data (docs/your-shader.md)"));
    }
    if step.starts_with("trace patched") {
        return coded(exit::DEVICE_LOST, format!("--verify: {line}: the patched pipeline faulted where the unpatched one ran; through device addresses it may read past a buffer whose descriptor reads the driver bounds-checked (check the shader's indices and the host contract); nothing written"));
    }
    coded(exit::DEVICE_LOST, format!("--verify: {line} (the driver crashed or hung before the pipelines ran); nothing written"))
}

/// The verification's outcome as lines or a coded error; nothing is written on an error.
/// `stderr`: the child's (where the validation layer's messages went).
fn outcome(out: Ended, stderr: &str) -> Result<Vec<String>> {
    let (device, compared, messages) = match out {
        Err((line, step)) => return Err(died_error(&line, &step)),
        Ok(VerifyOutput::Failed { kind, message }) => {
            let code = match kind {
                FailKind::DeviceLost => exit::DEVICE_LOST,
                FailKind::Vulkan => exit::VULKAN_ERROR,
                FailKind::Input => exit::BAD_INPUT,
            };
            return Err(coded(code, format!("--verify: {message}")));
        }
        Ok(VerifyOutput::Ran { device, compared, validation_errors }) => {
            (device, compared, validation_errors)
        }
    };
    if messages > 0 {
        let first = stderr.lines().find(|l| l.contains("VUID") || l.contains("Validation"));
        let first = first.map(|l| format!(" (one: {})", l.chars().take(300).collect::<String>()));
        return Err(coded(exit::VULKAN_ERROR, format!("--verify: {messages} validation messages while running the pipelines on {device}{}; nothing written", first.unwrap_or_default())));
    }
    match harness::judge(&device, &compared) {
        Verdict::Identical(lines) => Ok(lines),
        Verdict::Differs(line) => {
            Err(coded(exit::FINDINGS, format!("--verify: {line}; nothing written")))
        }
        Verdict::Unfit(why) => {
            Err(coded(exit::BAD_INPUT, format!("--verify: {why} (nothing written)")))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::WorkerExit;

    fn end(signal: Option<i32>, timed_out: bool) -> ChildEnd {
        let exit = WorkerExit {
            code: None,
            signal,
            stderr_tail: "llvmpipe: boom\n".into(),
            abandoned: None,
        };
        ChildEnd { exit, timed_out }
    }

    #[test]
    fn a_dead_or_silent_child_is_one_line_with_where_and_why() {
        let d = died(&end(Some(libc::SIGSEGV), false), "trace patched", Duration::from_secs(70));
        assert_eq!(d, "the pipelines' child process died of signal 11 (SIGSEGV) at `trace patched`; stderr: llvmpipe: boom");
        let t = died(&end(Some(libc::SIGTERM), true), "trace unpatched", Duration::from_secs(12));
        assert!(t.contains("was silent for 12s and was killed at `trace unpatched`"), "{t}");
        let e = outcome(Err((d, "trace patched".into())), "").unwrap_err();
        assert_eq!(exit::code_for(&e), exit::DEVICE_LOST);
        let l = exit::one_line(&e);
        assert!(!l.contains('\n') && l.contains("the patched pipeline faulted"), "{l}");
        assert!(!l.contains("driver crashed"), "{l}");
        let e = outcome(Err((t, "trace unpatched".into())), "").unwrap_err();
        assert_eq!(exit::code_for(&e), exit::BAD_INPUT);
        assert!(exit::one_line(&e).contains("the harness cannot run this input"));
        assert!(exit::one_line(&e).contains("rtprobe run --shader"));
    }
}
