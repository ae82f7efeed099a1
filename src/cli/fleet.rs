//! `rtprobe baseline`, `merge` and `diff`: glue between arguments and [`crate::fleet`]. They only
//! read reports and write files (atomically); no GPU work.
use super::args::{BaselineArgs, BaselineFormat, DiffArgs, DiffFormat, MergeArgs};
use super::exit::{self, coded};
use super::out::{errln, out, outln};
use crate::atomic::write_atomic;
use crate::fleet::baseline::Scope;
use crate::fleet::deqp_files::Patterns;
use crate::fleet::{diff, merge};
use crate::model::RunReport;
use crate::model::{Baseline, Filter};
use anyhow::{Context, Result};
use std::path::Path;

fn load(p: &Path) -> Result<RunReport> {
    RunReport::load(p).map_err(|e| coded(exit::BAD_INPUT, e))
}

/// A `run --shader` report, when `p` is one (its schema); `None` for any other file.
fn shader_run(p: &Path) -> Result<Option<crate::model::shader_run::ShaderRunReport>> {
    use crate::model::shader_run::SCHEMA;
    let Ok(text) = std::fs::read(p) else { return Ok(None) };
    let Ok(v) = serde_json::from_slice::<serde_json::Value>(&text) else { return Ok(None) };
    if v["schema"] != SCHEMA {
        return Ok(None);
    }
    serde_json::from_value(v).map(Some).map_err(|e| {
        coded(exit::BAD_INPUT, format!("{}: not a readable {SCHEMA} report ({e})", p.display()))
    })
}

pub fn baseline(a: &BaselineArgs) -> Result<u8> {
    super::paths::writable_file(&a.out, "-o")?;
    if let Some(r) = shader_run(&a.report)? {
        return shader_baseline(a, &r);
    }
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
    write_baseline(a, &mut b)?;
    outln!(
        "baseline: {} expected non-pass cells ({} flaky), {} performance bounds → {}",
        b.expected.len(),
        b.expected.iter().filter(|e| e.flake).count(),
        b.performance.len(),
        a.out.display()
    );
    Ok(exit::OK)
}

/// `b` with `--bug` on every expectation, written to `--out` in `--format`.
fn write_baseline(a: &BaselineArgs, b: &mut crate::model::Baseline) -> Result<()> {
    for e in &mut b.expected {
        e.bug.clone_from(&a.bug);
    }
    let text = match a.format {
        BaselineFormat::Json => b.to_json(),
        BaselineFormat::Deqp => b.to_deqp(),
    };
    write_atomic(&a.out, text.as_bytes()).with_context(|| "writing the baseline")
}

/// `rtprobe baseline` of a `run --shader` report: its findings by `cell id/variant`, JSON only.
fn shader_baseline(a: &BaselineArgs, r: &crate::model::shader_run::ShaderRunReport) -> Result<u8> {
    if !a.perf.is_empty() {
        return Err(coded(exit::USAGE, "--perf: a run --shader report times no phase; drop it"));
    }
    let mut b = crate::fleet::shader_baseline::from_report(r, &a.report.display().to_string());
    write_baseline(a, &mut b)?;
    outln!(
        "baseline: {} expected variants with findings ({} flaky) of {} → {}",
        b.expected.len(),
        b.expected.iter().filter(|e| e.flake).count(),
        r.cell,
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
    super::paths::writable_file(&a.out, "-o")?;
    let _lock = crate::report::lock::ReportLock::acquire(&a.out)
        .map_err(|e| coded(exit::BAD_INPUT, format!("{e}; merge into another -o")))?;
    let given = a.baseline.as_deref().map(load_baseline).transpose()?;
    let reports = a
        .reports
        .iter()
        .map(|p| Ok((p.display().to_string(), load(p)?)))
        .collect::<Result<Vec<_>>>()?;
    let n = reports.len();
    let checks: Vec<Option<&crate::model::BaselineCheck>> =
        reports.iter().map(|(_, r)| r.baseline.as_ref()).collect();
    let carried = match &given {
        Some(_) => None,
        None => merge::carried_check(&checks).map_err(|why| {
            coded(
                exit::BAD_INPUT,
                format!("{why}: give merge --baseline FILE to check the merged report"),
            )
        })?,
    };
    let mut m = merge::merge(reports, a.force).map_err(|e| coded(exit::BAD_INPUT, e))?;
    m.baseline = match (&given, a.baseline.as_deref()) {
        (Some(b), Some(p)) => {
            let scope = merged_scope(&m, b)?;
            Some(crate::fleet::baseline::check(&m, b, &p.display().to_string(), &scope))
        }
        _ => carried,
    };
    let bytes = serde_json::to_vec_pretty(&m).context("serializing the merged report")?;
    write_atomic(&a.out, &bytes).with_context(|| "writing the merged report")?;
    let retries = m.retries.values().sum::<usize>();
    outln!(
        "merged {n} reports: {} planned{}, {}, {} outside cells → {}",
        crate::model::plural(m.plan.planned, "cell"),
        match retries {
            0 => String::new(),
            1 => " (and 1 retry)".into(),
            n => format!(" (and {n} retries)"),
        },
        crate::model::plural(m.tally.findings, "finding"),
        crate::model::plural(m.tally.worker_faults, "worker fault"),
        a.out.display()
    );
    if let Some(why) = &m.incomplete {
        outln!("not complete: {why}");
    }
    if let Some(c) = &m.baseline {
        out!("{}", crate::fleet::baseline::render(c, a.allow_improvements));
    }
    let v = crate::report::verdict::verdict(&m, a.allow_improvements);
    outln!("{}", v.line());
    Ok(exit::of_verdict(&v))
}

/// Where the entries of `b` that the merged report `m` lacks went: its `--filter`s exclude them,
/// or its `--skips` left them out. Its shards are whole (`merge::whole_shards`), so none is
/// another shard's: any other entry is missing.
fn merged_scope(m: &RunReport, b: &Baseline) -> Result<Scope> {
    let bad = |e: String| coded(exit::BAD_INPUT, format!("the merged report's options: {e}"));
    let filters = m
        .options
        .filters
        .iter()
        .map(|f| Filter::parse(f).map_err(|e| bad(e.to_string())))
        .collect::<Result<Vec<_>>>()?;
    let skips = Patterns::of(m.options.skips.clone()).map_err(bad)?;
    let elsewhere = b.expected.iter().map(|e| e.cell.clone()).filter(|id| skips.matches(id));
    Ok(Scope { elsewhere: elsewhere.collect(), filters })
}

pub fn diff_cmd(a: &DiffArgs) -> Result<u8> {
    if !(a.noise >= 0.0 && a.noise_floor_ms >= 0.0) {
        return Err(coded(exit::USAGE, "--noise and --noise-floor-ms must be >= 0"));
    }
    if let Some(o) = &a.out {
        super::paths::writable_file(o, "-o")?;
    }
    let (old, new) = (load(&a.old)?, load(&a.new)?);
    if let Some(w) = diff::device_warning(&old, &new) {
        errln!("rtprobe: warning: {w}");
    }
    let d = diff::diff(&old, &new, a.noise, a.noise_floor_ms);
    let text = match a.format {
        DiffFormat::Text => diff::render_text(&d),
        DiffFormat::Md => diff::render_markdown(&d),
    };
    match &a.out {
        Some(o) => {
            write_atomic(o, text.as_bytes()).with_context(|| "writing the diff")?;
            outln!("diff: {}", o.display());
        }
        None => out!("{text}"),
    }
    Ok(if d.cells.is_empty() { exit::OK } else { exit::FINDINGS })
}
