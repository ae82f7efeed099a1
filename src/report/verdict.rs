//! A run's one verdict, said last: PASS or FAIL and why — findings, or with a baseline only what
//! it did not expect (regressions, missing cells, unexpected passes, slower phases, worker
//! faults), and canaries, injected faults or `--mutants` mutants the probe must catch (probe
//! defects) that went undetected. `run` and `merge` print it and exit with its code
//! (`cli::exit` maps [`Kind`] to 0, 1 and 11).
use crate::model::{plural, RunReport};

/// What the verdict rests on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// Nothing unexpected.
    Pass,
    /// Findings (with a baseline: what it did not expect), or worker faults outside cells.
    Findings,
    /// No finding, but a canary's or an injected fault, or a mutant the probe must catch, went
    /// undetected: classification unproven.
    Undetected,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Verdict {
    pub kind: Kind,
    /// Why, in a few words.
    pub why: String,
}

impl Verdict {
    /// `verdict: FAIL — 6 findings`.
    pub fn line(&self) -> String {
        let word = if self.kind == Kind::Pass { "PASS" } else { "FAIL" };
        format!("verdict: {word} — {}", self.why)
    }
}

/// The reasons a run with a baseline fails, `None` when it is as the baseline expects.
fn against_baseline(r: &RunReport, allow_improvements: bool) -> Option<Vec<String>> {
    let c = r.baseline.as_ref()?;
    if c.ok(allow_improvements) {
        return None;
    }
    let mut why = Vec::new();
    let regressions = c.regressions().count();
    if regressions > 0 {
        why.push(format!("{} against baseline {}", plural(regressions, "regression"), c.source));
    }
    let missing = c.missing().count();
    if missing > 0 {
        why.push(plural(missing, "missing cell") + " (expected to fault, not run)");
    }
    let passes = c.improvements().count();
    if passes > 0 && !allow_improvements {
        why.push(format!(
            "{passes} UnexpectedPass{} (update the baseline, or --allow-improvements)",
            if passes == 1 { "" } else { "es" }
        ));
    }
    if !c.performance.is_empty() {
        why.push(plural(c.performance.len(), "phase").to_string() + " slower than its bound");
    }
    if !c.worker_faults.is_empty() {
        why.push(plural(c.worker_faults.len(), "unexpected worker fault"));
    }
    Some(why)
}

/// How many of the findings are reads the spec leaves undefined (judged by rtprobe's
/// heuristic, not bisected): ` (12 outside the spec's guarantees: rtprobe's heuristic)`.
fn outside_spec_note(r: &RunReport, findings: usize) -> String {
    let outside = r.findings().filter(|c| c.outside_spec.is_some()).count();
    match outside {
        0 => String::new(),
        n if n == findings => {
            " (all outside the spec's guarantees, judged by rtprobe's heuristic)".to_string()
        }
        n => format!(" ({n} outside the spec's guarantees, judged by rtprobe's heuristic)"),
    }
}

/// The run's verdict (`allow_improvements`: `--allow-improvements`).
pub fn verdict(r: &RunReport, allow_improvements: bool) -> Verdict {
    let findings = r.findings().count();
    let worker_faults = r.workers.iter().filter(|w| w.is_fault()).count();
    let fail = match (&r.baseline, against_baseline(r, allow_improvements)) {
        (Some(_), Some(why)) => Some(why.join(", ")),
        (Some(_), None) => None,
        (None, _) if findings + worker_faults == 0 => None,
        (None, _) => Some(
            [(findings, "finding", ""), (worker_faults, "worker fault", " outside cells")]
                .iter()
                .filter(|(n, _, _)| *n > 0)
                .map(|(n, w, tail)| plural(*n, w) + tail)
                .collect::<Vec<_>>()
                .join(", ")
                + &outside_spec_note(r, findings),
        ),
    };
    if let Some(why) = fail {
        return Verdict { kind: Kind::Findings, why };
    }
    let canaries = r.undetected_canaries().count();
    let injections = r.tally.injections_undetected;
    let defects = r.mutants.as_ref().map_or(0, |m| m.probe_defects().count());
    if canaries + injections + defects > 0 {
        let mut what = Vec::new();
        match canaries {
            0 => {}
            1 => what.push("1 canary not detected".to_string()),
            n => what.push(format!("{n} canaries not detected")),
        }
        if injections > 0 {
            what.push(format!("{} not detected", plural(injections, "injected fault")));
        }
        if defects > 0 {
            what.push(format!("{} among the mutants", plural(defects, "probe defect")));
        }
        return Verdict {
            kind: Kind::Undetected,
            why: format!("{}: fault classification unproven on this driver", what.join(", ")),
        };
    }
    let ran = r.plan.to_run;
    let why = match &r.baseline {
        Some(c) if findings > 0 => format!(
            "{}, all expected by baseline {}{}",
            plural(findings, "finding"),
            c.source,
            if c.known_flakes > 0 {
                format!(" ({})", plural(c.known_flakes, "known flake"))
            } else {
                String::new()
            }
        ),
        Some(c) => format!("{} as baseline {} expects", plural(ran, "cell"), c.source),
        None => format!("{} ran, none faulted or mismatched", plural(ran, "cell")),
    };
    Verdict { kind: Kind::Pass, why }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{
        Attempt, BaselineCheck, Canary, Cell, CellCheck, CellReport, DescriptorModel, IndexSource,
        Outcome, Resource, Stage, Status,
    };

    fn cell(index: IndexSource) -> Cell {
        Cell::new(
            Stage::ClosestHit,
            Resource::StorageBuffer,
            index,
            DescriptorModel::DescriptorIndexing,
        )
    }

    fn ran(c: Cell, o: Outcome) -> CellReport {
        CellReport::new(&c, Attempt::for_tests(o, false))
    }

    #[test]
    fn findings_fail_and_a_clean_run_passes() {
        let r = RunReport::for_tests(vec![
            ran(cell(IndexSource::Literal), Outcome::Crash),
            ran(cell(IndexSource::SpecConstant), Outcome::Pass),
        ]);
        let v = verdict(&r, false);
        assert_eq!(v.kind, Kind::Findings);
        assert_eq!(v.line(), "verdict: FAIL — 1 finding");
        // A finding the spec leaves undefined (a dynamic index without nonuniformEXT) says so.
        let u = RunReport::for_tests(vec![ran(cell(IndexSource::Dynamic), Outcome::Crash)]);
        assert!(u.cells[0].outside_spec.is_some());
        assert_eq!(
            verdict(&u, false).line(),
            "verdict: FAIL — 1 finding (all outside the spec's guarantees, judged by rtprobe's heuristic)"
        );
        let ok = RunReport::for_tests(vec![ran(cell(IndexSource::Literal), Outcome::Pass)]);
        assert_eq!(
            verdict(&ok, false).line(),
            "verdict: PASS — 1 cell ran, none faulted or mismatched"
        );
    }

    #[test]
    fn a_baseline_that_expects_the_findings_passes_and_one_that_does_not_fails() {
        let mut r = RunReport::for_tests(vec![ran(cell(IndexSource::Dynamic), Outcome::Crash)]);
        r.baseline =
            Some(BaselineCheck { source: "b.json".into(), expected: 1, ..Default::default() });
        let v = verdict(&r, false);
        assert_eq!(v.kind, Kind::Pass, "{v:?}");
        assert!(v.why.contains("1 finding, all expected by baseline b.json"), "{v:?}");
        // Its twin: the same finding as a regression.
        r.baseline.as_mut().unwrap().cells.push(CellCheck {
            cell: r.cells[0].id.clone(),
            status: Status::Regression,
            expected: Outcome::Pass,
            actual: Outcome::Crash,
            why: None,
        });
        let v = verdict(&r, false);
        assert_eq!(v.kind, Kind::Findings);
        assert!(v.why.starts_with("1 regression against baseline b.json"), "{v:?}");
        // An unexpected pass fails unless allowed.
        r.baseline.as_mut().unwrap().cells[0].status = Status::Improvement;
        assert!(verdict(&r, false).why.contains("1 UnexpectedPass"));
        assert_eq!(verdict(&r, true).kind, Kind::Pass);
        // A cell expected to fault that did not run fails, allowed improvements or not.
        r.baseline.as_mut().unwrap().cells[0].status = Status::Missing;
        let v = verdict(&r, true);
        assert_eq!(v.kind, Kind::Findings, "{v:?}");
        assert_eq!(v.why, "1 missing cell (expected to fault, not run)");
    }

    #[test]
    fn an_undetected_canary_fails_only_when_nothing_else_does() {
        let r =
            RunReport::for_tests(vec![ran(Cell::canary(Canary::InvalidAddress), Outcome::Pass)]);
        let v = verdict(&r, false);
        assert_eq!(v.kind, Kind::Undetected);
        assert!(v.line().starts_with("verdict: FAIL — 1 canary not detected"), "{v:?}");
        let two = RunReport::for_tests(vec![
            ran(Cell::canary(Canary::InvalidAddress), Outcome::Pass),
            ran(Cell::canary(Canary::InfiniteLoop), Outcome::Pass),
        ]);
        assert!(
            verdict(&two, false).why.starts_with("2 canaries not detected"),
            "{:?}",
            verdict(&two, false)
        );
        let detected =
            RunReport::for_tests(vec![ran(Cell::canary(Canary::InvalidAddress), Outcome::Crash)]);
        assert_eq!(verdict(&detected, false).kind, Kind::Pass);
    }
}
