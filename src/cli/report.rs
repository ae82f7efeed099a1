//! `rtprobe report REPORT [--bisect FILE] [--lanes REPORT] [--no-validation-run] -o issue.md
//! [--format md|json]`: the vendor issue for a run's fault (see `report::issue`), with the
//! failing cell re-run under the validation layer (`issue_run`), written atomically. A
//! `reduce.json` goes to `report_reduce` instead.
use super::args::ReportArgs;
use super::bisect::offline;
use super::commands::Globals;
use super::exit::{self, coded};
use super::shared::load_report;
use crate::bisect::scope::ReportOptions;
use crate::bisect::Settings;
use crate::model::PatchMode;
use crate::model::{BisectFile, RunReport};
use crate::report::issue;
use anyhow::Result;

pub fn report(g: &Globals, a: &ReportArgs) -> Result<u8> {
    if super::report_reduce::is_reduce(a) {
        return super::report_reduce::report(a);
    }
    super::paths::writable_files(&[("-o", a.out.as_deref())])?;
    let r = load_report(&a.report)?;
    let ro = ReportOptions::of(&r)
        .map_err(|e| coded(exit::BAD_INPUT, format!("{}: {e}", a.report.display())))?;
    let b = bisection(a, &r, &ro)?;
    let lanes = match &a.lanes {
        Some(p) => Some(lanes_report(p, &r)?),
        None => None,
    };
    if let (Some(l), Some(p)) = (lanes.as_ref(), a.lanes.as_ref()) {
        lanes_cover(l, p, &b.bisection.representative)?;
    }
    let cell = crate::bisect::scope::cell_by_id(&b.bisection.representative);
    // the control of a validation run that never reaches the cell: the first settled, clean pass
    let control = b.bisection.isolation.iter().find_map(|l| {
        let clean = l.verdict == "pass" && l.settled != Some(false) && l.suspect.is_none();
        clean.then(|| crate::bisect::scope::cell_by_id(&l.cell)).flatten()
    });
    let validate = !a.no_validation_run && !r.options.validate;
    let (validation, sbt) = super::issue_run::measure(g, &r, &ro, (cell, control), validate);
    let extras = issue::Extras { lanes: lanes.as_ref(), validation, sbt };
    let issue = issue::build(&r, &a.report.display().to_string(), &b, &ro.inject, &extras)
        .map_err(|e| coded(exit::BAD_INPUT, e))?;
    super::issue_out::emit(a, || issue.markdown(), &issue)
}

/// The `--lanes` report must hold lane evidence for the issue's cell (`id`): else the option
/// would be silently ignored and the issue would ask for the report just given.
fn lanes_cover(l: &crate::model::RunReport, path: &std::path::Path, id: &str) -> Result<()> {
    let recorded = l.cells.iter().filter(|c| c.id == id).flat_map(|c| &c.attempts).any(|a| {
        a.result
            .as_ref()
            .and_then(|r| r.comparison.as_ref())
            .is_some_and(|c| c.lane_evidence.recorded())
    });
    if recorded {
        return Ok(());
    }
    Err(coded(
        exit::BAD_INPUT,
        format!(
            "--lanes {}: no lane evidence for {id} there; run `rtprobe run --lane-evidence force --filter` on that cell and give its report",
            path.display()
        ),
    ))
}

/// The `--lanes` report: a run of the report's device and driver build.
fn lanes_report(
    path: &std::path::Path,
    r: &crate::model::RunReport,
) -> Result<crate::model::RunReport> {
    let l = load_report(path)?;
    let same =
        ["name", "driver_uuid", "driver_version"].iter().all(|k| l.device[*k] == r.device[*k]);
    if !same {
        return Err(coded(
            exit::BAD_INPUT,
            format!(
                "--lanes {} is a run of {} (driver {}), not of the report's device; give a --lane-evidence force run of the same device",
                path.display(),
                l.device["name"],
                l.device["driver_version"]["decoded"]
            ),
        ));
    }
    Ok(l)
}

/// The bisection the issue is written from: `--bisect`'s file, checked to be of this report's
/// device and run, or an offline bisection of the report itself.
fn bisection(a: &ReportArgs, r: &RunReport, ro: &ReportOptions) -> Result<BisectFile> {
    Ok(match &a.bisect {
        Some(p) => {
            let b = BisectFile::load(p).map_err(|e| coded(exit::BAD_INPUT, e))?;
            if b.device["name"] != r.device["name"]
                || b.device["driver_uuid"] != r.device["driver_uuid"]
            {
                return Err(coded(
                    exit::BAD_INPUT,
                    format!(
                        "{} bisects a report of another device ({}), not {}",
                        p.display(),
                        b.device["name"],
                        a.report.display()
                    ),
                ));
            }
            // The same run: its start stamp and its injections (an injected fault must never be
            // written up as a driver bug through another report's issue).
            let report_inject: Vec<String> = ro.inject.iter().map(|i| i.spec.clone()).collect();
            if b.report_started != r.started || b.inject != report_inject {
                return Err(coded(
                    exit::BAD_INPUT,
                    format!(
                        "{} bisects another run ({}), not {} ({}); bisect this report first",
                        p.display(),
                        b.report.display(),
                        a.report.display(),
                        r.started
                    ),
                ));
            }
            b
        }
        None => {
            let filters = ro.scope_filters(&[]).map_err(|e| coded(exit::BAD_INPUT, e))?;
            let patches =
                if ro.patches == PatchMode::All { PatchMode::All } else { PatchMode::None };
            let bi = offline(r, &filters, patches, Settings::default(), &ro.inject, None)
                .map_err(|e| coded(exit::BAD_INPUT, format!("{}: {e}", a.report.display())))?;
            BisectFile::new(&a.report, r, &filters, &ro.inject, true, bi)
        }
    })
}
