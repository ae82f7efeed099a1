//! JUnit XML for CI systems: one testcase per cell; findings are failures, unsupported cells
//! skipped.
use crate::model::Outcome;
use crate::model::RunReport;
use crate::model::Status;

pub fn esc(s: &str) -> String {
    s.chars()
        .map(|c| match c {
            '&' => "&amp;".into(),
            '<' => "&lt;".into(),
            '>' => "&gt;".into(),
            '"' => "&quot;".into(),
            '\'' => "&apos;".into(),
            c if (c as u32) < 0x20 && c != '\n' && c != '\t' => " ".into(),
            c => c.to_string(),
        })
        .collect()
}

/// Whether the JUnit testcase fails: a finding of a probe cell (flaky ones too), or a canary
/// whose fault was not detected. A detected canary is a success; a retry (a workaround variant or
/// recommended pattern a round added) only informs its finding.
fn fails(r: &RunReport, c: &crate::model::CellReport) -> bool {
    match &c.canary_check {
        Some(chk) => !chk.detected,
        None if c.is_retry(r.options.patches) => false,
        None => {
            (c.outcome.is_finding() && expected_by_baseline(r, c).is_none())
                || (c.injection_undetected && c.outcome == Outcome::Pass)
        }
    }
}

/// What fails the run outside the cells: worker faults (setups, between cells, teardowns) and
/// phases over a baseline's time bound, as (name, failure type, message).
fn run_level_failures(r: &RunReport) -> Vec<(String, String, String)> {
    match &r.baseline {
        // With a baseline, only what it did not expect.
        Some(b) => b
            .worker_faults
            .iter()
            .enumerate()
            .map(|(k, w)| {
                (format!("worker-fault-{k}"), "unexpected_worker_fault".to_string(), w.clone())
            })
            .chain(b.performance.iter().map(|p| {
                (
                    format!("performance.{}", p.split(':').next().unwrap_or("phase")),
                    "performance_regression".to_string(),
                    p.clone(),
                )
            }))
            // An expected fault whose cell did not run: a failure of the run, by cell.
            .chain(b.missing().map(|m| {
                (
                    format!("baseline.{}", m.cell),
                    "missing".to_string(),
                    m.why.clone().unwrap_or_default(),
                )
            }))
            .collect(),
        None => r
            .workers
            .iter()
            .filter(|w| w.is_fault())
            .map(|w| {
                (
                    format!("worker-{}.{}", w.worker, w.phase),
                    w.outcome.as_str().to_string(),
                    w.detail.clone().unwrap_or_default(),
                )
            })
            .collect(),
    }
}

/// With `--baseline`: the finding is expected there (an expected fault or a known flake).
fn expected_by_baseline<'a>(r: &'a RunReport, c: &crate::model::CellReport) -> Option<&'a str> {
    let b = r.baseline.as_ref()?;
    match b.cells.iter().find(|x| x.cell == c.id).map(|x| x.status) {
        Some(Status::KnownFlake) => Some("known flake in the baseline"),
        Some(Status::Regression | Status::Improvement | Status::Missing) => None,
        // Not listed among the surprises: the baseline expected exactly this.
        Some(Status::Expected) | None => Some("expected by the baseline"),
    }
}

pub fn render(r: &RunReport) -> String {
    let run_level = run_level_failures(r);
    let failures = r.cells.iter().filter(|c| fails(r, c)).count() + run_level.len();
    let skipped = r
        .cells
        .iter()
        .filter(|c| matches!(c.outcome, Outcome::Unsupported | Outcome::NotImplemented))
        .count();
    let mut s = format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<testsuites>\n<testsuite name=\"rtprobe\" tests=\"{}\" failures=\"{failures}\" skipped=\"{skipped}\">\n",
        r.cells.len() + run_level.len()
    );
    for (name, kind, message) in &run_level {
        s += &format!("  <testcase classname=\"rtprobe.run\" name=\"{}\" time=\"0\"><failure type=\"{}\" message=\"{}\"/></testcase>\n", esc(name), esc(kind), esc(message));
    }
    for c in &r.cells {
        let class = format!("{}.{}", c.cell.stage, c.cell.resource);
        let secs = c.attempts.last().map(|a| a.wall_ms / 1e3).unwrap_or(0.0);
        s += &format!(
            "  <testcase classname=\"{}\" name=\"{}\" time=\"{secs:.3}\">",
            esc(&class),
            esc(&c.id)
        );
        let reason = esc(c.reason.as_deref().unwrap_or(""));
        let mut props = vec![];
        if let Some(inc) = c.incidence.as_ref().filter(|_| c.flaky) {
            props.push(("flaky", inc.label()));
        }
        if let Some(rule) = &c.outside_spec {
            props.push(("outside_spec", rule.clone()));
        }
        if !props.is_empty() {
            s += "<properties>";
            for (k, v) in props {
                s += &format!("<property name=\"{k}\" value=\"{}\"/>", esc(&v));
            }
            s += "</properties>";
        }
        if let Some(chk) = &c.canary_check {
            let expected: Vec<&str> = chk.expected.iter().map(|o| o.as_str()).collect();
            s += &if chk.detected {
                format!(
                    "<system-out>canary detected: {} (expected {})</system-out>",
                    c.outcome.as_str(),
                    expected.join(" or ")
                )
            } else {
                format!("<failure type=\"canary_undetected\" message=\"expected {}, got {}: {reason}\"/>", expected.join(" or "), c.outcome.as_str())
            };
        } else if c.is_retry(r.options.patches) {
            s += &format!(
                "<system-out>{}: {} (a retry of a finding, not a planned cell)</system-out>",
                esc(c.outcome.as_str()),
                reason
            );
        } else if let Some(why) = expected_by_baseline(r, c).filter(|_| c.outcome.is_finding()) {
            s += &format!(
                "<system-out>{}: {} ({why})</system-out>",
                esc(c.outcome.as_str()),
                reason
            );
        } else {
            match c.outcome {
                Outcome::Pass if c.injection_undetected => {
                    s += &format!("<failure type=\"injection_undetected\" message=\"{} ran and the cell passed\"/>", esc(c.injected.as_deref().unwrap_or("")))
                }
                Outcome::Pass => {}
                Outcome::Unsupported | Outcome::NotImplemented => s += &format!("<skipped message=\"{reason}\"/>"),
                Outcome::Mismatch | Outcome::DeviceLost | Outcome::Crash | Outcome::Timeout | Outcome::Error => {
                    let kind = if c.flaky { format!("{} (flaky)", c.outcome.as_str()) } else { c.outcome.as_str().to_string() };
                    s += &format!("<failure type=\"{}\" message=\"{reason}\"/>", esc(&kind))
                }
            }
        }
        s += "</testcase>\n";
    }
    s += "</testsuite>\n</testsuites>\n";
    s
}
