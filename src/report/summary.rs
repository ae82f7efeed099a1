//! The terminal summary printed at the end of `rtprobe run`.
use crate::model::RunReport;
use crate::model::{plural, Outcome};
use std::fmt::Write;

fn mark(o: Outcome) -> &'static str {
    match o {
        Outcome::Pass => "✅",
        Outcome::Unsupported => "➖",
        Outcome::NotImplemented => "🚧",
        Outcome::Mismatch => "❌",
        Outcome::DeviceLost => "💥",
        Outcome::Crash => "💥",
        Outcome::Timeout => "⏱",
        Outcome::Error => "⚠",
    }
}

/// What the summary leaves out.
#[derive(Clone, Copy, Debug, Default)]
pub struct Quiet {
    /// The pipeline cache's save errors: already said on an earlier run (the report keeps them).
    pub cache_errors: bool,
}

/// The summary (the verdict line and the baseline's are the CLI's, after it).
pub fn render(r: &RunReport) -> String {
    render_quiet(r, Quiet::default())
}

/// [`render`], leaving out what `quiet` says.
pub fn render_quiet(r: &RunReport, quiet: Quiet) -> String {
    let mut s = String::new();
    header(&mut s, r);
    scene_notes(&mut s, r);
    worker_and_canary_notes(&mut s, r);
    spec_and_injection_notes(&mut s, r);
    findings(&mut s, r);
    if let Some(m) = &r.mutants {
        s += &crate::report::mutants::render(m);
    }
    timing(&mut s, r, quiet);
    s
}

/// The device, the plan and the outcome counts.
fn header(s: &mut String, r: &RunReport) {
    let _ = writeln!(
        s,
        "rtprobe run on {} ({} {})",
        r.device["name"].as_str().unwrap_or("?"),
        r.device["driver_name"].as_str().unwrap_or("?"),
        r.device["driver_version"]["decoded"].as_str().unwrap_or("?")
    );
    let _ = writeln!(
        s,
        "plan: {} generated, {} filtered out, {} planned ({} to run, {} unsupported, {} not implemented in rtprobe)",
        r.plan.generated, r.plan.filtered_out, r.plan.planned, r.plan.to_run, r.plan.unsupported, r.plan.not_implemented
    );
    let _ = write!(s, "outcomes:");
    for o in Outcome::ALL {
        let n = r.summary.get(o.as_str()).copied().unwrap_or(0);
        let _ = write!(s, "  {} {} {n}", mark(*o), o.as_str());
    }
    let _ = writeln!(s);
    retries(s, r);
    if let Some(last) = r.resumed.last() {
        let _ = writeln!(
            s,
            "resumed: {} kept from the interrupted run (not run again), {} run now",
            plural(last.kept, "cell"),
            plural(last.to_run, "cell")
        );
    }
}

/// A `--scene` run's scene, and the cells it cannot discriminate (`reference::limits`): their
/// passes prove less, so the summary says which and why.
fn scene_notes(s: &mut String, r: &RunReport) {
    let Some(f) = &r.scene.params.file else { return };
    let _ = writeln!(
        s,
        "scene: {} ({} instances, {} triangles)",
        f.path, r.scene.instances, r.scene.triangles
    );
    if let Some(line) = scene_cost(r) {
        let _ = writeln!(s, "  {line}");
    }
    for l in &r.scene.limits {
        let first: Vec<&str> = l.cells.iter().take(3).map(String::as_str).collect();
        let more = l.cells.len().saturating_sub(first.len());
        let _ = writeln!(
            s,
            "  undiscriminating: {} on {:.0}% of their pixels: {} (e.g. {}{}; all in the report's scene.limits)",
            plural(l.cells.len(), "cell"),
            l.share * 100.0,
            l.why,
            first.join(", "),
            if more > 0 { format!(" and {more} more") } else { String::new() }
        );
    }
}

/// The scene's costs: load, CPU reference, the workers' AS builds, the CLI's peak memory.
fn scene_cost(r: &RunReport) -> Option<String> {
    let c = r.scene.cost.as_ref()?;
    let t = &r.timing;
    let build = if t.as_builds > 0 {
        format!(
            "AS build {:.0} ms (mean of {}, slowest {:.0} ms)",
            t.as_build_ms_mean,
            plural(t.as_builds, "worker"),
            t.as_build_ms_max
        )
    } else {
        "no AS built".into()
    };
    let peak = c.peak_mib.map_or("unknown".into(), |m| format!("{m} MiB"));
    Some(format!(
        "cost: load {:.1} ms, CPU reference {:.0} ms, {build}, peak memory {peak} (CLI)",
        c.load_ms, c.reference_ms
    ))
}

/// The retries a round added (workaround variants, recommended patterns), apart from the plan.
fn retries(s: &mut String, r: &RunReport) {
    if r.retries.is_empty() {
        return;
    }
    let cells: Vec<_> = r.cells.iter().filter(|c| c.is_retry(r.options.patches)).collect();
    let variants = cells.iter().filter(|c| c.cell.patch.is_some()).count();
    let counts: Vec<String> = r.retries.iter().map(|(o, n)| format!("{o} {n}")).collect::<Vec<_>>();
    let kinds: Vec<String> =
        [(variants, "workaround variant"), (cells.len() - variants, "recommended pattern")]
            .iter()
            .filter(|(n, _)| *n > 0)
            .map(|(n, w)| plural(*n, w))
            .collect();
    let _ = writeln!(
        s,
        "retries (not in the plan, not counted above): {} tried on the findings: {}",
        kinds.join(" and "),
        counts.join(", ")
    );
}

/// Canaries, fault injection, and worker faults outside any cell.
fn worker_and_canary_notes(s: &mut String, r: &RunReport) {
    let canaries: Vec<_> = r.cells.iter().filter(|c| c.canary_check.is_some()).collect();
    for c in &canaries {
        let chk = c.canary_check.as_ref().expect("filtered");
        let _ = writeln!(
            s,
            "canary {}: {} {} ({})",
            c.id,
            if chk.detected { "✅" } else { "❌" },
            c.outcome.as_str(),
            if chk.detected {
                "detected as expected"
            } else {
                "NOT detected: fault classification unproven on this driver; the run fails"
            }
        );
    }
    if !r.options.inject.is_empty() {
        let injected = r.cells.iter().filter(|c| c.injected.is_some()).count();
        let _ = writeln!(
            s,
            "fault injection: {} on purpose ({})",
            if injected == 1 {
                "1 cell misbehaves".to_string()
            } else {
                format!("{injected} cells misbehave")
            },
            r.options.inject.join("; ")
        );
    }
    // Worker faults outside any cell (failed setups, crashes between cells, hung teardowns); a
    // worker that halted the run is said by the run's own error line, not as a driver's fault.
    let faults: Vec<_> =
        r.workers.iter().filter(|w| w.outcome != Outcome::Pass && w.halt.is_none()).collect();
    if !faults.is_empty() {
        let _ = writeln!(s, "worker faults outside cells ({}):", faults.len());
        for w in faults.iter().take(10) {
            let _ = writeln!(
                s,
                "  {} worker {} {} in {} — {}",
                mark(w.outcome),
                w.worker,
                w.outcome.as_str(),
                w.phase,
                w.detail.as_deref().unwrap_or("")
            );
        }
    }
}

/// Reads outside the spec's guarantees, validation errors, undetected injections.
fn spec_and_injection_notes(s: &mut String, r: &RunReport) {
    let outside: Vec<_> = r.cells.iter().filter(|c| c.outside_spec.is_some()).collect();
    if let Some(first) = outside.first() {
        let other = outside.iter().filter(|c| c.element_reads().any(|e| e.other > 0)).count();
        let _ = writeln!(
            s,
            "outside the spec's guarantees: {} descriptors dynamically without nonuniformEXT, or with one their compiler dropped ({}); {other} of them read another element of the array on some pixels (allowed there; counts per cell in the report)",
            if outside.len() == 1 { "1 cell indexes".to_string() } else { format!("{} cells index", outside.len()) },
            first.outside_spec.as_deref().unwrap_or("")
        );
    }
    let vcells: Vec<_> = r
        .cells
        .iter()
        .filter(|c| {
            c.attempts.iter().any(|a| a.result.as_ref().is_some_and(|x| x.validation_errors > 0))
        })
        .collect();
    if !vcells.is_empty() {
        let _ = writeln!(s, "validation errors in {} (rtprobe misused the API there; their outcomes prove nothing): first {}", plural(vcells.len(), "cell"), vcells[0].id);
    }
    let undetected: Vec<_> = r.cells.iter().filter(|c| c.injection_undetected).collect();
    if let Some(first) = undetected.first() {
        let _ = writeln!(
            s,
            "❌ injected faults NOT detected in {} (the injection ran and the cell passed: detection unproven here), first {} ({})",
            plural(undetected.len(), "cell"),
            first.id,
            first.injected.as_deref().unwrap_or("")
        );
    }
}

/// The verdict: each finding (at most 40), or why there is none.
fn findings(s: &mut String, r: &RunReport) {
    let findings: Vec<_> = r.findings().collect();
    let not_run = r.plan.unsupported + r.plan.not_implemented;
    let worker_faults = r.workers.iter().filter(|w| w.is_fault()).count();
    if findings.is_empty() && worker_faults > 0 {
        let _ = writeln!(
            s,
            "no cell faulted or mismatched, but {} outside cells (above)",
            plural(worker_faults, "worker fault")
        );
    } else if findings.is_empty() && not_run > 0 {
        let _ = writeln!(
            s,
            "no faults or mismatches in the {} cells that ran; {} planned cells did not run ({} unsupported by the device, {} not implemented in rtprobe)",
            r.plan.to_run, not_run, r.plan.unsupported, r.plan.not_implemented
        );
    } else if findings.is_empty() {
        let _ = writeln!(s, "no faults or mismatches");
    } else {
        let flaky = findings.iter().filter(|c| c.flaky).count();
        let expected =
            |c: &crate::model::CellReport| r.baseline.as_ref().is_some_and(|b| b.expects(&c.id));
        let n_expected = findings.iter().filter(|c| expected(c)).count();
        let by_baseline = match &r.baseline {
            Some(b) if n_expected == findings.len() => {
                format!(", all expected by baseline {}", b.source)
            }
            Some(b) => format!(", {n_expected} expected by baseline {}", b.source),
            None => String::new(),
        };
        let _ = writeln!(
            s,
            "findings ({}{}{by_baseline}):",
            findings.len(),
            if flaky > 0 { format!(", {flaky} flaky") } else { String::new() }
        );
        for c in findings.iter().take(40) {
            finding(s, c, r.baseline.is_some() && expected(c));
        }
        if findings.len() > 40 {
            let _ = writeln!(s, "  … and {} more (see the report)", findings.len() - 40);
        }
    }
}

/// One finding with its pictures, workarounds, recommended pattern and GPU-AV result;
/// `expected`: the run's baseline expects it (no failure mark).
fn finding(s: &mut String, c: &crate::model::CellReport, expected: bool) {
    // The reason already carries "k of N attempts"; a flaky cell says so up front.
    let tag = match (c.flaky, expected) {
        (true, true) => " [FLAKY, expected]",
        (true, false) => " [FLAKY]",
        (false, true) => " [expected]",
        (false, false) => "",
    };
    let _ = writeln!(
        s,
        "  {} {:<12} {}{} — {}",
        if expected { "➖" } else { mark(c.outcome) },
        c.outcome.as_str(),
        c.id,
        tag,
        c.reason.as_deref().unwrap_or("")
    );
    if let Some(diff) = c
        .attempts
        .iter()
        .rev()
        .find_map(|a| a.result.as_ref()?.comparison.as_ref()?.pictures.last())
    {
        let _ = writeln!(s, "      pictures: {diff} (expected.png and actual.png beside it)");
    }
    if let Some(split) =
        c.attempts.iter().rev().find_map(|a| a.result.as_ref()?.comparison.as_ref()?.lanes.as_ref())
    {
        let _ = writeln!(s, "      lanes: {}", split.sentence(c.cell.stage.as_str()));
    }
    if !c.workarounds.is_empty() {
        let verified: Vec<&str> =
            c.workarounds.iter().filter(|w| w.verified).map(|w| w.patch.as_str()).collect();
        let tried: Vec<String> = c.workarounds.iter().map(|w| w.tried()).collect();
        if verified.is_empty() {
            let _ = writeln!(s, "      no verified workaround ({})", tried.join(", "));
        } else {
            let _ = writeln!(
                s,
                "      verified workaround: {} ({})",
                verified.join(", "),
                tried.join(", ")
            );
        }
    }
    if let Some(p) = &c.recommended {
        let _ = writeln!(s, "      {}", p.line());
    }
    if let Some(v) = &c.gpu_av {
        let _ = writeln!(s, "      {}", v.line());
    }
}

/// rtprobe's own share of the wall (`timing.own_ms`) and the driver's time taken from it; empty
/// for reports without it.
fn own(t: &crate::model::report::TimingSummary) -> String {
    t.own_ms.map_or(String::new(), |own| {
        format!(
            " (own {:.2} s; driver: device creation {:.2} s, setup waits {:.2} s, pipeline waits {:.2} s, fence waits {:.2} s)",
            own / 1e3,
            t.device_create_ms / 1e3,
            t.setup_wait_ms / 1e3,
            t.pipeline_wait_ms / 1e3,
            t.trace_ms / 1e3
        )
    })
}

/// Time per phase, the prebuild and the pipeline cache.
fn timing(s: &mut String, r: &RunReport, quiet: Quiet) {
    let t = &r.timing;
    let n = t.cells_timed.max(1) as f64;
    let _ = writeln!(
        s,
        "time: {:.1} s wall{}, {} (device {:.0} ms each{}); per cell: compile {:.1} ms, pipeline {:.1} ms, trace {:.1} ms, check {:.2} ms (readback {:.2}), overhead {:.1} ms",
        t.wall_ms / 1e3,
        own(t),
        plural(t.workers_started, "worker"),
        t.device_ms_mean,
        if t.as_builds > 0 {
            format!(", of it AS build {:.0} ms", t.as_build_ms_mean)
        } else {
            String::new()
        },
        t.compile_ms / n,
        t.pipeline_ms / n,
        t.trace_ms / n,
        t.check_ms / n,
        t.readback_ms / n,
        t.overhead_ms / n
    );
    if t.prebuilt_pipelines > 0 {
        let threads =
            r.options.threads.map(|n| n.to_string()).unwrap_or_else(|| "--threads".into());
        let _ = writeln!(s, "prebuild: {} pipelines created on {threads} threads ahead of their cells, {:.1} s wall, {} cells run meanwhile, {} of them judged on a checker thread (their per-cell time above is each one's time on its thread)", t.prebuilt_pipelines, t.prebuild_ms / 1e3, t.overlapped_cells, t.checked_apart);
    }
    if let Some(pc) = &r.pipeline_cache {
        let file = pc.file.as_ref().map(|f| f.display().to_string()).unwrap_or_default();
        let ignored = if pc.ignored.is_empty() {
            String::new()
        } else {
            format!("; ignored: {}", pc.ignored.join("; "))
        };
        let errors = if pc.save_errors.is_empty() || quiet.cache_errors {
            String::new()
        } else {
            format!("; {}", pc.save_errors.join("; "))
        };
        let _ = writeln!(
            s,
            "pipeline cache: {} bytes loaded ({}), {} bytes saved ({file}){ignored}{errors}",
            pc.loaded_bytes,
            plural(pc.workers_loaded, "worker"),
            pc.saved_bytes
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_scene_cost_line_says_the_as_build_or_that_none_was_built() {
        let mut r = RunReport::for_tests(vec![]);
        assert_eq!(scene_cost(&r), None, "no cost recorded: no line");
        r.scene.cost =
            Some(crate::model::SceneCost { load_ms: 0.3, reference_ms: 90.0, peak_mib: Some(80) });
        let line = scene_cost(&r).unwrap();
        assert!(line.contains("no AS built") && line.contains("80 MiB"), "{line}");
        r.timing.as_builds = 2;
        r.timing.as_build_ms_mean = 4.2;
        r.timing.as_build_ms_max = 24.0;
        let line = scene_cost(&r).unwrap();
        assert_eq!(
            line,
            "cost: load 0.3 ms, CPU reference 90 ms, AS build 4 ms (mean of 2 workers, slowest 24 ms), peak memory 80 MiB (CLI)"
        );
    }
}
