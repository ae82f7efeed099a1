//! Bisection against a simulated device: ground-truth predicates (deterministic or flaky), every
//! run counted.
use super::*;
use crate::matrix::plan::all_cells;
use crate::outcome::Outcome;

/// Faults on the cells of any of `truth`, each attempt with probability `p` (a seeded LCG).
struct Sim {
    truth: Vec<Filter>,
    p: f64,
    rng: u64,
    runs: usize,
}

impl Sim {
    fn new(truth: &[&str], p: f64) -> Self {
        Sim { truth: truth.iter().map(|t| Filter::parse(t).unwrap()).collect(), p, rng: 0x1234_5678, runs: 0 }
    }
    fn roll(&mut self) -> f64 {
        self.rng = self.rng.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (self.rng >> 11) as f64 / (1u64 << 53) as f64
    }
}

impl Oracle for Sim {
    fn run(&mut self, cells: &[Cell], isolated: bool, verdicts: &mut Verdicts) {
        for c in cells {
            self.runs += 1;
            let fault = self.truth.iter().any(|t| t.matches(c)) && self.roll() < self.p;
            let outcome = if fault { Outcome::Crash } else { Outcome::Pass };
            verdicts.record(c, attempt(outcome, isolated));
        }
    }
    fn can_run(&self) -> bool {
        true
    }
}

fn attempt(outcome: Outcome, isolated: bool) -> Attempt {
    Attempt { outcome, isolated, detail: None, result: None, worker_exit: None, injected: None, wall_ms: 0.0, phase: None, worker: 0, device_features: vec![] }
}

fn scope(filter: &str) -> Vec<Cell> {
    let f = Filter::parse(filter).unwrap();
    all_cells().0.into_iter().filter(|c| f.matches(c)).collect()
}

/// A "report": every cell of `ran` run once by `sim`.
fn report(sim: &mut Sim, ran: &[Cell]) -> Verdicts {
    let mut v = Verdicts::default();
    sim.run(ran, false, &mut v);
    v.runs = 0;
    v
}

fn bisect(truth: &[&str], p: f64, scope_filter: &str, ran_filter: &str) -> (Bisection, usize) {
    let mut sim = Sim::new(truth, p);
    let sc = scope(scope_filter);
    let ran = scope(ran_filter);
    let v = report(&mut sim, &ran);
    let before = sim.runs;
    let mut b = Bisector::new(sc, v, &mut sim, Settings::default(), vec![]);
    let r = b.bisect(None, &|_| true).unwrap();
    (r, sim.runs - before)
}

const SCOPE: &str = "descriptor_model=descriptor_indexing,resource=storage_buffer|uniform_buffer|acceleration_structure";

#[test]
fn single_axis_two_axis_and_value_sets_are_recovered_exactly() {
    for truth in ["index=dynamic", "stage=closest_hit,index=dynamic", "stage=raygen|miss,resource=uniform_buffer", "resource=storage_buffer|uniform_buffer,index=push_constant|dynamic"] {
        let (r, runs) = bisect(&[truth], 1.0, SCOPE, SCOPE);
        assert!(r.separable, "{truth}");
        assert_eq!(r.minimal, truth);
        assert!(render(&r, 816).ends_with(&format!("minimal: {truth}\n")));
        // Deterministic faults: only the runs that estimate the fault rate, and the workarounds.
        assert!(runs <= MIN_RATE_ATTEMPTS as usize + r.workarounds.len(), "{truth}: {runs} runs");
        assert!(r.unsettled.is_empty());
        assert_eq!(r.isolation[0].cell, r.representative);
        assert!(r.isolation[0].faults());
        assert!(r.isolation.iter().skip(1).any(|l| !l.faults()), "{truth}: a passing sibling");
    }
}

#[test]
fn a_redundant_predicate_comes_back_as_an_equivalent_set() {
    // as_access=address|address_patched already implies resource=acceleration_structure.
    let truth = "resource=acceleration_structure,as_access=address|address_patched";
    let (r, _) = bisect(&[truth], 1.0, SCOPE, SCOPE);
    let (t, m) = (Filter::parse(truth).unwrap(), Filter::parse(&r.minimal).unwrap());
    let sc = scope(SCOPE);
    assert!(sc.iter().all(|c| t.matches(c) == m.matches(c)), "{} is not equivalent to {truth}", r.minimal);
    assert!(m.terms.len() <= 2);
}

#[test]
fn a_fault_no_conjunction_separates_gives_a_disjunction() {
    let truth = ["stage=raygen,index=literal", "stage=closest_hit,index=dynamic"];
    let (r, _) = bisect(&truth, 1.0, SCOPE, SCOPE);
    assert!(!r.separable);
    assert_eq!(r.conjunctions, truth);
    assert_eq!(r.minimal, truth.join(";"));
    assert!(render(&r, 816).contains("NO single conjunction"));
}

#[test]
fn a_flaky_fault_is_recovered_with_repeats_below_the_threshold() {
    let scope_f = "descriptor_model=descriptor_indexing,resource=storage_buffer,stage=raygen|closest_hit|miss";
    let (r, runs) = bisect(&["stage=raygen|miss,index=dynamic"], 0.5, scope_f, scope_f);
    assert_eq!(r.minimal, "stage=raygen|miss,index=dynamic");
    assert!(r.unsettled.is_empty());
    assert!(r.worst_miss_probability < DEFAULT_MAX_MISS, "{}", r.worst_miss_probability);
    let p = r.fault_rate.unwrap();
    assert!(p > 0.2 && p < 0.8, "rate {p}");
    assert!(r.attempts_per_pass >= 4, "{}", r.attempts_per_pass);
    assert!(runs > 20, "passes were repeated: {runs}");
    let pass = r.isolation.iter().find(|l| l.verdict == "pass").unwrap();
    assert!(pass.line.contains("miss probability"), "{}", pass.line);
}

#[test]
fn cells_outside_the_report_are_run_only_where_needed() {
    // The report ran closest_hit only; the fault is on every stage's dynamic index.
    let (r, runs) = bisect(&["index=dynamic"], 1.0, "descriptor_model=descriptor_indexing", "descriptor_model=descriptor_indexing,stage=closest_hit");
    assert_eq!(r.minimal, "index=dynamic");
    assert!(runs < r.scope_cells / 2, "{runs} runs for {} cells", r.scope_cells);
    assert!(r.not_run > 0);
}

#[test]
fn offline_never_widens_over_cells_nobody_ran() {
    let mut sim = Sim::new(&["index=dynamic"], 1.0);
    let v = report(&mut sim, &scope("descriptor_model=descriptor_indexing,stage=closest_hit"));
    let mut off = Offline;
    let mut b = Bisector::new(scope("descriptor_model=descriptor_indexing"), v, &mut off, Settings::default(), vec![]);
    let r = b.bisect(None, &|_| true).unwrap();
    assert_eq!(r.minimal, "stage=closest_hit,index=dynamic");
    assert_eq!(r.runs, 0);
    // No repeats offline: the fault rate rests on nothing.
    assert!(r.fault_rate.is_none() && !r.unsettled.is_empty());
}

#[test]
fn no_fault_and_a_wrong_cell_are_errors() {
    let mut sim = Sim::new(&["stage=raygen"], 1.0);
    let sc = scope("descriptor_model=descriptor_indexing,stage=closest_hit");
    let v = report(&mut sim, &sc);
    let mut b = Bisector::new(sc.clone(), v.clone(), &mut sim, Settings::default(), vec![]);
    assert!(matches!(b.bisect(None, &|_| true), Err(BisectError::NoFault)));
    let mut sim = Sim::new(&["index=dynamic"], 1.0);
    let mut b = Bisector::new(sc.clone(), report(&mut sim, &sc), &mut sim, Settings::default(), vec![]);
    assert!(matches!(b.bisect(Some("closest_hit.storage_buffer.literal.descriptor_indexing"), &|_| true), Err(BisectError::NotFaulting(_))));
}

#[test]
fn workarounds_say_when_the_injection_decides_them() {
    let sc = scope("descriptor_model=descriptor_indexing,stage=closest_hit,resource=storage_buffer");
    let inj = vec![Injection::parse("stage=closest_hit,index=dynamic,patch=none").unwrap()];
    let mut sim = Sim::new(&["stage=closest_hit,index=dynamic,patch=none"], 1.0);
    let v = report(&mut sim, &sc);
    let mut b = Bisector::new(sc, v, &mut sim, Settings::default(), inj);
    let r = b.bisect(None, &|_| true).unwrap();
    assert!(!r.workarounds.is_empty());
    for w in &r.workarounds {
        assert_eq!(w.verdict, "pass");
        assert!(w.line.contains("not a workaround"), "{}", w.line);
    }
}

#[test]
fn with_every_patched_variant_in_scope_a_patch_none_predicate_comes_back() {
    // A `--patches all` report: the patch axis is sampled, and `patch=none` is a real term.
    let sc: Vec<Cell> = scope("descriptor_model=descriptor_indexing,resource=storage_buffer,stage=raygen|closest_hit")
        .into_iter()
        .flat_map(|c| std::iter::once(c).chain(c.applicable_patches().into_iter().map(move |p| Cell { patch: Some(p), ..c })))
        .collect();
    let truth = "stage=closest_hit,index=dynamic,patch=none";
    let mut sim = Sim::new(&[truth], 1.0);
    let v = report(&mut sim, &sc);
    let mut b = Bisector::new(sc, v, &mut sim, Settings::default(), vec![]);
    let r = b.bisect(None, &|_| true).unwrap();
    assert_eq!(r.minimal, truth);
    assert!(!r.not_varied.contains(&"patch".to_string()));
}

#[test]
fn cells_rtprobe_could_not_run_count_neither_way() {
    // An `error` inside the fault's region neither blocks the conjunction nor joins it.
    struct WithError(Sim, String);
    impl Oracle for WithError {
        fn run(&mut self, cells: &[Cell], isolated: bool, verdicts: &mut Verdicts) {
            for c in cells {
                if c.id() == self.1 {
                    verdicts.record(c, Attempt { detail: Some("could not".into()), ..attempt(Outcome::Error, isolated) });
                } else {
                    self.0.run(std::slice::from_ref(c), isolated, verdicts);
                }
            }
        }
        fn can_run(&self) -> bool {
            true
        }
    }
    let sc = scope("descriptor_model=descriptor_indexing,resource=storage_buffer,stage=raygen|closest_hit");
    let mut o = WithError(Sim::new(&["index=dynamic"], 1.0), "raygen.storage_buffer.dynamic.descriptor_indexing".into());
    let mut v = Verdicts::default();
    o.run(&sc, false, &mut v);
    let dynamic = sc.iter().filter(|c| c.index == crate::matrix::IndexSource::Dynamic).count();
    let mut b = Bisector::new(sc, v, &mut o, Settings::default(), vec![]);
    let r = b.bisect(None, &|_| true).unwrap();
    assert_eq!(r.minimal, "index=dynamic");
    assert_eq!(r.errored, vec!["raygen.storage_buffer.dynamic.descriptor_indexing".to_string()]);
    assert_eq!(r.faulting_cells, dynamic - 1);
}

#[test]
fn an_oracle_that_adds_nothing_ends_the_bisection() {
    // Runs that come back with no attempt (a supervisor that could not run them) must not loop.
    struct Deaf;
    impl Oracle for Deaf {
        fn run(&mut self, _: &[Cell], _: bool, _: &mut Verdicts) {}
        fn can_run(&self) -> bool {
            true
        }
    }
    let sc = scope("descriptor_model=descriptor_indexing,resource=storage_buffer,stage=raygen|closest_hit");
    let mut sim = Sim::new(&["index=dynamic"], 1.0);
    let v = report(&mut sim, &sc[..6]);
    let mut deaf = Deaf;
    let r = Bisector::new(sc, v, &mut deaf, Settings::default(), vec![]).bisect(None, &|_| true).unwrap();
    assert!(!r.unsettled.is_empty() || r.fault_rate.is_none());
}
