//! JUnit XML for CI systems: one testcase per cell; findings are failures, unsupported cells
//! skipped.
use super::run_report::RunReport;
use crate::outcome::Outcome;

fn esc(s: &str) -> String {
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

pub fn render(r: &RunReport) -> String {
    let failures = r.cells.iter().filter(|c| c.outcome.is_finding()).count();
    let skipped = r.cells.iter().filter(|c| matches!(c.outcome, Outcome::Unsupported | Outcome::NotImplemented)).count();
    let mut s = format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<testsuites>\n<testsuite name=\"rtprobe\" tests=\"{}\" failures=\"{failures}\" skipped=\"{skipped}\">\n",
        r.cells.len()
    );
    for c in &r.cells {
        let class = format!("{}.{}", c.cell.stage, c.cell.resource);
        let secs = c.attempts.last().map(|a| a.wall_ms / 1e3).unwrap_or(0.0);
        s += &format!("  <testcase classname=\"{}\" name=\"{}\" time=\"{secs:.3}\">", esc(&class), esc(&c.id));
        let reason = esc(c.reason.as_deref().unwrap_or(""));
        match c.outcome {
            Outcome::Pass => {}
            Outcome::Unsupported | Outcome::NotImplemented => s += &format!("<skipped message=\"{reason}\"/>"),
            Outcome::Mismatch | Outcome::DeviceLost | Outcome::Crash | Outcome::Timeout | Outcome::Error => {
                s += &format!("<failure type=\"{}\" message=\"{reason}\"/>", c.outcome.as_str())
            }
        }
        s += "</testcase>\n";
    }
    s += "</testsuite>\n</testsuites>\n";
    s
}
