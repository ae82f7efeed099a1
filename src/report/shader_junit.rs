//! JUnit XML of a `run --shader` report: one testcase per variant (classname the cell id, name
//! the variant), a failure for a finding the baseline (when the run had one) did not expect.
use super::junit::esc;
use crate::model::shader_run::{ShaderRunReport, ShaderVariant};
use crate::model::Status;

/// Why a finding is not a failure: the run's baseline expected it; `None`: it fails.
fn expected(r: &ShaderRunReport, v: &ShaderVariant) -> Option<&'static str> {
    let b = r.baseline.as_ref()?;
    let id = format!("{}/{}", r.cell, v.name);
    match b.cells.iter().find(|c| c.cell == id).map(|c| c.status) {
        Some(Status::KnownFlake) => Some("known flake in the baseline"),
        Some(Status::Regression | Status::Improvement | Status::Missing) => None,
        Some(Status::Expected) | None => Some("expected by the baseline"),
    }
}

/// The testcase of one variant.
fn testcase(r: &ShaderRunReport, v: &ShaderVariant) -> (String, bool) {
    let secs: f64 = v.attempts.iter().map(|a| a.attempt.wall_ms).sum::<f64>() / 1e3;
    let mut s = format!(
        "  <testcase classname=\"{}\" name=\"{}\" time=\"{secs:.3}\">",
        esc(&r.cell),
        esc(&v.name)
    );
    let detail = v.detail.as_deref().unwrap_or("");
    let incidence = v.incidence.as_ref().map(|i| format!(" ({})", i.label())).unwrap_or_default();
    let what = format!("{}: {detail}{incidence}", v.judgement.as_str());
    let failed = v.outcome.is_finding() && expected(r, v).is_none();
    if failed {
        s += &format!("<failure type=\"{}\" message=\"{}\"/>", esc(v.outcome.as_str()), esc(&what));
    } else if let Some(why) = expected(r, v).filter(|_| v.outcome.is_finding()) {
        s += &format!("<system-out>{} ({why})</system-out>", esc(&what));
    }
    s += "</testcase>\n";
    (s, failed)
}

pub fn render(r: &ShaderRunReport) -> String {
    let cases: Vec<(String, bool)> = r.variants.iter().map(|v| testcase(r, v)).collect();
    let failures = cases.iter().filter(|c| c.1).count();
    let mut s = format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<testsuites>\n<testsuite name=\"rtprobe.shader\" tests=\"{}\" failures=\"{failures}\" skipped=\"0\">\n",
        cases.len()
    );
    for (c, _) in cases {
        s += &c;
    }
    s += "</testsuite>\n</testsuites>\n";
    s
}
