//! `run --shader`'s plan, made before any GPU work: every input read (SPIR-V, or GLSL compiled
//! as `patch` compiles it: [`super::patch_inputs`]), reduced to its `--entry`, validated with
//! spirv-val, reflected by the harness, the pipeline completed (`harness::run::full_pipeline`)
//! and checked (the harness's groups); then the variants: each workaround patch that applies to
//! any module, patched as `rtprobe patch` patches them and validated again. A problem is one
//! line naming the input and what to do.
use super::args::RunArgs;
use super::exit::{self, coded};
use super::out::errln;
use super::patch_inputs::{self, Input, InputOptions};
use crate::harness::child::JobModule;
use crate::harness::inject::{self as injection, Request};
use crate::harness::{self, UserModule};
use crate::model::contract::HostContract;
use crate::model::shader_injection::{InjectedModule, InjectedVariant, ShaderInjection};
use crate::model::shader_run::ShaderInput;
use crate::patches::layout::Rules;
use crate::patches::pipeline::{self, Stage};
use crate::patches::{PatchError, PatchName, Validation};
use crate::tools::spirv::{self as spirv_tools, ValOptions};
use anyhow::Result;
use rspirv::spirv::ExecutionModel;
use std::collections::BTreeMap;

/// The push-constant bytes a patch may use: Vulkan's guaranteed `maxPushConstantsSize`.
const MAX_PUSH: u32 = 128;

/// One patched variant.
pub struct PlannedVariant {
    pub patch: PatchName,
    pub modules: Vec<JobModule>,
    pub contract: HostContract,
    /// What the patch did (`rtprobe patch`'s lines).
    pub lines: Vec<String>,
    /// The injected faults its modules still hold.
    pub faults: usize,
}

/// Everything `run --shader` runs.
pub struct ShaderPlan {
    pub inputs: Vec<ShaderInput>,
    /// The given modules, as the children get them (each supplies the missing stages itself,
    /// at the same bindings for every variant).
    pub given: Vec<UserModule>,
    /// The unpatched pipeline as it runs: the given modules and the stages supplied.
    pub modules: Vec<UserModule>,
    pub scalar: bool,
    pub variants: Vec<PlannedVariant>,
    /// Patches that do not apply, or cannot be run, and why.
    pub notes: Vec<String>,
    /// What `--inject-fault` injected, every variant's count included.
    pub injection: Option<ShaderInjection>,
}

pub use super::patch_inputs::hash_hex;

/// Whether a patch runs as a variant: one that reads what the original reads. `pin-index`
/// replaces the runtime index by a constant, so its outputs differ by design.
fn differential(p: PatchName) -> bool {
    match p {
        PatchName::AsToAddress | PatchName::Nonuniform | PatchName::SsboToAddress => true,
        PatchName::PinIndex => false,
    }
}

/// The execution model a file name's stage says (`sky.rmiss.spv`, `hit.rchit`).
fn named_model(path: &std::path::Path) -> Option<ExecutionModel> {
    let name = path.file_name()?.to_string_lossy().to_lowercase();
    let name = name.strip_suffix(".spv").unwrap_or(&name);
    Some(match patch_inputs::stage_from_name(std::path::Path::new(name))? {
        "rgen" => ExecutionModel::RayGenerationKHR,
        "rchit" => ExecutionModel::ClosestHitKHR,
        "rahit" => ExecutionModel::AnyHitKHR,
        "rmiss" => ExecutionModel::MissKHR,
        "rint" => ExecutionModel::IntersectionKHR,
        "rcall" => ExecutionModel::CallableKHR,
        "vert" => ExecutionModel::Vertex,
        "frag" => ExecutionModel::Fragment,
        "comp" => ExecutionModel::GLCompute,
        _ => return None,
    })
}

/// Reduce `input` to `--entry` (which must name one of its entry points); a module with several
/// entry points needs it.
fn entry(input: &mut Input, entry: Option<&str>) -> Result<()> {
    let bad = |e: String| coded(exit::BAD_INPUT, format!("{}: {e}", input.name));
    let mut m =
        crate::patches::load(&spirv_tools::bytes(&input.words)).map_err(|e| bad(e.to_string()))?;
    let Some(name) = entry else {
        if m.entry_points.len() < 2 {
            return Ok(());
        }
        return Err(bad(format!(
            "has {} entry points: pick one with --entry NAME",
            m.entry_points.len()
        )));
    };
    harness::entry::select_entry(&mut m, name, named_model(&input.path))
        .map_err(|e| bad(format!("{e} (--entry {name})")))?;
    input.words = crate::patches::assemble(&m);
    Ok(())
}

/// spirv-val on an input: its layout rules and the options it validates with (`None`: no
/// validator here, said once).
fn validate(input: &Input, warned: &mut bool) -> Result<(Rules, Option<ValOptions>)> {
    let validator =
        spirv_tools::tool(spirv_tools::SpirvTool::Val).map(|t| t.describe()).unwrap_or_default();
    match spirv_tools::validate_input(&input.words) {
        (Validation::Valid, o) => {
            Ok((if o.scalar_block_layout { Rules::Scalar } else { Rules::Standard }, Some(o)))
        }
        (Validation::Unavailable, _) => {
            if !std::mem::replace(warned, true) {
                errln!("rtprobe: warning: spirv-val is not installed (apt-get install spirv-tools): the inputs are not validated");
            }
            Ok((Rules::Standard, None))
        }
        (Validation::TooOld { validator, what }, _) => Err(coded(
            exit::BAD_INPUT,
            format!("{}: {validator} is too old for {what}; a newer SPIRV-Tools (scripts/setup-sid) validates it", input.name),
        )),
        (Validation::Invalid(msg), o) => Err(coded(
            exit::BAD_INPUT,
            format!(
                "{} fails spirv-val ({validator}, {}): {msg} — rtprobe runs only valid modules; fix the shader",
                input.name,
                o.describe()
            ),
        )),
    }
}

/// `--inject-fault`'s fault put into input `i` (its words replaced) and validated again as the
/// input was: what it matched.
fn inject(i: &mut Input, r: &Request, val: Option<&ValOptions>) -> Result<InjectedModule> {
    let bad = |e: String| coded(exit::BAD_INPUT, format!("{}: {e}", i.name));
    let mut m =
        crate::patches::load(&spirv_tools::bytes(&i.words)).map_err(|e| bad(e.to_string()))?;
    let done = injection::inject(&mut m, r);
    let words = crate::patches::assemble(&m);
    if let Some(Validation::Invalid(msg)) = val.map(|o| spirv_tools::validate(&words, o)) {
        return Err(coded(
            exit::INTERNAL,
            format!("{}: the module with the injected fault fails spirv-val ({msg}); please report it with the input", i.name),
        ));
    }
    i.words = words;
    Ok(InjectedModule {
        file: i.name.clone(),
        stage: injection::sites::stage(&m).map(|s| s.to_string()).unwrap_or_default(),
        matched: done.sites.len(),
        sites: done.sites,
        skipped: done.skipped,
    })
}

/// Read, reduce, validate and reflect every input (each with `inject`'s fault, when given);
/// complete and check the pipeline.
pub fn plan(a: &RunArgs, inject_fault: Option<&Request>) -> Result<ShaderPlan> {
    let opts = InputOptions {
        glsl: false,
        stage: None,
        include_dirs: &a.include_dirs,
        defines: &a.defines,
        target_env: a.target_env.unwrap_or_default(),
        stage_hint: "",
    };
    let mut inputs = patch_inputs::read_with(&opts, &a.shader)?;
    let ray_types = super::shader_hit_groups::parse(&a.hit_groups, &inputs)?;
    let (mut warned, mut injected) = (false, vec![]);
    let (mut stages, mut val, mut modules, mut described) = (vec![], vec![], vec![], vec![]);
    for i in inputs.iter_mut() {
        entry(i, a.entry.as_deref())?;
        let (rules, o) = validate(i, &mut warned)?;
        if let Some(r) = inject_fault {
            injected.push(inject(i, r, o.as_ref())?);
        }
        let mut m = UserModule::new(&i.name, &i.words).map_err(|e| {
            coded(exit::BAD_INPUT, format!("{e} — the harness cannot run this module as it is"))
        })?;
        m.ray_type = ray_types.get(&i.name).copied();
        if m.ray_type.is_some()
            && !matches!(m.iface.stage.as_str(), "closest_hit" | "any_hit" | "intersection")
        {
            let why = format!("--hit-group: {} is a {} shader; hit groups hold closest-hit, any-hit and intersection shaders", i.name, m.iface.stage);
            return Err(coded(exit::USAGE, why));
        }
        let module = crate::patches::load(&spirv_tools::bytes(&i.words))
            .map_err(|e| coded(exit::BAD_INPUT, format!("{}: {e}", i.name)))?;
        described.push(ShaderInput {
            file: i.name.clone(),
            stage: m.iface.stage.clone(),
            entry: m.iface.entry.clone(),
            hash: i.identity.clone(),
        });
        stages.push(Stage { file: i.name.clone(), module, rules });
        val.push(o);
        modules.push(m);
    }
    let given = modules.clone();
    let modules = harness::run::full_pipeline(modules)
        .map_err(|e| coded(exit::BAD_INPUT, format!("--shader: {e}")))?;
    harness::run::check_pipeline(&modules)
        .map_err(|e| coded(exit::BAD_INPUT, format!("--shader: {e}")))?;
    let scalar = stages.iter().any(|s| s.rules == Rules::Scalar);
    let (variants, mut notes) = variants(&stages, &val, &ray_types);
    let refs: Vec<&harness::UserModule> = modules.iter().collect();
    notes.extend(harness::traces::unbounded_recursion(&refs));
    let injection = inject_fault.map(|r| ShaderInjection {
        spec: r.spec.clone(),
        fault: r.fault.as_str().into(),
        variants: std::iter::once(InjectedVariant {
            name: "unpatched".into(),
            faults: stages.iter().map(|s| injection::count(&s.module)).sum(),
        })
        .chain(
            variants
                .iter()
                .map(|v| InjectedVariant { name: v.patch.as_str().into(), faults: v.faults }),
        )
        .collect(),
        modules: injected,
    });
    Ok(ShaderPlan { inputs: described, given, modules, scalar, variants, notes, injection })
}

/// Each differential patch applied to a copy of the pipeline: the variants that apply and
/// validate, and a note for each that does not.
fn variants(
    stages: &[Stage],
    val: &[Option<ValOptions>],
    ray_types: &BTreeMap<String, u32>,
) -> (Vec<PlannedVariant>, Vec<String>) {
    let (mut out, mut notes) = (Vec::new(), Vec::new());
    let names = crate::patches::LIST.iter().filter_map(|p| PatchName::parse(p.0).ok());
    for p in names.filter(|p| differential(*p)) {
        let mut copy: Vec<Stage> = stages
            .iter()
            .map(|s| Stage { file: s.file.clone(), module: s.module.clone(), rules: s.rules })
            .collect();
        let applied = match pipeline::apply(&mut copy, &[p], &BTreeMap::new(), MAX_PUSH) {
            Ok(a) => a,
            Err(e) => match e.error {
                PatchError::NothingToPatch { what, .. } => {
                    notes.push(format!("{} does not apply: {what}", p.as_str()));
                    continue;
                }
                error => {
                    notes.push(format!("{} not run: {error}", p.as_str()));
                    continue;
                }
            },
        };
        let words: Vec<Vec<u32>> =
            copy.iter().map(|s| crate::patches::assemble(&s.module)).collect();
        let invalid = words.iter().zip(val).zip(&copy).find_map(|((w, o), s)| {
            match o.as_ref().map(|o| spirv_tools::validate(w, o)) {
                Some(Validation::Invalid(m)) => Some(format!("{}: {m}", s.file)),
                _ => None,
            }
        });
        if let Some(why) = invalid {
            notes.push(format!(
                "{} not run: the patched module fails spirv-val ({why})",
                p.as_str()
            ));
            continue;
        }
        let modules = copy
            .iter()
            .zip(words)
            .map(|(s, words)| JobModule {
                name: s.file.clone(),
                words,
                ray_type: ray_types.get(&s.file).copied(),
            })
            .collect();
        out.push(PlannedVariant {
            patch: p,
            modules,
            contract: applied.contract,
            lines: applied.lines,
            faults: copy.iter().map(|s| injection::count(&s.module)).sum(),
        });
    }
    (out, notes)
}
