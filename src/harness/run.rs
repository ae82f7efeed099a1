//! `rtprobe __shader JOB.json`: `run --shader`'s device work, one variant of the user's pipeline
//! (unpatched, or one workaround patch fed as its host contract says) traced for a range of
//! attempts in a process of its own, started by `rtprobe run --shader` through
//! `runner::process::run_to_end` (own process group, dying with its parent, killed when silent).
//! The harness's resources are always made for the unpatched modules, as `patch --verify` makes
//! them, so every variant reads the same data. Each attempt says `trace K` on stdout before it
//! traces and writes its [`AttemptOutput`] to `DIR/VARIANT-K.json` (tmp + rename): its written
//! outputs (every storage image, every writable storage buffer) and the validation messages it
//! caused. After a device loss or a fence timeout the child stops (the device is gone): the
//! parent starts a fresh one for the attempts left, and an attempt the child died in is the
//! parent's to record (crash or timeout).
//!
//! Test hook: `RTPROBE_SHADER_FAULT=KIND[:VARIANT[:K]]` (VARIANT default `unpatched`, K: the
//! 1-based attempt, default every one): `crash` raises SIGSEGV, `hang` sleeps forever where
//! that attempt would trace, `flip` flips the first byte of its first output (a difference),
//! `teardown` raises SIGSEGV after the child wrote attempt K's output, before its teardown.
use super::child::JobModule;
use super::reflect::BindingKind;
use super::spec::SpecValue;
use super::supply;
use super::{Harness, HarnessError, Part, UserModule};
use crate::interface::{BindingDesc, DescriptorKind, HitGroup, PipelineDesc, PushRange};
use crate::model::contract::HostContract;
use crate::model::validation_message::MessageCounts;
use crate::model::{DescriptorModel, Outcome};
use crate::scene::gpu::BuildError;
use crate::vk::{features, Gpu, Instance, InstanceOptions};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

pub const FAULT_ENV: &str = "RTPROBE_SHADER_FAULT";

/// What the parent asks of the child.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ShaderJob {
    /// The device's index in `features::query_all`.
    pub device_index: usize,
    pub validate: bool,
    /// The modules' blocks need scalar layout.
    pub scalar: bool,
    /// The unpatched pipeline: the harness's resources are made for it.
    pub unpatched: Vec<JobModule>,
    /// This variant's modules, and the contract that feeds them (a patched variant).
    pub modules: Vec<JobModule>,
    #[serde(default)]
    pub contract: Option<HostContract>,
    /// The variant's name (`unpatched`, or the patch's): the output files' prefix.
    pub variant: String,
    /// The attempts to run, 1-based: `first ..= last`.
    pub first: u32,
    pub last: u32,
    /// The fence deadline of one submission.
    pub timeout_ms: u64,
    /// The fence deadline of the setup's submissions (`--setup-timeout`; absent: `timeout_ms`).
    #[serde(default)]
    pub setup_timeout_ms: Option<u64>,
    /// Where the outputs go.
    pub dir: PathBuf,
    /// How descriptors are bound (absent: descriptor indexing).
    #[serde(default)]
    pub model: Option<DescriptorModel>,
    /// `--spec`'s values.
    #[serde(default)]
    pub spec: Vec<SpecValue>,
    /// `--heap-layout`'s arrays.
    #[serde(default)]
    pub heap_layout: Option<Vec<super::heap::Array>>,
    /// `--array-size` and `--sink-size`.
    #[serde(default)]
    pub sizes: super::Sizes,
    /// `--profile`: robustness features and binding flags.
    #[serde(default)]
    pub profile: super::profile::ProfileSetup,
    /// The validation layer with GPU-AV (a re-run of a faulting variant).
    #[serde(default)]
    pub gpu_av: bool,
    /// `--fill`'s bytes.
    #[serde(default)]
    pub fills: super::fill::Fills,
    /// `--scene`: the glTF file traced instead of the harness scene.
    #[serde(default)]
    pub scene: Option<PathBuf>,
    /// `--fill TARGET=scene.NAME`: placed by the child from the loaded scene.
    #[serde(default)]
    pub scene_fills: Vec<super::scene_data::SceneFill>,
}

/// An attempt's messages beside its error count (`model::validation_message`): the errors that
/// report an invalid access, and the warnings.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Kinds {
    pub invalid_access: u64,
    pub warnings: u64,
}

/// What one attempt came to.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AttemptOutput {
    Ran {
        device: String,
        parts: Vec<Part>,
        validation_messages: u64,
        /// The first few messages' text, with their VUIDs.
        #[serde(default)]
        validation_texts: Vec<String>,
        /// Of the messages, those that report an invalid access, and the warnings.
        #[serde(default)]
        kinds: Kinds,
    },
    Failed {
        outcome: Outcome,
        message: String,
        validation_messages: u64,
        #[serde(default)]
        validation_texts: Vec<String>,
        #[serde(default)]
        kinds: Kinds,
    },
}

/// The pipeline's modules as the harness runs them: the given ones, with a raygen and a miss
/// supplied where they have none (`super::supply`; the child supplies them again, at the same
/// bindings for every variant).
pub fn full_pipeline(modules: Vec<UserModule>) -> Result<Vec<UserModule>, HarnessError> {
    super::supply::supply(modules)
}

/// Whether the harness can make a pipeline of `modules`: one raygen, a miss, hit shaders and
/// callables, as [`Harness`] groups them, and one descriptor for every set and binding
/// (`super::bindings`: aliased buffer blocks merge, other kinds sharing a binding are refused).
pub fn check_pipeline(modules: &[UserModule]) -> Result<(), HarnessError> {
    let refs: Vec<&UserModule> = modules.iter().collect();
    super::groups(&refs)?;
    super::bindings::check(modules)
}

/// What the harness's pipeline provides `modules` (`interface::check` holds them to it): every
/// binding the modules reflect, aliases merged (`super::bindings`; where they cannot be, the
/// first declaration of a set and binding), seen by
/// every ray tracing stage; the push range of the longest block; the device's hit-attribute
/// limit; per ray type the two hit groups [`Harness`] makes (the procedural one with the
/// harness's own intersection shader, not among `modules`, when none is given).
pub fn pipeline_desc(modules: &[UserModule], max_hit_attribute: u32) -> PipelineDesc {
    let stages = super::resources::rt_stages();
    let mut bindings: Vec<BindingDesc> = Vec::new();
    let all: Vec<super::reflect::Binding> =
        modules.iter().flat_map(|m| m.iface.bindings.iter().cloned()).collect();
    let merged = super::bindings::merged(&all).map(|m| m.into_values().collect());
    for b in merged.as_ref().unwrap_or(&all) {
        if bindings.iter().any(|d| (d.set, d.binding) == (b.set, b.binding)) {
            continue;
        }
        let kind = match b.kind {
            BindingKind::AccelerationStructure => DescriptorKind::AccelerationStructure,
            BindingKind::StorageImage(_) => DescriptorKind::StorageImage,
            BindingKind::StorageBuffer(_) => DescriptorKind::StorageBuffer,
            BindingKind::UniformBuffer(_) => DescriptorKind::UniformBuffer,
            BindingKind::SampledImage => DescriptorKind::SampledImage,
            BindingKind::Sampler => DescriptorKind::Sampler,
            BindingKind::CombinedImageSampler => DescriptorKind::CombinedImageSampler,
        };
        bindings.push(BindingDesc { set: b.set, binding: b.binding, kind, count: b.count, stages });
    }
    let push = modules.iter().map(|m| m.iface.push_end).max().unwrap_or(0);
    let refs: Vec<&UserModule> = modules.iter().collect();
    let hit_groups = super::groups(&refs).map_or_else(
        |_| vec![],
        |g| {
            g.types
                .iter()
                .flat_map(|t| {
                    let (closest_hit, any_hit) = (t.hit[0], t.any_hit);
                    [
                        HitGroup { closest_hit, any_hit, intersection: None },
                        HitGroup { closest_hit: t.hit[1], any_hit, intersection: t.intersection },
                    ]
                })
                .collect()
        },
    );
    PipelineDesc {
        bindings,
        push: (push > 0).then_some(PushRange { offset: 0, size: push.div_ceil(4) * 4, stages }),
        max_hit_attribute,
        hit_groups,
    }
}

/// The variable-sized bindings the harness makes for `modules` (the full pipeline) under
/// `flags` on `info`, in words (`super::variable`): what each child's layouts and allocations
/// will be.
pub fn variable_counts(
    modules: &[UserModule],
    flags: &crate::model::profile::BindingFlags,
    info: &crate::vk::DeviceInfo,
) -> Vec<String> {
    let all: Vec<super::reflect::Binding> =
        modules.iter().flat_map(|m| m.iface.bindings.iter().cloned()).collect();
    let Ok(merged) = super::bindings::merged(&all) else { return Vec::new() };
    let counts = super::variable::counts(&merged, flags, &super::variable::limits(info));
    super::variable::words(&counts)
}

/// The file attempt `k` of `variant` writes.
pub fn output_path(dir: &Path, variant: &str, k: u32) -> PathBuf {
    dir.join(format!("{variant}-{k}.json"))
}

/// The outcome of a harness failure: a device loss, a fence timeout, else rtprobe's `error`.
pub fn outcome_of(e: &HarnessError) -> Outcome {
    match e {
        HarnessError::Vk(v) if v.is_device_lost() => Outcome::DeviceLost,
        // A setup's build past `--setup-timeout` is a timeout as a trace past `--timeout` is.
        HarnessError::Timeout(_) | HarnessError::Build(BuildError::TimedOut(_)) => Outcome::Timeout,
        HarnessError::Vk(_)
        | HarnessError::Build(BuildError::Vk(_))
        | HarnessError::Unsupported(_)
        | HarnessError::Interface(_) => Outcome::Error,
    }
}

fn say(step: &str) {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    let _ = serde_json::to_writer(&mut out, &super::child::Step { step: step.into() });
    let _ = out.write_all(b"\n");
    let _ = out.flush();
}

/// The test hook's fault for attempt `k` of `variant`, if it names it.
fn hook(variant: &str, k: u32) -> Option<String> {
    let spec = std::env::var(FAULT_ENV).ok()?;
    let mut it = spec.split(':');
    let kind = it.next()?.to_string();
    let v = it.next().unwrap_or("unpatched");
    let at = it.next().and_then(|a| a.parse::<u32>().ok());
    (v == variant && at.is_none_or(|a| a == k)).then_some(kind)
}

fn misbehave(kind: Option<&str>) {
    match kind {
        Some("crash") => unsafe {
            // Rust's own SIGSEGV handler ignores a raised signal; restore the default first.
            libc::signal(libc::SIGSEGV, libc::SIG_DFL);
            libc::raise(libc::SIGSEGV);
        },
        Some("hang") => loop {
            std::thread::sleep(Duration::from_secs(3600));
        },
        _ => {}
    }
}

fn write(job: &ShaderJob, k: u32, out: &AttemptOutput) -> Result<(), String> {
    let bytes = serde_json::to_vec(out).map_err(|e| e.to_string())?;
    crate::atomic::write_atomic(&output_path(&job.dir, &job.variant, k), &bytes)
        .map_err(|e| e.to_string())
}

fn modules(list: &[JobModule]) -> Result<Vec<UserModule>, HarnessError> {
    list.iter().map(JobModule::user_module).collect()
}

/// The harness of `job`: its device, the unpatched pipeline's resources, a push range that fits
/// every module and the contract.
fn harness(job: &ShaderJob) -> Result<(Harness, Vec<UserModule>), HarnessError> {
    let (unpatched, variant) = (modules(&job.unpatched)?, modules(&job.modules)?);
    // Stages the modules lack supplied, at the same bindings in every variant (as `verify_with`).
    let at = supply::free_binding(&unpatched).max(supply::free_binding(&variant));
    let (unpatched, variant) = (supply::supply_at(unpatched, at)?, supply::supply_at(variant, at)?);
    let (unpatched, variant) = (job.sizes.apply(unpatched), job.sizes.apply(variant));
    let options = InstanceOptions { validate: job.validate || job.gpu_av, gpu_av: job.gpu_av };
    let inst = Arc::new(Instance::new(&options)?);
    let all = features::query_all(&inst)?;
    let info = all
        .get(job.device_index)
        .ok_or_else(|| HarnessError::Unsupported("the device vanished".into()))?
        .clone();
    let model = job.model.unwrap_or(DescriptorModel::DescriptorIndexing);
    let mut req = super::requirements_for(job.scalar, model);
    req.robustness = job.profile.robustness();
    super::enable_needs(unpatched.iter().chain(&variant).map(|m| m.words.as_slice()), &mut req)?;
    let gpu = Gpu::new(inst, info, req)?;
    let push = unpatched
        .iter()
        .chain(&variant)
        .map(|m| m.iface.push_end)
        .max()
        .unwrap_or(0)
        .max(job.contract.as_ref().map_or(0, |c| c.push_end));
    let refs: Vec<&UserModule> = unpatched.iter().collect();
    let scene = match &job.scene {
        Some(p) => Some(super::SceneSetup {
            loaded: crate::scene::gltf::Loaded::load(p)
                .map_err(|e| HarnessError::Unsupported(e.to_string()))?,
            fills: job.scene_fills.clone(),
        }),
        None => None,
    };
    let setup = super::Setup {
        model,
        spec: job.spec.clone(),
        heap_layout: job.heap_layout.clone(),
        sink: job.sizes.sink,
        profile: job.profile,
        fills: job.fills.clone(),
        scene,
        setup_timeout: job.setup_timeout_ms.map(Duration::from_millis),
    };
    let h = Harness::with_setup(gpu, &refs, push, Duration::from_millis(job.timeout_ms), setup)?;
    Ok((h, variant))
}

/// Run the job's attempts; an error is the write's.
fn run(job: &ShaderJob) -> Result<(), String> {
    say("setup");
    let mut seen = crate::vk::instance::validation_counts();
    let messages = |seen: &mut MessageCounts| {
        let now = crate::vk::instance::validation_counts();
        let c = now.since(std::mem::replace(seen, now));
        (c.errors, Kinds { invalid_access: c.invalid_access, warnings: c.warnings })
    };
    let (h, variant) = match harness(job) {
        Ok(x) => x,
        Err(e) => {
            let (validation_messages, kinds) = messages(&mut seen);
            let out = AttemptOutput::Failed {
                outcome: outcome_of(&e),
                message: format!("setup: {e}"),
                validation_messages,
                validation_texts: crate::vk::instance::take_validation_texts(),
                kinds,
            };
            return write(job, job.first, &out);
        }
    };
    let refs: Vec<&UserModule> = variant.iter().collect();
    for k in job.first..=job.last {
        say(&format!("trace {k}"));
        let fault = hook(&job.variant, k);
        misbehave(fault.as_deref());
        let out = match h.trace(&refs, job.contract.as_ref()) {
            Ok(parts) => {
                let mut parts = parts;
                if let (Some("flip"), Some(b)) =
                    (fault.as_deref(), parts.first_mut().and_then(|p| p.bytes.first_mut()))
                {
                    *b ^= 0xFF;
                }
                let (validation_messages, kinds) = messages(&mut seen);
                AttemptOutput::Ran {
                    device: h.device_name(),
                    parts,
                    validation_messages,
                    validation_texts: crate::vk::instance::take_validation_texts(),
                    kinds,
                }
            }
            Err(e) => {
                let outcome = outcome_of(&e);
                let (validation_messages, kinds) = messages(&mut seen);
                let out = AttemptOutput::Failed {
                    outcome,
                    message: e.to_string(),
                    validation_messages,
                    validation_texts: crate::vk::instance::take_validation_texts(),
                    kinds,
                };
                if outcome.ends_worker() {
                    write(job, k, &out)?;
                    // The device is gone: no teardown through it.
                    unsafe { libc::_exit(0) };
                }
                out
            }
        };
        write(job, k, &out)?;
    }
    say("teardown");
    if hook(&job.variant, job.last).as_deref() == Some("teardown") {
        misbehave(Some("crash"));
    }
    Ok(())
}

/// The child's entry: 0 when it wrote its results, 2 otherwise.
pub fn main(job_path: &Path) -> u8 {
    crate::native_crash::install();
    let read = std::fs::read(job_path)
        .map_err(|e| e.to_string())
        .and_then(|b| serde_json::from_slice::<ShaderJob>(&b).map_err(|e| e.to_string()));
    let job = match read {
        Ok(j) => j,
        Err(e) => {
            eprintln!("rtprobe __shader: cannot read job {}: {e}", job_path.display());
            return 2;
        }
    };
    match run(&job) {
        Ok(()) => 0,
        Err(e) => {
            eprintln!("rtprobe __shader: writing a result in {}: {e}", job.dir.display());
            2
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_hook_names_a_variant_and_an_attempt() {
        // One test sets and clears the variable: no other test of this binary reads it.
        std::env::set_var(FAULT_ENV, "crash:unpatched:2");
        assert_eq!(hook("unpatched", 2).as_deref(), Some("crash"));
        assert_eq!(hook("unpatched", 1), None);
        assert_eq!(hook("nonuniform", 2), None);
        std::env::set_var(FAULT_ENV, "flip:nonuniform");
        assert_eq!(hook("nonuniform", 3).as_deref(), Some("flip"));
        assert_eq!(hook("unpatched", 3), None);
        std::env::remove_var(FAULT_ENV);
        assert_eq!(hook("unpatched", 1), None);
    }

    #[test]
    fn faults_end_the_child_and_input_errors_do_not() {
        assert_eq!(outcome_of(&HarnessError::Timeout(Duration::from_secs(1))), Outcome::Timeout);
        let build = HarnessError::Build(BuildError::TimedOut(Duration::from_millis(10)));
        assert_eq!(outcome_of(&build), Outcome::Timeout);
        assert_eq!(outcome_of(&HarnessError::Unsupported("x".into())), Outcome::Error);
        assert!(outcome_of(&HarnessError::Timeout(Duration::ZERO)).ends_worker());
    }
}
