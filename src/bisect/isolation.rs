//! The isolation list in plain words: a cell as a sentence (`closest_hit reading storage_buffer
//! with dynamic index (nonuniformEXT), descriptor_indexing`) and a verdict with its evidence
//! (`❌ crash (6 of 6, p ≥ 0.61 at 95%)`, `✅ passes (5 of 5; miss ≤ 0.94% for p ≥ 0.61)`).
use super::Verdicts;
use crate::model::Cell;
use crate::model::IsolationLine;

/// One cell as a sentence a driver engineer can read without knowing rtprobe's ids.
pub fn describe(c: &Cell) -> String {
    crate::model::registry::describe(c)
}

impl IsolationLine {
    pub fn faults(&self) -> bool {
        self.verdict != "pass" && self.verdict != "not_run"
    }

    /// A pass whose miss probability is below the threshold.
    pub fn settled(&self) -> bool {
        self.settled == Some(true)
    }
}

/// What a line's verdict is held to: the rate bound of the faulting cell a pass is compared
/// with (None: no faulting cell), and the threshold.
#[derive(Clone, Copy, Debug)]
pub struct Evidence {
    pub against: Option<f64>,
    pub max_miss: f64,
}

/// The line for `cell` from what `verdicts` know: a finding with its k of N and rate bound, a
/// pass with its miss probability against `ev.against`.
pub fn line(cell: &Cell, varied: Option<&str>, verdicts: &Verdicts, ev: Evidence) -> IsolationLine {
    let description = describe(cell);
    let report = verdicts.get(cell).filter(|r| !r.attempts.is_empty());
    let reason = report
        .filter(|r| r.outcome == crate::model::outcome::Outcome::Error)
        .and_then(|r| r.reason.clone());
    let (k, n) = verdicts.counts(cell);
    let mut l = IsolationLine {
        cell: cell.id(),
        varied: varied.map(String::from),
        description,
        verdict: "not_run".into(),
        agreeing: 0,
        attempts: n,
        rate_bound: None,
        miss_probability: None,
        settled: None,
        suspect: None,
        reason,
        injected: None,
        line: String::new(),
    };
    // A pass's faulting sibling that its lenient reads may hide (`suspect`).
    let mut sus = None;
    if let Some(r) = report {
        l.verdict = r.outcome.as_str().to_string();
        l.injected = r.injected.clone();
        if r.outcome.is_finding() {
            l.agreeing = k;
            l.rate_bound = Some(crate::model::stats::rate_bound(k, n));
        } else {
            l.agreeing = n - k;
            if r.outcome == crate::model::outcome::Outcome::Pass {
                l.rate_bound = ev.against;
                l.miss_probability =
                    Some(ev.against.map_or(1.0, |p| crate::model::stats::miss(p, n)));
                l.settled = l.miss_probability.map(|m| m < ev.max_miss);
                sus = verdicts.suspect(cell);
                l.suspect = sus.map(|(sib, _)| sib.id());
            }
        }
    }
    let conf = format!("{:.0}%", 100.0 * crate::model::stats::CONFIDENCE);
    let evidence = match (l.verdict.as_str(), l.miss_probability, l.rate_bound) {
        ("not_run", _, _) => "❔ not run".to_string(),
        ("pass", Some(m), Some(p)) => {
            let weak = if l.settled() { "" } else { "; too little evidence, not concluded on" };
            format!("✅ passes ({} of {n}; miss ≤ {} for p ≥ {p:.2}{weak})", l.agreeing, percent(m))
        }
        ("pass", _, _) => {
            format!("✅ passes ({} of {n}; no faulting cell to hold it to)", l.agreeing)
        }
        ("error", _, _) => error_evidence(report, l.reason.as_deref()),
        (v, _, Some(p)) => format!("❌ {v} ({k} of {n}, p ≥ {p:.2} at {conf})"),
        (v, _, None) => format!("❌ {v} ({k} of {n})"),
    };
    l.line = format!("{}: {evidence}", l.description);
    if let Some((sib, other)) = sus {
        l.line += &format!(" — suspect, not used: {} read what another lane's index gives (accepted without nonuniformEXT by rtprobe's heuristic; the spec leaves it undefined), while {} faults", crate::model::plural(other, "pixel"), describe(&sib));
    }
    if verdicts.state(cell) == super::State::Doubtful(super::Doubt::UndefinedFault) {
        l.line += &format!(
            " — not used: the spec leaves this read undefined ({})",
            crate::model::NO_NONUNIFORM_VUID
        );
    }
    l
}

/// An error's words: no evidence (`Verdicts::counts` leaves it out), so the attempts made and
/// how many said error, with the reason.
fn error_evidence(report: Option<&crate::model::CellReport>, reason: Option<&str>) -> String {
    let made = report.map_or(0, |r| r.attempts.iter().filter(|a| !a.not_run()).count());
    let errors = report.map_or(0, |r| {
        r.attempts.iter().filter(|a| a.outcome == crate::model::outcome::Outcome::Error).count()
    });
    format!(
        "⚠ error ({errors} of {}; rtprobe could not run it, no evidence either way): {}",
        crate::model::plural(made, "attempt"),
        reason.unwrap_or("no detail")
    )
}

/// A probability as a short percentage (`0.78%`, `< 0.01%`).
pub fn percent(p: f64) -> String {
    if p > 0.0 && p < 1e-4 {
        "< 0.01%".into()
    } else {
        format!("{:.2}%", 100.0 * p)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{DescriptorModel, IndexSource, Resource, Stage};

    #[test]
    fn cells_read_as_sentences() {
        let c = Cell::new(
            Stage::ClosestHit,
            Resource::StorageBuffer,
            IndexSource::SpecConstant,
            DescriptorModel::DescriptorIndexing,
        );
        assert_eq!(
            describe(&c),
            "closest_hit reading storage_buffer with spec_constant index, descriptor_indexing"
        );
        let d = Cell {
            index: IndexSource::Dynamic,
            nonuniform: true,
            patch: Some(crate::model::cell::Workaround::SsboToAddress),
            ..c
        };
        assert_eq!(describe(&d), "closest_hit reading storage_buffer with dynamic index (nonuniformEXT), descriptor_indexing, patched with ssbo-to-address");
        assert_eq!(percent(0.0078125), "0.78%");
        assert_eq!(percent(1e-9), "< 0.01%");
    }

    #[test]
    fn an_error_line_counts_the_attempts_made_not_the_evidence() {
        use crate::model::{Attempt, Outcome};
        let c = Cell::new(
            Stage::ClosestHit,
            Resource::StorageBuffer,
            IndexSource::Dynamic,
            DescriptorModel::DescriptorIndexing,
        );
        let mut v = Verdicts::default();
        v.record(&c, Attempt::for_tests(Outcome::Error, false));
        let ev = Evidence { against: Some(0.5), max_miss: 0.01 };
        let l = line(&c, None, &v, ev);
        // No evidence (0 of 0 counted), but one attempt made, and it said error.
        assert_eq!(v.counts(&c), (0, 0));
        assert!(l.line.contains("⚠ error (1 of 1 attempt; rtprobe could not run it"), "{}", l.line);
        assert!(l.line.ends_with(": error happened"), "{}", l.line);
        v.record(&c, Attempt::for_tests(Outcome::Error, true));
        assert!(line(&c, None, &v, ev).line.contains("error (2 of 2 attempts;"));
    }
}
