//! `rtprobe run`: check the arguments, resolve them into a plan (before any GPU work), print it
//! (`--list`) or run its rounds (`campaign`) through the supervisor, with a progress bar, and
//! print the summary.
use super::args::RunArgs;
use super::commands::{open_instance, Globals};
use super::exit::{self, coded};
use super::shared::{default_jobs, default_threads, supervisor_options, SupervisorOracle};
use crate::atomic::write_atomic;
use crate::campaign::{start, Campaign, Policy, Progress, Recorder};
use crate::fleet::baseline::Scope;
use crate::fleet::shard::Shard;
use crate::matrix::plan::{self, PlanOptions};
use crate::model::report::RunOptions;
use crate::model::{
    Baseline, Cell, Filter, Injection, Mutant, MutantPrediction, Outcome, PlanStatus, RunPlan,
    RunReport, SceneParams,
};
use crate::report::mutants::{Prefilter, Sample};
use crate::report::writer::ReportWriter;
use crate::report::{junit, summary, time};
use crate::runner::supervisor::SupervisorOptions;
use crate::vk::{features, DeviceInfo};
use anyhow::{Context, Result};
use std::collections::HashSet;
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
    let p = SceneParams {
        seed: a.seed,
        width: w,
        height: h,
        instances: a.instances,
        mesh_detail: a.mesh_detail,
    };
    p.validate().map_err(|e| coded(exit::USAGE, format!("scene: {e}")))?;
    Ok(p)
}

/// `--pipeline-cache DIR|off`, else the default folder (`None`: off, or no folder known).
fn pipeline_cache_dir(arg: Option<&str>) -> Option<PathBuf> {
    match arg {
        Some("off") => None,
        Some(dir) => Some(PathBuf::from(dir)),
        None => crate::exec::pipeline_cache::default_dir(),
    }
}

fn slug(name: &str) -> String {
    let s: String = name
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c.to_ascii_lowercase() } else { '-' })
        .collect();
    s.split('-').filter(|p| !p.is_empty()).take(4).collect::<Vec<_>>().join("-")
}

pub fn run(g: &Globals, a: &RunArgs) -> Result<u8> {
    // The binding stages are read here once (a bundle's, or the user's RTPROBE_BINDING_STAGES);
    // from now on the report's options and each worker's job file carry them.
    let (a, binding_stages) = match &a.cell_spec {
        Some(p) => cell_spec_args(a, p)?,
        None => (a.clone(), std::env::var("RTPROBE_BINDING_STAGES").ok()),
    };
    let a = &a;
    let c = check(a)?;
    tracing::debug!("run: arguments checked");
    let inst = open_instance(g)?;
    let info = select_device(&inst, a)?;
    tracing::debug!("run: instance created, device selected");
    let mut options = run_options(g, a, &c, &info, binding_stages);
    let mode = super::shared::pipeline_mode(a.pipelines, &info)
        .map_err(|e| coded(exit::UNSUPPORTED_DEVICE, e))?;
    options.pipelines = Some(mode);
    let (the_plan, scope, sharded_out) = plan_run(a, &c, &info);
    if a.list {
        print_list(&the_plan, c.shard, sharded_out);
        return Ok(exit::OK);
    }
    tracing::debug!("run: planned");
    let started = time::now_unix();
    let out = out_path(a, started, &info);
    let fresh = start::fresh(
        &info,
        c.params,
        &the_plan,
        sharded_out,
        options.clone(),
        std::env::args().collect(),
        started,
    );
    let writer = ReportWriter::new(out.clone(), base_report(a, fresh)?, &the_plan);
    let (cells, canaries) = start::pending(&writer, &the_plan, a.resume.is_some());
    writer.save(false).with_context(|| "writing the report")?;
    let opts = supervisor(a, &options, &info, &c);
    let job_dir = opts.job_dir.clone();
    let mut oracle = SupervisorOracle::for_run(opts);
    let bar = progress_bar();
    let mut rec = Recorder::new(writer, Box::new(Bar(bar.clone())));
    let wall = Instant::now();
    let supported = |cell: &Cell| plan::device_support(&info, cell).is_supported();
    let policy = Policy::of(&options, || inst.validation_layer_version());
    // The mutants' reference (a scene and its trace on the CPU), made only when asked for.
    let prefilter = policy.mutants.as_ref().map(|_| Prefilter::new(&c.params));
    let applies = |cell: &Cell| -> Result<MutantPrediction, String> {
        prefilter.as_ref().ok_or_else(|| "no --mutants".to_string())?.applies(cell)
    };
    tracing::debug!("run: report started, rounds begin");
    Campaign { oracle: &mut oracle, rec: &mut rec, supported: &supported, applies: &applies }
        .run(&policy, &cells, &canaries);
    tracing::debug!("run: rounds done");
    bar.finish_and_clear();
    let _ = std::fs::remove_dir_all(&job_dir);
    if let Some(e) = rec.save_error.take() {
        return Err(anyhow::Error::from(e).context("writing the report"));
    }
    if let Some(halt) = rec.halted {
        rec.writer.save(true).with_context(|| "writing the report")?;
        return Err(exit::halted(halt, &out));
    }
    let source = a.baseline.as_ref().map(|p| p.display().to_string());
    let baseline = c.baseline.as_ref().zip(source.as_deref()).map(|(b, s)| (b, s, &scope));
    start::finish(&mut rec, wall.elapsed(), baseline);
    print_end(a, &rec.writer, &out)
}

/// The run's plan: the device's matrix with the filters, then this shard's part, then cut or
/// copied to `--cells-scale`; with the scope a baseline is checked in and how many planned cells
/// the shard and the scale left out.
fn plan_run(a: &RunArgs, c: &Checked, info: &DeviceInfo) -> (RunPlan, Scope, usize) {
    let mut the_plan = plan::plan(
        info,
        &PlanOptions {
            filters: c.filters.clone(),
            canaries: a.canaries,
            patches: a.patches,
            inject: c.inject.clone(),
        },
    );
    let before_shard: HashSet<String> = the_plan.cells.iter().map(|c| c.cell.id()).collect();
    let sharded_out = c.shard.map(|s| s.apply(&mut the_plan)).unwrap_or(0);
    // Baseline entries another shard runs, or --filter excludes, are not this run's to miss
    // (cells --cells-scale leaves out are: the run did not check them).
    let scope = Scope {
        other_shards: the_plan.cells.iter().fold(before_shard, |mut ids, c| {
            ids.remove(&c.cell.id());
            ids
        }),
        filters: c.filters.clone(),
    };
    let scaled_out = a.cells_scale.map(|n| the_plan.scale_to(n)).unwrap_or(0);
    (the_plan, scope, sharded_out + scaled_out)
}

/// A repro bundle's cell (`--cell-spec`): exactly that cell, its scene, injections and binding
/// stages, its SPIR-V when the bundle has it, and no persisted pipeline cache.
fn cell_spec_args(a: &RunArgs, p: &Path) -> Result<(RunArgs, Option<String>)> {
    let spec = crate::model::bundle::CellSpec::load(p)?;
    let mut args = spec.run_args(a)?;
    args.spirv_dir = spec.spirv_dir(p)?;
    // The cell's own compile, not a binary a cache kept from another run (docs/performance.md).
    args.pipeline_cache = Some("off".into());
    args.fresh = true;
    if let Some(dir) = &args.spirv_dir {
        let made_by: std::collections::BTreeSet<&str> =
            spec.modules.iter().map(|m| m.compiler.as_str()).collect();
        eprintln!(
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
    inject: Vec<Injection>,
    shard: Option<Shard>,
    baseline: Option<Baseline>,
    params: SceneParams,
    /// `--mutants` / `--mutant` / `--mutants-sample`: the mutants tried (empty: none).
    mutants: Vec<Mutant>,
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
    if a.repeat.is_some_and(|n| n == 0 || n > 1000) {
        return Err(coded(exit::USAGE, "--repeat must be 1..=1000"));
    }
    let shard =
        a.shard.as_deref().map(Shard::parse).transpose().map_err(|e| coded(exit::USAGE, e))?;
    let baseline = a.baseline.as_deref().map(super::fleet::load_baseline).transpose()?;
    let params = scene_params(a)?;
    if a.jobs.is_some_and(|j| j == 0 || j > 64) {
        return Err(coded(exit::USAGE, "--jobs must be 1..=64"));
    }
    if a.cells_scale.is_some_and(|n| n == 0 || n > 100_000) {
        return Err(coded(exit::USAGE, "--cells-scale must be 1..=100000"));
    }
    if a.threads.is_some_and(|t| t == 0 || t > 64) {
        return Err(coded(exit::USAGE, "--threads must be 1..=64"));
    }
    if a.pipeline_cache.as_deref().is_some_and(|d| d.trim().is_empty()) {
        return Err(coded(exit::USAGE, "--pipeline-cache needs a folder, or `off`"));
    }
    if !(a.timeout > 0.0 && a.timeout <= 3600.0) {
        return Err(coded(exit::USAGE, "--timeout must be in (0, 3600] seconds"));
    }
    if !(a.setup_timeout > 0.0 && a.setup_timeout <= 3600.0) {
        return Err(coded(exit::USAGE, "--setup-timeout must be in (0, 3600] seconds"));
    }
    let mutants = mutants_of(a)?;
    Ok(Checked { filters, inject, shard, baseline, params, mutants })
}

fn select_device(inst: &crate::vk::Instance, a: &RunArgs) -> Result<DeviceInfo> {
    let all = features::query_all(inst)?;
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
    if g.validate && a.threads.is_some_and(|t| t > 1) {
        eprintln!("rtprobe: note: --validate runs with --threads 1, so that each validation error is counted for the cell that raised it");
    }
    RunOptions {
        jobs: Some(a.jobs.unwrap_or_else(|| default_jobs(info))),
        threads: Some(threads),
        pipeline_cache: pipeline_cache_dir(a.pipeline_cache.as_deref()),
        rerun_pipeline_cache: None,
        isolation: a.isolation,
        timeout_s: a.timeout,
        setup_timeout_s: Some(a.setup_timeout),
        confirm: !a.no_confirm,
        canaries: a.canaries,
        filters: a.filter.clone(),
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
        ..supervisor_options(
            info.index,
            c.params,
            o.jobs.unwrap_or_else(|| default_jobs(info)),
            o.isolation,
            o.timeout_s,
            o.validate,
            c.inject.clone(),
        )
    }
}

/// `--list`: the plan, cell by cell, and its counts.
fn print_list(the_plan: &RunPlan, shard: Option<Shard>, sharded_out: usize) {
    for pc in &the_plan.cells {
        match &pc.status {
            PlanStatus::Run => println!("run          {}", pc.cell.id()),
            PlanStatus::Unsupported { reason } => {
                println!("unsupported  {}  ({reason})", pc.cell.id())
            }
            PlanStatus::NotImplemented { reason } => {
                println!("not_implemented  {}  ({reason})", pc.cell.id())
            }
        }
    }
    let to_run = the_plan.to_run().count();
    println!(
        "{} planned: {} to run, {} unsupported, {} not implemented in rtprobe; {} filtered out",
        the_plan.cells.len(),
        to_run,
        the_plan.unsupported_count(),
        the_plan.not_implemented_count(),
        the_plan.filtered_out
    );
    if let Some(s) = shard {
        println!("shard {}: {sharded_out} cells left to the other shards", s.label());
    }
    for ng in &the_plan.not_generated {
        println!("not generated: {} ({} combinations)", ng.rule, ng.count);
    }
    if the_plan.to_run().any(|c| c.heap_access == Some(crate::model::HeapAccess::Direct)) {
        if let Some(g) = crate::shadergen::glslang::find() {
            println!(
                "compiler: heap_access=direct shaders by {}; all others by {}",
                g.describe(),
                crate::shadergen::compile::SHADERC
            );
        }
    }
}

/// `-o`, else the report resumed, else `reports/run-<time>-<device>.json`.
fn out_path(a: &RunArgs, started: u64, info: &DeviceInfo) -> PathBuf {
    match (&a.out, &a.resume) {
        (Some(o), _) => o.clone(),
        (None, Some(r)) => r.clone(),
        (None, None) => PathBuf::from("reports").join(format!(
            "run-{}-{}.json",
            time::stamp(started),
            slug(&info.name())
        )),
    }
}

/// The report the run writes into: `fresh`, or with `--resume` the old one, if it is the same run.
fn base_report(a: &RunArgs, fresh: RunReport) -> Result<RunReport> {
    let Some(r) = &a.resume else { return Ok(fresh) };
    let old = RunReport::load(r).map_err(|e| coded(exit::BAD_INPUT, e))?;
    start::resume(old, &fresh).map_err(|why| {
        coded(
            exit::BAD_INPUT,
            format!("cannot resume {}: {why}; start a new run instead", r.display()),
        )
    })
}

/// The progress bar: attempts scheduled against attempts ended, the last one's outcome and cell.
fn progress_bar() -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::new(0);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{bar:30} {pos}/{len} {elapsed} {msg}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    bar
}

struct Bar(indicatif::ProgressBar);

impl Progress for Bar {
    fn scheduled(&self, n: u64) {
        self.0.inc_length(n);
    }
    fn ended(&self, cell: &Cell, outcome: Option<Outcome>) {
        self.0.inc(1);
        if let Some(o) = outcome {
            self.0.set_message(format!("{} {}", o.as_str(), cell.id()));
        }
    }
}

/// Write the final report (and `--junit`), print the summary and the baseline's verdict; the
/// exit code.
fn print_end(a: &RunArgs, writer: &ReportWriter, out: &Path) -> Result<u8> {
    writer.save(true).with_context(|| "writing the report")?;
    if let Some(j) = &a.junit {
        write_atomic(j, junit::render(&writer.report).as_bytes())
            .with_context(|| "writing the JUnit file")?;
    }
    tracing::debug!("run: report written");
    print!("{}", summary::render(&writer.report));
    if let Some(c) = &writer.report.baseline {
        print!("{}", crate::fleet::baseline::render(c, a.allow_improvements));
    }
    println!("report: {}", out.display());
    Ok(exit_code(&writer.report, a.allow_improvements))
}

/// Without a baseline: findings first (exit 1), then canaries whose fault, injections and
/// `--mutants` survivors the probe must catch (probe defects) that went undetected (exit 11).
/// With one, only what the baseline did not expect is a finding. A worker fault outside any cell
/// (a crash between cells, a hung teardown) is always a finding.
fn exit_code(r: &RunReport, allow_improvements: bool) -> u8 {
    let findings = match &r.baseline {
        Some(c) => !c.ok(allow_improvements),
        None => r.findings().next().is_some() || r.workers.iter().any(|w| w.is_fault()),
    };
    if findings {
        exit::FINDINGS
    } else if r.undetected_canaries().next().is_some()
        || r.tally.injections_undetected > 0
        || r.mutants.as_ref().is_some_and(|m| m.probe_defects().next().is_some())
    {
        exit::CANARY_UNDETECTED
    } else {
        exit::OK
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::Attempt;
    use crate::model::Canary;
    use crate::model::CellReport;

    fn report(cells: Vec<CellReport>) -> RunReport {
        RunReport::for_tests(cells)
    }

    fn ran(cell: Cell, outcome: Outcome) -> CellReport {
        CellReport::new(&cell, Attempt::for_tests(outcome, false))
    }

    #[test]
    fn an_undetected_canary_fails_the_run_and_a_detected_one_does_not() {
        let detected = report(vec![
            ran(Cell::canary(Canary::InvalidAddress), Outcome::Crash),
            ran(Cell::canary(Canary::InfiniteLoop), Outcome::Timeout),
        ]);
        assert_eq!(exit_code(&detected, false), exit::OK);
        assert_eq!(detected.tally.canaries_detected, 2);
        assert_eq!(detected.summary["crash"], 0, "a detected canary is not a crash finding");
        let junit = crate::report::junit::render(&detected);
        assert!(junit.contains("failures=\"0\""), "{junit}");
        // A driver on which the invalid read ran to completion: classification unproven.
        let undetected = report(vec![ran(Cell::canary(Canary::InvalidAddress), Outcome::Pass)]);
        assert_eq!(exit_code(&undetected, false), exit::CANARY_UNDETECTED);
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
        let mut r = report(vec![ran(cell, Outcome::Timeout)]);
        assert_eq!(exit_code(&r, false), exit::OK);
        r.mutants = Some(MutantReport { entries: vec![survivor(false)], ..Default::default() });
        assert_eq!(exit_code(&r, false), exit::OK);
        r.mutants = Some(MutantReport { entries: vec![survivor(true)], ..Default::default() });
        assert_eq!(exit_code(&r, false), exit::CANARY_UNDETECTED);
    }
}
