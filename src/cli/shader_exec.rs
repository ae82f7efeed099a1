//! `run --shader`'s attempts: each variant's traces in child processes (`rtprobe __shader JOB`,
//! `harness::run`), started through `runner::process::run_to_end` as `patch --verify` starts its
//! child: its own process group, dying with rtprobe, killed when silent past its deadline
//! (setup: `--setup-timeout` more; each trace: twice the fence deadline, `--timeout`, plus
//! [`STEP_SLACK`]). A child that dies or hangs in an attempt makes that attempt a `crash` or a
//! `timeout`; a fresh child runs the attempts left. Then every attempt's outputs are compared
//! with the reference, the unpatched pipeline's first attempt, by `harness::compare`.
use super::exit::{self, coded};
use crate::harness::child::{JobModule, Step};
use crate::harness::run::{output_path, AttemptOutput, ShaderJob};
use crate::harness::spec::SpecValue;
use crate::harness::{self, Compared, Part, PartKind, Verdict};
use crate::model::contract::HostContract;
use crate::model::shader_run::{OutputHash, ShaderAttempt, CANNOT_SHOW};
use crate::model::{Attempt, DescriptorModel, Outcome};
use crate::runner::process::{run_to_end, ChildEnd};
use anyhow::{Context, Result};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Silence allowed per trace beyond twice the fence deadline.
const STEP_SLACK: Duration = Duration::from_secs(10);
/// SIGTERM to SIGKILL, and how long a killed child is waited for.
const GRACE: Duration = Duration::from_secs(2);
const KILL_WAIT: Duration = Duration::from_secs(5);

/// What every child of a run shares.
#[derive(Clone)]
pub struct Ctx {
    pub device_index: usize,
    pub validate: bool,
    pub scalar: bool,
    pub unpatched: Vec<JobModule>,
    pub repeat: u32,
    pub timeout: Duration,
    pub setup_timeout: Duration,
    /// The run's scratch folder (job and output files).
    pub dir: PathBuf,
    pub model: DescriptorModel,
    pub spec: Vec<SpecValue>,
    pub heap_layout: Option<Vec<crate::harness::heap::Array>>,
    /// `--array-size` and `--sink-size`.
    pub sizes: crate::harness::Sizes,
    /// `--profile`'s robustness and binding flags.
    pub profile: crate::harness::profile::ProfileSetup,
    /// The children's instance with GPU-AV (a faulting variant's re-run).
    pub gpu_av: bool,
    /// `--fill`'s bytes.
    pub fills: crate::harness::fill::Fills,
    /// `--scene`'s file, and the fills that read it.
    pub scene: Option<PathBuf>,
    pub scene_fills: Vec<crate::harness::scene_data::SceneFill>,
}

/// One attempt as it came back: the record, and the outputs when it ran.
pub struct Ran {
    pub attempt: ShaderAttempt,
    pub parts: Option<Vec<Part>>,
    pub device: Option<String>,
}

/// One child for the attempts `first..=ctx.repeat` of `variant`: how it ended, its last step.
fn child(ctx: &Ctx, variant: &str, job: &ShaderJob) -> Result<(ChildEnd, String, Duration)> {
    let path = ctx.dir.join(format!("{variant}-job-{}.json", job.first));
    let bytes = serde_json::to_vec(job).context("the --shader job")?;
    crate::atomic::write_atomic(&path, &bytes)
        .map_err(|e| coded(exit::BAD_INPUT, format!("writing {}: {e}", path.display())))?;
    let step_silence = ctx.timeout * 2 + STEP_SLACK;
    let mut step = String::from("start");
    let end = run_to_end(
        "__shader",
        &path,
        step_silence + ctx.setup_timeout,
        (GRACE, KILL_WAIT),
        &mut |line| {
            if let Ok(s) = serde_json::from_str::<Step>(line) {
                step = s.step;
            }
            if step == "setup" {
                step_silence + ctx.setup_timeout
            } else {
                step_silence
            }
        },
    )
    .context("starting a --shader child")?;
    Ok((end, step, step_silence))
}

/// The attempt an output file holds; the first validation message is the detail of an attempt
/// that ran.
fn read_output(path: &Path, wall_ms: f64) -> Option<Ran> {
    let out: AttemptOutput = serde_json::from_slice(&std::fs::read(path).ok()?).ok()?;
    Some(match out {
        AttemptOutput::Ran { device, parts, validation_messages, validation_texts, kinds } => {
            let outputs = parts
                .iter()
                .map(|p| OutputHash {
                    label: p.label.clone(),
                    hash: super::shader_plan::hash_hex(&p.bytes),
                })
                .collect();
            let mut attempt = Attempt::new(Outcome::Pass, true).with_wall_ms(wall_ms);
            if let Some(first) = validation_texts.first() {
                attempt = attempt.with_detail(format!("validation: {first}"));
            }
            let attempt = ShaderAttempt {
                attempt,
                validation_messages,
                invalid_access: kinds.invalid_access,
                validation_warnings: kinds.warnings,
                validation: validation_texts,
                outputs,
                differs: None,
                against: None,
            };
            Ran { attempt, parts: Some(parts), device: Some(device) }
        }
        AttemptOutput::Failed {
            outcome,
            message,
            validation_messages,
            validation_texts,
            kinds,
        } => {
            let attempt = Attempt::new(outcome, true).with_detail(message).with_wall_ms(wall_ms);
            let attempt = ShaderAttempt {
                attempt,
                validation_messages,
                invalid_access: kinds.invalid_access,
                validation_warnings: kinds.warnings,
                validation: validation_texts,
                outputs: vec![],
                differs: None,
                against: None,
            };
            Ran { attempt, parts: None, device: None }
        }
    })
}

/// A variant's attempts and how a child that wrote every output then ended badly ended (a crash
/// or a hang in teardown: not an attempt's, but the run's to report).
pub struct VariantRun {
    pub ran: Vec<Ran>,
    pub teardown: Option<String>,
}

/// Whether a child ended as a child that finished does: status 0, not killed.
fn clean(end: &ChildEnd) -> bool {
    !end.timed_out && end.exit.signal.is_none() && end.exit.code == Some(0)
}

/// Every attempt of one variant, `ctx.repeat` of them, each a fresh child's after a fault.
pub fn run_variant(
    ctx: &Ctx,
    variant: &str,
    modules: &[JobModule],
    contract: Option<&HostContract>,
) -> Result<VariantRun> {
    let mut out: Vec<Ran> = Vec::new();
    let mut teardown = None;
    let mut k = 1;
    while k <= ctx.repeat {
        let job = ShaderJob {
            device_index: ctx.device_index,
            validate: ctx.validate,
            scalar: ctx.scalar,
            unpatched: ctx.unpatched.clone(),
            modules: modules.to_vec(),
            contract: contract.cloned(),
            variant: variant.into(),
            first: k,
            last: ctx.repeat,
            timeout_ms: ctx.timeout.as_millis() as u64,
            setup_timeout_ms: Some(ctx.setup_timeout.as_millis() as u64),
            dir: ctx.dir.clone(),
            model: Some(ctx.model),
            spec: ctx.spec.clone(),
            profile: ctx.profile,
            gpu_av: ctx.gpu_av,
            heap_layout: ctx.heap_layout.clone(),
            sizes: ctx.sizes,
            fills: ctx.fills.clone(),
            scene: ctx.scene.clone(),
            scene_fills: ctx.scene_fills.clone(),
        };
        let started = Instant::now();
        let (end, step, silence) = child(ctx, variant, &job)?;
        let first = k;
        let per = started.elapsed().as_secs_f64() * 1000.0;
        while k <= ctx.repeat {
            let Some(r) = read_output(&output_path(&ctx.dir, variant, k), per / ctx.repeat as f64)
            else {
                break;
            };
            out.push(r);
            k += 1;
        }
        // A child stops by itself only after a failed attempt (a device loss, a fence timeout,
        // a failed setup): a fresh one runs the rest. Else it died or hung in attempt k.
        let stopped = k > first && out.last().is_some_and(|r| r.parts.is_none());
        if k > ctx.repeat && !stopped && !clean(&end) {
            let line = end.describe("the child process", &step, silence);
            teardown = Some(format!("after its last attempt, {line}"));
        }
        if k > ctx.repeat || stopped {
            continue;
        }
        let line = end.describe("the child process", &step, silence);
        let outcome = if end.timed_out { Outcome::Timeout } else { Outcome::Crash };
        let attempt = Attempt::new(outcome, true)
            .with_detail(line)
            .with_exit(end.exit.clone())
            .with_wall_ms(started.elapsed().as_secs_f64() * 1000.0);
        let attempt = ShaderAttempt::bare(attempt);
        out.push(Ran { attempt, parts: None, device: None });
        k += 1;
    }
    Ok(VariantRun { ran: out, teardown })
}

fn unit(kind: PartKind) -> &'static str {
    match kind {
        PartKind::Image => "texels",
        PartKind::Buffer => "4-byte words",
    }
}

/// The first output `compared` says differs, in `harness::compare`'s numbers.
fn first_difference(compared: &[Compared]) -> Option<&Compared> {
    compared.iter().find(|c| c.differing > 0)
}

/// Attempts after the first that ran compared in full with it: a difference is `what`'s
/// instability (`the unpatched pipeline`, or a patched variant's own when the unpatched one
/// produced nothing to compare with).
fn compare_among(device: &str, ran: &mut [Ran], what: &str) -> Option<Vec<Part>> {
    let k0 = ran.iter().position(|r| r.parts.is_some())?;
    let reference = ran[k0].parts.clone()?;
    for (k, r) in ran.iter_mut().enumerate().skip(k0 + 1) {
        let Some(parts) = &r.parts else { continue };
        let c = harness::compare(&reference, &reference, parts);
        r.attempt.differs = first_difference(&c).map(|d| {
            format!(
                "attempt {}'s {} differs from attempt {}'s in {} of {} {} on {device}: {what} is not deterministic",
                k + 1,
                d.label,
                k0 + 1,
                d.differing,
                d.texels,
                unit(d.kind)
            )
        });
    }
    Some(reference)
}

/// Why patched variants were not compared with the unpatched pipeline.
pub const UNCOMPARED: &str = "not compared with the unpatched pipeline: it produced no outputs";

/// What [`compare_all`] found beyond each attempt's `differs`.
#[derive(Debug, Default, PartialEq)]
pub struct Judged {
    /// A note when nothing compared can tell a wrong read from a right one.
    pub note: Option<String>,
    /// Set when the unpatched pipeline produced no outputs ([`UNCOMPARED`]): each patched
    /// variant's attempts were compared among themselves only.
    pub uncompared: Option<&'static str>,
}

/// Judge every attempt's outputs against the reference — the unpatched pipeline's first
/// attempt that ran (`again`: its second, whose unstable units patched variants leave out).
/// Unpatched attempts are compared in full (a difference is instability); a patched one in
/// `harness::judge`'s words. Without any unpatched outputs, each patched variant's attempts
/// are compared among themselves, and never called identical to the unpatched ones.
pub fn compare_all(
    device: &str,
    unpatched: &mut [Ran],
    patched: &mut [(String, Vec<Ran>)],
) -> Judged {
    let cannot = |w: String| Some(format!("{CANNOT_SHOW}: {w}"));
    let unfit = |p: &[Part]| match harness::judge(device, &harness::compare(p, p, p)) {
        Verdict::Unfit(why) => cannot(why),
        Verdict::Differs(_) | Verdict::Identical(_) => None,
    };
    let Some(reference) = compare_among(device, unpatched, "the unpatched pipeline") else {
        let mut note = None;
        for (name, ran) in patched.iter_mut() {
            let what = format!("the {name} pipeline");
            if let Some(r) = compare_among(device, ran, &what) {
                note = note.or_else(|| unfit(&r));
            }
        }
        return Judged { note, uncompared: (!patched.is_empty()).then_some(UNCOMPARED) };
    };
    let again = unpatched
        .iter()
        .filter_map(|r| r.parts.as_ref())
        .nth(1)
        .cloned()
        .unwrap_or_else(|| reference.clone());
    let mut note = None;
    for (name, ran) in patched.iter_mut() {
        for r in ran.iter_mut() {
            let Some(parts) = &r.parts else { continue };
            match harness::judge(device, &harness::compare(&reference, &again, parts)) {
                Verdict::Differs(line) => r.attempt.differs = Some(format!("{name}: {line}")),
                Verdict::Identical(_) => {}
                Verdict::Unfit(why) => note = cannot(why),
            }
        }
    }
    Judged { note: unfit(&reference).or(note), uncompared: None }
}
