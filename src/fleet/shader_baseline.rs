//! Baselines for `run --shader`: expectations by `cell id/variant`
//! (`shader:hit.rchit@1a2b3c4d5e6f/unpatched`) in the native JSON format, written from a
//! shader-run report (`rtprobe baseline`) and checked as generated cells are (`baseline`'s
//! rules: the expected fault, a known flake at a rate its record explains, a regression, an
//! unexpected pass, a missing variant).
use super::baseline::{accepts, rate_rose};
use crate::model::baseline::{DEQP_FLAKE_RATE, SCHEMA};
use crate::model::shader_run::{ShaderRunReport, ShaderVariant};
use crate::model::{Baseline, BaselineCheck, CellCheck, Expectation, Outcome, Status};
use std::collections::BTreeMap;

/// A variant's id in a baseline: the cell id, `/`, the variant's name.
pub fn variant_id(r: &ShaderRunReport, v: &ShaderVariant) -> String {
    format!("{}/{}", r.cell, v.name)
}

/// The outcomes of a variant's attempts that are evidence (not `error`).
fn evidence(v: &ShaderVariant) -> Vec<Outcome> {
    v.attempts.iter().map(|a| a.attempt.outcome).filter(|o| *o != Outcome::Error).collect()
}

/// Whether a finding came in some attempts only (a flake).
fn flaky(v: &ShaderVariant) -> bool {
    v.incidence.as_ref().is_some_and(|i| i.faulted < i.attempts)
}

/// The expectations of a finished shader run: every variant with a finding.
pub fn from_report(r: &ShaderRunReport, source: &str) -> Baseline {
    let expected = r
        .variants
        .iter()
        .filter(|v| v.outcome.is_finding())
        .map(|v| {
            let mut also: Vec<Outcome> =
                evidence(v).into_iter().filter(|o| *o != v.outcome && o.is_finding()).collect();
            also.sort();
            also.dedup();
            Expectation {
                cell: variant_id(r, v),
                outcome: v.outcome,
                flake: flaky(v),
                also,
                rate: v
                    .incidence
                    .as_ref()
                    .map(|i| format!("{} of {} attempts", i.faulted, i.attempts)),
                bug: None,
            }
        })
        .collect();
    Baseline {
        schema: SCHEMA.into(),
        device: r.device.clone(),
        driver_version: String::new(),
        source: source.into(),
        expected,
        worker_faults: vec![],
        performance: BTreeMap::new(),
    }
}

/// How one variant compares with its expectation (`None`: not listed).
fn classify(v: &ShaderVariant, e: Option<&Expectation>) -> (Status, Outcome, Option<String>) {
    let actual = v.outcome;
    let Some(e) = e else {
        let status = if actual.is_finding() { Status::Regression } else { Status::Expected };
        return (status, Outcome::Pass, None);
    };
    if e.flake {
        let known = |o: Outcome| o == Outcome::Pass || accepts(e, o);
        let ran = evidence(v);
        if !(ran.iter().all(|&o| known(o)) && known(actual)) {
            let why = "an outcome this flake was never seen with".to_string();
            return (Status::Regression, e.outcome, Some(why));
        }
        let k = ran.iter().filter(|o| o.is_finding()).count() as u32;
        let recorded = e.recorded().ok().flatten().unwrap_or(DEQP_FLAKE_RATE);
        return match rate_rose(recorded, k, ran.len() as u32) {
            Some(why) => (Status::Regression, e.outcome, Some(why)),
            None => (Status::KnownFlake, e.outcome, None),
        };
    }
    let status = if accepts(e, actual) {
        Status::Expected
    } else if actual.is_finding() {
        Status::Regression
    } else {
        Status::Improvement
    };
    (status, e.outcome, None)
}

/// A shader run against a baseline: each variant by its id; an entry of this cell whose
/// variant did not run is missing. Entries of other cells are not this run's (not counted).
pub fn check(r: &ShaderRunReport, b: &Baseline, source: &str) -> BaselineCheck {
    let mut out = BaselineCheck { source: source.into(), ..Default::default() };
    let by_id: BTreeMap<&str, &Expectation> =
        b.expected.iter().map(|e| (e.cell.as_str(), e)).collect();
    let mut ids = Vec::new();
    for v in &r.variants {
        let id = variant_id(r, v);
        let (status, expected, why) = classify(v, by_id.get(id.as_str()).copied());
        match status {
            Status::Expected => out.expected += 1,
            Status::KnownFlake => out.known_flakes += 1,
            Status::Regression | Status::Improvement | Status::Missing => {}
        }
        if status != Status::Expected {
            out.cells.push(CellCheck {
                cell: id.clone(),
                status,
                expected,
                actual: v.outcome,
                why,
            });
        }
        ids.push(id);
    }
    let prefix = format!("{}/", r.cell);
    for e in &b.expected {
        if !e.cell.starts_with(&prefix) {
            out.not_run_cells.push(e.cell.clone());
        } else if !ids.contains(&e.cell) {
            out.cells.push(CellCheck {
                cell: e.cell.clone(),
                status: Status::Missing,
                expected: e.outcome,
                actual: Outcome::NotImplemented,
                why: Some(format!(
                    "expected {}, but this run has no such variant",
                    e.outcome.as_str()
                )),
            });
        }
    }
    out.not_run = out.not_run_cells.len();
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::shader_run::{ShaderAttempt, ShaderVariant};
    use crate::model::Attempt;

    fn variant(name: &str, outcomes: &[Outcome]) -> ShaderVariant {
        let attempts =
            outcomes.iter().map(|o| ShaderAttempt::bare(Attempt::new(*o, true))).collect();
        ShaderVariant::judged(name, None, vec![], attempts, None)
    }

    fn report(variants: Vec<ShaderVariant>) -> ShaderRunReport {
        ShaderRunReport {
            schema: String::new(),
            rtprobe_version: String::new(),
            device: "d".into(),
            cell: "shader:hit.rchit@0123".into(),
            options: serde_json::Value::Null,
            inputs: vec![],
            outcome: Outcome::Pass,
            variants,
            notes: vec![],
            injection: None,
            compare: None,
            index_bounds: None,
            baseline: None,
            profile: None,
            cell_options: Default::default(),
        }
    }

    #[test]
    fn findings_are_expected_by_variant_and_a_pass_is_an_improvement() {
        use Outcome::{Crash, Pass};
        let faulty = report(vec![variant("unpatched", &[Crash, Crash]), variant("p", &[Pass])]);
        let b = from_report(&faulty, "f.json");
        let ids: Vec<&str> = b.expected.iter().map(|e| e.cell.as_str()).collect();
        assert_eq!(ids, ["shader:hit.rchit@0123/unpatched"]);
        let c = check(&faulty, &b, "b");
        assert!(c.ok(false) && c.expected == 2, "{c:?}");
        // Twins: the fault gone is an unexpected pass; a new fault in another variant is a
        // regression; a variant the run lacks is missing.
        let clean = report(vec![variant("unpatched", &[Pass]), variant("p", &[Pass])]);
        let c = check(&clean, &b, "b");
        assert_eq!((c.improvements().count(), c.ok(false), c.ok(true)), (1, false, true));
        let worse = report(vec![variant("unpatched", &[Crash]), variant("p", &[Crash])]);
        assert_eq!(check(&worse, &b, "b").regressions().count(), 1);
        let fewer = report(vec![variant("p", &[Pass])]);
        assert_eq!(check(&fewer, &b, "b").missing().count(), 1);
    }

    #[test]
    fn a_fault_in_some_attempts_is_a_flake_held_to_its_rate() {
        use Outcome::{Crash, Pass};
        let flaky = report(vec![variant("unpatched", &[Crash, Pass, Pass, Pass])]);
        let b = from_report(&flaky, "f.json");
        assert!(b.expected[0].flake, "{b:?}");
        assert_eq!(check(&flaky, &b, "b").known_flakes, 1);
        let always = report(vec![variant("unpatched", &[Crash; 12])]);
        assert_eq!(check(&always, &b, "b").regressions().count(), 1);
    }
}
