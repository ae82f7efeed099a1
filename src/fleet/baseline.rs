//! Expectations (baselines), as Mesa's CI keeps `<driver>-fails.txt` / `-flakes.txt` and
//! deqp-runner reads `--baseline`: the non-pass outcomes a device is known to have, per cell id,
//! optional flake entries with their bug link and failure rate, and optional performance bounds
//! per phase. A run compared against it fails only on what is *unexpected*: a regression (worse
//! than expected) or an improvement (better than expected, so the baseline gets updated).
//!
//! Two file forms:
//! - native JSON (`"schema": "rtprobe.baseline/1"`) with a header (device, driver, where it came
//!   from), `expected` entries and `performance` bounds;
//! - deqp-runner's `test,Status` lines (`#` comments), statuses `Fail` (mismatch or error),
//!   `Crash` (crash or device loss), `Timeout`, `Flake`. Read by extension `.csv`/`.txt` or
//!   content; written with `--format deqp`.
use crate::model::baseline::SCHEMA;
use crate::model::Outcome;
use crate::model::{
    Baseline, BaselineCheck, CellCheck, Expectation, PerfBound, Status, WorkerFault,
};
use crate::model::{CellReport, RunReport};
use std::collections::BTreeMap;

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

fn worker_faults(r: &RunReport) -> Vec<(WorkerFault, String)> {
    r.workers
        .iter()
        .filter(|w| w.is_fault())
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

/// deqp-runner's status of a fault (`None`: no fault).
pub fn deqp_status(o: Outcome) -> Option<&'static str> {
    match o {
        Outcome::Pass | Outcome::Unsupported | Outcome::NotImplemented => None,
        Outcome::Mismatch | Outcome::Error => Some("Fail"),
        Outcome::Crash | Outcome::DeviceLost => Some("Crash"),
        Outcome::Timeout => Some("Timeout"),
    }
}

/// The outcomes a deqp-runner status stands for (the first is what the verdict is recorded as).
fn from_deqp(status: &str) -> Option<(Outcome, bool)> {
    Some(match status {
        "Fail" | "ExpectedFail" => (Outcome::Mismatch, false),
        "Crash" => (Outcome::Crash, false),
        "Timeout" => (Outcome::Timeout, false),
        "Flake" | "KnownFlake" => (Outcome::Crash, true),
        _ => return None,
    })
}

/// A deqp-runner `Flake` line says only that the test is unreliable: any failure is tolerated.
pub const DEQP_FLAKE_ALSO: &[Outcome] = &[Outcome::Mismatch, Outcome::Timeout, Outcome::DeviceLost];

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
            return Ok(b);
        }
        Self::parse_deqp(file, text)
    }

    /// deqp-runner's `test,Status` lines; `# device: …` / `# driver: …` comments fill the header.
    fn parse_deqp(file: &str, text: &str) -> Result<Baseline, BaselineError> {
        let mut b = Baseline {
            schema: SCHEMA.into(),
            device: String::new(),
            driver_version: String::new(),
            source: file.into(),
            expected: vec![],
            worker_faults: vec![],
            performance: BTreeMap::new(),
        };
        for (n, raw) in text.lines().enumerate() {
            let line = raw.trim();
            if let Some(c) = line.strip_prefix('#') {
                let c = c.trim();
                if let Some(v) = c.strip_prefix("device:") {
                    b.device = v.trim().into();
                } else if let Some(v) = c.strip_prefix("driver:") {
                    b.driver_version = v.trim().into();
                }
                continue;
            }
            if line.is_empty() {
                continue;
            }
            let err =
                |message: String| BaselineError::Line { file: file.into(), line: n + 1, message };
            let (cell, status) = line
                .split_once(',')
                .ok_or_else(|| err(format!("{line:?} is not `cell,Status`")))?;
            let (outcome, flake) = from_deqp(status.trim()).ok_or_else(|| {
                err(format!("unknown status {:?} (Fail, Crash, Timeout, Flake)", status.trim()))
            })?;
            let also = if flake { DEQP_FLAKE_ALSO.to_vec() } else { vec![] };
            b.expected.push(Expectation {
                cell: cell.trim().into(),
                outcome,
                flake,
                also,
                rate: None,
                bug: None,
            });
        }
        Ok(b)
    }

    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("baseline serializes") + "\n"
    }

    /// deqp-runner form (performance bounds and flake details do not fit it and are dropped).
    pub fn to_deqp(&self) -> String {
        let mut s = format!(
            "# rtprobe baseline (deqp-runner form)\n# device: {}\n# driver: {}\n",
            self.device, self.driver_version
        );
        for e in &self.expected {
            let status = if e.flake { "Flake" } else { deqp_status(e.outcome).unwrap_or("Fail") };
            s += &format!("{},{status}\n", e.cell);
        }
        s
    }

    fn get(&self, id: &str) -> Option<&Expectation> {
        self.expected.iter().find(|e| e.cell == id)
    }
}

fn classify(c: &CellReport, e: Option<&Expectation>) -> (Status, Outcome) {
    let actual = c.outcome;
    match e {
        None => {
            (if actual.is_finding() { Status::Regression } else { Status::Expected }, Outcome::Pass)
        }
        Some(e) if e.flake => {
            // A flake tolerates, in any mix, a pass and the outcomes it was seen with (by deqp
            // class: crash and device loss are one fault); any other outcome is a regression.
            let class = |o: Outcome| deqp_status(o).unwrap_or("Pass");
            let known = |o: Outcome| {
                o == Outcome::Pass
                    || std::iter::once(e.outcome)
                        .chain(e.also.iter().copied())
                        .any(|k| class(k) == class(o))
            };
            let all_known = c.attempts.iter().filter(|a| !a.not_run()).all(|a| known(a.outcome))
                && known(actual);
            (if all_known { Status::KnownFlake } else { Status::Regression }, e.outcome)
        }
        Some(e) => {
            // Outcomes of one deqp class (crash / device loss; mismatch / error) are the same fault.
            let same = actual == e.outcome
                || (actual.is_finding() && deqp_status(actual) == deqp_status(e.outcome));
            // Passing where a fault was expected is better; another fault is not (deqp-runner
            // fails on any unexpected status too).
            let status = if same {
                Status::Expected
            } else if actual.is_finding() {
                Status::Regression
            } else {
                Status::Improvement
            };
            (status, e.outcome)
        }
    }
}

/// Compare a run with a baseline: per planned probe cell (canaries, retries — a round's
/// workaround variants and patterns, whose errors are rtprobe's — and unsupported cells aside)
/// and per phase.
pub fn check(r: &RunReport, b: &Baseline, source: &str) -> BaselineCheck {
    let mut out = BaselineCheck { source: source.into(), ..Default::default() };
    let probe = |c: &&CellReport| {
        c.cell.canary.is_none()
            && !c.is_retry(r.options.patches)
            && c.outcome != Outcome::Unsupported
    };
    for c in r.cells.iter().filter(probe) {
        let e = b.get(&c.id);
        let (status, expected) = classify(c, e);
        match status {
            Status::Expected => out.expected += 1,
            Status::KnownFlake => out.known_flakes += 1,
            Status::Regression | Status::Improvement => {}
        }
        if status != Status::Expected {
            out.cells.push(CellCheck { cell: c.id.clone(), status, expected, actual: c.outcome });
        }
    }
    out.not_run_cells = b
        .expected
        .iter()
        .filter(|e| !r.cells.iter().any(|c| c.id == e.cell && !c.attempts.is_empty()))
        .map(|e| e.cell.clone())
        .collect();
    out.not_run = out.not_run_cells.len();
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
    out
}

/// Lines for the terminal summary.
pub fn render(c: &BaselineCheck, allow_improvements: bool) -> String {
    let mut s = format!(
        "baseline {}: {} as expected, {}, {}, {}{}\n",
        c.source,
        c.expected,
        crate::model::plural(c.known_flakes, "known flake"),
        crate::model::plural(c.regressions().count(), "regression"),
        match c.improvements().count() {
            1 => "1 unexpected pass".to_string(),
            n => format!("{n} unexpected passes"),
        },
        if c.not_run > 0 { format!(", {} entries not run here", c.not_run) } else { String::new() }
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
        };
        s += &format!(
            "  {what}: {} expected {} got {}{then}\n",
            x.cell,
            x.expected.as_str(),
            x.actual.as_str()
        );
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
            let c = check(&r, &back, "b");
            assert!(c.ok(false), "{text}\n{c:?}");
            assert_eq!(c.known_flakes, 1);
        }
        // A flake tolerates what it was seen with, not a mismatch it never showed.
        let wrong =
            RunReport::for_tests(vec![cell_with(I::Dynamic, &[Outcome::Mismatch, Outcome::Pass])]);
        let c = check(&wrong, &b, "b");
        assert_eq!(c.regressions().count(), 1, "{c:?}");
        // A steady expected fault that now passes is an improvement; another fault a regression.
        let fixed = RunReport::for_tests(vec![
            cell_with(I::Literal, &[Outcome::Pass]),
            cell_with(I::SpecConstant, &[Outcome::Timeout]),
        ]);
        let c = check(&fixed, &b, "b");
        assert_eq!((c.improvements().count(), c.regressions().count()), (1, 1), "{c:?}");
    }

    #[test]
    fn perf_bound_limit() {
        let p = PerfBound { mean_ms: 2.0, factor: 2.0, slack_ms: 1.0 };
        assert_eq!(p.limit(), 5.0);
    }
}
