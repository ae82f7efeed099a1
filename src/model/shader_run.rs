//! `run --shader`'s report (`rtprobe.shader-run/1`): the user's inputs with their hashes, the
//! cell id naming them, each variant of their pipeline (unpatched, and each workaround patch
//! that applies) with its attempts, and the verdicts judged from the attempts alone — there is
//! no CPU reference for a user's shader ([`judge_variant`]). A fault (device lost, crash,
//! timeout) is a finding with its incidence; an attempt with validation messages, or one
//! rtprobe could not run, is an `error` (no evidence about the driver); unpatched attempts whose
//! outputs differ from the first are `unstable` (outcome `mismatch`); a patched variant whose
//! outputs differ from the unpatched ones is a `mismatch` naming the patch.
use super::shader_options::CellOptions;
use super::shader_outputs::{CompareInfo, OutputData};
use super::{Attempt, Incidence, Outcome};
use serde::{Deserialize, Serialize};

pub const SCHEMA: &str = "rtprobe.shader-run/1";

/// How a note that the outputs cannot tell a wrong read from a right one starts.
pub const CANNOT_SHOW: &str = "the outputs cannot show a difference";

/// One input file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ShaderInput {
    pub file: String,
    /// raygen, closest_hit, … (the module's entry point).
    pub stage: String,
    pub entry: String,
    /// FNV-1a 128, hex, of what made the module (`cli::patch_inputs::Input::identity`): a SPIR-V
    /// file's bytes; a GLSL file's contents with every include it reaches, the defines and the
    /// target environment.
    pub hash: String,
}

/// The cell id of a pipeline of user shaders: `shader:` and each file's name with the first 12
/// hex digits of its hash, joined by `+` (`shader:hit.rchit@1a2b3c4d5e6f+…`).
pub fn cell_id(inputs: &[ShaderInput]) -> String {
    let parts: Vec<String> = inputs
        .iter()
        .map(|i| {
            let name = i.file.rsplit('/').next().unwrap_or(&i.file);
            format!("{name}@{}", &i.hash[..i.hash.len().min(12)])
        })
        .collect();
    format!("shader:{}", parts.join("+"))
}

/// The cell id of a run of `inputs` with `options` (`--entry`, `--fill`, …): [`cell_id`], then
/// `#` and the options hash's first 12 hex digits when any option was given.
pub fn cell_id_with(inputs: &[ShaderInput], options: &CellOptions) -> String {
    let id = cell_id(inputs);
    if options.is_empty() {
        return id;
    }
    format!("{id}#{}", &options.hash()[..12])
}

/// One written output of an attempt: its label (`set 0 binding 1[0]`, `storage buffer …`) and
/// the FNV-1a 128 hash of its bytes.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct OutputHash {
    pub label: String,
    pub hash: String,
}

/// One trace of one variant.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ShaderAttempt {
    #[serde(flatten)]
    pub attempt: Attempt,
    /// Validation-layer messages while this attempt ran (with `--validate`; the first attempt
    /// of a child also counts its setup's).
    #[serde(default)]
    pub validation_messages: u64,
    /// Of `validation_messages`, the GPU-AV errors that report an invalid access by the shader
    /// (`super::validation_message`; none in older reports).
    #[serde(skip_serializing_if = "is_zero", default)]
    pub invalid_access: u64,
    /// Validation-layer warnings while it ran (GPU-AV's setup among them): counted, no verdict.
    #[serde(skip_serializing_if = "is_zero", default)]
    pub validation_warnings: u64,
    /// The first few validation messages' text, with their VUIDs.
    #[serde(skip_serializing_if = "Vec::is_empty", default)]
    pub validation: Vec<String>,
    #[serde(skip_serializing_if = "Vec::is_empty", default)]
    pub outputs: Vec<OutputHash>,
    /// How its outputs differ from the reference (the unpatched pipeline's first attempt), in
    /// `harness::judge`'s words; `None`: identical, or nothing to compare.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub differs: Option<String>,
    /// How its outputs differ beyond `--tolerance` from the `--compare` report's (a finding);
    /// `None`: within it, or no tolerance given (differences are then notes).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub against: Option<String>,
}

impl ShaderAttempt {
    /// `attempt` alone: no validation message, no output, no difference.
    pub fn bare(attempt: Attempt) -> ShaderAttempt {
        ShaderAttempt {
            attempt,
            validation_messages: 0,
            invalid_access: 0,
            validation_warnings: 0,
            validation: vec![],
            outputs: vec![],
            differs: None,
            against: None,
        }
    }
}

fn is_zero(n: &u64) -> bool {
    *n == 0
}

/// What a variant's attempts come to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Judgement {
    /// Every attempt ran, no message, outputs as the reference's.
    Pass,
    /// Device lost, crash or timeout in some attempt.
    Fault,
    /// Unpatched attempts whose outputs differ from each other.
    Unstable,
    /// A patched variant whose outputs differ from the unpatched ones.
    PatchDiffers,
    /// Outputs that differ beyond `--tolerance` from the `--compare` report's.
    CompareDiffers,
    /// Validation messages: the harness or the input misused the API; not evidence.
    Validation,
    /// rtprobe could not run the attempt (a Vulkan error, an input the harness cannot make).
    Error,
}

impl Judgement {
    pub fn as_str(self) -> &'static str {
        match self {
            Judgement::Pass => "pass",
            Judgement::Fault => "fault",
            Judgement::Unstable => "unstable",
            Judgement::PatchDiffers => "patch_differs",
            Judgement::CompareDiffers => "compare_differs",
            Judgement::Validation => "validation",
            Judgement::Error => "error",
        }
    }
}

/// One variant: the unpatched pipeline (`patch` None) or one workaround patch applied.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ShaderVariant {
    pub name: String,
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub patch: Option<String>,
    /// What the patch did (`rtprobe patch`'s lines) and the host contract it was fed by.
    #[serde(skip_serializing_if = "Vec::is_empty", default)]
    pub patch_lines: Vec<String>,
    pub attempts: Vec<ShaderAttempt>,
    pub outcome: Outcome,
    pub judgement: Judgement,
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub detail: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub incidence: Option<Incidence>,
    /// Why a patched variant's outputs were compared only among its own attempts (the unpatched
    /// pipeline produced none); its differences are then `unstable`.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub uncompared: Option<String>,
    /// How a child that wrote every output then ended (a crash or hang in teardown).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub teardown: Option<String>,
    /// The first attempt's outputs, for another run's `--compare` (`shader_outputs`).
    #[serde(skip_serializing_if = "Vec::is_empty", default)]
    pub data: Vec<OutputData>,
    /// A faulting variant's re-run under GPU-AV (`--validate=gpu-av`), its attempts apart.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub gpu_av: Option<ShaderGpuAv>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GpuAvJudgement {
    /// Every attempt passed with no invalid-access report, enough of them that a fault as
    /// frequent as the variant's would have shown (miss probability below 1%), and the control
    /// (the variant without GPU-AV, in the same round) faulted again: GPU-AV hides the fault.
    Masks,
    /// Every attempt passed, but that is no proof: too few passes for the variant's incidence,
    /// or the control did not fault again (the fault did not repeat in this round).
    Inconclusive,
    /// GPU-AV reported an invalid access by the shader: an `error`, not a finding.
    Reports,
    /// An attempt faulted under GPU-AV too (and no invalid-access report explains it).
    StillFaults,
    /// The attempts under GPU-AV could not run (a harness error): nothing said.
    Error,
}

/// The messages of the attempts under GPU-AV by kind (`super::validation_message`): only
/// `invalid_access` can change the verdict.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct GpuAvMessages {
    /// Errors that report an invalid access by the shader.
    pub invalid_access: u64,
    /// Other errors (GPU-AV's setup, API usage not about the access).
    pub other_errors: u64,
    /// Warnings (GPU-AV's setup, performance).
    pub warnings: u64,
}

/// A faulting variant's re-run under GPU-AV (`super::shader_gpu_av` judges it).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ShaderGpuAv {
    pub attempts: Vec<ShaderAttempt>,
    pub judgement: GpuAvJudgement,
    /// The judgement in words.
    pub line: String,
    /// The control: the variant traced again without GPU-AV in the same round, when every
    /// attempt under GPU-AV passed (`masks` needs it to fault again).
    #[serde(skip_serializing_if = "Vec::is_empty", default)]
    pub control: Vec<ShaderAttempt>,
    /// When every attempt under GPU-AV passed: the chance that they all missed a fault as
    /// frequent as the variant's (`super::stats::pass_miss` on its incidence).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub miss_probability: Option<f64>,
    /// The attempts' messages by kind (none in older reports).
    #[serde(default)]
    pub messages: GpuAvMessages,
}

/// The report `run --shader` writes.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ShaderRunReport {
    pub schema: String,
    pub rtprobe_version: String,
    pub device: String,
    pub cell: String,
    pub options: serde_json::Value,
    pub inputs: Vec<ShaderInput>,
    pub variants: Vec<ShaderVariant>,
    /// The worst variant's outcome.
    pub outcome: Outcome,
    /// Patches that do not apply, or were not run, and why; differential checks that compared
    /// nothing informative; what an injection matched (`ShaderInjection::line`).
    #[serde(skip_serializing_if = "Vec::is_empty", default)]
    pub notes: Vec<String>,
    /// What `--inject-fault` injected (`None`: no injection).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub injection: Option<super::shader_injection::ShaderInjection>,
    /// What `--profile` enabled and bound (`None`: no profile).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub profile: Option<super::profile::ProfileRecord>,
    /// The options that changed what ran, hashed into the cell id (none in older reports).
    #[serde(skip_serializing_if = "CellOptions::is_empty", default)]
    pub cell_options: CellOptions,
    /// What `--compare` compared the run with.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub compare: Option<CompareInfo>,
    /// The descriptor-index check before the variants ran (none in older reports).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub index_bounds: Option<super::index_bounds::IndexBounds>,
    /// The run held to `--baseline` (by `cell id/variant`).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub baseline: Option<super::BaselineCheck>,
}

/// An attempt's own judgement: its fault, an error, its validation messages, its outputs
/// against the reference (`differs`; `unstable` for the unpatched variant), else a pass.
fn judge_attempt(a: &ShaderAttempt, patched: bool) -> (Outcome, Judgement) {
    match a.attempt.outcome {
        o @ (Outcome::DeviceLost | Outcome::Crash | Outcome::Timeout) => (o, Judgement::Fault),
        Outcome::Error | Outcome::Unsupported | Outcome::NotImplemented => {
            (Outcome::Error, Judgement::Error)
        }
        Outcome::Pass | Outcome::Mismatch => {
            if a.validation_messages > 0 {
                (Outcome::Error, Judgement::Validation)
            } else if a.differs.is_some() {
                let j = if patched { Judgement::PatchDiffers } else { Judgement::Unstable };
                (Outcome::Mismatch, j)
            } else if a.against.is_some() {
                (Outcome::Mismatch, Judgement::CompareDiffers)
            } else {
                (Outcome::Pass, Judgement::Pass)
            }
        }
    }
}

/// A variant's verdict: its worst attempt (outcome severity), that attempt's detail (its
/// difference, else its own detail) and, for a finding, the incidence over the attempts that
/// are evidence (not `error`: validation messages or a harness failure say nothing about the
/// driver), with the chance that as many attempts miss a fault of the observed rate.
pub fn judge_variant(
    attempts: &[ShaderAttempt],
    patched: bool,
) -> (Outcome, Judgement, Option<String>, Option<Incidence>) {
    let judged: Vec<(Outcome, Judgement)> =
        attempts.iter().map(|a| judge_attempt(a, patched)).collect();
    let Some(worst) = (0..attempts.len()).max_by_key(|k| (judged[*k].0.severity(), usize::MAX - k))
    else {
        return (Outcome::Error, Judgement::Error, Some("no attempt ran".into()), None);
    };
    let (outcome, judgement) = judged[worst];
    let a = &attempts[worst];
    let detail =
        a.differs.clone().or_else(|| a.against.clone()).or_else(|| a.attempt.detail.clone());
    let evidence: Vec<&(Outcome, Judgement)> =
        judged.iter().filter(|j| j.0 != Outcome::Error).collect();
    let (n, k) = (evidence.len() as u32, evidence.iter().filter(|j| j.0.is_finding()).count());
    let k = k as u32;
    let incidence =
        (outcome.is_finding() && outcome != Outcome::Error && n > 0).then(|| Incidence {
            faulted: k,
            attempts: n,
            reproduced_alone: None,
            miss_probability: super::stats::miss(k as f64 / n as f64, n),
        });
    (outcome, judgement, detail, incidence)
}

impl ShaderVariant {
    /// A variant judged from its attempts ([`judge_variant`]; as the unpatched one's when it
    /// was not compared with the unpatched pipeline).
    pub fn judged(
        name: &str,
        patch: Option<String>,
        patch_lines: Vec<String>,
        attempts: Vec<ShaderAttempt>,
        uncompared: Option<String>,
    ) -> ShaderVariant {
        let differential = patch.is_some() && uncompared.is_none();
        let (outcome, judgement, detail, incidence) = judge_variant(&attempts, differential);
        ShaderVariant {
            name: name.into(),
            patch,
            patch_lines,
            attempts,
            outcome,
            judgement,
            detail,
            incidence,
            uncompared,
            teardown: None,
            gpu_av: None,
            data: vec![],
        }
    }
}

impl ShaderRunReport {
    /// The worst variant's outcome again (after a GPU-AV re-run changed a variant's).
    pub fn refresh_outcome(&mut self) {
        let worst = self.variants.iter().map(|v| v.outcome).max_by_key(|o| o.severity());
        self.outcome = worst.unwrap_or(Outcome::Error);
    }

    /// The variant whose verdict decides the run's: the worst, the first of equals.
    pub fn worst(&self) -> Option<&ShaderVariant> {
        self.variants
            .iter()
            .enumerate()
            .max_by_key(|(k, v)| (v.outcome.severity(), usize::MAX - k))
            .map(|(_, v)| v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn attempt(outcome: Outcome, messages: u64, differs: Option<&str>) -> ShaderAttempt {
        ShaderAttempt {
            validation_messages: messages,
            differs: differs.map(String::from),
            ..ShaderAttempt::bare(
                Attempt::new(outcome, true).with_detail(format!("{}!", outcome.as_str())),
            )
        }
    }

    fn pass() -> ShaderAttempt {
        ShaderAttempt {
            attempt: Attempt::new(Outcome::Pass, true),
            ..attempt(Outcome::Pass, 0, None)
        }
    }

    #[test]
    fn identical_attempts_pass_without_incidence() {
        let (o, j, d, i) = judge_variant(&[pass(), pass(), pass()], false);
        assert_eq!((o, j, d, i), (Outcome::Pass, Judgement::Pass, None, None));
    }

    #[test]
    fn a_crash_in_one_of_three_is_a_fault_with_its_incidence() {
        let (o, j, d, i) =
            judge_variant(&[pass(), attempt(Outcome::Crash, 0, None), pass()], false);
        assert_eq!((o, j, d.as_deref()), (Outcome::Crash, Judgement::Fault, Some("crash!")));
        let i = i.expect("a finding has an incidence");
        assert_eq!((i.faulted, i.attempts), (1, 3));
        assert!((i.miss_probability - (2.0f64 / 3.0).powi(3)).abs() < 1e-12);
    }

    #[test]
    fn a_device_loss_outranks_a_difference() {
        let a =
            [attempt(Outcome::Pass, 0, Some("x differs")), attempt(Outcome::DeviceLost, 0, None)];
        let (o, j, _, i) = judge_variant(&a, true);
        assert_eq!((o, j), (Outcome::DeviceLost, Judgement::Fault));
        assert_eq!(i.map(|i| (i.faulted, i.attempts)), Some((2, 2)));
    }

    #[test]
    fn differing_unpatched_attempts_are_unstable_and_patched_ones_name_the_patch() {
        let a = [pass(), attempt(Outcome::Pass, 0, Some("image differs in 3 of 4096 texels"))];
        let (o, j, d, _) = judge_variant(&a, false);
        assert_eq!((o, j), (Outcome::Mismatch, Judgement::Unstable));
        assert_eq!(d.as_deref(), Some("image differs in 3 of 4096 texels"));
        let (o, j, _, i) = judge_variant(&a, true);
        assert_eq!((o, j), (Outcome::Mismatch, Judgement::PatchDiffers));
        assert_eq!(i.map(|i| (i.faulted, i.attempts)), Some((1, 2)));
    }

    #[test]
    fn validation_messages_are_an_error_and_no_evidence() {
        let a = [pass(), attempt(Outcome::Pass, 2, None), attempt(Outcome::Crash, 0, None)];
        // The crash stays the verdict; the attempt with messages is not counted.
        let (o, _, _, i) = judge_variant(&a, false);
        assert_eq!(o, Outcome::Crash);
        assert_eq!(i.map(|i| (i.faulted, i.attempts)), Some((1, 2)));
        let (o, j, _, i) = judge_variant(&[pass(), attempt(Outcome::Pass, 1, None)], false);
        assert_eq!((o, j, i), (Outcome::Error, Judgement::Validation, None));
        // Messages beside a difference: the messages decide (the difference is no evidence).
        let (o, j, _, _) = judge_variant(&[attempt(Outcome::Pass, 1, Some("d"))], true);
        assert_eq!((o, j), (Outcome::Error, Judgement::Validation));
    }

    #[test]
    fn outputs_beyond_the_compare_tolerance_are_a_mismatch_below_faults_and_messages() {
        let against =
            |o, m| ShaderAttempt { against: Some("x differs".into()), ..attempt(o, m, None) };
        let (o, j, d, i) = judge_variant(&[pass(), against(Outcome::Pass, 0)], false);
        assert_eq!(
            (o, j, d.as_deref()),
            (Outcome::Mismatch, Judgement::CompareDiffers, Some("x differs"))
        );
        assert_eq!(i.map(|i| (i.faulted, i.attempts)), Some((1, 2)));
        let (o, j, _, _) = judge_variant(&[against(Outcome::Crash, 0)], false);
        assert_eq!((o, j), (Outcome::Crash, Judgement::Fault));
        let (o, j, _, _) = judge_variant(&[against(Outcome::Pass, 1)], false);
        assert_eq!((o, j), (Outcome::Error, Judgement::Validation));
    }

    #[test]
    fn no_attempt_is_an_error() {
        let (o, j, d, i) = judge_variant(&[], false);
        assert_eq!((o, j, i), (Outcome::Error, Judgement::Error, None));
        assert_eq!(d.as_deref(), Some("no attempt ran"));
    }

    #[test]
    fn the_cell_id_names_each_file_and_its_hash() {
        let input = |f: &str, h: &str| ShaderInput {
            file: f.into(),
            stage: "raygen".into(),
            entry: "main".into(),
            hash: h.into(),
        };
        let id = cell_id(&[input("a/b/cam.rgen", "0123456789abcdef"), input("hit.rchit", "ff")]);
        assert_eq!(id, "shader:cam.rgen@0123456789ab+hit.rchit@ff");
    }

    fn options_inputs() -> Vec<ShaderInput> {
        vec![ShaderInput {
            file: "hit.rchit".into(),
            stage: "closest_hit".into(),
            entry: "main".into(),
            hash: "0123456789abcdef0123".into(),
        }]
    }

    /// Without options the id is the inputs' id as before; `--entry` and `--fill` (a file's
    /// content hash included) each change it, and the same options give the same id.
    #[test]
    fn the_cell_id_changes_with_entry_and_fill() {
        let plain = cell_id_with(&options_inputs(), &CellOptions::default());
        assert_eq!(plain, "shader:hit.rchit@0123456789ab");
        let entry = CellOptions { entry: Some("shadeB".into()), ..CellOptions::default() };
        let other = CellOptions { entry: Some("shadeC".into()), ..CellOptions::default() };
        let fill = |f: &str| CellOptions { fill: vec![f.into()], ..CellOptions::default() };
        let ids = [
            cell_id_with(&options_inputs(), &entry),
            cell_id_with(&options_inputs(), &other),
            cell_id_with(&options_inputs(), &fill("0.1=zero")),
            cell_id_with(&options_inputs(), &fill("0.1=file:aaaa")),
            cell_id_with(&options_inputs(), &fill("0.1=file:bbbb")),
            cell_id_with(&options_inputs(), &fill("push.0=zero")),
        ];
        for (i, a) in ids.iter().enumerate() {
            assert!(a.starts_with(&format!("{plain}#")) && a.len() == plain.len() + 13, "{a}");
            for b in &ids[i + 1..] {
                assert_ne!(a, b);
            }
        }
        assert_eq!(cell_id_with(&options_inputs(), &entry), ids[0]);
        // A field's value never passes for another field's.
        let spec = CellOptions { spec: vec!["shadeB".into()], ..CellOptions::default() };
        assert_ne!(cell_id_with(&options_inputs(), &spec), ids[0]);
    }

    /// Issue 24: `--profile`'s effect is in the id; one word more is another id; a profile that
    /// changes nothing leaves the id (and every earlier id, hashed without the field) as it was.
    #[test]
    fn the_cell_id_changes_with_the_profiles_effect() {
        let with = |words: &[&str]| CellOptions {
            array_size: Some(8),
            profile: words.iter().map(|w| w.to_string()).collect(),
            ..CellOptions::default()
        };
        let none = cell_id_with(&options_inputs(), &with(&[]));
        let one = cell_id_with(&options_inputs(), &with(&["partially_bound"]));
        let two = cell_id_with(&options_inputs(), &with(&["partially_bound", "nullDescriptor"]));
        assert!(none != one && one != two && none != two, "{none} {one} {two}");
        assert_eq!(one, cell_id_with(&options_inputs(), &with(&["partially_bound"])));
        let plain = CellOptions { array_size: Some(8), ..CellOptions::default() };
        assert_eq!(none, cell_id_with(&options_inputs(), &plain));
        let only = CellOptions { profile: vec!["robustBufferAccess".into()], ..Default::default() };
        assert!(cell_id_with(&options_inputs(), &only).contains('#'));
    }

    /// `--hit-group` is in the id: a shader serving another ray type is another pipeline; the
    /// same groups give the same id, and runs without it keep their ids.
    #[test]
    fn the_cell_id_changes_with_the_hit_groups() {
        let with = |groups: &[&str]| CellOptions {
            array_size: Some(8),
            hit_groups: groups.iter().map(|g| g.to_string()).collect(),
            ..CellOptions::default()
        };
        let none = cell_id_with(&options_inputs(), &with(&[]));
        let one = cell_id_with(&options_inputs(), &with(&["1=shadow.rahit"]));
        let other = cell_id_with(&options_inputs(), &with(&["0=shadow.rahit"]));
        assert!(none != one && one != other && none != other, "{none} {one} {other}");
        assert_eq!(one, cell_id_with(&options_inputs(), &with(&["1=shadow.rahit"])));
        let plain = CellOptions { array_size: Some(8), ..CellOptions::default() };
        assert_eq!(none, cell_id_with(&options_inputs(), &plain));
    }
}
