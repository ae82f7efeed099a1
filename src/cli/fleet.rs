//! `rtprobe baseline`, `merge` and `diff`: glue between arguments and [`crate::fleet`]. They only
//! read reports and write files (atomically); no GPU work.
use super::args::{BaselineArgs, BaselineFormat, DiffArgs, DiffFormat, MergeArgs};
use super::exit::{self, coded};
use crate::atomic::write_atomic;
use crate::fleet::{diff, merge};
use crate::model::Baseline;
use crate::model::RunReport;
use anyhow::{Context, Result};
use std::path::Path;

fn load(p: &Path) -> Result<RunReport> {
    RunReport::load(p).map_err(|e| coded(exit::BAD_INPUT, e))
}

pub fn baseline(a: &BaselineArgs) -> Result<u8> {
    let r = load(&a.report)?;
    if !r.complete {
        return Err(coded(
            exit::BAD_INPUT,
            format!(
                "{} is an unfinished run; finish it with `rtprobe run --resume` first",
                a.report.display()
            ),
        ));
    }
    if !(a.perf_factor >= 1.0 && a.perf_slack_ms >= 0.0) {
        return Err(coded(exit::USAGE, "--perf-factor must be >= 1 and --perf-slack-ms >= 0"));
    }
    let mut b = Baseline::from_report(
        &r,
        &a.report.display().to_string(),
        &a.perf,
        a.perf_factor,
        a.perf_slack_ms,
    )
    .map_err(|e| coded(exit::USAGE, e))?;
    for e in &mut b.expected {
        e.bug.clone_from(&a.bug);
    }
    let text = match a.format {
        BaselineFormat::Json => b.to_json(),
        BaselineFormat::Deqp => b.to_deqp(),
    };
    write_atomic(&a.out, text.as_bytes()).with_context(|| "writing the baseline")?;
    println!(
        "baseline: {} expected non-pass cells ({} flaky), {} performance bounds → {}",
        b.expected.len(),
        b.expected.iter().filter(|e| e.flake).count(),
        b.performance.len(),
        a.out.display()
    );
    Ok(exit::OK)
}

pub fn load_baseline(p: &Path) -> Result<Baseline> {
    let text = std::fs::read_to_string(p).map_err(|e| {
        coded(exit::BAD_INPUT, format!("cannot read baseline {}: {e}", p.display()))
    })?;
    Baseline::parse(&p.display().to_string(), &text)
        .map_err(|e| coded(exit::BAD_INPUT, e.to_string()))
}

pub fn merge_cmd(a: &MergeArgs) -> Result<u8> {
    let reports = a
        .reports
        .iter()
        .map(|p| Ok((p.display().to_string(), load(p)?)))
        .collect::<Result<Vec<_>>>()?;
    let n = reports.len();
    let m = merge::merge(reports, a.force).map_err(|e| coded(exit::BAD_INPUT, e))?;
    let bytes = serde_json::to_vec_pretty(&m).context("serializing the merged report")?;
    write_atomic(&a.out, &bytes).with_context(|| "writing the merged report")?;
    println!(
        "merged {n} reports: {} cells, {} findings, {} worker faults outside cells → {}",
        m.cells.len(),
        m.tally.findings,
        m.tally.worker_faults,
        a.out.display()
    );
    Ok(exit::OK)
}

pub fn diff_cmd(a: &DiffArgs) -> Result<u8> {
    if !(a.noise >= 0.0 && a.noise_floor_ms >= 0.0) {
        return Err(coded(exit::USAGE, "--noise and --noise-floor-ms must be >= 0"));
    }
    let (old, new) = (load(&a.old)?, load(&a.new)?);
    let d = diff::diff(&old, &new, a.noise, a.noise_floor_ms);
    let text = match a.format {
        DiffFormat::Text => diff::render_text(&d),
        DiffFormat::Md => diff::render_markdown(&d),
    };
    if let Some(o) = &a.out {
        write_atomic(o, text.as_bytes()).with_context(|| "writing the diff")?;
    }
    print!("{text}");
    Ok(if d.cells.is_empty() { exit::OK } else { exit::FINDINGS })
}
