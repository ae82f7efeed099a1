//! Each verdict of the kill matrix from an attempt, with its twin: a fault is never a kill, a
//! survivor the reference says must be caught is a probe defect, one the cell's lenient rule
//! allows names the rule.
use super::*;
use crate::model::{
    CellResult, Comparison, DescriptorModel, ElementReads, IndexSource, Resource, Stage, Timings,
};

fn cell() -> Cell {
    Cell::new(
        Stage::ClosestHit,
        Resource::StorageBuffer,
        IndexSource::Dynamic,
        DescriptorModel::DescriptorIndexing,
    )
}

/// An attempt with `outcome` whose comparison carries `prediction` (and, when `lenient`, the
/// own/other/neither reads of an undefined read).
fn attempt(outcome: Outcome, prediction: Option<MutantPrediction>, lenient: bool) -> Attempt {
    let comparison = Comparison {
        mutant: prediction,
        element_reads: lenient.then(|| ElementReads {
            outside_spec: "VUID-X".into(),
            other: 3,
            ..Default::default()
        }),
        ..Default::default()
    };
    let result = CellResult {
        outcome,
        detail: Some(format!("{} detail", outcome.as_str())),
        timings: Timings::default(),
        comparison: Some(comparison),
        fault: None,
        validation_errors: 0,
    };
    Attempt::new(outcome, false).with_result(result).with_wall_ms(2.0)
}

const P: MutantPrediction =
    MutantPrediction { differing: 12, caught: 12, from_lanes: false, caught_by_heuristic: 0 };

#[test]
fn a_mismatch_is_a_kill_and_a_fault_is_not() {
    let k =
        verdict((&cell(), Mutant::IndexNext), P, Some(&attempt(Outcome::Mismatch, Some(P), false)));
    assert_eq!(
        (k.status, k.probe_defect, k.outcome),
        (MutantStatus::Killed, false, Some(Outcome::Mismatch))
    );
    assert_eq!(k.cell, cell().id());
    for o in [Outcome::Crash, Outcome::DeviceLost, Outcome::Timeout] {
        let f = verdict((&cell(), Mutant::IndexNext), P, Some(&attempt(o, None, false)));
        assert_eq!(f.status, MutantStatus::Fault, "{o:?}");
        assert!(!f.status.applicable() || f.status != MutantStatus::Killed);
    }
    let e = verdict((&cell(), Mutant::IndexNext), P, Some(&attempt(Outcome::Error, None, false)));
    assert_eq!(e.status, MutantStatus::NotRun);
    assert_eq!(verdict((&cell(), Mutant::IndexNext), P, None).status, MutantStatus::NotRun);
}

#[test]
fn a_survivor_is_a_probe_defect_unless_the_rule_allows_every_differing_pixel() {
    let s = verdict((&cell(), Mutant::ValueBits), P, Some(&attempt(Outcome::Pass, Some(P), false)));
    assert_eq!(
        (s.status, s.probe_defect, s.allowed_by.as_deref()),
        (MutantStatus::Survived, true, None)
    );
    assert!(s.why.starts_with("PROBE DEFECT"), "{}", s.why);
    // The twin: the reference says the lenient rule allows all 12 differing pixels.
    let lenient = MutantPrediction { caught: 0, ..P };
    let a = verdict(
        (&cell(), Mutant::IndexNext),
        P,
        Some(&attempt(Outcome::Pass, Some(lenient), true)),
    );
    assert_eq!(
        (a.status, a.probe_defect, a.allowed_by.as_deref()),
        (MutantStatus::Survived, false, Some("VUID-X"))
    );
    // After the run the device's lane evidence can show a broadcast equivalent.
    let none =
        MutantPrediction { differing: 0, caught: 0, from_lanes: true, caught_by_heuristic: 0 };
    let q = verdict(
        (&cell(), Mutant::IndexBroadcast),
        P,
        Some(&attempt(Outcome::Pass, Some(none), false)),
    );
    assert_eq!(q.status, MutantStatus::Equivalent);
}

#[test]
fn samples_parse_and_bad_ones_are_refused() {
    assert_eq!(Sample::parse("40:7"), Ok(Sample { n: 40, seed: 7 }));
    assert_eq!(Sample::parse("3"), Ok(Sample { n: 3, seed: 1 }));
    for bad in ["", "0", "x:1", "4:y", "-1"] {
        assert!(Sample::parse(bad).is_err(), "{bad}");
    }
}

#[test]
fn the_summary_names_probe_defects_loudly() {
    let mut r = MutantReport { mutants: vec![Mutant::ValueBits], ..Default::default() };
    annotate_into(
        &mut r,
        verdict((&cell(), Mutant::ValueBits), P, Some(&attempt(Outcome::Pass, Some(P), false))),
    );
    let text = render(&r);
    assert!(text.contains("PROBE DEFECT") && text.contains("1 probe defects"), "{text}");
    let mut ok = MutantReport { mutants: vec![Mutant::ValueBits], ..Default::default() };
    annotate_into(
        &mut ok,
        verdict((&cell(), Mutant::ValueBits), P, Some(&attempt(Outcome::Mismatch, Some(P), false))),
    );
    assert!(!render(&ok).contains("PROBE DEFECT"));
}

fn annotate_into(r: &mut MutantReport, e: MutantEntry) {
    r.entries.push(e);
    r.recount();
}

/// A survivor whose must-catch pixels were all judged by the other-lane heuristic (an undefined
/// read, so the mutated read is undefined too: the driver may read any lane's index) is allowed,
/// with the rule; one with a single pixel judged exactly is a probe defect. (lavapipe 25's
/// compute UBO / image cells without nonuniformEXT × index-next: 512 of 4096 pixels per-lane
/// reads would flag, the driver read the leader's index + 1, which the subgroup computed.)
#[test]
fn a_survivor_caught_only_by_the_heuristic_is_allowed_and_one_exact_pixel_is_a_defect() {
    let heuristic = MutantPrediction {
        differing: 4096,
        caught: 512,
        caught_by_heuristic: 512,
        from_lanes: false,
    };
    let a = verdict(
        (&cell(), Mutant::IndexNext),
        heuristic,
        Some(&attempt(Outcome::Pass, Some(heuristic), true)),
    );
    assert_eq!(
        (a.status, a.probe_defect, a.allowed_by.as_deref()),
        (MutantStatus::Survived, false, Some("VUID-X"))
    );
    assert!(a.why.contains("512 of 4096") && a.why.contains("mutated read too"), "{}", a.why);
    let one_exact = MutantPrediction { caught_by_heuristic: 511, ..heuristic };
    let d = verdict(
        (&cell(), Mutant::IndexNext),
        one_exact,
        Some(&attempt(Outcome::Pass, Some(one_exact), true)),
    );
    assert_eq!((d.status, d.probe_defect), (MutantStatus::Survived, true));
    assert!(d.why.starts_with("PROBE DEFECT: the reference predicts 1 of 4096"), "{}", d.why);
}
