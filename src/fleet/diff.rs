//! `rtprobe diff OLD.json NEW.json`: what changed between two runs — a driver update, another
//! GPU, a new rtprobe — per cell (fixed, regressed, changed, new, gone) and per phase of the time
//! per cell beyond a noise threshold. As a table, or as Markdown for a PR comment.
use super::baseline::{phase_mean, PHASES};
use crate::model::Outcome;
use crate::model::{CellReport, RunReport};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::fmt::Write;

#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Change {
    /// A finding before, a pass now.
    Fixed,
    /// A pass before, a finding now (or a worse finding).
    Regressed,
    /// Another finding, another flakiness, or support changed (unsupported ↔ run).
    Changed,
    /// Only in NEW.
    New,
    /// Only in OLD.
    Gone,
}

impl Change {
    pub fn as_str(self) -> &'static str {
        match self {
            Change::Fixed => "fixed",
            Change::Regressed => "regressed",
            Change::Changed => "changed",
            Change::New => "new",
            Change::Gone => "gone",
        }
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CellDiff {
    pub cell: String,
    pub change: Change,
    pub old: Option<String>,
    pub new: Option<String>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PhaseDiff {
    pub phase: String,
    pub old_ms: f64,
    pub new_ms: f64,
    pub ratio: f64,
}

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ReportDiff {
    pub old_device: String,
    pub new_device: String,
    pub cells: Vec<CellDiff>,
    /// Phases whose mean time per cell changed beyond the noise threshold.
    pub timing: Vec<PhaseDiff>,
    pub unchanged: usize,
}

impl ReportDiff {
    pub fn is_empty(&self) -> bool {
        self.cells.is_empty() && self.timing.is_empty()
    }
}

fn verdict(c: &CellReport) -> String {
    let mut s = c.outcome.as_str().to_string();
    if c.flaky {
        if let Some(i) = &c.incidence {
            s += &format!(" (flaky {} of {})", i.faulted, i.attempts);
        }
    }
    s
}

fn change(old: &CellReport, new: &CellReport) -> Option<Change> {
    let (o, n) = (old.outcome, new.outcome);
    if o == n && old.flaky == new.flaky {
        return None;
    }
    Some(match (o.is_finding(), n.is_finding()) {
        (true, false) if n == Outcome::Pass => Change::Fixed,
        (false, true) if o == Outcome::Pass => Change::Regressed,
        (true, true) if n.severity() > o.severity() => Change::Regressed,
        _ => Change::Changed,
    })
}

/// A warning when OLD and NEW were made on different devices (by name): their differences may be
/// the devices', not a driver's. Another driver version of the same device is what `diff` is for.
pub fn device_warning(old: &RunReport, new: &RunReport) -> Option<String> {
    let name = |r: &RunReport| r.device["name"].as_str().unwrap_or("?").to_string();
    (old.device["name"] != new.device["name"]).then(|| {
        format!(
            "the reports were made on different devices ({} and {}): what differs may be the devices, not a driver change",
            name(old),
            name(new)
        )
    })
}

/// Compare two reports. `noise`: a phase's time per cell must change by more than this factor
/// (0.5 = ±50%) and by more than `floor_ms` to be reported.
pub fn diff(old: &RunReport, new: &RunReport, noise: f64, floor_ms: f64) -> ReportDiff {
    let name = |r: &RunReport| {
        format!(
            "{} ({})",
            r.device["name"].as_str().unwrap_or("?"),
            r.device["driver_version"]["decoded"].as_str().unwrap_or("?")
        )
    };
    let mut d = ReportDiff { old_device: name(old), new_device: name(new), ..Default::default() };
    let olds: BTreeMap<&str, &CellReport> = old.cells.iter().map(|c| (c.id.as_str(), c)).collect();
    let news: BTreeMap<&str, &CellReport> = new.cells.iter().map(|c| (c.id.as_str(), c)).collect();
    for c in &new.cells {
        match olds.get(c.id.as_str()) {
            None => d.cells.push(CellDiff {
                cell: c.id.clone(),
                change: Change::New,
                old: None,
                new: Some(verdict(c)),
            }),
            Some(o) => match change(o, c) {
                Some(ch) => d.cells.push(CellDiff {
                    cell: c.id.clone(),
                    change: ch,
                    old: Some(verdict(o)),
                    new: Some(verdict(c)),
                }),
                None => d.unchanged += 1,
            },
        }
    }
    for c in old.cells.iter().filter(|c| !news.contains_key(c.id.as_str())) {
        d.cells.push(CellDiff {
            cell: c.id.clone(),
            change: Change::Gone,
            old: Some(verdict(c)),
            new: None,
        });
    }
    d.cells.sort_by(|a, b| (a.change, &a.cell).cmp(&(b.change, &b.cell)));
    for p in PHASES {
        if let (Some(a), Some(b)) = (phase_mean(old, p), phase_mean(new, p)) {
            let ratio = if a > 0.0 { b / a } else { f64::INFINITY };
            if (b - a).abs() > floor_ms && (ratio > 1.0 + noise || ratio < 1.0 / (1.0 + noise)) {
                d.timing.push(PhaseDiff { phase: p.to_string(), old_ms: a, new_ms: b, ratio });
            }
        }
    }
    d
}

fn counts(d: &ReportDiff) -> String {
    let mut parts = vec![];
    for ch in [Change::Fixed, Change::Regressed, Change::Changed, Change::New, Change::Gone] {
        let n = d.cells.iter().filter(|c| c.change == ch).count();
        if n > 0 {
            parts.push(format!("{n} {}", ch.as_str()));
        }
    }
    if parts.is_empty() {
        "no outcome changes".into()
    } else {
        parts.join(", ")
    }
}

pub fn render_text(d: &ReportDiff) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "diff: {} → {}", d.old_device, d.new_device);
    let _ = writeln!(s, "cells: {} ({} unchanged)", counts(d), d.unchanged);
    for c in &d.cells {
        let _ = writeln!(
            s,
            "  {:<10} {}  {} → {}",
            c.change.as_str(),
            c.cell,
            c.old.as_deref().unwrap_or("—"),
            c.new.as_deref().unwrap_or("—")
        );
    }
    if d.timing.is_empty() {
        let _ = writeln!(s, "time per cell: no phase changed beyond the noise threshold");
    }
    for t in &d.timing {
        let _ = writeln!(
            s,
            "  time  {:<9} {:.2} → {:.2} ms/cell ({:.2}×)",
            t.phase, t.old_ms, t.new_ms, t.ratio
        );
    }
    s
}

pub fn render_markdown(d: &ReportDiff) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "### rtprobe: {} → {}\n", d.old_device, d.new_device);
    let _ = writeln!(s, "**{}** ({} cells unchanged)\n", counts(d), d.unchanged);
    if !d.cells.is_empty() {
        let _ = writeln!(s, "| change | cell | before | after |\n|---|---|---|---|");
        for c in &d.cells {
            let icon = match c.change {
                Change::Fixed => "✅ fixed",
                Change::Regressed => "❌ regressed",
                Change::Changed => "🔁 changed",
                Change::New => "🆕 new",
                Change::Gone => "➖ gone",
            };
            let _ = writeln!(
                s,
                "| {icon} | `{}` | {} | {} |",
                c.cell,
                c.old.as_deref().unwrap_or("—"),
                c.new.as_deref().unwrap_or("—")
            );
        }
        s += "\n";
    }
    if !d.timing.is_empty() {
        let _ = writeln!(
            s,
            "| phase | before (ms/cell) | after (ms/cell) | ratio |\n|---|---|---|---|"
        );
        for t in &d.timing {
            let _ = writeln!(
                s,
                "| {} | {:.2} | {:.2} | {:.2}× |",
                t.phase, t.old_ms, t.new_ms, t.ratio
            );
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_devices_are_warned_of_and_two_drivers_of_one_are_not() {
        let mut a = RunReport::for_tests(vec![]);
        let mut b = RunReport::for_tests(vec![]);
        b.device["driver_version"] = serde_json::json!({ "decoded": "26.2.6" });
        assert_eq!(device_warning(&a, &b), None);
        a.device["name"] = serde_json::json!("llvmpipe");
        b.device["name"] = serde_json::json!("NVIDIA H100");
        let w = device_warning(&a, &b).unwrap();
        assert!(w.contains("(llvmpipe and NVIDIA H100)"), "{w}");
    }
}
