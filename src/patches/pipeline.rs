//! Patching a pipeline's modules together (`rtprobe patch a.rgen b.rchit c.rmiss`): every patch
//! runs on every module in order, with one set of push-constant addresses for the whole pipeline
//! ([`super::push::Slots`]: past every stage's own push data, one address per descriptor, the same
//! in every stage that reads it, never past `maxPushConstantsSize`) and one set of SpecIds
//! ([`super::pin_index::SpecIds`]). The result carries the host contract
//! ([`crate::model::contract`]): what the application must add for the patched modules to read
//! what the originals read.
use super::as_to_address::{self, Mode};
use super::guard::on_copy;
use super::layout::Rules;
use super::name::PatchName;
use super::pin_index::{self, SpecIds};
use super::push::{self, SlotKind, Slots};
use super::{nonuniform, ssbo_to_address, PatchError};
use crate::model::contract::{
    AddressEntry, AddressKind, ContractModule, HostContract, PushRange, SpecEntry,
};
use rspirv::dr::{Module, Operand};
use rspirv::spirv::ExecutionModel;
use std::collections::{BTreeMap, BTreeSet};

/// One module of the pipeline.
pub struct Stage {
    /// The input's name, for messages and the contract.
    pub file: String,
    pub module: Module,
    /// The layout rules its blocks follow (scalar when it validates only with
    /// `--scalar-block-layout`).
    pub rules: Rules,
}

/// A patch failing on one module (`file`), or on the options (no file).
#[derive(Debug, thiserror::Error)]
#[error("{}{error}", file.as_ref().map(|f| format!("{f}: ")).unwrap_or_default())]
pub struct StageError {
    pub file: Option<String>,
    #[source]
    pub error: PatchError,
}

fn options_error(error: PatchError) -> StageError {
    StageError { file: None, error }
}

/// What patching did: one line per patch and module, warnings, and the host contract.
#[derive(Clone, Debug)]
pub struct Applied {
    pub lines: Vec<String>,
    pub warnings: Vec<String>,
    pub contract: HostContract,
}

/// The stage name of an execution model (`closest_hit`, …; others in lower case), the one
/// spelling `patch`, the harness and the reflection use.
pub fn stage_name(model: ExecutionModel) -> String {
    match model {
        ExecutionModel::RayGenerationKHR => "raygen",
        ExecutionModel::ClosestHitKHR => "closest_hit",
        ExecutionModel::AnyHitKHR => "any_hit",
        ExecutionModel::MissKHR => "miss",
        ExecutionModel::IntersectionKHR => "intersection",
        ExecutionModel::CallableKHR => "callable",
        ExecutionModel::GLCompute => "compute",
        ExecutionModel::Vertex => "vertex",
        ExecutionModel::Fragment => "fragment",
        other => return format!("{other:?}").to_lowercase(),
    }
    .to_string()
}

/// The stage name and entry point of a module's first entry point.
pub fn stage_of(m: &Module) -> Option<(String, String)> {
    let ep = m.entry_points.first()?;
    let model = match ep.operands.first()? {
        Operand::ExecutionModel(e) => *e,
        _ => return None,
    };
    let entry = match ep.operands.get(2)? {
        Operand::LiteralString(s) => s.clone(),
        _ => return None,
    };
    let stage = stage_name(model);
    Some((stage.to_string(), entry))
}

/// The `key=value` options, read for one patch.
struct Opts<'a>(&'a BTreeMap<String, String>);

impl Opts<'_> {
    /// The number `k=N`, if given.
    fn num(&self, p: PatchName, k: &str) -> Result<Option<u32>, PatchError> {
        self.0
            .get(k)
            .map(|v| {
                v.parse::<u32>().map_err(|_| PatchError::BadOption {
                    patch: p.as_str(),
                    what: format!("{k}={v:?} is not a number"),
                })
            })
            .transpose()
    }

    /// The value `choices` pairs with `k`'s, if given.
    fn choice<T: Copy>(
        &self,
        p: PatchName,
        k: &str,
        choices: &[(&str, T)],
    ) -> Result<Option<T>, PatchError> {
        let Some(v) = self.0.get(k) else {
            return Ok(None);
        };
        match choices.iter().find(|(name, _)| *name == v.as_str()) {
            Some((_, t)) => Ok(Some(*t)),
            None => {
                let names: Vec<&str> = choices.iter().map(|c| c.0).collect();
                Err(PatchError::BadOption {
                    patch: p.as_str(),
                    what: format!("{k}={v:?}: use {}", names.join(" or ")),
                })
            }
        }
    }
}

/// A patch's parsed options.
enum Parsed {
    As(as_to_address::Options),
    Nonuniform(bool),
    Pin(pin_index::Options),
    Ssbo(ssbo_to_address::Options),
}

fn parse(p: PatchName, o: &Opts) -> Result<Parsed, PatchError> {
    let (set, binding) = (o.num(p, "set")?, o.num(p, "binding")?);
    Ok(match p {
        PatchName::AsToAddress => {
            let mode = o.choice(p, "mode", &[("direct", Mode::Direct), ("table", Mode::Table)])?;
            Parsed::As(as_to_address::Options { mode, set, binding })
        }
        PatchName::Nonuniform => Parsed::Nonuniform(
            o.choice(p, "strip", &[("false", false), ("true", true)])?.unwrap_or(false),
        ),
        PatchName::PinIndex => {
            Parsed::Pin(pin_index::Options { set, binding, value: o.num(p, "value")?.unwrap_or(0) })
        }
        PatchName::SsboToAddress => Parsed::Ssbo(ssbo_to_address::Options { set, binding }),
    })
}

/// The stages reading an address, and its array length.
type Readers = (BTreeSet<String>, Option<u32>);

/// Each module's push block ([start, end)), the pipeline's push end, and where addresses start.
type PushLayout = (Vec<Option<[u32; 2]>>, u32, u32);

/// The pipeline-wide state the patches share.
struct Shared {
    slots: Slots,
    spec: SpecIds,
    /// Stages reading each address / spec constant, and what each address holds.
    address_stages: BTreeMap<(SlotKind, u32, u32), Readers>,
    spec_stages: BTreeMap<u32, (u32, u32, BTreeSet<String>)>,
    added_khr: bool,
}

impl Shared {
    /// Note that `stage` reads the address of (kind, set, binding), an array of `elements`.
    fn reads_address(&mut self, key: (SlotKind, u32, u32), elements: Option<u32>, stage: &str) {
        let s = self.address_stages.entry(key).or_default();
        s.0.insert(stage.into());
        s.1 = elements;
    }
}

/// `as-to-address` on one module, and its line.
fn run_as(
    m: &mut Module,
    o: &as_to_address::Options,
    rules: Rules,
    stage: &str,
    sh: &mut Shared,
) -> Result<String, PatchError> {
    let r = on_copy(m, |w| as_to_address::apply(w, o, &mut sh.slots, rules))?;
    sh.added_khr |= r.added_khr;
    let mut parts = Vec::new();
    for e in &r.entries {
        let (kind, mode) = match e.mode {
            Mode::Table => (SlotKind::AsTable, "table"),
            Mode::Direct => (SlotKind::AsAddress, "direct"),
        };
        sh.reads_address((kind, e.set, e.binding), e.elements, stage);
        parts.push(format!(
            "set {} binding {}: address at push-constant offset {} ({mode} mode)",
            e.set, e.binding, e.offset
        ));
    }
    Ok(format!(
        "as-to-address: {} loads rewritten, {} descriptor variables removed; {}",
        r.rewritten_loads,
        r.removed_variables,
        parts.join("; ")
    ))
}

/// `pin-index` on one module, and its line.
fn run_pin(
    m: &mut Module,
    o: &pin_index::Options,
    stage: &str,
    sh: &mut Shared,
) -> Result<String, PatchError> {
    let r = on_copy(m, |w| pin_index::apply(w, o, &mut sh.spec))?;
    let mut parts = Vec::new();
    for d in &r.descriptors {
        let s = sh.spec_stages.entry(d.spec_id).or_insert((d.set, d.binding, BTreeSet::new()));
        s.2.insert(stage.into());
        parts.push(format!("set {} binding {} -> SpecId {}", d.set, d.binding, d.spec_id));
    }
    Ok(format!(
        "pin-index: {} accesses now index with spec constants (default {}): {}",
        r.pinned,
        o.value,
        parts.join(", ")
    ))
}

/// `ssbo-to-address` on one module, and its line.
fn run_ssbo(
    m: &mut Module,
    o: &ssbo_to_address::Options,
    rules: Rules,
    stage: &str,
    sh: &mut Shared,
) -> Result<String, PatchError> {
    let r = on_copy(m, |w| ssbo_to_address::apply(w, o, &mut sh.slots, rules))?;
    let mut parts = Vec::new();
    for e in &r.entries {
        sh.reads_address((SlotKind::BufferTable, e.set, e.binding), e.elements, stage);
        parts.push(format!(
            "set {} binding {}: table address at push-constant offset {}",
            e.set, e.binding, e.offset
        ));
    }
    Ok(format!(
        "ssbo-to-address: {} loads now read through buffer addresses; {}",
        r.rewritten_loads,
        parts.join("; ")
    ))
}

/// Run patch `parsed` on one module: the line saying what it did.
fn run_one(
    m: &mut Module,
    parsed: &Parsed,
    rules: Rules,
    stage: &str,
    sh: &mut Shared,
) -> Result<String, PatchError> {
    match parsed {
        Parsed::As(o) => run_as(m, o, rules, stage, sh),
        Parsed::Nonuniform(strip) => {
            let r = on_copy(m, |w| nonuniform::apply(w, *strip))?;
            Ok(if *strip {
                format!("nonuniform: {} NonUniform decorations stripped", r.stripped)
            } else {
                format!("nonuniform: {} objects decorated NonUniform", r.decorated)
            })
        }
        Parsed::Pin(o) => run_pin(m, o, stage, sh),
        Parsed::Ssbo(o) => run_ssbo(m, o, rules, stage, sh),
    }
}

/// The modules' push blocks ([start, end) each) and where the pipeline's addresses start: past
/// every block (`offset=` may move them further, never into a block).
fn push_layout(stages: &[Stage], offset: Option<u32>) -> Result<PushLayout, StageError> {
    let mut blocks = Vec::new();
    let mut end = 0;
    for s in stages {
        let e = push::end(&s.module, s.rules, "patch")
            .map_err(|error| StageError { file: Some(s.file.clone()), error })?;
        let b = push::block(&s.module, "patch").ok().flatten();
        blocks.push(b.map(|b| [push::start(&s.module, b.st), e]));
        end = end.max(e);
    }
    let start = match offset {
        None => end,
        Some(o) => {
            if let Some((s, e)) = stages
                .iter()
                .zip(&blocks)
                .find_map(|(s, b)| b.filter(|b| o < b[1]).map(|b| (s, b[1])))
            {
                return Err(StageError {
                    file: Some(s.file.clone()),
                    error: PatchError::BadOption {
                        patch: "patch",
                        what: format!(
                            "offset={o} overlaps the push-constant block, which ends at {e}"
                        ),
                    },
                });
            }
            o
        }
    };
    Ok((blocks, end, start))
}

/// Apply `patches` in order to every module of `stages`, with `options` (`key=value`, each key
/// belonging to one of them) and push constants up to `max_push` bytes.
pub fn apply(
    stages: &mut [Stage],
    patches: &[PatchName],
    options: &BTreeMap<String, String>,
    max_push: u32,
) -> Result<Applied, StageError> {
    for k in options.keys() {
        if !patches.iter().any(|p| p.keys().contains(&k.as_str())) {
            return Err(options_error(PatchError::UnknownOption(k.clone())));
        }
    }
    let o = Opts(options);
    let offset = o.num(PatchName::AsToAddress, "offset").map_err(options_error)?;
    let spec_first = o.num(PatchName::PinIndex, "spec-id").map_err(options_error)?;
    let parsed: Vec<Parsed> =
        patches.iter().map(|p| parse(*p, &o)).collect::<Result<_, _>>().map_err(options_error)?;
    let (blocks, old_end, start) = push_layout(stages, offset)?;
    let used = stages.iter().flat_map(|s| pin_index::used(&s.module)).collect();
    let mut sh = Shared {
        slots: Slots::new(start, max_push),
        spec: SpecIds::new(used, spec_first),
        address_stages: BTreeMap::new(),
        spec_stages: BTreeMap::new(),
        added_khr: false,
    };
    let names: Vec<(String, String)> =
        stages.iter().map(|s| stage_of(&s.module).unwrap_or_default()).collect();
    let mut lines = Vec::new();
    let mut patched: Vec<Vec<String>> = vec![Vec::new(); stages.len()];
    for (p, parsed) in patches.iter().zip(&parsed) {
        let mut nothing = Vec::new();
        let mut any = false;
        for (i, s) in stages.iter_mut().enumerate() {
            match run_one(&mut s.module, parsed, s.rules, &names[i].0, &mut sh) {
                Ok(line) => {
                    any = true;
                    patched[i].push(p.as_str().to_string());
                    lines.push(if blocks.len() > 1 { format!("{}: {line}", s.file) } else { line });
                }
                Err(PatchError::NothingToPatch { what, .. }) => {
                    nothing.push((s.file.clone(), what));
                }
                Err(error) => return Err(StageError { file: Some(s.file.clone()), error }),
            }
        }
        if !any {
            return Err(nothing_to_patch(p.as_str(), nothing));
        }
    }
    let warnings = one_stage_warning(stages, &blocks, offset);
    let contract = contract(stages, &names, &blocks, &patched, &sh, old_end, options);
    Ok(Applied { lines, warnings, contract })
}

/// The error of a patch that found nothing to patch in any module, from each module's reason:
/// the files sorted, and each distinct reason once with the files it holds for, so that the
/// message does not depend on the order the modules were given in.
fn nothing_to_patch(patch: &'static str, mut reasons: Vec<(String, String)>) -> StageError {
    reasons.sort();
    let mut files: Vec<String> = reasons.iter().map(|r| r.0.clone()).collect();
    files.dedup();
    let mut by_reason: BTreeMap<&str, Vec<&str>> = BTreeMap::new();
    for (f, what) in &reasons {
        by_reason.entry(what).or_default().push(f);
    }
    let what = if by_reason.len() == 1 {
        reasons.first().map(|r| r.1.clone()).unwrap_or_default()
    } else {
        let mut groups: Vec<(&Vec<&str>, &str)> = by_reason.iter().map(|(w, f)| (f, *w)).collect();
        groups.sort();
        let parts: Vec<String> =
            groups.iter().map(|(f, w)| format!("{}: {w}", f.join(", "))).collect();
        parts.join("; ")
    };
    StageError { file: Some(files.join(", ")), error: PatchError::NothingToPatch { patch, what } }
}

/// Given one module without a push block, which now has one at `offset` 0 or its end: other
/// stages of its pipeline may use those bytes.
fn one_stage_warning(
    stages: &[Stage],
    blocks: &[Option<[u32; 2]>],
    offset: Option<u32>,
) -> Vec<String> {
    match (stages, blocks) {
        ([s], [None]) if offset.is_none() && push::block(&s.module, "patch").ok().flatten().is_some() => vec![format!(
            "{} had no push-constant block: the new one starts at byte 0; if other stages of its pipeline \
             use push constants, patch them together (rtprobe patch a.rgen b.rchit c.rmiss ...) or pass \
             --option offset=<their end>",
            s.file
        )],
        _ => Vec::new(),
    }
}

/// The contract's addresses, in offset order: what each holds and which stages read it.
fn addresses(sh: &Shared) -> Vec<AddressEntry> {
    let mut out: Vec<AddressEntry> = sh
        .slots
        .taken()
        .iter()
        .filter_map(|(k, off)| {
            let (st, elements) = sh.address_stages.get(&(k.kind, k.set, k.binding))?;
            let kind = match k.kind {
                SlotKind::AsAddress => AddressKind::AccelerationStructure,
                SlotKind::AsTable => AddressKind::AccelerationStructureTable,
                SlotKind::BufferTable => AddressKind::BufferTable,
            };
            let stages = st.iter().cloned().collect();
            Some(AddressEntry {
                offset: *off,
                kind,
                set: k.set,
                binding: k.binding,
                elements: *elements,
                stages,
            })
        })
        .collect();
    out.sort_by_key(|a| a.offset);
    out
}

/// The host contract of the patched pipeline.
fn contract(
    stages: &[Stage],
    names: &[(String, String)],
    blocks: &[Option<[u32; 2]>],
    patched: &[Vec<String>],
    sh: &Shared,
    old_end: u32,
    options: &BTreeMap<String, String>,
) -> HostContract {
    let modules = stages
        .iter()
        .enumerate()
        .map(|(i, s)| ContractModule {
            file: s.file.clone(),
            stage: names[i].0.clone(),
            entry: names[i].1.clone(),
            push_block: blocks[i],
            patched: patched[i].clone(),
        })
        .collect();
    let addresses = addresses(sh);
    let push_range = addresses.first().map(|first| {
        let end = addresses.iter().map(|a| a.offset + 8).max().unwrap_or(first.offset);
        let stages: BTreeSet<String> =
            addresses.iter().flat_map(|a| a.stages.iter().cloned()).collect();
        PushRange {
            offset: first.offset,
            size: end - first.offset,
            stages: stages.into_iter().collect(),
        }
    });
    let push_end = push_range.as_ref().map_or(old_end, |r| r.offset + r.size).max(old_end);
    let value = options.get("value").and_then(|v| v.parse().ok()).unwrap_or(0);
    let specialization = sh
        .spec_stages
        .iter()
        .map(|(id, (set, binding, st))| SpecEntry {
            spec_id: *id,
            set: *set,
            binding: *binding,
            value,
            stages: st.iter().cloned().collect(),
        })
        .collect();
    let mut requires = Vec::new();
    if !addresses.is_empty() {
        requires.extend(["bufferDeviceAddress".to_string(), "shaderInt64".to_string()]);
    }
    if sh.added_khr {
        requires.push("VK_KHR_ray_tracing_pipeline (the SPV_NV_ray_tracing module now declares RayTracingKHR for OpConvertUToAccelerationStructureKHR)".into());
    }
    HostContract {
        modules,
        push_range,
        push_end,
        addresses,
        specialization,
        requires,
        ..HostContract::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stage(file: &str, kind: shaderc::ShaderKind, glsl: &str) -> Stage {
        let module = crate::patches::compiled(kind, file, glsl);
        Stage { file: file.into(), module, rules: Rules::Standard }
    }

    const HEAD: &str = "#version 460\n#extension GL_EXT_ray_tracing : require\n";

    fn pipeline() -> Vec<Stage> {
        let rgen = format!(
            "{HEAD}layout(set = 0, binding = 0) uniform accelerationStructureEXT t;\n\
            layout(location = 0) rayPayloadEXT vec4 c;\n\
            void main() {{ traceRayEXT(t, 0u, 0xFF, 0, 0, 0, vec3(0), 0.0, vec3(1), 1.0, 0); }}\n"
        );
        let chit = format!("{HEAD}layout(push_constant) uniform P {{ vec4 tint; vec2 k; }} pc;\n\
            layout(set = 0, binding = 0) uniform accelerationStructureEXT t;\n\
            layout(location = 0) rayPayloadInEXT vec4 c;\nlayout(location = 1) rayPayloadEXT vec4 s;\n\
            void main() {{ traceRayEXT(t, 0u, 0xFF, 0, 0, 1, vec3(0), 0.0, vec3(1), 1.0, 1); c = pc.tint * s + pc.k.x; }}\n");
        vec![
            stage("a.rgen", shaderc::ShaderKind::RayGeneration, &rgen),
            stage("b.rchit", shaderc::ShaderKind::ClosestHit, &chit),
        ]
    }

    fn options(kv: &[(&str, &str)]) -> BTreeMap<String, String> {
        kv.iter().map(|(k, v)| (k.to_string(), v.to_string())).collect()
    }

    #[test]
    fn one_address_per_descriptor_past_every_stage_and_in_every_stage_that_reads_it() {
        let mut s = pipeline();
        let a = apply(&mut s, &[PatchName::AsToAddress], &options(&[]), 128).unwrap();
        // b.rchit's block ends at 24: the TLAS both stages read gets one address there.
        let c = &a.contract;
        assert_eq!(c.addresses.len(), 1);
        assert_eq!((c.addresses[0].offset, c.addresses[0].set, c.addresses[0].binding), (24, 0, 0));
        assert_eq!(c.addresses[0].stages, vec!["closest_hit".to_string(), "raygen".to_string()]);
        assert_eq!(c.push_range.as_ref().map(|r| (r.offset, r.size)), Some((24, 8)));
        assert_eq!(c.push_end, 32);
        assert_eq!(c.modules[1].push_block, Some([0, 24]));
        assert!(a.warnings.is_empty(), "{:?}", a.warnings);
        for st in &s {
            let v = crate::patches::validate(&crate::patches::assemble(&st.module));
            assert!(
                matches!(
                    v,
                    crate::patches::Validation::Valid | crate::patches::Validation::Unavailable
                ),
                "{}: {v:?}",
                st.file
            );
        }
    }

    #[test]
    fn nothing_to_patch_says_the_same_in_any_order_of_the_modules() {
        let miss = stage(
            "c.rmiss",
            shaderc::ShaderKind::Miss,
            &format!("{HEAD}layout(location = 0) rayPayloadInEXT vec4 c;\nvoid main() {{ c = vec4(1); }}\n"),
        );
        // Declares an acceleration structure but never loads it.
        let unused = stage(
            "b.rchit",
            shaderc::ShaderKind::ClosestHit,
            &format!(
                "{HEAD}layout(set = 0, binding = 0) uniform accelerationStructureEXT t;\n\
                layout(location = 0) rayPayloadInEXT vec4 c;\nvoid main() {{ c = vec4(2); }}\n"
            ),
        );
        let words: Vec<(String, Vec<u32>)> = [miss, unused]
            .iter()
            .map(|s| (s.file.clone(), crate::patches::assemble(&s.module)))
            .collect();
        let order = |idx: &[usize]| {
            let mut st: Vec<Stage> = idx
                .iter()
                .map(|i| {
                    let (f, w) = &words[*i];
                    let module = crate::patches::load(&crate::tools::spirv::bytes(w)).unwrap();
                    Stage { file: f.clone(), module, rules: Rules::Standard }
                })
                .collect();
            apply(&mut st, &[PatchName::AsToAddress], &options(&[]), 128).unwrap_err().to_string()
        };
        let (a, b) = (order(&[0, 1]), order(&[1, 0]));
        assert_eq!(a, b);
        assert!(a.starts_with("b.rchit, c.rmiss: as-to-address: nothing to patch: "), "{a}");
        // Each module's own reason, not the first module's.
        assert!(
            a.contains("b.rchit: acceleration-structure descriptors are declared but never loaded"),
            "{a}"
        );
        assert!(a.contains("c.rmiss: the module declares no acceleration structure type"), "{a}");
    }

    #[test]
    fn an_offset_inside_another_stages_block_or_past_the_limit_is_refused() {
        // a.rgen has no block, but b.rchit's bytes 0..24 are the pipeline's: offset=16 overlaps.
        let e =
            apply(&mut pipeline(), &[PatchName::AsToAddress], &options(&[("offset", "16")]), 128)
                .unwrap_err();
        assert_eq!(e.file.as_deref(), Some("b.rchit"));
        assert!(
            e.to_string().contains("overlaps the push-constant block, which ends at 24"),
            "{e}"
        );
        assert_eq!(
            apply(&mut pipeline(), &[PatchName::AsToAddress], &options(&[("offset", "32")]), 128)
                .unwrap()
                .contract
                .addresses[0]
                .offset,
            32
        );
        let e = apply(&mut pipeline(), &[PatchName::AsToAddress], &options(&[]), 28).unwrap_err();
        assert!(e.to_string().contains("past maxPushConstantsSize 28"), "{e}");
        // One stage alone without a block: warned about.
        let mut one = pipeline();
        one.truncate(1);
        let a = apply(&mut one, &[PatchName::AsToAddress], &options(&[]), 128).unwrap();
        assert!(a.warnings[0].contains("a.rgen had no push-constant block"), "{:?}", a.warnings);
    }
}
