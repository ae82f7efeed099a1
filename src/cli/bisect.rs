//! `rtprobe bisect REPORT`: load the report, find its device, run the bisection through the
//! supervisor with the report's scene and injections, print the isolation list and
//! `minimal: PREDICATE`, and write `--json`.
use super::args::BisectArgs;
use super::commands::Globals;
use super::exit::{self, coded};
use super::out::out;
use super::shared::{load_report, report_device, SupervisorOracle};
use crate::atomic::write_atomic;
use crate::bisect::scope::{report_scope, ReportOptions};
use crate::bisect::{self, Bisector, Settings, Verdicts};
use crate::matrix::plan::{self, PlanOptions};
use crate::model::BisectFile;
use crate::model::Cell;
use crate::model::PatchMode;
use crate::model::RunReport;
use anyhow::{Context, Result};

fn check_args(a: &BisectArgs) -> Result<()> {
    if !(a.max_miss > 0.0 && a.max_miss < 1.0) {
        return Err(coded(exit::USAGE, "--max-miss must be in (0, 1)"));
    }
    if a.max_attempts == 0 || a.max_attempts > 1000 {
        return Err(coded(exit::USAGE, "--max-attempts must be 1..=1000"));
    }
    if a.jobs.is_some_and(|j| j == 0 || j > 64) {
        return Err(coded(exit::USAGE, "--jobs must be 1..=64"));
    }
    Ok(())
}

/// Bisect the report's own verdicts, running nothing (`--offline`, and `report` without
/// `--bisect`).
pub(crate) fn offline(
    report: &RunReport,
    filters: &[crate::model::Filter],
    patches: PatchMode,
    settings: Settings,
    inject: &[crate::model::Injection],
    cell: Option<&str>,
) -> Result<crate::model::Bisection, bisect::BisectError> {
    let scope = report_scope(report, filters, patches);
    let verdicts = Verdicts::from_report(report);
    let ran = |c: &Cell| verdicts.get(c).is_some();
    let mut off = bisect::Offline;
    Bisector::new(scope, verdicts.clone(), &mut off, settings, inject.to_vec()).bisect(cell, &ran)
}

pub fn bisect(g: &Globals, a: &BisectArgs) -> Result<u8> {
    check_args(a)?;
    super::paths::writable_files(&[("--json", a.json.as_deref())])?;
    if !a.offline {
        // (its job files; `--offline` runs nothing)
        super::paths::temp_usable()?;
    }
    let report = load_report(&a.report)?;
    let ro = ReportOptions::of(&report)
        .map_err(|e| coded(exit::BAD_INPUT, format!("{}: {e}", a.report.display())))?;
    let filters = ro.scope_filters(&a.filter).map_err(|e| coded(exit::USAGE, e))?;
    let settings =
        Settings { max_miss: a.max_miss, max_attempts: a.max_attempts, ..Settings::default() };
    let verdicts = Verdicts::from_report(&report);
    let patches = if ro.patches == PatchMode::All { PatchMode::All } else { PatchMode::None };
    let mut device_uuid_rerun = None;
    let result = if a.offline {
        offline(&report, &filters, patches, settings, &ro.inject, a.cell.as_deref())
    } else {
        let (_inst, info, rerun) = report_device(g, &report)?;
        device_uuid_rerun = rerun;
        let the_plan = plan::plan(
            &info,
            &PlanOptions {
                filters: filters.clone(),
                canaries: false,
                patches,
                inject: ro.inject.clone(),
            },
        );
        let scope: Vec<Cell> = the_plan.to_run().copied().collect();
        let jobs = a.jobs.or(ro.jobs).unwrap_or_else(|| super::shared::default_jobs(&info));
        let mut opts = super::shared::supervisor_options(
            info.index,
            report.scene.params.clone(),
            jobs,
            ro.isolation,
            ro.timeout_s,
            ro.validate || g.validate,
            ro.inject.clone(),
        );
        if let Some(s) = ro.setup_timeout_s.filter(|s| *s > 0.0 && *s <= 3600.0) {
            opts.setup_timeout = std::time::Duration::from_secs_f64(s);
        }
        opts.rerun_jobs = super::shared::rerun_jobs(&info, jobs);
        // The report's options that change results: the cells bisect runs use them too.
        super::shared::as_the_report_ran(&mut opts, &report.options);
        let mut oracle = SupervisorOracle::for_bisect(opts);
        let supported = |c: &Cell| plan::device_support(&info, c).is_supported();
        let settings = Settings { batch: 2 * jobs, ..settings };
        Bisector::new(scope, verdicts, &mut oracle, settings, ro.inject.clone())
            .bisect(a.cell.as_deref(), &supported)
    };
    let b = result.map_err(|e| match e {
        bisect::BisectError::Halted(h) => exit::bisect_halted(h),
        e => coded(exit::BAD_INPUT, format!("{}: {e}", a.report.display())),
    })?;
    let mut file = BisectFile::new(&a.report, &report, &filters, &ro.inject, a.offline, b);
    if let Some(uuid) = device_uuid_rerun {
        file.text.push_str(&format!(
            "re-run on another card of the same driver build (UUID {uuid}), not the report's\n"
        ));
        file.device_uuid_rerun = Some(uuid);
    }
    if let Some(path) = &a.json {
        write_atomic(path, &serde_json::to_vec_pretty(&file)?).context("writing the bisection")?;
    }
    out!("{}", file.text);
    Ok(exit::OK)
}
