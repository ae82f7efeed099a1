//! The report a run starts from — fresh (device, scene, options, plan) or a report it resumes,
//! held to the same run — the cells still to run, and how the report ends (timing, completion,
//! the baseline check).
use super::Recorder;
use crate::fleet::baseline::Scope;
use crate::model::report::RunOptions;
use crate::model::report::{PlanSummary, ResultOption, SceneSummary, TimingSummary, SCHEMA};
use crate::model::{Baseline, Cell, RunPlan, RunReport, SceneParams};
use crate::report::time;
use crate::report::writer::ReportWriter;
use crate::scene::Scene;
use crate::vk::DeviceInfo;
use serde_json::json;
use std::time::Duration;

/// A report `--resume` cannot continue: it was made by another run (device, scene or a
/// result-changing option differ).
#[derive(Debug, thiserror::Error)]
#[error("{why}")]
pub struct NotSameRun {
    pub why: String,
}

/// The report of a run that has not run a cell yet. `started`: seconds since the epoch.
pub fn fresh(
    info: &DeviceInfo,
    scene: SceneSummary,
    plan: &RunPlan,
    sharded_out: usize,
    options: RunOptions,
    command_line: Vec<String>,
    started: u64,
) -> RunReport {
    RunReport {
        schema: SCHEMA.into(),
        tool: json!({ "name": "rtprobe", "version": env!("CARGO_PKG_VERSION") }),
        command_line,
        started: time::rfc3339(started),
        finished: None,
        complete: false,
        incomplete: None,
        device: crate::caps::device_json(info),
        matrix_support: crate::caps::matrix_json(info),
        matrix_support_schema: Some(crate::caps::SCHEMA.into()),
        scene,
        options,
        plan: PlanSummary {
            generated: plan.generated,
            filtered_out: plan.filtered_out,
            planned: plan.cells.len(),
            to_run: plan.to_run().count(),
            unsupported: plan.unsupported_count(),
            not_implemented: plan.not_implemented_count(),
            not_generated: plan.not_generated.clone(),
            sharded_out,
        },
        summary: Default::default(),
        retries: Default::default(),
        resumed: vec![],
        tally: Default::default(),
        timing: TimingSummary::default(),
        baseline: None,
        workers: vec![],
        pipeline_cache: None,
        mutants: None,
        driver_cache: None,
        cells: vec![],
    }
}

/// The report's scene: `params` (a `--scene` file's identity among them) and what `scene`, made
/// from them, holds; the cells it cannot discriminate and its CPU cost.
pub fn scene_summary(
    params: SceneParams,
    scene: &Scene,
    limits: Vec<crate::model::SceneLimit>,
    cost: crate::model::SceneCost,
) -> SceneSummary {
    SceneSummary {
        params,
        instances: scene.instances.len(),
        blas: scene.meshes.len() + 1,
        triangles: scene.triangle_count(),
        ambiguous_pixels: crate::reference::ambiguous_primaries(scene),
        limits,
        cost: Some(cost),
    }
}

/// `old` continued by the run whose fresh report is `fresh`: the same run in every
/// result-changing option but `--repeat` (a resumed run may ask for more), and the same shard.
pub fn resume(old: RunReport, fresh: &RunReport) -> Result<RunReport, NotSameRun> {
    let options: Vec<ResultOption> = ResultOption::MERGED
        .iter()
        .copied()
        .filter(|k| *k != ResultOption::Repeat)
        .chain([ResultOption::Shard])
        .collect();
    crate::fleet::merge::same_run(&old, fresh, &options)
        .map_err(|why| NotSameRun { why: why.to_string() })?;
    Ok(RunReport {
        command_line: fresh.command_line.clone(),
        complete: false,
        incomplete: None,
        finished: None,
        ..old
    })
}

/// The plan's cells still to run — all, or after a resume those without an attempt that ran —
/// as (probe cells, canaries): canaries run after every probe cell and its confirmation. A resume
/// is recorded in the report (`resumed`: when, the cells kept, the cells left).
pub fn pending(writer: &mut ReportWriter, plan: &RunPlan, resumed: bool) -> (Vec<Cell>, Vec<Cell>) {
    let done = if resumed { writer.done() } else { Default::default() };
    let (cells, canaries): (Vec<Cell>, Vec<Cell>) = plan
        .to_run()
        .filter(|c| !done.contains(&c.id()))
        .copied()
        .partition(|c| c.canary.is_none());
    if resumed {
        writer.report.resumed.push(crate::model::report::Resumed {
            at: time::rfc3339(time::now_unix()),
            kept: done.len(),
            to_run: cells.len() + canaries.len(),
        });
    }
    (cells, canaries)
}

/// End the report: wall time (added to a resumed run's), the workers' mean device setup time,
/// when it finished, complete, and with `baseline` (the expectations, where they came from, and
/// where the cells this run did not plan went) how the run compares.
pub fn finish(rec: &mut Recorder, wall: Duration, baseline: Option<(&Baseline, &str, &Scope)>) {
    let r = &mut rec.writer.report;
    r.timing.wall_ms += wall.as_secs_f64() * 1e3;
    let t = &r.timing;
    let slots = r.options.jobs.unwrap_or(1).min(t.workers_started);
    use crate::model::report::{own_ms, DriverMs};
    r.timing.own_ms = Some(own_ms(t.wall_ms, DriverMs::of(t), slots));
    r.timing.device_ms_mean = if r.timing.workers_started > 0 {
        rec.device_ms_sum / r.timing.workers_started as f64
    } else {
        0.0
    };
    if rec.as_builds > 0 {
        // Builds recorded before a `--resume` keep their share of the mean.
        let before = r.timing.as_builds - rec.as_builds;
        r.timing.as_build_ms_mean = (r.timing.as_build_ms_mean * before as f64
            + rec.as_build_ms_sum)
            / r.timing.as_builds as f64;
    }
    let now = time::now_unix();
    r.finished = Some(time::rfc3339(now));
    r.complete = true;
    if let Some((b, source, scope)) = baseline {
        r.baseline = Some(crate::fleet::baseline::check(r, b, source, scope));
    }
}
