//! `rtprobe run`: check the arguments (`--resume` takes them from its report), resolve them into
//! a plan (before any GPU work; `cli::plan`), print it (`--list`) or lock the report and run its
//! rounds (`campaign`) through the supervisor with progress (`cli::progress`), then print the
//! summary and the one verdict line, and write the report's companions (JUnit, `--output-dir`).
use super::args::RunArgs;
use super::commands::{open_instance, Globals};
use super::exit::{self, coded};
use super::out::{errln, out, outln};
use super::plan::{self as run_plan, PlanArgs};
use super::shared::{
    default_jobs, default_threads, rerun_jobs, supervisor_options, SupervisorOracle,
};
use crate::atomic::{write_atomic, WriteError};
use crate::campaign::{start, Campaign, Policy, Recorder};
use crate::fleet::baseline::Scope;
use crate::fleet::deqp_files::Patterns;
use crate::fleet::shard::Shard;
use crate::matrix::plan;
use crate::model::report::RunOptions;
use crate::model::{
    Baseline, Cell, Filter, Injection, Mutant, MutantPrediction, RunPlan, RunReport, SceneParams,
};
use crate::report::lock::{LockError, ReportLock};
use crate::report::mutants::{Prefilter, Sample};
use crate::report::writer::ReportWriter;
use crate::report::{junit, summary, time, verdict};
use crate::runner::supervisor::SupervisorOptions;
use crate::vk::{features, DeviceInfo};
use anyhow::{Context, Result};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

fn scene_params(a: &RunArgs) -> Result<SceneParams> {
    let (w, h) = a
        .size
        .split_once(['x', 'X'])
        .and_then(|(w, h)| Some((w.trim().parse::<u32>().ok()?, h.trim().parse::<u32>().ok()?)))
        .ok_or_else(|| {
            coded(exit::USAGE, format!("--size {:?} is not WIDTHxHEIGHT (e.g. 64x64)", a.size))
        })?;
    let mut p = SceneParams {
        seed: a.seed,
        width: w,
        height: h,
        instances: a.instances,
        mesh_detail: a.mesh_detail,
        file: None,
    };
    if let Some(path) = &a.scene {
        // The loader's one-line error (exit 9) before any device work; the file's instances
        // replace `--instances`.
        let loaded = crate::scene::gltf::Loaded::load(path)?;
        p.instances = loaded.instances.len() as u32;
        p.file = Some(crate::scene::file::identity(&loaded)?);
        p.validate()
            .map_err(|e| coded(exit::BAD_INPUT, format!("--scene {}: {e}", path.display())))?;
    }
    p.validate().map_err(|e| coded(exit::USAGE, format!("scene: {e}")))?;
    Ok(p)
}

/// The run's scene made on the CPU (`load_ms`: how long that took), traced by the reference,
/// timed, and held to the plan's cells: those it cannot discriminate.
fn scene_summary(
    params: &SceneParams,
    (scene, load_ms): (crate::scene::Scene, f64),
    plan: &RunPlan,
) -> Result<crate::model::report::SceneSummary> {
    let t = Instant::now();
    let sref = crate::reference::SceneReference::compute(&scene);
    let reference_ms = t.elapsed().as_secs_f64() * 1e3;
    let cells: Vec<Cell> = plan.to_run().copied().collect();
    let limits = crate::reference::limits::of(&scene, &sref, &cells);
    let cost = crate::model::SceneCost { load_ms, reference_ms, peak_mib: peak_mib() };
    if params.file.is_some() {
        errln!(
            "scene: loaded in {load_ms:.0} ms, CPU reference in {reference_ms:.0} ms, peak memory {}",
            cost.peak_mib.map_or("unknown".into(), |m| format!("{m} MiB"))
        );
    }
    Ok(start::scene_summary(params.clone(), &scene, limits, cost))
}

/// This process's peak resident memory (VmHWM), in MiB.
fn peak_mib() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib.div_ceil(1024))
}

/// `--pipeline-cache DIR|off`, else the default folder (`None`: off, or no folder known).
fn pipeline_cache_dir(arg: Option<&str>) -> Option<PathBuf> {
    match arg {
        Some("off") => None,
        Some(dir) => Some(PathBuf::from(dir)),
        None => crate::exec::pipeline_cache::default_dir(),
    }
}

pub(super) fn slug(name: &str) -> String {
    let s: String = name
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c.to_ascii_lowercase() } else { '-' })
        .collect();
    s.split('-').filter(|p| !p.is_empty()).take(4).collect::<Vec<_>>().join("-")
}

pub fn run(g: &Globals, a: &RunArgs) -> Result<u8> {
    // The binding stages are read here once (a bundle's, the user's RTPROBE_BINDING_STAGES, or
    // the resumed report's); from now on the report's options and each job file carry them.
    let (a, mut binding_stages) = match &a.cell_spec {
        Some(p) => cell_spec_args(a, p)?,
        None => (a.clone(), std::env::var("RTPROBE_BINDING_STAGES").ok()),
    };
    // `--resume`: the report stays locked for the whole run (`_resume_lock`).
    let (g, a, resumed, _resume_lock) = match &a.resume {
        Some(p) => {
            let (g, a, (old, lock)) = resumed_args(g, &a, p)?;
            binding_stages = binding_stages.or_else(|| old.options.binding_stages.clone());
            (g, a, Some(old), Some(lock))
        }
        None => (Globals { validate: g.validate, gpu_av: g.gpu_av }, a, None, None),
    };
    let (g, a) = (&g, &a);
    let c = check(a)?;
    tracing::debug!("run: arguments checked");
    let inst = open_instance(g)?;
    let info = select_device(&inst, a, resumed.as_ref())?;
    tracing::debug!("run: instance created, device selected");
    let mut options = run_options(g, a, &c, &info, binding_stages);
    let mode = super::shared::pipeline_mode(a.pipelines, &info)
        .map_err(|e| coded(exit::UNSUPPORTED_DEVICE, e))?;
    options.pipelines = Some(mode);
    let pa = c.plan_args(a);
    let made = run_plan::make(&info, &pa);
    let (mut the_plan, mut sharded_out) = (made.plan, made.sharded_out);
    // (cells --cells-scale leaves out stay in the baseline's scope: the run did not check them)
    sharded_out += a.cells_scale.map(|n| the_plan.scale_to(n)).unwrap_or(0);
    if a.list {
        run_plan::print_list(&the_plan, c.shard, sharded_out);
        return run_plan::nothing_planned(&the_plan, &pa, sharded_out).map_or(Ok(exit::OK), Err);
    }
    if let Some(e) = run_plan::nothing_planned(&the_plan, &pa, sharded_out) {
        return Err(e);
    }
    // The scene made on the CPU (a `--scene` file loaded again and held to its hash) and held to
    // the plan and the device before anything is written (`scene_check`).
    let t = Instant::now();
    let scene = crate::scene::Scene::of(&c.params)?;
    let load_ms = t.elapsed().as_secs_f64() * 1e3;
    super::scene_check::check(&scene, &mut the_plan, &info)?;
    if let Some(e) = run_plan::nothing_runs(&the_plan, &info, sharded_out) {
        return Err(e);
    }
    tracing::debug!("run: planned");
    let started = time::now_unix();
    let (out, _lock) = reserve_out(a, started, &info, resumed.is_some())?;
    let scene = scene_summary(&c.params, (scene, load_ms), &the_plan)?;
    let fresh = start::fresh(
        &info,
        scene,
        &the_plan,
        sharded_out,
        options.clone(),
        std::env::args().collect(),
        started,
    );
    let base = match resumed {
        Some(old) => continued(a, old, fresh)?,
        None => fresh,
    };
    let scope = Scope { elsewhere: made.elsewhere, filters: c.filters.clone() };
    let c = Checked { baseline: with_flakes(&c, &the_plan), scope, ..c };
    run_rounds(&inst, a, &c, &info, &the_plan, options, base, out)
}

/// `--resume REPORT`: the report locked (no other run writes it) and read, and the arguments
/// taken from it (`cli::resume`).
fn resumed_args(
    g: &Globals,
    a: &RunArgs,
    p: &Path,
) -> Result<(Globals, RunArgs, (RunReport, ReportLock))> {
    let lock = ReportLock::acquire(p).map_err(|e| match e {
        LockError::Busy { .. } => coded(
            exit::BAD_INPUT,
            format!("cannot resume: {e}; wait for it to end (or stop it), then resume"),
        ),
        e => coded(exit::BAD_INPUT, e),
    })?;
    let old = RunReport::load(p).map_err(|e| coded(exit::BAD_INPUT, e))?;
    let (g, a) = super::resume::args(g, a, p, &old)?;
    Ok((g, a, (old, lock)))
}

/// The run's rounds through the supervisor, from the report `base` written to `out`, then the
/// end: summary, files, verdict.
#[allow(clippy::too_many_arguments)] // one call, from `run`, with what it resolved
fn run_rounds(
    inst: &crate::vk::Instance,
    a: &RunArgs,
    c: &Checked,
    info: &DeviceInfo,
    the_plan: &RunPlan,
    options: RunOptions,
    base: RunReport,
    out: PathBuf,
) -> Result<u8> {
    let mut writer = ReportWriter::new(out.clone(), base, the_plan);
    let (cells, canaries) = start::pending(&mut writer, the_plan, a.resume.is_some());
    writer.save(false).with_context(|| "writing the report")?;
    crate::runner::groups::set_resume_hint(&super::resume::command(a, &out));
    let opts = supervisor(a, &options, info, c);
    let mut oracle = SupervisorOracle::for_run(opts);
    let mut rec = Recorder::new(writer, super::progress::for_stderr());
    let wall = Instant::now();
    let supported = |cell: &Cell| plan::device_support(info, cell).is_supported();
    let policy = Policy::of(&options, || inst.validation_layer_version());
    // The mutants' reference (a scene and its trace on the CPU), made only when asked for.
    let prefilter = policy.mutants.as_ref().map(|_| Prefilter::new(&c.params)).transpose()?;
    let applies = |cell: &Cell| -> Result<MutantPrediction, String> {
        prefilter.as_ref().ok_or_else(|| "no --mutants".to_string())?.applies(cell)
    };
    tracing::debug!("run: report started, rounds begin");
    Campaign { oracle: &mut oracle, rec: &mut rec, supported: &supported, applies: &applies }
        .run(&policy, &cells, &canaries);
    tracing::debug!("run: rounds done");
    rec.progress.finish();
    if let Some(e) = rec.save_error.take() {
        return Err(save_failed(e, a, &out));
    }
    if let Some(halt) = rec.halted {
        rec.writer.save(true).map_err(|e| save_failed(e, a, &out))?;
        return Err(exit::halted(halt, &out));
    }
    let baseline = c.baseline.as_ref().map(|(b, s)| (b, s.as_str(), &c.scope));
    start::finish(&mut rec, wall.elapsed(), baseline);
    print_end(a, &rec.writer, &out)
}

/// A report save that failed: on a full disk, the report on disk is the last whole save (each
/// save replaces it atomically), so it is valid and `--resume` finishes the run.
fn save_failed(e: WriteError, a: &RunArgs, out: &Path) -> anyhow::Error {
    if e.storage_full() && out.exists() {
        return coded(
            exit::BAD_INPUT,
            format!(
                "writing the report: {e}; the report on disk is the last one saved whole, valid and resumable: free some space, then `{}`",
                super::resume::command(a, out)
            ),
        );
    }
    anyhow::Error::from(e).context("writing the report")
}

/// A repro bundle's cell (`--cell-spec`): exactly that cell, its scene, injections and binding
/// stages, its SPIR-V when the bundle has it, and no persisted pipeline cache.
fn cell_spec_args(a: &RunArgs, p: &Path) -> Result<(RunArgs, Option<String>)> {
    let spec = crate::model::bundle::CellSpec::load(p)?;
    if let Some(f) = &spec.scene.file {
        crate::scene::file::load_same(f)?;
    }
    let mut args = spec.run_args(a)?;
    args.spirv_dir = spec.spirv_dir(p)?;
    // The cell's own compile, not a binary a cache kept from another run (docs/performance.md).
    args.pipeline_cache = Some("off".into());
    args.fresh = true;
    if let Some(dir) = &args.spirv_dir {
        let made_by: std::collections::BTreeSet<&str> =
            spec.modules.iter().map(|m| m.compiler.as_str()).collect();
        errln!(
            "running the bundle's SPIR-V ({}, made by {}), not recompiling",
            dir.display(),
            made_by.into_iter().collect::<Vec<_>>().join(", ")
        );
    }
    Ok((args, spec.binding_stages.clone()))
}

/// `run`'s arguments, parsed and held to their ranges (usage errors, before any device work).
struct Checked {
    filters: Vec<Filter>,
    skips: Patterns,
    inject: Vec<Injection>,
    shard: Option<Shard>,
    /// `--baseline` (with `--flakes` added once the plan is known) and where it came from.
    baseline: Option<(Baseline, String)>,
    flakes: Option<(Patterns, String)>,
    params: SceneParams,
    /// `--mutants` / `--mutant` / `--mutants-sample`: the mutants tried (empty: none).
    mutants: Vec<Mutant>,
    /// Where the baseline entries the plan lacks went (other shards, `--filter`, `--skips`): set
    /// once the plan is made.
    scope: Scope,
}

/// The mutants `--mutants`, `--mutant NAME` and `--mutants-sample` ask for (empty: none).
fn mutants_of(a: &RunArgs) -> Result<Vec<Mutant>> {
    if let Some(s) = &a.mutants_sample {
        Sample::parse(s).map_err(|e| coded(exit::USAGE, e))?;
    }
    let named: Vec<Mutant> = a
        .mutant
        .iter()
        .map(|n| {
            crate::model::mutant::parse_list(n)
                .map_err(|e| coded(exit::USAGE, format!("--mutant: {e}")))
        })
        .collect::<Result<Vec<_>>>()?
        .into_iter()
        .flatten()
        .collect();
    Ok(if !named.is_empty() {
        Mutant::ALL.iter().copied().filter(|m| named.contains(m)).collect()
    } else if a.mutants || a.mutants_sample.is_some() {
        Mutant::ALL.to_vec()
    } else {
        vec![]
    })
}

impl Checked {
    fn plan_args<'a>(&'a self, a: &RunArgs) -> PlanArgs<'a> {
        PlanArgs {
            filters: &self.filters,
            skips: &self.skips,
            canaries: a.canaries,
            patches: a.patches,
            inject: &self.inject,
            shard: self.shard,
        }
    }
}

/// A `--skips` / `--flakes` file (deqp-runner's regular expressions, `fleet::deqp_files`).
fn patterns(p: &Path, flag: &str) -> Result<Patterns> {
    let text = std::fs::read_to_string(p)
        .map_err(|e| coded(exit::BAD_INPUT, format!("cannot read {flag} {}: {e}", p.display())))?;
    Patterns::parse(&p.display().to_string(), &text).map_err(|e| coded(exit::BAD_INPUT, e))
}

fn check(a: &RunArgs) -> Result<Checked> {
    let filters = a
        .filter
        .iter()
        .map(|f| Filter::parse(f).map_err(|e| coded(exit::USAGE, e)))
        .collect::<Result<Vec<_>>>()?;
    let inject = a
        .inject_fault
        .iter()
        .filter(|s| !s.trim().is_empty())
        .map(|s| Injection::parse(s).map_err(|e| coded(exit::USAGE, e)))
        .collect::<Result<Vec<_>>>()?;
    check_ranges(a)?;
    let shard =
        a.shard.as_deref().map(Shard::parse).transpose().map_err(|e| coded(exit::USAGE, e))?;
    let baseline = match &a.baseline {
        Some(p) => Some((super::fleet::load_baseline(p)?, p.display().to_string())),
        None => None,
    };
    let skips = match (&a.skips, &a.skip_patterns) {
        (Some(p), _) => patterns(p, "--skips")?,
        (None, Some(lines)) => {
            Patterns::of(lines.clone()).map_err(|e| coded(exit::BAD_INPUT, e))?
        }
        (None, None) => Patterns::of(vec![]).map_err(|e| coded(exit::INTERNAL, e))?,
    };
    let flakes = match &a.flakes {
        Some(p) => Some((patterns(p, "--flakes")?, p.display().to_string())),
        None => None,
    };
    let params = scene_params(a)?;
    check_outputs(a)?;
    let mutants = mutants_of(a)?;
    let scope = Scope::default();
    Ok(Checked { filters, skips, inject, shard, baseline, flakes, params, mutants, scope })
}

/// The numbers `run` takes, in their ranges.
fn check_ranges(a: &RunArgs) -> Result<()> {
    let bad = |cond: bool, what: &str| {
        if cond {
            Err(coded(exit::USAGE, what.to_string()))
        } else {
            Ok(())
        }
    };
    bad(a.repeat.is_some_and(|n| n == 0 || n > 1000), "--repeat must be 1..=1000")?;
    bad(a.jobs.is_some_and(|j| j == 0 || j > 64), "--jobs must be 1..=64")?;
    bad(a.threads.is_some_and(|t| t == 0 || t > 64), "--threads must be 1..=64")?;
    bad(a.cells_scale.is_some_and(|n| n == 0 || n > 100_000), "--cells-scale must be 1..=100000")?;
    bad(
        a.pipeline_cache.as_deref().is_some_and(|d| d.trim().is_empty()),
        "--pipeline-cache needs a folder, or `off`",
    )?;
    bad(!(a.timeout > 0.0 && a.timeout <= 3600.0), "--timeout must be in (0, 3600] seconds")?;
    bad(
        !(a.setup_timeout > 0.0 && a.setup_timeout <= 3600.0),
        "--setup-timeout must be in (0, 3600] seconds",
    )
}

/// Every file and folder the run will write, writable before it starts.
fn check_outputs(a: &RunArgs) -> Result<()> {
    super::paths::writable_files(&[("-o", a.out.as_deref()), ("--junit", a.junit.as_deref())])?;
    super::paths::temp_usable()?;
    for (flag, dir) in [("--output-dir", &a.output_dir), ("--dump", &a.dump)] {
        if let Some(d) = dir {
            super::paths::writable_dir(d, flag)?;
        }
    }
    Ok(())
}

/// The baseline with `--flakes`' cells of the plan added as known flakes.
fn with_flakes(c: &Checked, the_plan: &RunPlan) -> Option<(Baseline, String)> {
    let Some((flakes, file)) = &c.flakes else { return c.baseline.clone() };
    let ids: Vec<String> = the_plan.cells.iter().map(|p| p.cell.id()).collect();
    let (base, source) = match &c.baseline {
        Some((b, s)) => (Some(b.clone()), format!("{s} + --flakes {file}")),
        None => (None, format!("--flakes {file}")),
    };
    let b = crate::fleet::deqp_files::with_flakes(
        base,
        flakes,
        &source,
        ids.iter().map(String::as_str),
    );
    Some((b, source))
}

/// The device: `--device`, else for `--resume` the report's own (by identity), else the first
/// RT-capable one (for a report of a device not here, the resume is then refused saying what
/// differs: `continued`).
fn select_device(
    inst: &crate::vk::Instance,
    a: &RunArgs,
    resumed: Option<&RunReport>,
) -> Result<DeviceInfo> {
    let all = features::query_all(inst)?;
    if let (Some(r), None) = (resumed, &a.device) {
        let same = |d: &&DeviceInfo| {
            let j = crate::caps::device_json(d);
            crate::fleet::merge::DEVICE_KEYS.iter().all(|k| j[*k] == r.device[*k])
        };
        if let Some(d) = all.iter().find(same) {
            return Ok(d.clone());
        }
    }
    Ok(features::select(&all, a.device.as_deref())?.clone())
}

/// The run's options as its report records them: jobs and threads (defaults per device type),
/// the pipeline cache folder, and every result-changing option.
fn run_options(
    g: &Globals,
    a: &RunArgs,
    c: &Checked,
    info: &DeviceInfo,
    binding_stages: Option<String>,
) -> RunOptions {
    // Under validation a cell's `validation_errors` is the global counter's difference around its
    // own work, so its pipelines must be created at its turn: VUIDs raised on prebuild threads
    // would fall outside every cell's window. `--validate` (any mode) runs with one thread.
    let threads = if g.validate { 1 } else { a.threads.unwrap_or_else(|| default_threads(info)) };
    let jobs = a.jobs.unwrap_or_else(|| default_jobs(info));
    if g.validate && a.threads.is_some_and(|t| t > 1) {
        errln!("rtprobe: note: --validate runs with --threads 1, so that each validation error is counted for the cell that raised it");
    }
    RunOptions {
        jobs: Some(jobs),
        rerun_jobs: Some(rerun_jobs(info, jobs)),
        threads: Some(threads),
        pipeline_cache: pipeline_cache_dir(a.pipeline_cache.as_deref()),
        rerun_pipeline_cache: None,
        isolation: a.isolation,
        timeout_s: a.timeout,
        setup_timeout_s: Some(a.setup_timeout),
        confirm: !a.no_confirm,
        canaries: a.canaries,
        filters: a.filter.clone(),
        skips: c.skips.lines.clone(),
        patches: a.patches,
        validate: g.validate,
        gpu_av: g.gpu_av,
        inject: c.inject.iter().map(|i| i.spec.clone()).collect(),
        repeat: a.repeat,
        shard: c.shard.map(|s| s.label()),
        pipelines: None,
        cells_scale: a.cells_scale,
        binding_stages,
        lane_evidence: a.lane_evidence,
        spirv_from: a.spirv_dir.clone(),
        merged_from: vec![],
        mutants: c.mutants.clone(),
        mutants_sample: a.mutants_sample.clone(),
        extra: Default::default(),
    }
}

/// The supervisor options of the run's workers, from its options.
fn supervisor(a: &RunArgs, o: &RunOptions, info: &DeviceInfo, c: &Checked) -> SupervisorOptions {
    SupervisorOptions {
        dump: a.dump.clone(),
        spirv_dir: a.spirv_dir.clone(),
        setup_timeout: Duration::from_secs_f64(a.setup_timeout),
        threads: o.threads.unwrap_or(1),
        pipeline_cache: o.pipeline_cache.clone(),
        binding_stages: o.binding_stages.clone(),
        lane_evidence: o.lane_evidence,
        fresh: a.fresh,
        internal_cache_control: crate::vk::device::internal_cache_control(info),
        linked: o.pipelines == Some(crate::model::PipelineMode::Linked),
        rerun_jobs: o.rerun_jobs.unwrap_or_else(|| rerun_jobs(info, o.jobs.unwrap_or(1))),
        ..supervisor_options(
            info.index,
            c.params.clone(),
            o.jobs.unwrap_or_else(|| default_jobs(info)),
            o.isolation,
            o.timeout_s,
            o.validate,
            c.inject.clone(),
        )
    }
}

/// Where the report goes, locked for this run (no other run writes it meanwhile): `-o`, else
/// `--output-dir`'s report.json, else the report resumed (`resumed`: already locked), else the
/// first free `reports/run-<time>-<device>[-N].json`.
fn reserve_out(
    a: &RunArgs,
    started: u64,
    info: &DeviceInfo,
    resumed: bool,
) -> Result<(PathBuf, Option<ReportLock>)> {
    let busy = |e: LockError| match e {
        LockError::Busy { .. } => coded(exit::BAD_INPUT, format!("{e}; give this run another -o")),
        e => coded(exit::BAD_INPUT, e),
    };
    let given =
        a.out.clone().or_else(|| a.output_dir.as_deref().map(super::output_dir::report_path));
    match (given, &a.resume) {
        (Some(o), Some(r)) if resumed && o == *r => Ok((o, None)),
        (Some(o), _) => Ok((o.clone(), Some(ReportLock::acquire(&o).map_err(busy)?))),
        (None, Some(r)) if resumed => Ok((r.clone(), None)),
        (None, _) => {
            let stem = format!("run-{}-{}", time::stamp(started), slug(&info.name()));
            let (path, lock) = ReportLock::unique(Path::new("reports"), &stem).map_err(busy)?;
            Ok((path, Some(lock)))
        }
    }
}

/// The report `--resume` continues, if `fresh` is the same run (it is, unless an argument given
/// to this run differs: `cli::resume` refuses those first).
fn continued(a: &RunArgs, old: RunReport, fresh: RunReport) -> Result<RunReport> {
    let path = a.resume.as_deref().unwrap_or(Path::new("?"));
    start::resume(old, &fresh).map_err(|why| {
        coded(
            exit::BAD_INPUT,
            format!("cannot resume {}: {why}; start a new run instead", path.display()),
        )
    })
}

/// The pipeline cache's save errors were said on an earlier run already (the cache folder keeps
/// a note of the last ones said; lavapipe 26 fails every save the same way): say them once.
fn cache_errors_known(r: &RunReport) -> bool {
    let Some(pc) = &r.pipeline_cache else { return false };
    let Some(file) = &pc.file else { return false };
    let note = file.with_extension("save-error");
    if pc.save_errors.is_empty() {
        let _ = std::fs::remove_file(&note);
        return false;
    }
    let text = pc.save_errors.join("\n");
    if std::fs::read_to_string(&note).is_ok_and(|t| t == text) {
        return true;
    }
    let _ = crate::atomic::write_atomic(&note, text.as_bytes());
    false
}

/// Write the final report and its companions (`--junit`, `--output-dir`), print the summary,
/// the baseline's lines and the verdict; the exit code is the verdict's.
fn print_end(a: &RunArgs, writer: &ReportWriter, out: &Path) -> Result<u8> {
    writer.save(true).map_err(|e| save_failed(e, a, out))?;
    tracing::debug!("run: report saved");
    let r = &writer.report;
    if let Some(j) = &a.junit {
        write_atomic(j, junit::render(r).as_bytes()).with_context(|| "writing the JUnit file")?;
    }
    if let Some(d) = &a.output_dir {
        super::output_dir::write(d, r)?;
    }
    let quiet = summary::Quiet { cache_errors: cache_errors_known(r) };
    out!("{}", summary::render_quiet(r, quiet));
    if let Some(c) = &r.baseline {
        out!("{}", crate::fleet::baseline::render(c, a.allow_improvements));
    }
    outln!("report: {}", out.display());
    if let Some(d) = &a.output_dir {
        outln!("deqp-runner files: {}", d.join("results.csv").display());
    }
    let v = verdict::verdict(r, a.allow_improvements);
    outln!("{}", v.line());
    tracing::debug!("run: summary printed");
    Ok(exit::of_verdict(&v))
}

#[cfg(test)]
mod tests {
    use crate::model::Attempt;
    use crate::model::Canary;
    use crate::model::{Cell, CellReport, Outcome, RunReport};
    use crate::report::verdict::verdict;

    fn ran(cell: Cell, outcome: Outcome) -> CellReport {
        CellReport::new(&cell, Attempt::for_tests(outcome, false))
    }

    #[test]
    fn an_undetected_canary_fails_the_run_and_a_detected_one_does_not() {
        let code = |r: &RunReport| super::exit::of_verdict(&verdict(r, false));
        let detected = RunReport::for_tests(vec![
            ran(Cell::canary(Canary::InvalidAddress), Outcome::Crash),
            ran(Cell::canary(Canary::InfiniteLoop), Outcome::Timeout),
        ]);
        assert_eq!(code(&detected), super::exit::OK);
        assert_eq!(detected.tally.canaries_detected, 2);
        assert_eq!(detected.summary["crash"], 0, "a detected canary is not a crash finding");
        let junit = crate::report::junit::render(&detected);
        assert!(junit.contains("failures=\"0\""), "{junit}");
        // A driver on which the invalid read ran to completion: classification unproven.
        let undetected =
            RunReport::for_tests(vec![ran(Cell::canary(Canary::InvalidAddress), Outcome::Pass)]);
        assert_eq!(code(&undetected), super::exit::CANARY_UNDETECTED);
        assert_eq!(undetected.tally.canaries_undetected, 1);
        let junit = crate::report::junit::render(&undetected);
        assert!(junit.contains("failures=\"1\"") && junit.contains("canary_undetected"), "{junit}");
        assert!(crate::report::summary::render(&undetected).contains("NOT detected"));
    }

    /// A mutant the reference says must be caught that survived is a probe defect: detection is
    /// unproven, as with an undetected canary (exit 11); a survivor the cell's rule allows is not.
    #[test]
    fn a_probe_defect_among_the_mutants_exits_11_and_an_allowed_survivor_does_not() {
        use crate::model::{Mutant, MutantEntry, MutantReport, MutantStatus};
        let cell = Cell::canary(Canary::InfiniteLoop);
        let survivor = |probe_defect: bool| MutantEntry {
            cell: "c".into(),
            mutant: Mutant::IndexNext,
            status: MutantStatus::Survived,
            why: String::new(),
            outcome: Some(Outcome::Pass),
            prediction: None,
            probe_defect,
            allowed_by: (!probe_defect).then(|| "VUID".into()),
            wall_ms: 0.0,
        };
        let code = |r: &RunReport| super::exit::of_verdict(&verdict(r, false));
        let mut r = RunReport::for_tests(vec![ran(cell, Outcome::Timeout)]);
        assert_eq!(code(&r), super::exit::OK);
        r.mutants = Some(MutantReport { entries: vec![survivor(false)], ..Default::default() });
        assert_eq!(code(&r), super::exit::OK);
        r.mutants = Some(MutantReport { entries: vec![survivor(true)], ..Default::default() });
        assert_eq!(code(&r), super::exit::CANARY_UNDETECTED);
        assert!(verdict(&r, false).line().contains("1 probe defect among the mutants"));
    }
}
