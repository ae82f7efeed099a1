//! `rtprobe run --shader FILE…`: the user's own ray tracing pipeline in the harness, isolated
//! and judged without a CPU reference. The plan first ([`super::shader_plan`]: inputs read,
//! validated, reflected, the pipeline checked, the variants patched), then the device and the
//! interface check, then each variant's attempts in child processes ([`super::shader_exec`]),
//! the verdicts (`model::shader_run`), the report (`rtprobe.shader-run/1`, written atomically),
//! `--dump`'s PNGs and the summary ([`super::shader_report`]).
use super::args::RunArgs;
use super::commands::{open_instance, Globals};
use super::exit::{self, coded};
use super::out::outln;
use super::shader_exec::{self, Ctx, Ran, VariantRun};
use super::shader_plan::{self, ShaderPlan};
use super::shader_profile;
use crate::harness::child::JobModule;
use crate::harness::inject::Request;
use crate::harness::Sizes;
use crate::model::index_bounds::IndexBounds;
use crate::model::profile::ProfileRecord;
use crate::model::shader_options::CellOptions;
use crate::model::shader_run::{self, ShaderRunReport, ShaderVariant};
use crate::model::DescriptorModel;
use crate::report::lock::{LockError, ReportLock};
use anyhow::{Context, Result};
use std::path::{Path, PathBuf};
use std::time::Duration;

/// Attempts per variant without `--repeat`: enough to see a fault that comes one time in two
/// (missed with p = 1/8) and a pipeline that is not deterministic.
pub const DEFAULT_REPEAT: u32 = 3;

/// The arguments `run --shader` takes (clap ids); every other one given is refused.
const TAKEN: &[&str] = &[
    "shader",
    "entry",
    "hit_groups",
    "include_dirs",
    "defines",
    "target_env",
    "array_size",
    "no_index_check",
    "sink_size",
    "device",
    "out",
    "dump",
    "timeout",
    "setup_timeout",
    "repeat",
    "validate",
    "verbose",
    "spec",
    "descriptor_model",
    "heap_layout",
    "profile",
    "inject_fault",
    "fill",
    "scene",
    "compare",
    "tolerance",
    "junit",
    "baseline",
    "allow_improvements",
    // clap's ids of the argument groups themselves.
    "RunArgs",
    "Cli",
];

/// One line for the first argument given that `--shader` does not take.
fn refuse_others(a: &RunArgs) -> Result<()> {
    let Some(id) = a.explicit.iter().find(|id| !TAKEN.contains(&id.as_str())) else {
        return Ok(());
    };
    let flag = format!("--{}", id.replace('_', "-"));
    Err(coded(
        exit::USAGE,
        format!("{flag} cannot be used with --shader: it applies to the generated matrix, which --shader replaces; drop it (--shader takes --entry, --hit-group, -I, -D, --target-env, --spec, --descriptor-model, --heap-layout, --profile, --array-size, --sink-size, --fill, --scene, --repeat, --timeout, --dump, -o, --device, --validate, --inject-fault, --compare, --tolerance, --junit, --baseline, --allow-improvements)"),
    ))
}

/// `--inject-fault` for `--shader`: one at most, `device` or `hang`, on the axes of an access.
fn injection(a: &RunArgs) -> Result<Option<Request>> {
    match a.inject_fault.as_slice() {
        [] => Ok(None),
        [one] => Request::parse(one).map(Some).map_err(|e| coded(exit::USAGE, e.to_string())),
        more => Err(coded(
            exit::USAGE,
            format!("--inject-fault: {} given; --shader takes one (join alternatives in one term: stage=closest_hit|any_hit)", more.len()),
        )),
    }
}

/// `--repeat`, `--timeout` and `--setup-timeout` checked.
fn numbers(a: &RunArgs) -> Result<(u32, Duration, Duration)> {
    let repeat = a.repeat.unwrap_or(DEFAULT_REPEAT);
    if !(1..=1000).contains(&repeat) {
        return Err(coded(exit::USAGE, format!("--repeat {repeat}: give 1 to 1000 attempts")));
    }
    let secs = |s: f64, flag: &str| {
        if s.is_finite() && s > 0.0 && s <= 3600.0 {
            Ok(Duration::from_secs_f64(s))
        } else {
            Err(coded(exit::USAGE, format!("{flag} {s}: give seconds in (0, 3600]")))
        }
    };
    Ok((repeat, secs(a.timeout, "--timeout")?, secs(a.setup_timeout, "--setup-timeout")?))
}

/// `--array-size` and `--sink-size` checked.
fn sizes(a: &RunArgs) -> Result<Sizes> {
    use crate::harness::sizes::{MAX_ARRAY_SIZE, SINK_BOUNDS};
    let array = match a.array_size {
        Some(n) if !(1..=MAX_ARRAY_SIZE as u64).contains(&n) => {
            return Err(coded(
                exit::USAGE,
                format!("--array-size {n}: give 1 to {MAX_ARRAY_SIZE} elements"),
            ))
        }
        n => n.map(|n| n as u32),
    };
    let sink = a.sink_size.unwrap_or(crate::harness::sizes::SINK_SIZE);
    if !SINK_BOUNDS.contains(&sink) {
        return Err(coded(
            exit::USAGE,
            format!(
                "--sink-size {sink}: give {} to {} bytes",
                SINK_BOUNDS.start(),
                SINK_BOUNDS.end()
            ),
        ));
    }
    Ok(Sizes { array, sink })
}

/// What is refused before any device work: `-o` naming a folder, `--dump` naming something
/// not a folder.
fn refuse_early(a: &RunArgs) -> Result<()> {
    if let Some(o) = a.out.as_ref().filter(|o| o.is_dir()) {
        return Err(coded(
            exit::USAGE,
            format!(
                "-o {}: is a folder; give the report's file name (-o DIR/report.json)",
                o.display()
            ),
        ));
    }
    if let Some(d) = a.dump.as_ref().filter(|d| d.exists() && !d.is_dir()) {
        return Err(coded(
            exit::USAGE,
            format!("--dump {}: is a file; give a folder for the PNGs", d.display()),
        ));
    }
    Ok(())
}

/// What `run --shader` takes from the device it runs on: its index and label, what `--profile`
/// enabled, its largest device-local heap, whether it has subgroup vote in every ray tracing
/// stage and its `maxBoundDescriptorSets` (the index check's).
struct Chosen {
    index: usize,
    name: String,
    profile: Option<ProfileRecord>,
    heap: u64,
    vote: bool,
    max_sets: u32,
}

/// The device `--device` names, checked for what the harness needs, for `--profile`'s
/// features, and for the pipeline's interface (`interface::check` against the harness's layout
/// and the device's hit-attribute limit): its index and name, and what the profile enabled.
fn device(
    g: &Globals,
    a: &RunArgs,
    plan: &ShaderPlan,
    (model, profile): (DescriptorModel, Option<&shader_profile::Loaded>),
) -> Result<Chosen> {
    let inst = open_instance(g)?;
    let all = crate::vk::features::query_all(&inst)?;
    let info = crate::vk::features::select(&all, a.device.as_deref())?;
    let mut req = crate::harness::requirements_for(plan.scalar, model);
    req.robustness = shader_profile::setup(profile).robustness();
    crate::harness::enable_needs(plan.modules.iter().map(|m| m.words.as_slice()), &mut req)
        .map_err(|e| coded(exit::BAD_INPUT, format!("--shader: {e}")))?;
    let record = profile
        .map(|p| shader_profile::check(p, info, &req, (model, &plan.modules)))
        .transpose()?;
    let missing = req.missing_on(info);
    if !missing.is_empty() {
        return Err(coded(
            exit::UNSUPPORTED_DEVICE,
            format!(
                "--shader: {} cannot run the pipeline: missing {}",
                info.name(),
                missing.join(", ")
            ),
        ));
    }
    let max_hit = info.properties.rt_pipeline.map_or(0, |p| p.max_ray_hit_attribute_size);
    let desc = crate::harness::run::pipeline_desc(&plan.modules, max_hit);
    let words: Vec<&[u32]> = plan.modules.iter().map(|m| m.words.as_slice()).collect();
    crate::interface::check(&words, &desc).map_err(|e| {
        coded(
            exit::BAD_INPUT,
            format!("--shader: the pipeline does not fit the harness's layout: {e}"),
        )
    })?;
    let heap = crate::harness::scene_data::largest_device_heap(&info.memory);
    Ok(Chosen {
        index: info.index,
        name: info.label(),
        profile: record,
        heap,
        vote: info.subgroup_vote_in_ray_tracing(),
        max_sets: info.properties.core.limits.max_bound_descriptor_sets,
    })
}

/// `--scene`'s file loaded (the loader's one-line error, exit 9) and its content hash: the
/// file's bytes and the data read from its buffers (a `.gltf`'s `.bin` edited is another cell).
fn load_scene(a: &RunArgs) -> Result<Option<(crate::scene::gltf::Loaded, String)>> {
    use crate::harness::scene_data::{bytes, DESC_ORDER};
    let Some(p) = &a.scene else { return Ok(None) };
    let loaded = crate::scene::gltf::Loaded::load(p)?;
    let mut all = std::fs::read(p)
        .map_err(|e| coded(exit::BAD_INPUT, format!("--scene {}: {e}", p.display())))?;
    DESC_ORDER.iter().for_each(|i| all.extend(bytes(&loaded, *i)));
    Ok(Some((loaded, super::patch_inputs::hash_hex(&all))))
}

/// What `scene.textures` takes: the decoded images' device bytes, and the scene's hash with
/// their texels (an image file beside the scene edited is another cell); nothing without it.
#[derive(Default)]
struct SceneImages {
    bytes: u64,
    hash: Option<String>,
}

/// Every image of the scene decoded when a fill puts them in a texture array (one that does not
/// decode: the loader's line, exit 9, before any device work).
fn scene_images(
    scene: Option<&(crate::scene::gltf::Loaded, String)>,
    fills: &[crate::harness::scene_data::SceneFill],
) -> Result<SceneImages> {
    use crate::harness::scene_textures as tex;
    let wanted = !crate::harness::scene_data::texture_targets(fills).is_empty();
    let Some((l, hash)) = scene.filter(|_| wanted) else {
        return Ok(SceneImages::default());
    };
    let decoded = tex::decoded(l)?;
    let mut all = hash.clone().into_bytes();
    for t in &decoded {
        all.extend(t.width.to_le_bytes());
        all.extend(t.height.to_le_bytes());
        all.extend(&t.rgba8);
    }
    let hash = Some(super::patch_inputs::hash_hex(&all));
    Ok(SceneImages { bytes: tex::bytes(&decoded), hash })
}

/// The scene's device memory — its geometry for the acceleration structures, the buffers its
/// fills name and the images `scene.textures` uploads — held to the device's largest
/// device-local heap, before any upload.
fn scene_fits(
    a: &RunArgs,
    l: &crate::scene::gltf::Loaded,
    (fills, texture_bytes): (&[crate::harness::scene_data::SceneFill], u64),
    heap: u64,
) -> Result<()> {
    let items: Vec<_> = fills.iter().map(|f| f.item).collect();
    let need =
        l.geometry_bytes() + crate::harness::scene_data::bytes_needed(l, &items, texture_bytes);
    if need <= heap {
        return Ok(());
    }
    let mib = |b: u64| b.div_ceil(1 << 20);
    Err(coded(
        exit::UNSUPPORTED_DEVICE,
        format!(
            "--scene {}: needs {} MiB of device memory, more than the device's largest device-local heap ({} MiB); give a smaller scene or fewer scene fills",
            a.scene.as_deref().unwrap_or(Path::new("")).display(),
            mib(need),
            mib(heap)
        ),
    ))
}

/// Where the report goes, locked: `-o`, else the first free `reports/shader-<time>-<device>.json`.
fn reserve_out(a: &RunArgs, device: &str) -> Result<(PathBuf, ReportLock)> {
    let busy = |e: LockError| coded(exit::BAD_INPUT, format!("{e}; give this run another -o"));
    match &a.out {
        Some(o) => Ok((o.clone(), ReportLock::acquire(o).map_err(busy)?)),
        None => {
            let stamp = crate::report::time::stamp(crate::report::time::now_unix());
            // The device's name alone: its label's driver in parentheses is no file name's.
            let name = device.rsplit_once(" (").map_or(device, |(n, _)| n);
            let stem = format!("shader-{stamp}-{}", super::run::slug(name));
            ReportLock::unique(Path::new("reports"), &stem).map_err(busy)
        }
    }
}

/// The descriptor model `--descriptor-model` asks for, checked against what the modules read:
/// heap modules run only with the heap model, set/binding modules never with it.
fn model(a: &RunArgs, plan: &ShaderPlan) -> Result<DescriptorModel> {
    let m = model_of(a, plan)?;
    let texture = plan.modules.iter().flat_map(|m| &m.iface.bindings).find(|b| {
        use crate::harness::reflect::BindingKind as K;
        match b.kind {
            K::SampledImage | K::Sampler | K::CombinedImageSampler => true,
            K::AccelerationStructure
            | K::StorageImage(_)
            | K::StorageBuffer(_)
            | K::UniformBuffer(_) => false,
        }
    });
    match (m, texture) {
        (DescriptorModel::DescriptorIndexing, _) | (_, None) => Ok(m),
        (DescriptorModel::DescriptorBuffer | DescriptorModel::DescriptorHeap, Some(b)) => Err(coded(
            exit::USAGE,
            format!("--descriptor-model {}: set {} binding {} is a texture or sampler, which the harness binds with descriptor sets only for now; run with descriptor_indexing", m.as_str(), b.set, b.binding),
        )),
    }
}

/// The model `--descriptor-model` asks for, or the one the modules imply.
fn model_of(a: &RunArgs, plan: &ShaderPlan) -> Result<DescriptorModel> {
    let heap = crate::harness::heap::uses_heap(&plan.given);
    let bad = |m: &str, why: &str| coded(exit::USAGE, format!("--descriptor-model {m}: {why}"));
    match (a.descriptor_model, heap) {
        (None | Some(DescriptorModel::DescriptorHeap), true) => Ok(DescriptorModel::DescriptorHeap),
        (None | Some(DescriptorModel::DescriptorIndexing), false) => {
            Ok(DescriptorModel::DescriptorIndexing)
        }
        (Some(DescriptorModel::DescriptorBuffer), false) => Ok(DescriptorModel::DescriptorBuffer),
        (Some(m @ (DescriptorModel::DescriptorIndexing | DescriptorModel::DescriptorBuffer)), true) => {
            Err(bad(m.as_str(), "the modules read a descriptor heap (DescriptorHeapEXT), which only the descriptor_heap model binds; drop the flag or give descriptor_heap"))
        }
        (Some(DescriptorModel::DescriptorHeap), false) => Err(bad(
            "descriptor_heap",
            "the modules bind descriptors by set and binding, not through a heap; give descriptor_indexing",
        )),
    }
}

/// The heap model's arrays: `--heap-layout`'s ranges, else what the modules index (checked
/// here, before the device: a layout they do not determine is one line naming the flag).
fn heap_layout(
    a: &RunArgs,
    plan: &ShaderPlan,
    model: DescriptorModel,
) -> Result<Option<Vec<crate::harness::heap::Array>>> {
    let heap = match model {
        DescriptorModel::DescriptorHeap => true,
        DescriptorModel::DescriptorIndexing | DescriptorModel::DescriptorBuffer => false,
    };
    match (&a.heap_layout, heap) {
        (Some(_), false) => Err(coded(
            exit::USAGE,
            format!("--heap-layout: the {} model has no heap; drop it", model.as_str()),
        )),
        (Some(f), true) => {
            let text = std::fs::read_to_string(f).map_err(|e| {
                coded(exit::BAD_INPUT, format!("--heap-layout {}: {e}", f.display()))
            })?;
            crate::harness::heap::layout_file(&text)
                .map(Some)
                .map_err(|e| coded(exit::BAD_INPUT, format!("--heap-layout {}: {e}", f.display())))
        }
        (None, true) => {
            crate::harness::heap::arrays(&plan.given)
                .map_err(|e| coded(exit::BAD_INPUT, format!("--shader: {e}")))?;
            Ok(None)
        }
        (None, false) => Ok(None),
    }
}

/// `--compare`'s report, read and checked against the run's cell (its options included), and
/// `--tolerance` checked.
fn other_report(a: &RunArgs, cell: &str) -> Result<Option<ShaderRunReport>> {
    if let Some(t) = a.tolerance.filter(|t| !(t.is_finite() && *t >= 0.0)) {
        return Err(coded(exit::USAGE, format!("--tolerance {t}: give a finite number >= 0")));
    }
    let unsized_run = a.array_size.is_none();
    a.compare.as_deref().map(|p| super::shader_compare::load(p, cell, unsized_run)).transpose()
}

/// What a run takes before its device: the plan, the children's context (its temporary folder
/// made), the device's label (name and driver), the options in the cell id, what `--profile` enabled,
/// `--compare`'s report and `--baseline`'s expectations.
pub(super) struct Prepared {
    pub(super) plan: ShaderPlan,
    pub(super) ctx: Ctx,
    pub(super) device_name: String,
    pub(super) cell_options: CellOptions,
    pub(super) profile: Option<ProfileRecord>,
    /// The device has subgroup vote in every ray tracing stage (the index check's uniformity).
    vote: bool,
    /// The device's `maxBoundDescriptorSets` (the index check needs one set more).
    max_sets: u32,
    other: Option<ShaderRunReport>,
    baseline: Option<crate::model::Baseline>,
    /// `ctx.dir`: the children's job and result files, removed with this.
    _work: crate::runner::groups::JobFolder,
}

/// The children's work folder, and the interrupt handler that kills them, removes it and says
/// no report was written.
fn work_folder() -> Result<crate::runner::groups::JobFolder> {
    crate::runner::groups::handle_interrupts(crate::runner::groups::Left::NoReport);
    super::paths::work_dir("rtprobe-shader")
}

/// Everything checked and planned before the report is reserved.
pub(super) fn prepare(g: &Globals, a: &RunArgs) -> Result<Prepared> {
    refuse_others(a)?;
    refuse_early(a)?;
    let profile = shader_profile::read(a.profile.as_deref())?;
    let (repeat, timeout, setup_timeout) = numbers(a)?;
    let scene = load_scene(a)?;
    let mut sizes = sizes(a)?;
    if let (Some((l, _)), None) = (&scene, sizes.array) {
        let most = crate::harness::sizes::MAX_ARRAY_SIZE;
        sizes.array = Some(crate::harness::scene::loaded_bound(l).min(most));
    }
    let inject_fault = injection(a)?;
    let mut plan = shader_plan::plan(a, inject_fault.as_ref())?;
    plan.modules = sizes.apply(plan.modules);
    let model = model(a, &plan)?;
    let heap_layout = heap_layout(a, &plan, model)?;
    let spec = crate::harness::spec::parse_all(&a.spec, &plan.given)
        .map_err(|e| coded(exit::USAGE, e.to_string()))?;
    let (fills, scene_fills, fill_words) =
        super::shader_fill::fills(a, &plan, &sizes, scene.as_ref().map(|(l, _)| l))?;
    let images = scene_images(scene.as_ref(), &scene_fills)?;
    let resolved = super::shader_fill::Resolved {
        spec: crate::harness::spec::canonical(&spec, &plan.given),
        fill: fill_words,
        profile: shader_profile::setup(profile.as_ref())
            .effective(model == DescriptorModel::DescriptorIndexing),
        scene: scene.as_ref().map(|(_, h)| images.hash.clone().unwrap_or(h.clone())),
    };
    let cell_options = super::shader_fill::cell_options(a, &plan, model, resolved)?;
    let other = other_report(a, &shader_run::cell_id_with(&plan.inputs, &cell_options))?;
    let baseline = a.baseline.as_deref().map(super::fleet::load_baseline).transpose()?;
    super::paths::writable_files(&[("--junit", a.junit.as_deref())])?;
    let Chosen { index: device_index, name: device_name, profile: record, heap, vote, max_sets } =
        device(g, a, &plan, (model, profile.as_ref()))?;
    if let Some((l, _)) = &scene {
        scene_fits(a, l, (&scene_fills, images.bytes), heap)?;
    }
    let work = work_folder()?;
    let dir = work.path().to_path_buf();
    let ctx = Ctx {
        device_index,
        validate: g.validate,
        scalar: plan.scalar,
        unpatched: plan
            .given
            .iter()
            .map(|m| JobModule {
                name: m.name.clone(),
                words: m.words.clone(),
                ray_type: m.ray_type,
            })
            .collect(),
        repeat,
        timeout,
        setup_timeout,
        dir,
        model,
        spec,
        heap_layout,
        sizes,
        fills,
        scene: a.scene.as_ref().map(|p| std::path::absolute(p).unwrap_or(p.clone())),
        scene_fills,
        profile: shader_profile::setup(profile.as_ref()),
        gpu_av: false,
    };
    let profile = record;
    Ok(Prepared {
        plan,
        ctx,
        device_name,
        cell_options,
        profile,
        vote,
        max_sets,
        other,
        baseline,
        _work: work,
    })
}

pub fn run_shaders(g: &Globals, a: &RunArgs) -> Result<u8> {
    let mut p = prepare(g, a)?;
    let (out, _lock) = reserve_out(a, &p.device_name)?;
    let report = judged_report(g, a, &mut p);
    let report = report.and_then(|mut r| {
        if g.gpu_av {
            r.variants =
                super::shader_gpu_av::rerun(&p.ctx, &p.plan, std::mem::take(&mut r.variants))?;
            r.refresh_outcome();
        }
        Ok(r)
    });
    finish(a, &p, report?, &out)
}

/// The descriptor-index check (`shader_bounds`); after a size-up, the device's checks and
/// `--profile`'s record made again for the sized pipeline and the size in the cell id; then
/// `--compare`'s report held to that id.
fn index_check(g: &Globals, a: &RunArgs, p: &mut Prepared) -> Result<IndexBounds> {
    let bounds = if a.no_index_check {
        IndexBounds::unchecked("--no-index-check")
    } else {
        super::shader_bounds::check(
            &mut p.ctx,
            &mut p.plan,
            (a.array_size.is_some(), (p.vote, p.max_sets)),
        )?
    };
    if let Some((_, to)) = bounds.grown {
        let profile = shader_profile::read(a.profile.as_deref())?;
        let model = (p.ctx.model, profile.as_ref());
        p.profile = device(g, a, &p.plan, model)?.profile;
        // What runs is what `--array-size` would have run: the same cell.
        p.cell_options.array_size = Some(to as u64);
    }
    let cell = shader_run::cell_id_with(&p.plan.inputs, &p.cell_options);
    if let (Some(other), Some(path)) = (&p.other, &a.compare) {
        super::shader_compare::same_cell(path, other, &cell)?;
    }
    Ok(bounds)
}

/// The variants run, compared among themselves and with `--compare`'s report, `--dump`ed, and
/// the report made with the options that changed what ran.
fn judged_report(g: &Globals, a: &RunArgs, p: &mut Prepared) -> Result<ShaderRunReport> {
    let bounds = index_check(g, a, p)?;
    let (plan, ctx) = (&p.plan, &p.ctx);
    let (unpatched, patched) = run_all(ctx, plan)?;
    let (mut unpatched, unpatched_teardown) = (unpatched.ran, unpatched.teardown);
    let mut teardowns = vec![unpatched_teardown];
    let mut patched: Patched = patched
        .into_iter()
        .map(|(n, v)| {
            teardowns.push(v.teardown);
            (n, v.ran)
        })
        .collect();
    let device = unpatched
        .iter()
        .chain(patched.iter().flat_map(|p| &p.1))
        .find_map(|r| r.device.clone())
        .unwrap_or(p.device_name.clone());
    let mut notes = plan.notes.clone();
    notes.extend(plan.injection.as_ref().map(|i| i.line()));
    notes.extend(bounds.note());
    let judged = shader_exec::compare_all(&device, &mut unpatched, &mut patched);
    notes.extend(judged.note);
    let compared = p.other.as_ref().map(|other| {
        let against = super::shader_compare::Against {
            other,
            path: a.compare.as_deref().unwrap_or(Path::new("")),
            tolerance: a.tolerance,
            modules: &plan.modules,
        };
        super::shader_compare::compare_all(&against, &mut unpatched, &mut patched)
    });
    if let Some(d) = &a.dump {
        dump(d, plan, &unpatched, &patched)?;
    }
    let (data, capped) = embedded(&unpatched, &patched);
    notes.extend(capped);
    let (compare_notes, compare) = compared.unzip();
    notes.extend(compare_notes.into_iter().flatten());
    let mut report = report(
        a,
        plan,
        device,
        unpatched,
        patched,
        (notes, judged.uncompared),
        (ctx.repeat, ctx.timeout, g.validate),
    );
    report.options["descriptor_model"] = serde_json::json!(ctx.model.as_str());
    for ((v, t), d) in report.variants.iter_mut().zip(teardowns).zip(data) {
        (v.teardown, v.data) = (t, d);
    }
    super::shader_uniform::explain(&ctx.unpatched, &bounds, &mut report.variants);
    report.compare = compare;
    if let Some((_, to)) = bounds.grown {
        // What ran: `reduce` re-creates the run from it.
        report.options["array_size"] = serde_json::json!(to);
    }
    report.index_bounds = (!bounds.is_empty()).then_some(bounds);
    let cell_options = std::mem::take(&mut p.cell_options);
    report.options["fill"] = serde_json::json!(cell_options.fill);
    // The `--fill` arguments as given: `reduce` re-creates the run from them.
    report.options["fill_args"] = serde_json::json!(a.fill);
    report.cell = shader_run::cell_id_with(&plan.inputs, &cell_options);
    report.cell_options = cell_options;
    report.options["profile"] = serde_json::json!(p.profile.as_ref().map(|p| &p.hash));
    report.options["gpu_av"] = serde_json::json!(g.gpu_av);
    report.options["scene"] = serde_json::json!(a.scene.as_ref().map(|p| p.display().to_string()));
    report.options["hit_groups"] = serde_json::json!(a.hit_groups);
    report.profile = p.profile.take();
    Ok(report)
}

/// Each variant's outputs to embed, and a note for those over the cap.
fn embedded(
    unpatched: &[shader_exec::Ran],
    patched: &Patched,
) -> (Vec<Vec<crate::model::shader_outputs::OutputData>>, Option<String>) {
    let mut all: Vec<(&str, &[shader_exec::Ran])> = vec![("unpatched", unpatched)];
    all.extend(patched.iter().map(|(n, r)| (n.as_str(), r.as_slice())));
    super::shader_compare::embed(&all)
}

/// The baseline's check, the report (atomically), `--junit`, the summary; the exit code.
fn finish(a: &RunArgs, p: &Prepared, mut report: ShaderRunReport, out: &Path) -> Result<u8> {
    if let (Some(b), Some(path)) = (&p.baseline, &a.baseline) {
        let source = path.display().to_string();
        report.baseline = Some(crate::fleet::shader_baseline::check(&report, b, &source));
    }
    let json = serde_json::to_vec_pretty(&report).context("the report's JSON")?;
    crate::atomic::write_atomic(out, &json)
        .map_err(|e| coded(exit::BAD_INPUT, format!("writing {}: {e}", out.display())))?;
    if let Some(j) = &a.junit {
        let xml = crate::report::shader_junit::render(&report);
        crate::atomic::write_atomic(j, xml.as_bytes())
            .map_err(|e| coded(exit::BAD_INPUT, format!("writing {}: {e}", j.display())))?;
    }
    let (lines, code) = super::shader_report::summary(&report, out, a.allow_improvements);
    for l in lines {
        outln!("{l}");
    }
    Ok(code)
}

/// Patched variants with their attempts.
type Patched = Vec<(String, Vec<Ran>)>;

fn run_all(ctx: &Ctx, plan: &ShaderPlan) -> Result<(VariantRun, Vec<(String, VariantRun)>)> {
    let unpatched = shader_exec::run_variant(ctx, "unpatched", &ctx.unpatched, None)?;
    let mut patched = Vec::new();
    for v in &plan.variants {
        let name = v.patch.as_str();
        patched.push((
            name.to_string(),
            shader_exec::run_variant(ctx, name, &v.modules, Some(&v.contract))?,
        ));
    }
    Ok((unpatched, patched))
}

/// `--dump DIR`: the images of each variant's first attempt that ran and of every attempt that
/// differs from the reference.
fn dump(dir: &Path, plan: &ShaderPlan, unpatched: &[Ran], patched: &Patched) -> Result<()> {
    std::fs::create_dir_all(dir)
        .map_err(|e| coded(exit::BAD_INPUT, format!("--dump {}: {e}", dir.display())))?;
    let all = std::iter::once(("unpatched", unpatched))
        .chain(patched.iter().map(|(n, r)| (n.as_str(), r.as_slice())));
    for (name, ran) in all {
        let first = ran.iter().position(|r| r.parts.is_some());
        for (k, r) in ran.iter().enumerate() {
            let Some(parts) = &r.parts else { continue };
            if Some(k) == first || r.attempt.differs.is_some() {
                let prefix = format!("{name}-{}", k + 1);
                super::shader_report::dump(dir, &prefix, &plan.modules, parts).map_err(|e| {
                    coded(exit::BAD_INPUT, format!("--dump {}: {e:#}", dir.display()))
                })?;
            }
        }
    }
    Ok(())
}

fn report(
    a: &RunArgs,
    plan: &ShaderPlan,
    device: String,
    unpatched: Vec<Ran>,
    patched: Patched,
    (notes, uncompared): (Vec<String>, Option<&str>),
    (repeat, timeout, validate): (u32, Duration, bool),
) -> ShaderRunReport {
    let attempts = |ran: Vec<Ran>| ran.into_iter().map(|r| r.attempt).collect::<Vec<_>>();
    let mut variants =
        vec![ShaderVariant::judged("unpatched", None, vec![], attempts(unpatched), None)];
    for ((name, ran), planned) in patched.into_iter().zip(&plan.variants) {
        let mut lines = planned.lines.clone();
        if !planned.contract.is_empty() {
            lines.push(planned.contract.sentence());
        }
        let why = uncompared.map(String::from);
        variants.push(ShaderVariant::judged(&name, Some(name.clone()), lines, attempts(ran), why));
    }
    let outcome = variants
        .iter()
        .map(|v| v.outcome)
        .max_by_key(|o| o.severity())
        .unwrap_or(crate::model::Outcome::Error);
    let options = serde_json::json!({
        "repeat": repeat,
        "timeout_s": timeout.as_secs_f64(),
        "validate": validate,
        "entry": a.entry,
        "include_dirs": a.include_dirs,
        "defines": a.defines,
        "target_env": format!("{:?}", a.target_env.unwrap_or_default()),
        "spec": a.spec,
        "heap_layout": a.heap_layout,
        "array_size": a.array_size,
        "sink_size": a.sink_size,
    });
    ShaderRunReport {
        schema: shader_run::SCHEMA.into(),
        rtprobe_version: env!("CARGO_PKG_VERSION").into(),
        device,
        cell: shader_run::cell_id(&plan.inputs),
        options,
        inputs: plan.inputs.clone(),
        variants,
        outcome,
        notes,
        injection: plan.injection.clone(),
        profile: None,
        cell_options: Default::default(),
        compare: None,
        index_bounds: None,
        baseline: None,
    }
}
