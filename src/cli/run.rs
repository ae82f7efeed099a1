//! `rtprobe run`: resolve arguments into a plan (before any GPU work), print it (`--list`) or
//! hand it to the supervisor, and keep the report, progress bar and summary.
use super::args::RunArgs;
use super::commands::{open_instance, Globals};
use super::exit::{self, coded};
use super::shared::{default_jobs, default_threads, supervisor_options, use_binding_stages};
use crate::caps;
use crate::fleet::{merge, shard::Shard};
use crate::model::Injection;
use crate::matrix::plan::{self, PlanOptions};
use crate::model::{Filter, PatchMode, PlanStatus};
use crate::reference::SceneReference;
use crate::model::report::{PlanSummary, ResultOption, RunOptions, SceneSummary, TimingSummary, SCHEMA};
use crate::report::writer::ReportWriter;
use crate::model::RunReport;
use crate::atomic::write_atomic;
use crate::report::{junit, summary, time};
use crate::runner::supervisor::{Event, Supervisor, SupervisorOptions};
use crate::model::Isolation;
use crate::scene::Scene;
use crate::model::SceneParams;
use crate::vk::features;
use anyhow::{Context, Result};
use serde_json::json;
use std::path::PathBuf;
use std::time::{Duration, Instant};

fn scene_params(a: &RunArgs) -> Result<SceneParams> {
    let (w, h) = a
        .size
        .split_once(['x', 'X'])
        .and_then(|(w, h)| Some((w.trim().parse::<u32>().ok()?, h.trim().parse::<u32>().ok()?)))
        .ok_or_else(|| coded(exit::USAGE, format!("--size {:?} is not WIDTHxHEIGHT (e.g. 64x64)", a.size)))?;
    let p = SceneParams { seed: a.seed, width: w, height: h, instances: a.instances, mesh_detail: a.mesh_detail };
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
    let s: String = name.chars().map(|c| if c.is_ascii_alphanumeric() { c.to_ascii_lowercase() } else { '-' }).collect();
    s.split('-').filter(|p| !p.is_empty()).take(4).collect::<Vec<_>>().join("-")
}

pub fn run(g: &Globals, a: &RunArgs) -> Result<u8> {
    if let Some(p) = &a.cell_spec {
        // A repro bundle's cell: exactly that cell, its scene and injections.
        let spec = crate::model::bundle::CellSpec::load(p)?;
        use_binding_stages(spec.binding_stages.as_deref());
        let mut args = spec.run_args(a)?;
        args.spirv_dir = spec.spirv_dir(p)?;
        // The cell's own compile, not a binary a cache kept from another run (docs/performance.md).
        args.pipeline_cache = Some("off".into());
        if let Some(dir) = &args.spirv_dir {
            let made_by: std::collections::BTreeSet<&str> = spec.modules.iter().map(|m| m.compiler.as_str()).collect();
            eprintln!("running the bundle's SPIR-V ({}, made by {}), not recompiling", dir.display(), made_by.into_iter().collect::<Vec<_>>().join(", "));
        }
        return run(g, &args);
    }
    let filters = a.filter.iter().map(|f| Filter::parse(f).map_err(|e| coded(exit::USAGE, e))).collect::<Result<Vec<_>>>()?;
    let inject = a.inject_fault.iter().filter(|s| !s.trim().is_empty()).map(|s| Injection::parse(s).map_err(|e| coded(exit::USAGE, e))).collect::<Result<Vec<_>>>()?;
    if a.repeat.is_some_and(|n| n == 0 || n > 1000) {
        return Err(coded(exit::USAGE, "--repeat must be 1..=1000"));
    }
    let shard = a.shard.as_deref().map(Shard::parse).transpose().map_err(|e| coded(exit::USAGE, e))?;
    let baseline = a.baseline.as_deref().map(super::fleet::load_baseline).transpose()?;
    let params = scene_params(a)?;
    if a.jobs.is_some_and(|j| j == 0 || j > 64) {
        return Err(coded(exit::USAGE, "--jobs must be 1..=64"));
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
    let inst = open_instance(g)?;
    let all = features::query_all(&inst)?;
    let info = features::select(&all, a.device.as_deref())?.clone();
    drop(all);
    let jobs = a.jobs.unwrap_or_else(|| default_jobs(&info));
    // Under validation a cell's `validation_errors` is the global counter's difference around its
    // own work, so its pipelines must be created at its turn: VUIDs raised on prebuild threads
    // would fall outside every cell's window. `--validate` (any mode) runs with one thread.
    let threads = if g.validate { 1 } else { a.threads.unwrap_or_else(|| default_threads(&info)) };
    if g.validate && a.threads.is_some_and(|t| t > 1) {
        eprintln!("rtprobe: note: --validate runs with --threads 1, so that each validation error is counted for the cell that raised it");
    }
    let cache_dir = pipeline_cache_dir(a.pipeline_cache.as_deref());
    let mut the_plan = plan::plan(&info, &PlanOptions { filters: filters.clone(), canaries: a.canaries, patches: a.patches, inject: inject.clone() });
    let sharded_out = shard.map(|s| s.apply(&mut the_plan)).unwrap_or(0);

    if a.list {
        for pc in &the_plan.cells {
            match &pc.status {
                PlanStatus::Run => println!("run          {}", pc.cell.id()),
                PlanStatus::Unsupported { reason } => println!("unsupported  {}  ({reason})", pc.cell.id()),
                PlanStatus::NotImplemented { reason } => println!("not_implemented  {}  ({reason})", pc.cell.id()),
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
                println!("compiler: heap_access=direct shaders by {} {}; all others by shaderc", g.path.display(), g.version);
            }
        }
        return Ok(exit::OK);
    }

    let scene = Scene::build(&params);
    let sref = SceneReference::compute(&scene);
    let started = time::now_unix();
    let out = match (&a.out, &a.resume) {
        (Some(o), _) => o.clone(),
        (None, Some(r)) => r.clone(),
        (None, None) => PathBuf::from("reports").join(format!("run-{}-{}.json", time::stamp(started), slug(&info.name()))),
    };
    let fresh = RunReport {
        schema: SCHEMA.into(),
        tool: json!({ "name": "rtprobe", "version": env!("CARGO_PKG_VERSION") }),
        command_line: std::env::args().collect(),
        started: format!("{} ({started})", time::stamp(started)),
        finished: None,
        complete: false,
        device: caps::device_json(&info),
        matrix_support: caps::matrix_json(&info),
        scene: SceneSummary {
            params,
            instances: scene.instances.len(),
            blas: scene.meshes.len() + 1,
            triangles: scene.triangle_count(),
            ambiguous_pixels: sref.ambiguous_pixels(),
        },
        options: RunOptions {
            jobs,
            threads: Some(threads),
            pipeline_cache: cache_dir.clone(),
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
            inject: inject.iter().map(|i| i.spec.clone()).collect(),
            repeat: a.repeat,
            shard: shard.map(|s| s.label()),
            binding_stages: std::env::var("RTPROBE_BINDING_STAGES").ok(),
            spirv_from: a.spirv_dir.clone(),
            merged_from: vec![],
        },
        plan: PlanSummary {
            generated: the_plan.generated,
            filtered_out: the_plan.filtered_out,
            planned: the_plan.cells.len(),
            to_run: the_plan.to_run().count(),
            unsupported: the_plan.unsupported_count(),
            not_implemented: the_plan.not_implemented_count(),
            not_generated: the_plan.not_generated.clone(),
            sharded_out,
        },
        summary: Default::default(),
        tally: Default::default(),
        timing: TimingSummary::default(),
        baseline: None,
        workers: vec![],
        pipeline_cache: None,
        cells: vec![],
    };
    let base = match &a.resume {
        Some(r) => {
            let old = RunReport::load(r).map_err(|e| coded(exit::BAD_INPUT, e))?;
            let options: Vec<ResultOption> = ResultOption::MERGED.iter().copied().filter(|k| *k != ResultOption::Repeat).chain([ResultOption::Shard]).collect();
            merge::same_run(&old, &fresh, &options)
                .map_err(|why| coded(exit::BAD_INPUT, format!("cannot resume {}: {why}; start a new run instead", r.display())))?;
            RunReport { command_line: fresh.command_line.clone(), complete: false, finished: None, ..old }
        }
        None => fresh,
    };
    let writer = ReportWriter::new(out.clone(), base, &the_plan);
    let done = if a.resume.is_some() { writer.done() } else { Default::default() };
    let pending: Vec<_> = the_plan.to_run().filter(|c| !done.contains(&c.id())).copied().collect();
    // Canaries run after every probe cell and its confirmation (they may wedge a real GPU).
    let (canaries, cells): (Vec<_>, Vec<_>) = pending.into_iter().partition(|c| c.canary.is_some());
    writer.save(false).with_context(|| "writing the report")?;

    let opts = SupervisorOptions {
        dump: a.dump.clone(),
        spirv_dir: a.spirv_dir.clone(),
        setup_timeout: Duration::from_secs_f64(a.setup_timeout),
        threads,
        pipeline_cache: cache_dir.clone(),
        binding_stages: std::env::var("RTPROBE_BINDING_STAGES").ok(),
        ..supervisor_options(info.index, params, jobs, a.isolation, a.timeout, g.validate, inject.clone())
    };
    let job_dir = opts.job_dir.clone();
    let gpu_av_opts = opts.clone();
    let mut sup = Supervisor::new(opts);
    let bar = indicatif::ProgressBar::new((cells.len() + canaries.len()) as u64);
    bar.set_style(indicatif::ProgressStyle::with_template("{bar:30} {pos}/{len} {elapsed} {msg}").unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()));
    let wall = Instant::now();
    let mut st = RunState { writer, bar, device_ms_sum: 0.0, save_error: None, last_save: Instant::now() };
    sup.run(&cells, false, &mut |ev| st.on_event(ev));
    if !a.no_confirm && a.isolation == Isolation::Worker {
        let again: Vec<_> = st
            .writer
            .report
            .cells
            .iter()
            .filter(|c| c.cell.canary.is_none() && c.attempts.len() == 1 && !c.attempts[0].not_run() && c.outcome.worth_confirming())
            .map(|c| c.cell)
            .collect();
        if !again.is_empty() {
            st.bar.inc_length(again.len() as u64);
            sup.run(&again, true, &mut |ev| st.on_event(ev));
        }
    }
    if let Some(n) = a.repeat {
        // Every faulting cell gets n attempts in all, each alone in a fresh worker.
        loop {
            let more: Vec<_> = st.writer.report.findings().filter(|c| (c.attempts.len() as u32) < n).map(|c| c.cell).collect();
            if more.is_empty() {
                break;
            }
            st.bar.inc_length(more.len() as u64);
            sup.run(&more, true, &mut |ev| st.on_event(ev));
        }
    }
    if a.patches == PatchMode::Faults {
        // Retry every faulting cell with each workaround that applies and that the device can
        // run (not again after a resume).
        let done = st.writer.done();
        let retries: Vec<_> = st
            .writer
            .report
            .findings()
            .flat_map(|c| c.cell.applicable_patches().into_iter().map(move |p| crate::model::Cell { patch: Some(p), ..c.cell }))
            .filter(|c| plan::device_support(&info, c).is_supported() && !done.contains(&c.id()))
            .collect();
        if !retries.is_empty() {
            st.bar.inc_length(retries.len() as u64);
            sup.run(&retries, false, &mut |ev| st.on_event(ev));
        }
        // The recommended pattern nearest each finding (report::recommended), where the plan
        // did not hold it and the device can run it.
        let patterns: Vec<_> = crate::report::recommended::missing(&st.writer.report).into_iter().filter(|c| plan::device_support(&info, c).is_supported()).collect();
        if !patterns.is_empty() {
            st.bar.inc_length(patterns.len() as u64);
            sup.run(&patterns, false, &mut |ev| st.on_event(ev));
        }
        // A workaround is verified only by as many passing runs as its cell had attempts: one
        // pass against an intermittent fault proves nothing. Variants that still pass are run
        // again (alone) until they match their cell's count; one fault ends that.
        loop {
            let report = &st.writer.report;
            let mut more: Vec<_> = report
                .cells
                .iter()
                .filter(|v| v.cell.patch.is_some() && v.outcome == crate::model::outcome::Outcome::Pass)
                .filter(|v| report.cells.iter().find(|b| b.cell == v.cell.base()).is_some_and(|b| b.outcome.is_finding() && v.attempts.len() < b.attempts.len()))
                .map(|v| v.cell)
                .collect();
            // Recommended patterns likewise, against the findings they stand for.
            more.extend(crate::report::recommended::retries(report));
            if more.is_empty() {
                break;
            }
            st.bar.inc_length(more.len() as u64);
            sup.run(&more, true, &mut |ev| st.on_event(ev));
        }
    }
    if g.gpu_av {
        // Each finding again, alone, under GPU-AV, next to its control (report::gpu_av); kept
        // apart from the cells' own attempts. A finding that passes runs again until it has the
        // passes its own incidence needs (gpu_av::more); at most CAP rounds.
        let layer = inst.validation_layer_version();
        let (mut again, skipped) = crate::report::gpu_av::schedule(&st.writer.report, layer);
        let mut got = Vec::new();
        let av_opts = SupervisorOptions { validate: true, gpu_av: true, threads: 1, pipeline_cache: None, job_dir: job_dir.join("gpu-av"), ..gpu_av_opts };
        for _ in 0..crate::report::gpu_av::CAP {
            if again.is_empty() {
                break;
            }
            st.bar.inc_length(again.len() as u64);
            let bar = &st.bar;
            Supervisor::new(av_opts.clone()).run(&again, true, &mut |ev| {
                if let crate::runner::supervisor::Event::Attempt { cell, attempt } = ev {
                    bar.inc(1);
                    got.push((*cell, attempt));
                }
            });
            again = crate::report::gpu_av::more(&st.writer.report, &got);
        }
        crate::report::gpu_av::annotate(&mut st.writer.report, &got, &skipped);
    }
    if !canaries.is_empty() {
        sup.run(&canaries, false, &mut |ev| st.on_event(ev));
    }
    crate::report::writer::annotate_findings(&mut st.writer.report);
    let RunState { mut writer, bar, device_ms_sum, save_error, .. } = st;
    bar.finish_and_clear();
    let _ = std::fs::remove_dir_all(&job_dir);
    if let Some(e) = save_error {
        return Err(anyhow::Error::from(e).context("writing the report"));
    }
    let r = &mut writer.report;
    r.timing.wall_ms += wall.elapsed().as_secs_f64() * 1e3;
    r.timing.device_ms_mean = if r.timing.workers_started > 0 { device_ms_sum / r.timing.workers_started as f64 } else { 0.0 };
    let now = time::now_unix();
    r.finished = Some(format!("{} ({now})", time::stamp(now)));
    r.complete = true;
    if let (Some(b), Some(p)) = (&baseline, &a.baseline) {
        r.baseline = Some(crate::fleet::baseline::check(r, b, &p.display().to_string()));
    }
    writer.save(true).with_context(|| "writing the report")?;
    if let Some(j) = &a.junit {
        write_atomic(j, junit::render(&writer.report).as_bytes()).with_context(|| "writing the JUnit file")?;
    }
    print!("{}", summary::render(&writer.report));
    if let Some(c) = &writer.report.baseline {
        print!("{}", crate::fleet::baseline::render(c, a.allow_improvements));
    }
    println!("report: {}", out.display());
    Ok(exit_code(&writer.report, a.allow_improvements))
}

/// Without a baseline: findings first (exit 1), then canaries whose fault went undetected (exit
/// 11). With one, only what the baseline did not expect is a finding. A worker fault outside any
/// cell (a crash between cells, a hung teardown) is always a finding.
fn exit_code(r: &RunReport, allow_improvements: bool) -> u8 {
    let findings = match &r.baseline {
        Some(c) => !c.ok(allow_improvements),
        None => r.findings().next().is_some() || r.workers.iter().any(|w| w.outcome.is_finding()),
    };
    if findings {
        exit::FINDINGS
    } else if r.undetected_canaries().next().is_some() || r.tally.injections_undetected > 0 {
        exit::CANARY_UNDETECTED
    } else {
        exit::OK
    }
}


struct RunState {
    writer: ReportWriter,
    bar: indicatif::ProgressBar,
    device_ms_sum: f64,
    save_error: Option<crate::atomic::WriteError>,
    /// When the report was last written (passes are written at most every [`SAVE_INTERVAL`]).
    last_save: Instant,
}

/// Passes are saved at most this often: the whole report is rewritten on each save (2 MB for the
/// H100's default matrix), and saving after every pass made the supervisor the bottleneck of a
/// fast GPU run. Faults, worker events and the end of the run are saved at once.
const SAVE_INTERVAL: Duration = Duration::from_millis(100);

impl RunState {
    fn save(&mut self, urgent: bool) {
        if !urgent && self.last_save.elapsed() < SAVE_INTERVAL {
            return;
        }
        self.last_save = Instant::now();
        if let Err(e) = self.writer.save(false) {
            self.save_error.get_or_insert(e);
        }
    }

    fn on_event(&mut self, ev: Event) {
        match ev {
            Event::WorkerReady { device_ms, pipeline_cache, .. } => {
                self.writer.report.timing.workers_started += 1;
                self.device_ms_sum += device_ms;
                if let Some(l) = pipeline_cache {
                    let s = self.writer.report.pipeline_cache.get_or_insert_with(Default::default);
                    s.file = Some(l.path);
                    if l.loaded_bytes > 0 {
                        s.workers_loaded += 1;
                        s.loaded_bytes = s.loaded_bytes.max(l.loaded_bytes);
                    }
                    if let Some(why) = l.ignored.filter(|w| !s.ignored.contains(w)) {
                        s.ignored.push(why);
                    }
                }
            }
            Event::Prebuilt { wall_ms, pipelines, .. } => {
                self.writer.report.timing.prebuild_ms += wall_ms;
                self.writer.report.timing.prebuilt_pipelines += pipelines;
            }
            Event::CacheSaved(saved) => {
                let s = self.writer.report.pipeline_cache.get_or_insert_with(Default::default);
                match saved {
                    Ok(bytes) => {
                        s.saves += 1;
                        s.saved_bytes = bytes;
                    }
                    Err(e) if !s.save_errors.contains(&e) => s.save_errors.push(e),
                    Err(_) => {}
                }
            }
            Event::Worker(w) => {
                self.writer.record_worker(w);
                self.save(true);
            }
            Event::Attempt { cell, attempt } => {
                self.bar.inc(1);
                self.bar.set_message(format!("{} {}", attempt.outcome.as_str(), cell.id()));
                let urgent = attempt.outcome != crate::model::outcome::Outcome::Pass;
                self.writer.record(cell, attempt);
                self.save(urgent);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{Canary, Cell};
    use crate::model::Outcome;
    use crate::model::CellReport;
    use crate::model::Attempt;

    fn report(cells: Vec<CellReport>) -> RunReport {
        RunReport::for_tests(cells)
    }

    fn ran(cell: Cell, outcome: Outcome) -> CellReport {
        CellReport::new(&cell, Attempt::for_tests(outcome, false))
    }

    #[test]
    fn an_undetected_canary_fails_the_run_and_a_detected_one_does_not() {
        let detected = report(vec![ran(Cell::canary(Canary::InvalidAddress), Outcome::Crash), ran(Cell::canary(Canary::InfiniteLoop), Outcome::Timeout)]);
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
}
