//! Expectations (baselines), as Mesa's CI keeps `<driver>-fails.txt` / `-flakes.txt` and
//! deqp-runner reads `--baseline`: the non-pass outcomes a device is known to have, per cell id,
//! optional flake entries with their bug link and failure rate, and optional performance bounds
//! per phase. A run compared against it fails only on what is *unexpected*: a regression (worse
//! than expected, or another fault), a missing cell (expected to fault, and it did not run), or
//! an improvement (better than expected, so the baseline gets updated).
//!
//! Rules that keep a regression from hiding (issue 22):
//! - an outcome is matched exactly (`error` is not `mismatch`), but for crash and device loss;
//! - a flake tolerates its outcomes only at a rate its recorded one explains: it fails when
//!   `P(X ≥ k | n, p) < 1%`, p the recorded rate's 95% upper Clopper–Pearson bound, or when
//!   Fisher's exact test finds the run's k of n above the recorded rate at 1% (the bound alone
//!   cannot: 6 of 6 against 1 of 8 is P = 1.09% there, 0.23% by Fisher's test); without a
//!   recorded rate (a deqp `Flake` line) the rate is deqp-runner's own, one fault in two;
//! - an expected fault whose cell is unsupported or not implemented here, or that neither this
//!   run nor another shard of it plans, is `Missing`; only entries another shard runs or the
//!   run's `--filter` excludes are "not run here".
//!
//! Two file forms:
//! - native JSON (`"schema": "rtprobe.baseline/1"`) with a header (device, driver, where it came
//!   from), `expected` entries and `performance` bounds;
//! - deqp-runner's `test,Status` lines (`deqp`). Read by content; written with `--format deqp`.
use crate::model::baseline::{DEQP_FLAKE_RATE, SCHEMA};
use crate::model::stats::{binomial_tail, cp_upper, fisher_greater, CONFIDENCE};
use crate::model::Outcome;
use crate::model::{
    Baseline, BaselineCheck, CellCheck, Expectation, PerfBound, Status, WorkerFault,
};
use crate::model::{Cell, CellReport, Filter, RunReport};
use std::collections::{BTreeMap, HashSet};

/// A flake fails when its run is this unlikely at the recorded rate.
pub const FLAKE_MAX_P: f64 = 0.01;

/// The phases a baseline can bound (means per timed cell, from the report's timing summary).
pub const PHASES: &[&str] = &["compile", "pipeline", "setup", "trace", "check"];

pub fn phase_mean(r: &RunReport, phase: &str) -> Option<f64> {
    let t = &r.timing;
    let sum = match phase {
        "compile" => t.compile_ms,
        "pipeline" => t.pipeline_ms,
        "setup" => t.setup_ms,
        "trace" => t.trace_ms,
        "check" => t.check_ms,
        _ => return None,
    };
    (t.cells_timed > 0).then(|| sum / t.cells_timed as f64)
}

/// The report's worker faults a baseline holds it to: every one but those a cell's own verdict
/// explains (a worker that died while an overlapped cell ran, where that cell, re-run alone, is
/// itself a crash, device loss or timeout: the fault is that cell's, and the cell is held to its
/// own expectation; `WorkerEvent::explained_by`). Whether a cell overlapped depends on timing,
/// so without this a run would differ from its baseline by scheduling alone.
fn worker_faults(r: &RunReport) -> Vec<(WorkerFault, String)> {
    let verdicts: std::collections::HashMap<&str, Outcome> =
        r.cells.iter().map(|c| (c.id.as_str(), c.outcome)).collect();
    r.workers
        .iter()
        .filter(|w| w.is_fault() && !w.explained_by(|id| verdicts.get(id).copied()))
        .map(|w| {
            (
                WorkerFault { phase: w.phase.to_string(), outcome: w.outcome },
                format!(
                    "worker {} {} in {}: {}",
                    w.worker,
                    w.outcome.as_str(),
                    w.phase,
                    w.detail.as_deref().unwrap_or("")
                ),
            )
        })
        .collect()
}

#[derive(Debug, thiserror::Error)]
pub enum BaselineError {
    #[error("{file}: line {line}: {message}")]
    Line { file: String, line: usize, message: String },
    #[error("{file}: {message}")]
    File { file: String, message: String },
    /// `--perf PHASE` names no phase of [`PHASES`], or the report timed no cell in it.
    #[error("--perf {phase}: not a phase ({}) or the report timed no cell", PHASES.join(", "))]
    NoPhaseMean { phase: String },
}

impl Baseline {
    /// The expectations of a finished run: every finding (flaky ones as flakes with their rate),
    /// with performance bounds for `perf` phases (`factor`× the run's mean plus `slack_ms`).
    pub fn from_report(
        r: &RunReport,
        source: &str,
        perf: &[String],
        factor: f64,
        slack_ms: f64,
    ) -> Result<Baseline, BaselineError> {
        let mut expected = Vec::new();
        let probe = |c: &&CellReport| c.cell.canary.is_none() && !c.is_retry(r.options.patches);
        for c in r.cells.iter().filter(probe).filter(|c| c.outcome.is_finding()) {
            let mut also: Vec<Outcome> =
                c.attempts.iter().map(|a| a.outcome).filter(|o| *o != c.outcome).collect();
            also.sort();
            also.dedup();
            expected.push(Expectation {
                cell: c.id.clone(),
                outcome: c.outcome,
                flake: c.flaky,
                also,
                rate: c
                    .incidence
                    .as_ref()
                    .map(|i| format!("{} of {} attempts", i.faulted, i.attempts)),
                bug: None,
            });
        }
        let mut performance = BTreeMap::new();
        for p in perf {
            let mean =
                phase_mean(r, p).ok_or_else(|| BaselineError::NoPhaseMean { phase: p.clone() })?;
            performance.insert(p.clone(), PerfBound { mean_ms: mean, factor, slack_ms });
        }
        let mut worker_faults: Vec<WorkerFault> =
            worker_faults(r).into_iter().map(|(f, _)| f).collect();
        worker_faults.sort();
        worker_faults.dedup();
        Ok(Baseline {
            schema: SCHEMA.into(),
            device: r.device["name"].as_str().unwrap_or("?").into(),
            driver_version: r.device["driver_version"]["decoded"].as_str().unwrap_or("?").into(),
            source: source.into(),
            expected,
            worker_faults,
            performance,
        })
    }

    pub fn parse(file: &str, text: &str) -> Result<Baseline, BaselineError> {
        if text.trim_start().starts_with('{') {
            let b: Baseline = serde_json::from_str(text).map_err(|e| BaselineError::File {
                file: file.into(),
                message: format!("not an rtprobe baseline: {e}"),
            })?;
            if b.schema != SCHEMA {
                return Err(BaselineError::File {
                    file: file.into(),
                    message: format!("schema {:?}, expected {SCHEMA:?}", b.schema),
                });
            }
            for e in &b.expected {
                e.recorded()
                    .map_err(|message| BaselineError::File { file: file.into(), message })?;
            }
            return Ok(b);
        }
        super::deqp::parse(file, text).map_err(|e| BaselineError::Line {
            file: file.into(),
            line: e.line,
            message: e.message,
        })
    }

    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("baseline serializes") + "\n"
    }

    /// deqp-runner form (`deqp::write`).
    pub fn to_deqp(&self) -> String {
        super::deqp::write(self)
    }
}

/// Crash and device loss are one fault (a GPU fault may end the worker either way); every other
/// outcome is its own.
fn same_fault(a: Outcome, b: Outcome) -> bool {
    a == b
        || matches!(
            (a, b),
            (Outcome::Crash, Outcome::DeviceLost) | (Outcome::DeviceLost, Outcome::Crash)
        )
}

pub fn accepts(e: &Expectation, o: Outcome) -> bool {
    std::iter::once(e.outcome).chain(e.also.iter().copied()).any(|k| same_fault(k, o))
}

/// How a cell compared: its status, the outcome expected, and why where that needs saying.
type Classified = (Status, Outcome, Option<String>);

fn classify(c: &CellReport, e: Option<&Expectation>) -> Classified {
    let actual = c.outcome;
    let Some(e) = e else {
        let status = if actual.is_finding() { Status::Regression } else { Status::Expected };
        return (status, Outcome::Pass, None);
    };
    if matches!(actual, Outcome::Unsupported | Outcome::NotImplemented) || c.attempts.is_empty() {
        let why =
            format!("expected {}, but the cell is {} here", e.outcome.as_str(), actual.as_str());
        return (Status::Missing, e.outcome, Some(why));
    }
    if e.flake {
        return flake(c, e);
    }
    // Passing where a fault was expected is better; another fault is not (deqp-runner fails on
    // any unexpected status too).
    let status = if accepts(e, actual) {
        Status::Expected
    } else if actual.is_finding() {
        Status::Regression
    } else {
        Status::Improvement
    };
    (status, e.outcome, None)
}

/// A known flake: a pass and the outcomes it was seen with, in any mix, at a rate its recorded
/// one explains.
fn flake(c: &CellReport, e: &Expectation) -> Classified {
    let known = |o: Outcome| o == Outcome::Pass || accepts(e, o);
    let ran: Vec<Outcome> = c.attempts.iter().filter(|a| !a.not_run()).map(|a| a.outcome).collect();
    if !(ran.iter().all(|&o| known(o)) && known(c.outcome)) {
        let why = "an outcome this flake was never seen with".to_string();
        return (Status::Regression, e.outcome, Some(why));
    }
    let k = ran.iter().filter(|o| o.is_finding()).count() as u32;
    let recorded = e.recorded().ok().flatten().unwrap_or(DEQP_FLAKE_RATE);
    match rate_rose(recorded, k, ran.len() as u32) {
        Some(why) => (Status::Regression, e.outcome, Some(why)),
        None => (Status::KnownFlake, e.outcome, None),
    }
}

/// Why `k` faults in `n` attempts are more than a flake recorded at `k0` of `n0` explains, or
/// `None`: `P(X ≥ k | n, p) < FLAKE_MAX_P` at p = the recorded rate's 95% upper Clopper–Pearson
/// bound, or Fisher's exact test of the run against the record below `FLAKE_MAX_P`.
pub fn rate_rose((k0, n0): (u32, u32), k: u32, n: u32) -> Option<String> {
    let bound = cp_upper(k0, n0, 1.0 - CONFIDENCE);
    let at_bound = binomial_tail(k, n, bound);
    let fisher = fisher_greater(k, n, k0, n0);
    (at_bound < FLAKE_MAX_P || fisher < FLAKE_MAX_P).then(|| {
        format!(
            "its fault rate rose: {k} of {n} attempts against {k0} of {n0} recorded (P = {at_bound:.4} at the recorded rate's 95% bound {bound:.3}, Fisher's exact P = {fisher:.4}; below {FLAKE_MAX_P} fails)"
        )
    })
}

/// Where the cells a run did not plan went: the ids other shards of it run (its plan before
/// `--shard`, less its own) or its `--skips` left out, and its `--filter`s.
#[derive(Clone, Debug, Default)]
pub struct Scope {
    pub elsewhere: HashSet<String>,
    pub filters: Vec<Filter>,
}

impl Scope {
    /// Whether another shard runs `id`, `--skips` left it out or the filters exclude it (a
    /// baseline may cover more than one run asks for); `false` for a cell this run should have
    /// planned.
    fn elsewhere(&self, id: &str) -> bool {
        self.elsewhere.contains(id)
            || (!self.filters.is_empty()
                && Cell::parse_id(id).is_ok_and(|c| !self.filters.iter().all(|f| f.matches(&c))))
    }
}

/// Compare a run with a baseline: per planned probe cell (canaries and retries — a round's
/// workaround variants and patterns, whose errors are rtprobe's — aside) and per phase; entries
/// for cells the run did not plan are checked against `scope`.
pub fn check(r: &RunReport, b: &Baseline, source: &str, scope: &Scope) -> BaselineCheck {
    let mut out = BaselineCheck { source: source.into(), ..Default::default() };
    let by_id: BTreeMap<&str, &Expectation> =
        b.expected.iter().map(|e| (e.cell.as_str(), e)).collect();
    let probe = |c: &&CellReport| c.cell.canary.is_none() && !c.is_retry(r.options.patches);
    for c in r.cells.iter().filter(probe) {
        let e = by_id.get(c.id.as_str()).copied();
        if e.is_none() && !c.outcome.is_finding() && c.outcome != Outcome::Pass {
            continue; // unsupported or not implemented, and expected to be: nothing to say
        }
        let (status, expected, why) = classify(c, e);
        match status {
            Status::Expected => out.expected += 1,
            Status::KnownFlake => out.known_flakes += 1,
            Status::Regression | Status::Improvement | Status::Missing => {}
        }
        if status != Status::Expected {
            out.cells.push(CellCheck {
                cell: c.id.clone(),
                status,
                expected,
                actual: c.outcome,
                why,
            });
        }
    }
    let planned: HashSet<&str> = r.cells.iter().map(|c| c.id.as_str()).collect();
    for e in b.expected.iter().filter(|e| !planned.contains(e.cell.as_str())) {
        if scope.elsewhere(&e.cell) {
            out.not_run_cells.push(e.cell.clone());
        } else {
            out.cells.push(CellCheck {
                cell: e.cell.clone(),
                status: Status::Missing,
                expected: e.outcome,
                actual: Outcome::NotImplemented,
                why: Some(format!(
                    "expected {}, but neither this run nor another shard of it plans the cell",
                    e.outcome.as_str()
                )),
            });
        }
    }
    out.not_run = out.not_run_cells.len();
    worker_and_phase_checks(r, b, &mut out);
    out
}

/// Worker faults outside cells and phase times against the baseline.
fn worker_and_phase_checks(r: &RunReport, b: &Baseline, out: &mut BaselineCheck) {
    for (fault, text) in worker_faults(r) {
        if b.worker_faults.contains(&fault) {
            out.expected_worker_faults += 1;
        } else {
            out.worker_faults.push(text);
        }
    }
    for (phase, bound) in &b.performance {
        if let Some(mean) = phase_mean(r, phase) {
            if mean > bound.limit() {
                out.performance.push(format!(
                    "{phase}: {mean:.2} ms/cell > {:.2} ms/cell ({}× the baseline's {:.2} + {:.1} ms)",
                    bound.limit(),
                    bound.factor,
                    bound.mean_ms,
                    bound.slack_ms
                ));
            }
        }
    }
}

/// Lines for the terminal summary.
pub fn render(c: &BaselineCheck, allow_improvements: bool) -> String {
    let mut s = format!(
        "baseline {}: {} as expected, {}, {}, {} missing, {}{}\n",
        c.source,
        c.expected,
        crate::model::plural(c.known_flakes, "known flake"),
        crate::model::plural(c.regressions().count(), "regression"),
        c.missing().count(),
        match c.improvements().count() {
            1 => "1 unexpected pass".to_string(),
            n => format!("{n} unexpected passes"),
        },
        if c.not_run > 0 {
            format!(", {} entries left to other shards or outside --filter", c.not_run)
        } else {
            String::new()
        }
    );
    for x in &c.cells {
        // deqp-runner's word for a pass where a fault was expected: UnexpectedPass.
        let (what, then) = match x.status {
            Status::Regression => ("REGRESSION", ""),
            Status::Improvement if allow_improvements => ("UnexpectedPass", " (allowed)"),
            Status::Improvement => {
                ("UnexpectedPass", " (update the baseline, or --allow-improvements)")
            }
            Status::KnownFlake => ("known flake", ""),
            Status::Expected => ("expected", ""),
            Status::Missing => ("MISSING", ""),
        };
        let why = x.why.as_deref().map(|w| format!(": {w}")).unwrap_or_default();
        s += &match x.status {
            Status::Missing => format!("  {what}: {}{why}\n", x.cell),
            _ => format!(
                "  {what}: {} expected {} got {}{why}{then}\n",
                x.cell,
                x.expected.as_str(),
                x.actual.as_str()
            ),
        };
    }
    for p in &c.performance {
        s += &format!("  PERFORMANCE REGRESSION: {p}\n");
    }
    for w in &c.worker_faults {
        s += &format!("  UNEXPECTED WORKER FAULT: {w}\n");
    }
    if c.expected_worker_faults > 0 {
        s += &format!(
            "  {} worker faults outside cells, as the baseline expects\n",
            c.expected_worker_faults
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::RunReport;

    #[test]
    fn deqp_form_round_trips_and_bad_lines_name_the_line() {
        let text = "# device: llvmpipe\n# driver: 25.0.7\na.b.c,Crash\nd.e.f,Fail\n\ng.h.i,Timeout\nj.k.l,Flake\n";
        let b = Baseline::parse("x.csv", text).unwrap();
        assert_eq!(b.device, "llvmpipe");
        assert_eq!(b.expected.len(), 4);
        assert!(b.expected[3].flake);
        let again = Baseline::parse("y.csv", &b.to_deqp()).unwrap();
        assert_eq!(again.expected, b.expected);
        assert_eq!(again.to_deqp(), b.to_deqp());
        let e = Baseline::parse("z.csv", "a.b,Crash\nnonsense\n").unwrap_err().to_string();
        assert!(e.contains("z.csv: line 2"), "{e}");
        let e = Baseline::parse("z.csv", "a.b,Exploded\n").unwrap_err().to_string();
        assert!(e.contains("unknown status"), "{e}");
        // The JSON form round-trips too.
        let j = Baseline::parse("b.json", &b.to_json()).unwrap();
        assert_eq!(j, Baseline { source: "x.csv".into(), ..b });
    }

    fn cell(index: crate::model::IndexSource) -> crate::model::Cell {
        use crate::model::{DescriptorModel, Resource, Stage};
        crate::model::Cell::new(
            Stage::ClosestHit,
            Resource::StorageBuffer,
            index,
            DescriptorModel::DescriptorIndexing,
        )
    }

    fn cell_with(index: crate::model::IndexSource, outcomes: &[Outcome]) -> CellReport {
        use crate::model::Attempt;
        let mut c = CellReport::new(&cell(index), Attempt::for_tests(outcomes[0], false));
        for o in &outcomes[1..] {
            c.attempts.push(Attempt::for_tests(*o, true));
        }
        c.refresh();
        c
    }

    #[test]
    fn a_baseline_made_from_a_run_expects_that_run_in_both_forms() {
        use crate::model::IndexSource as I;
        // A flaky device loss, a steady crash, a mismatch: the run's own baseline, written as
        // JSON or as deqp-runner lines and read back, finds nothing unexpected in it.
        let r = RunReport::for_tests(vec![
            cell_with(I::Dynamic, &[Outcome::DeviceLost, Outcome::Pass]),
            cell_with(I::Literal, &[Outcome::Crash, Outcome::Crash]),
            cell_with(I::SpecConstant, &[Outcome::Mismatch]),
            cell_with(I::PushConstant, &[Outcome::Pass]),
        ]);
        let b = Baseline::from_report(&r, "r.json", &[], 2.0, 1.0).unwrap();
        for text in [b.to_json(), b.to_deqp()] {
            let back = Baseline::parse("b", &text).unwrap();
            let c = check(&r, &back, "b", &Scope::default());
            assert!(c.ok(false), "{text}\n{c:?}");
            assert_eq!(c.known_flakes, 1);
        }
        // A flake tolerates what it was seen with, not a mismatch it never showed.
        let wrong =
            RunReport::for_tests(vec![cell_with(I::Dynamic, &[Outcome::Mismatch, Outcome::Pass])]);
        let c = check(&wrong, &b, "b", &Scope::default());
        assert_eq!(c.regressions().count(), 1, "{c:?}");
        // A steady expected fault that now passes is an improvement; another fault a regression.
        let fixed = RunReport::for_tests(vec![
            cell_with(I::Literal, &[Outcome::Pass]),
            cell_with(I::SpecConstant, &[Outcome::Timeout]),
        ]);
        let c = check(&fixed, &b, "b", &Scope::default());
        assert_eq!((c.improvements().count(), c.regressions().count()), (1, 1), "{c:?}");
    }

    /// A worker that died while an overlapped cell ran is that cell's fault when the cell,
    /// re-run alone, crashed too: a baseline of the crash expects the run whether the cell
    /// overlapped or not. Its twins: the cell passed alone (a fault that did not repeat), or the
    /// entry names no cell — both stay unexpected worker faults.
    #[test]
    fn an_overlapped_cells_own_fault_explains_the_prebuild_death() {
        use crate::model::{IndexSource as I, Phase, WorkerEvent};
        let crash = cell_with(I::Literal, &[Outcome::Crash, Outcome::Crash]);
        let b =
            Baseline::from_report(&RunReport::for_tests(vec![crash.clone()]), "r", &[], 2.0, 1.0)
                .unwrap();
        let death = |cell: Option<&str>| WorkerEvent {
            worker: 1,
            phase: Phase::Prebuild,
            outcome: Outcome::Crash,
            detail: Some("worker killed by signal 11 (SIGSEGV) in prebuild".into()),
            cells: 2,
            wall_ms: 1.0,
            device_features: vec![],
            worker_exit: None,
            halt: None,
            overlapped_cell: cell.map(String::from),
            fault: None,
        };
        let unexpected = |cells: Vec<CellReport>, w: WorkerEvent| {
            let mut r = RunReport::for_tests(cells);
            r.workers.push(w);
            check(&r, &b, "b", &Scope::default()).worker_faults.len()
        };
        assert_eq!(unexpected(vec![crash.clone()], death(Some(&crash.id))), 0);
        let passed = cell_with(I::Literal, &[Outcome::Pass]);
        assert_eq!(unexpected(vec![passed], death(Some(&crash.id))), 1);
        assert_eq!(unexpected(vec![crash.clone()], death(None)), 1);
    }

    fn expect(cell: &CellReport, outcome: Outcome, flake: bool, rate: Option<&str>) -> Baseline {
        let e = Expectation {
            cell: cell.id.clone(),
            outcome,
            flake,
            also: if flake { vec![Outcome::Pass] } else { vec![] },
            rate: rate.map(String::from),
            bug: None,
        };
        let mut b = Baseline::parse("b.csv", "").unwrap();
        b.expected.push(e);
        b
    }

    fn status_of(r: &RunReport, b: &Baseline, scope: &Scope) -> Vec<Status> {
        check(r, b, "b", scope).cells.iter().map(|c| c.status).collect()
    }

    /// T1 of issue 22: an expected `error` that became a mismatch is another fault.
    #[test]
    fn an_expected_error_does_not_absorb_a_mismatch() {
        use crate::model::IndexSource as I;
        let c = cell_with(I::Literal, &[Outcome::Mismatch]);
        let r = RunReport::for_tests(vec![c.clone()]);
        let b = expect(&c, Outcome::Error, false, None);
        assert_eq!(status_of(&r, &b, &Scope::default()), [Status::Regression]);
        assert!(!check(&r, &b, "b", &Scope::default()).ok(true));
        // Crash and device loss stay one fault; the same outcome is expected.
        let lost = RunReport::for_tests(vec![cell_with(I::Literal, &[Outcome::DeviceLost])]);
        assert!(check(&lost, &expect(&c, Outcome::Crash, false, None), "b", &Scope::default())
            .ok(false));
        assert!(check(&r, &expect(&c, Outcome::Mismatch, false, None), "b", &Scope::default())
            .ok(false));
    }

    /// T2 of issue 22: a flake recorded at 1 of 8 that crashed 6 of 6 times.
    #[test]
    fn a_flake_whose_rate_rose_is_a_regression() {
        use crate::model::IndexSource as I;
        let c = cell_with(I::Literal, &[Outcome::Crash; 6]);
        let r = RunReport::for_tests(vec![c.clone()]);
        let b = expect(&c, Outcome::Crash, true, Some("1 of 8 attempts"));
        let checked = check(&r, &b, "b", &Scope::default());
        assert_eq!(checked.cells[0].status, Status::Regression, "{checked:?}");
        let why = checked.cells[0].why.as_deref().unwrap();
        assert!(why.contains("6 of 6 attempts against 1 of 8"), "{why}");
        // At about the recorded rate it stays a known flake: 1, 2 or 3 of 6.
        for faults in [1usize, 2, 3] {
            let mut outcomes = vec![Outcome::Pass; 6];
            outcomes[..faults].fill(Outcome::Crash);
            let r = RunReport::for_tests(vec![cell_with(I::Literal, &outcomes)]);
            assert!(check(&r, &b, "b", &Scope::default()).ok(false), "{faults} of 6");
        }
        // A flake recorded at 3 of 3 explains any rate.
        let b = expect(&c, Outcome::Crash, true, Some("3 of 3 attempts"));
        assert!(check(&r, &b, "b", &Scope::default()).ok(false));
        // Without a rate (a deqp `Flake` line): deqp-runner's one fault in two, whose bound
        // 0.975 explains 4 of 4 (T3) and anything up to 179 of 179, not 180 of 180.
        let b = Baseline::parse("f.csv", &format!("{},Flake\n", c.id)).unwrap();
        let four = RunReport::for_tests(vec![cell_with(I::Literal, &[Outcome::Mismatch; 4])]);
        assert_eq!(check(&four, &b, "b", &Scope::default()).known_flakes, 1);
        let all =
            |n: usize| RunReport::for_tests(vec![cell_with(I::Literal, &vec![Outcome::Crash; n])]);
        assert!(check(&all(179), &b, "b", &Scope::default()).ok(false));
        assert!(!check(&all(180), &b, "b", &Scope::default()).ok(false));
    }

    #[test]
    fn the_flake_rule_meets_its_figures() {
        assert!(rate_rose((1, 8), 6, 6).is_some(), "Fisher: 7/3003");
        assert!(rate_rose((1, 8), 7, 7).is_some(), "P = 0.0051 at the bound");
        assert!(rate_rose((1, 8), 1, 6).is_none());
        assert!(rate_rose((1, 2), 4, 4).is_none());
        let bound = cp_upper(1, 8, 0.05);
        assert!(binomial_tail(6, 6, bound) > FLAKE_MAX_P, "the bound alone passes 6 of 6");
    }

    /// T4 of issue 22: an expected crash whose cell is now unsupported, or not planned.
    #[test]
    fn an_expected_fault_that_did_not_run_is_missing_unless_another_shard_runs_it() {
        use crate::model::IndexSource as I;
        let mut c = cell_with(I::Literal, &[Outcome::Pass]);
        c.attempts.clear();
        c.outcome = Outcome::Unsupported;
        let r = RunReport::for_tests(vec![c.clone()]);
        let b = expect(&c, Outcome::Crash, false, None);
        assert_eq!(status_of(&r, &b, &Scope::default()), [Status::Missing]);
        assert!(!check(&r, &b, "b", &Scope::default()).ok(true));
        // Not in this run's report: missing, unless another shard runs it or --filter
        // excludes it.
        let other = RunReport::for_tests(vec![cell_with(I::Dynamic, &[Outcome::Pass])]);
        assert_eq!(status_of(&other, &b, &Scope::default()), [Status::Missing]);
        let shards = Scope { elsewhere: [c.id.clone()].into(), filters: vec![] };
        let checked = check(&other, &b, "b", &shards);
        assert!(checked.ok(false) && checked.not_run == 1, "{checked:?}");
        let filtered =
            Scope { filters: vec![Filter::parse("index=dynamic").unwrap()], ..Scope::default() };
        assert!(check(&other, &b, "b", &filtered).ok(false));
        let kept =
            Scope { filters: vec![Filter::parse("index=literal").unwrap()], ..Scope::default() };
        assert_eq!(status_of(&other, &b, &kept), [Status::Missing]);
        assert!(render(&check(&r, &b, "b", &Scope::default()), false).contains("MISSING: "));
    }

    #[test]
    fn perf_bound_limit() {
        let p = PerfBound { mean_ms: 2.0, factor: 2.0, slack_ms: 1.0 };
        assert_eq!(p.limit(), 5.0);
    }
}
