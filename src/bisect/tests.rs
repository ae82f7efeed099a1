//! Bisection against a simulated device: ground-truth predicates (deterministic or flaky), every
//! run counted.
use super::*;
use crate::matrix::plan::all_cells;
use crate::model::Attempt;
use crate::model::Outcome;

/// Faults on the cells of any of `truth`, each attempt with probability `p` (a seeded LCG).
struct Sim {
    truth: Vec<Filter>,
    p: f64,
    rng: u64,
    runs: usize,
}

impl Sim {
    fn new(truth: &[&str], p: f64) -> Self {
        Sim {
            truth: truth.iter().map(|t| Filter::parse(t).unwrap()).collect(),
            p,
            rng: 0x1234_5678,
            runs: 0,
        }
    }
    fn roll(&mut self) -> f64 {
        self.rng = self.rng.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (self.rng >> 11) as f64 / (1u64 << 53) as f64
    }
}

impl Oracle for Sim {
    fn run(&mut self, cells: &[Cell], mode: Mode, on: &mut dyn FnMut(Event)) {
        for c in cells {
            self.runs += 1;
            let fault = self.truth.iter().any(|t| t.matches(c)) && self.roll() < self.p;
            let outcome = if fault { Outcome::Crash } else { Outcome::Pass };
            on(Event::Attempt { cell: *c, attempt: attempt(outcome, mode != Mode::Shared) });
        }
    }
    fn can_run(&self) -> bool {
        true
    }
}

/// `sim`, except that cell `late` passes until its attempt `from` and faults from then on (a rare
/// fault that only repeats find).
struct Late {
    sim: Sim,
    late: String,
    from: u32,
    seen: u32,
}

impl Oracle for Late {
    fn run(&mut self, cells: &[Cell], mode: Mode, on: &mut dyn FnMut(Event)) {
        for c in cells {
            if c.id() == self.late {
                self.seen += 1;
                on(Event::Attempt {
                    cell: *c,
                    attempt: attempt(
                        if self.seen >= self.from { Outcome::Crash } else { Outcome::Pass },
                        mode != Mode::Shared,
                    ),
                });
            } else {
                self.sim.run(std::slice::from_ref(c), mode, on);
            }
        }
    }
    fn can_run(&self) -> bool {
        true
    }
}

fn attempt(outcome: Outcome, isolated: bool) -> Attempt {
    Attempt::new(outcome, isolated)
}

/// The planned probe cells `filter` selects. The scene-layout cells (`scene_layout`, a fetch of
/// the hit triangle, not a probe resource read) are left out: these scopes were written for the
/// probe reads, and a layout sibling that passes would rightly add `scene_layout=none` to their
/// minimal descriptions.
fn scope(filter: &str) -> Vec<Cell> {
    let f = Filter::parse(&format!("{filter},scene_layout=none")).unwrap();
    all_cells().0.into_iter().filter(|c| f.matches(c)).collect()
}

/// A "report": every cell of `ran` run once by `sim`.
fn report(sim: &mut Sim, ran: &[Cell]) -> Verdicts {
    let mut v = Verdicts::default();
    sim.run(ran, Mode::Shared, &mut |ev| v.on_event(ev));
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

/// The attempts a fault that never misses gets: the first N with N >= the attempts a pass held to
/// `alpha^(1/N)` needs.
fn deterministic_fault_attempts(max_miss: f64) -> u32 {
    (1..)
        .find(|&n| {
            n >= crate::model::stats::attempts_needed(
                crate::model::stats::rate_bound(n, n),
                max_miss,
                DEFAULT_MAX_ATTEMPTS,
            )
        })
        .unwrap()
}

const SCOPE: &str = "descriptor_model=descriptor_indexing,resource=storage_buffer|uniform_buffer|acceleration_structure";

#[test]
fn single_axis_two_axis_and_value_sets_are_recovered_exactly() {
    for truth in [
        "index=dynamic",
        "stage=closest_hit,index=dynamic",
        "stage=raygen|miss,resource=uniform_buffer",
        "resource=storage_buffer|uniform_buffer,index=push_constant|dynamic",
    ] {
        let (r, runs) = bisect(&[truth], 1.0, SCOPE, SCOPE);
        assert!(r.separable, "{truth}");
        assert_eq!(r.minimal, truth);
        assert!(render(&r, 816).ends_with(&format!("minimal: {truth}\n")));
        // Deterministic faults: the minimal failing cell is repeated until it has as many attempts
        // as a pass held to its bound then needs; every pass relied on gets exactly that many.
        let n0 = deterministic_fault_attempts(DEFAULT_MAX_MISS);
        let need = crate::model::stats::attempts_needed(
            crate::model::stats::rate_bound(n0, n0),
            DEFAULT_MAX_MISS,
            DEFAULT_MAX_ATTEMPTS,
        );
        assert_eq!(r.attempts_per_pass, need);
        assert_eq!((r.isolation[0].agreeing, r.isolation[0].attempts), (n0, n0), "{truth}");
        assert!(
            r.isolation[0].line.contains(&format!(
                "({n0} of {n0}, p ≥ {:.2} at 95%)",
                crate::model::stats::rate_bound(n0, n0)
            )),
            "{}",
            r.isolation[0].line
        );
        assert!(
            runs <= (n0 as usize - 1) + r.passes_relied_on * need as usize,
            "{truth}: {runs} runs"
        );
        assert!(r.concluded() && r.unsettled.is_empty());
        assert!(r.worst_miss_probability < DEFAULT_MAX_MISS);
        assert_eq!(r.isolation[0].cell, r.representative);
        assert!(r.isolation[0].faults());
        assert!(r.isolation.iter().skip(1).any(|l| !l.faults()), "{truth}: a passing sibling");
        for l in r.isolation.iter().filter(|l| l.verdict == "pass") {
            assert_eq!(l.attempts, need, "{}", l.line);
            let m = crate::model::stats::miss(crate::model::stats::rate_bound(n0, n0), need);
            assert!(l.line.contains(&format!("miss ≤ {}", isolation::percent(m))), "{}", l.line);
        }
    }
}

#[test]
fn a_redundant_predicate_comes_back_as_an_equivalent_set() {
    // as_access=address|address_patched already implies resource=acceleration_structure.
    let truth = "resource=acceleration_structure,as_access=address|address_patched";
    let (r, _) = bisect(&[truth], 1.0, SCOPE, SCOPE);
    let (t, m) = (Filter::parse(truth).unwrap(), Filter::parse(&r.minimal).unwrap());
    let sc = scope(SCOPE);
    assert!(
        sc.iter().all(|c| t.matches(c) == m.matches(c)),
        "{} is not equivalent to {truth}",
        r.minimal
    );
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
    assert!(r.concluded(), "{:?}", r.unsettled);
    assert!(r.worst_miss_probability < DEFAULT_MAX_MISS, "{}", r.worst_miss_probability);
    // The bound is the minimal failing cell's own k of N, below the true rate 0.5 (at 95%).
    let rep = &r.isolation[0];
    let p = r.fault_rate_bound.unwrap();
    assert_eq!(p, crate::model::stats::rate_bound(rep.agreeing, rep.attempts));
    assert!(rep.agreeing < rep.attempts, "a rate-0.5 fault missed some attempts: {}", rep.line);
    assert!(p < 0.5, "bound {p}");
    // It was repeated until it had the attempts a pass then needs, and every pass those.
    assert!(rep.attempts >= r.attempts_per_pass, "{}", rep.line);
    assert_eq!(
        r.attempts_per_pass,
        crate::model::stats::attempts_needed(p, DEFAULT_MAX_MISS, DEFAULT_MAX_ATTEMPTS)
    );
    for l in r.isolation.iter().filter(|l| l.verdict == "pass") {
        assert!(l.attempts >= r.attempts_per_pass && l.settled(), "{}", l.line);
        assert!(
            l.line.contains("miss ≤ ") && l.line.contains(&format!("for p ≥ {p:.2}")),
            "{}",
            l.line
        );
    }
    assert!(runs > 20, "passes were repeated: {runs}");
}

#[test]
fn cells_outside_the_report_are_run_only_where_needed() {
    // The report ran closest_hit only; the fault is on every stage's dynamic index.
    let (r, runs) = bisect(
        &["index=dynamic"],
        1.0,
        "descriptor_model=descriptor_indexing",
        "descriptor_model=descriptor_indexing,stage=closest_hit",
    );
    assert_eq!(r.minimal, "index=dynamic");
    assert!(runs < r.scope_cells / 2, "{runs} runs for {} cells", r.scope_cells);
    assert!(r.not_run > 0);
}

#[test]
fn offline_never_widens_over_cells_nobody_ran() {
    let mut sim = Sim::new(&["index=dynamic"], 1.0);
    let v = report(&mut sim, &scope("descriptor_model=descriptor_indexing,stage=closest_hit"));
    let mut off = Offline;
    let mut b = Bisector::new(
        scope("descriptor_model=descriptor_indexing"),
        v,
        &mut off,
        Settings::default(),
        vec![],
    );
    let r = b.bisect(None, &|_| true).unwrap();
    assert_eq!(r.minimal, "stage=closest_hit,index=dynamic");
    assert_eq!(r.runs, 0);
    // No repeats offline: one fault of one attempt bounds the rate only by alpha, and the passes
    // relied on (one attempt each) are not concluded on.
    assert_eq!(r.fault_rate_bound, Some(1.0 - crate::model::stats::CONFIDENCE));
    assert!(!r.concluded() && !r.unsettled.is_empty());
    assert!(render(&r, 816).contains("NOT CONCLUDED"));
}

/// The review of #29: a run whose only findings are undefined reads (no `nonuniformEXT`) said
/// "no finding" to bisect and report, while `run` had failed on them.
#[test]
fn a_scope_whose_only_faults_are_undefined_reads_says_so() {
    let mut sim = Sim::new(&["index=dynamic,nonuniform=false"], 1.0);
    let sc = scope("descriptor_model=descriptor_indexing,stage=closest_hit,resource=sampled_image");
    let v = report(&mut sim, &sc);
    let mut b = Bisector::new(sc.clone(), v, &mut sim, Settings::default(), vec![]);
    let e = b.bisect(None, &|_| true).unwrap_err();
    assert!(matches!(e, BisectError::OnlyUndefined(n) if n > 0), "{e}");
    assert!(e.to_string().contains("VUID-RuntimeSpirv-None-10148"), "{e}");
    // Its twin: a defined fault beside them is bisected.
    let mut sim = Sim::new(&["index=dynamic"], 1.0);
    let v = report(&mut sim, &sc);
    let mut b = Bisector::new(sc, v, &mut sim, Settings::default(), vec![]);
    assert!(b.bisect(None, &|_| true).is_ok());
}

#[test]
fn no_fault_and_a_wrong_cell_are_errors() {
    let mut sim = Sim::new(&["stage=raygen"], 1.0);
    let sc = scope("descriptor_model=descriptor_indexing,stage=closest_hit");
    let v = report(&mut sim, &sc);
    let mut b = Bisector::new(sc.clone(), v.clone(), &mut sim, Settings::default(), vec![]);
    assert!(matches!(b.bisect(None, &|_| true), Err(BisectError::NoFault)));
    let mut sim = Sim::new(&["index=dynamic"], 1.0);
    let mut b =
        Bisector::new(sc.clone(), report(&mut sim, &sc), &mut sim, Settings::default(), vec![]);
    assert!(matches!(
        b.bisect(Some("closest_hit.storage_buffer.literal.descriptor_indexing"), &|_| true),
        Err(BisectError::NotFaulting(_))
    ));
}

#[test]
fn workarounds_say_when_the_injection_decides_them() {
    let sc =
        scope("descriptor_model=descriptor_indexing,stage=closest_hit,resource=storage_buffer");
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
    let sc: Vec<Cell> = scope(
        "descriptor_model=descriptor_indexing,resource=storage_buffer,stage=raygen|closest_hit",
    )
    .into_iter()
    .flat_map(|c| {
        std::iter::once(c)
            .chain(c.applicable_patches().into_iter().map(move |p| Cell { patch: Some(p), ..c }))
    })
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
        fn run(&mut self, cells: &[Cell], mode: Mode, on: &mut dyn FnMut(Event)) {
            for c in cells {
                if c.id() == self.1 {
                    on(Event::Attempt {
                        cell: *c,
                        attempt: Attempt {
                            detail: Some("could not".into()),
                            ..attempt(Outcome::Error, mode != Mode::Shared)
                        },
                    });
                } else {
                    self.0.run(std::slice::from_ref(c), mode, on);
                }
            }
        }
        fn can_run(&self) -> bool {
            true
        }
    }
    let sc = scope(
        "descriptor_model=descriptor_indexing,resource=storage_buffer,stage=raygen|closest_hit",
    );
    // (The dynamic cells without nonuniformEXT fault too, but the spec leaves their reads
    // undefined: doubtful, counted neither way either.)
    let mut o = WithError(
        Sim::new(&["index=dynamic"], 1.0),
        "raygen.storage_buffer.dynamic.nonuniform.descriptor_indexing".into(),
    );
    let mut v = Verdicts::default();
    o.run(&sc, Mode::Shared, &mut |ev| v.on_event(ev));
    let defined =
        sc.iter().filter(|c| c.index == crate::model::IndexSource::Dynamic && c.nonuniform).count();
    let mut b = Bisector::new(sc, v, &mut o, Settings::default(), vec![]);
    let r = b.bisect(None, &|_| true).unwrap();
    assert_eq!(r.minimal, "nonuniform=true");
    assert_eq!(
        r.errored,
        vec!["raygen.storage_buffer.dynamic.nonuniform.descriptor_indexing".to_string()]
    );
    assert_eq!(r.faulting_cells, defined - 1);
    assert!(!r.doubtful.is_empty());
}

#[test]
fn an_oracle_that_adds_nothing_ends_the_bisection() {
    // Runs that come back with no attempt (a supervisor that could not run them) must not loop.
    struct Deaf;
    impl Oracle for Deaf {
        fn run(&mut self, _: &[Cell], _: Mode, _: &mut dyn FnMut(Event)) {}
        fn can_run(&self) -> bool {
            true
        }
    }
    let sc = scope(
        "descriptor_model=descriptor_indexing,resource=storage_buffer,stage=raygen|closest_hit",
    );
    let mut sim = Sim::new(&["index=dynamic"], 1.0);
    let v = report(&mut sim, &sc[..6]);
    let mut deaf = Deaf;
    let r = Bisector::new(sc, v, &mut deaf, Settings::default(), vec![])
        .bisect(None, &|_| true)
        .unwrap();
    assert!(!r.concluded());
}

#[test]
fn an_oracle_that_halts_ends_the_bisection_with_the_halt() {
    // A worker that cannot start its shader compiler halts every run: bisection must say so (the
    // CLI exits 12), not conclude "not concluded (attempt cap or offline)" and exit 0.
    struct Halting;
    impl Oracle for Halting {
        fn run(&mut self, _: &[Cell], _: Mode, on: &mut dyn FnMut(Event)) {
            on(Event::Halt(crate::model::Halt::NoShaderCompiler));
        }
    }
    let sc = scope(
        "descriptor_model=descriptor_indexing,resource=storage_buffer,stage=raygen|closest_hit",
    );
    let mut sim = Sim::new(&["index=dynamic"], 1.0);
    let v = report(&mut sim, &sc[..6]);
    let r = Bisector::new(sc, v, &mut Halting, Settings::default(), vec![]).bisect(None, &|_| true);
    assert!(
        matches!(r, Err(BisectError::Halted(crate::model::Halt::NoShaderCompiler))),
        "{:?}",
        r.map(|b| b.minimal)
    );
}

#[test]
fn a_pass_with_too_little_evidence_is_not_concluded_on() {
    // Three attempts at most: a fault seen 3 of 3 is only p >= alpha^(1/3) at 95%, and a pass of 3
    // attempts would miss such a fault with probability (1 - alpha^(1/3))^3, above 1%.
    let sc = scope(
        "descriptor_model=descriptor_indexing,resource=storage_buffer,stage=raygen|closest_hit",
    );
    let mut sim = Sim::new(&["stage=closest_hit,index=dynamic"], 1.0);
    let v = report(&mut sim, &sc);
    let settings = Settings { max_attempts: 3, ..Settings::default() };
    let r = Bisector::new(sc, v, &mut sim, settings, vec![]).bisect(None, &|_| true).unwrap();
    let (bound, miss) = (
        crate::model::stats::rate_bound(3, 3),
        crate::model::stats::miss(crate::model::stats::rate_bound(3, 3), 3),
    );
    assert!(miss >= DEFAULT_MAX_MISS, "{miss}");
    assert_eq!(r.fault_rate_bound, Some(bound));
    assert!(!r.concluded());
    let passes: Vec<_> = r.isolation.iter().filter(|l| l.verdict == "pass").collect();
    assert!(!passes.is_empty());
    for l in passes {
        assert_eq!(l.attempts, 3);
        assert!(!l.settled() && l.line.contains("not concluded on"), "{}", l.line);
        assert!((l.miss_probability.unwrap() - miss).abs() < 1e-12);
        assert!(r.unsettled.contains(&l.cell), "{}", l.cell);
    }
    assert!(render(&r, 816).contains("NOT CONCLUDED"));
    // With the default cap the same fault concludes.
    let mut sim = Sim::new(&["stage=closest_hit,index=dynamic"], 1.0);
    let sc = scope(
        "descriptor_model=descriptor_indexing,resource=storage_buffer,stage=raygen|closest_hit",
    );
    let v = report(&mut sim, &sc);
    assert!(Bisector::new(sc, v, &mut sim, Settings::default(), vec![])
        .bisect(None, &|_| true)
        .unwrap()
        .concluded());
}

#[test]
fn a_lenient_pass_that_read_other_elements_is_suspect_when_a_defined_sibling_faults() {
    use crate::model::IndexSource;
    use crate::model::{Comparison, ElementReads};
    let lenient = scope("stage=closest_hit,resource=sampled_image,index=dynamic,nonuniform=false,descriptor_model=descriptor_indexing")[0];
    let literal = Cell { index: IndexSource::Literal, ..lenient };
    let reads = |other: usize| {
        let comparison = Comparison {
            element_reads: Some(ElementReads {
                outside_spec: "x".into(),
                own: 10,
                other,
                neither: 0,
                ..ElementReads::default()
            }),
            ..Comparison::default()
        };
        let result = crate::model::CellResult {
            outcome: Outcome::Pass,
            detail: None,
            timings: Default::default(),
            comparison: Some(comparison),
            fault: None,
            validation_errors: 0,
        };
        Attempt { result: Some(result), ..attempt(Outcome::Pass, false) }
    };
    let ev = isolation::Evidence { against: Some(0.6), max_miss: DEFAULT_MAX_MISS };
    // Other elements read, and the literal sibling faults: suspect, naming it.
    let mut v = Verdicts::default();
    v.record(&lenient, reads(3));
    v.record(&literal, attempt(Outcome::Mismatch, false));
    let l = isolation::line(&lenient, Some("index"), &v, ev);
    assert_eq!(l.suspect.as_deref(), Some(literal.id().as_str()));
    assert!(
        l.line.contains("suspect, not used: 3 pixels read what another lane's index gives")
            && l.line.contains("with literal index, descriptor_indexing faults"),
        "{}",
        l.line
    );
    // Twins: every lane read its own element, or no defined sibling faults: clean.
    let mut own = Verdicts::default();
    own.record(&lenient, reads(0));
    own.record(&literal, attempt(Outcome::Mismatch, false));
    assert!(isolation::line(&lenient, None, &own, ev).suspect.is_none());
    let mut clean = Verdicts::default();
    clean.record(&lenient, reads(3));
    clean.record(&literal, attempt(Outcome::Pass, false));
    let l = isolation::line(&lenient, None, &clean, ev);
    assert!(l.suspect.is_none() && !l.line.contains("suspect"), "{}", l.line);
    // A cell with nonuniformEXT judged exactly (no element reads: the qualifier reached the
    // driver) is never suspect; one judged leniently because its compiler dropped the qualifier
    // (its comparison has element reads, `exec::seen`) is, like the cell
    // without it.
    let nu = Cell { nonuniform: true, ..lenient };
    let mut v = Verdicts::default();
    v.record(&nu, attempt(Outcome::Pass, false));
    v.record(&literal, attempt(Outcome::Mismatch, false));
    assert!(isolation::line(&nu, None, &v, ev).suspect.is_none());
    let mut v = Verdicts::default();
    v.record(&nu, reads(3));
    v.record(&literal, attempt(Outcome::Mismatch, false));
    assert_eq!(isolation::line(&nu, None, &v, ev).suspect.as_deref(), Some(literal.id().as_str()));
}

#[test]
fn a_sibling_that_faults_while_the_isolation_list_is_settled_is_covered() {
    // The raygen dynamic cell with nonuniformEXT faults every time; its closest-hit sibling
    // passes its first attempts and faults from its fourth on (a rare fault). The search first
    // finds `stage=raygen,…`; settling the isolation list then repeats the sibling until it
    // faults, and the description must cover it: no isolation line may show a fault the minimal
    // description excludes.
    let sc = scope("descriptor_model=descriptor_indexing,resource=storage_buffer,stage=raygen|closest_hit,index=literal|dynamic,base=push_data|none,reorder=none");
    let mut o = Late {
        sim: Sim::new(&["stage=raygen,index=dynamic,nonuniform=true"], 1.0),
        late: "closest_hit.storage_buffer.dynamic.nonuniform.descriptor_indexing".into(),
        from: 4,
        seen: 0,
    };
    let mut v = Verdicts::default();
    o.run(&sc, Mode::Shared, &mut |ev| v.on_event(ev));
    v.runs = 0;
    let r = Bisector::new(sc.clone(), v, &mut o, Settings::default(), vec![])
        .bisect(None, &|_| true)
        .unwrap();
    assert!(o.seen >= 4, "the late sibling was repeated into its fault ({} attempts)", o.seen);
    assert_eq!(r.minimal, "nonuniform=true", "{r:?}");
    assert_eq!(r.faulting_cells, 2);
    let minimal = Filter::parse(&r.minimal).unwrap();
    for l in r.isolation.iter().filter(|l| l.verdict != "pass") {
        let c = sc.iter().find(|c| c.id() == l.cell).unwrap();
        assert!(minimal.matches(c), "{} faults outside {}", l.cell, r.minimal);
    }
}

#[test]
fn descriptions_prefer_primary_axes_over_the_optional_axes_stand_in_values() {
    // In a scope with closest-hit base variants, `base=none` (not a closest-hit dynamic cell)
    // separates raygen from closest-hit as well as `stage=raygen` does: the description names
    // the stage. A fault that needs the base keeps it.
    let sc = "descriptor_model=descriptor_indexing,resource=storage_buffer,stage=raygen|closest_hit,index=literal|dynamic,reorder=none";
    let (r, _) = bisect(&["stage=raygen,nonuniform=true"], 1.0, sc, sc);
    assert!(!r.minimal.contains("base=") && !r.minimal.contains("sampler="), "{}", r.minimal);
    assert_eq!(Filter::parse(&r.minimal).unwrap().terms.len(), 2, "{}", r.minimal);
    let (r, _) = bisect(&["base=buffer"], 1.0, sc, sc);
    assert_eq!(r.minimal, "base=buffer");
}

#[test]
fn a_workaround_in_scope_that_faults_while_settled_is_covered() {
    // A scope planned with `--patches all` holds the patched variants. The raygen dynamic cell
    // with nonuniformEXT faults every time; its ssbo-to-address variant passes its first attempt
    // and faults from the second on. Whichever phase repeats it into its fault (the search's
    // settling, or the workarounds' settling that now runs inside the coverage loop), the
    // description must cover it: no `patch=` restriction may exclude it.
    let mut sc = scope("descriptor_model=descriptor_indexing,resource=storage_buffer,stage=raygen|closest_hit,index=literal|dynamic,base=push_data|none,reorder=none");
    let patched: Vec<Cell> = sc
        .iter()
        .flat_map(|c| {
            c.applicable_patches().into_iter().map(move |p| Cell { patch: Some(p), ..*c })
        })
        .collect();
    sc.extend(patched);
    let late = "raygen.storage_buffer.dynamic.nonuniform.descriptor_indexing.patch-ssbo-to-address";
    assert!(sc.iter().any(|c| c.id() == late));
    let mut o = Late {
        sim: Sim::new(&["stage=raygen,index=dynamic,nonuniform=true,patch=none"], 1.0),
        late: late.into(),
        from: 2,
        seen: 0,
    };
    // The report ran the plain cells; the patched ones are run by the bisection.
    let mut v = Verdicts::default();
    let plain: Vec<Cell> = sc.iter().filter(|c| c.patch.is_none()).copied().collect();
    o.run(&plain, Mode::Shared, &mut |ev| v.on_event(ev));
    v.runs = 0;
    let r = Bisector::new(sc.clone(), v, &mut o, Settings::default(), vec![])
        .bisect(None, &|_| true)
        .unwrap();
    assert!(o.seen >= 2, "the late workaround was repeated into its fault ({} attempts)", o.seen);
    let minimal = Filter::parse(&r.minimal).unwrap();
    let late_cell = sc.iter().find(|c| c.id() == late).unwrap();
    assert!(minimal.matches(late_cell), "{} excludes the faulting {late}", r.minimal);
    for l in r
        .workarounds
        .iter()
        .chain(&r.isolation)
        .filter(|l| l.verdict != "pass" && l.verdict != "not_run")
    {
        let c = sc.iter().find(|c| c.id() == l.cell).unwrap();
        assert!(minimal.matches(c), "{} faults outside {}", l.cell, r.minimal);
    }
}

#[test]
fn evidence_counts_only_attempts_the_driver_decided() {
    // A worker whose setup failed never ran the cell (`not_run`), and an `error` is rtprobe's:
    // neither is evidence. Counted, they would raise a finding's rate bound (so passes held to it
    // need fewer attempts) and lengthen a pass's record.
    let c = scope(
        "descriptor_model=descriptor_indexing,resource=storage_buffer,stage=raygen,index=literal",
    )[0];
    let never_ran = |o: Outcome| Attempt {
        phase: Some(crate::model::phase::Phase::Setup),
        ..attempt(o, false)
    };
    let mut v = Verdicts::default();
    v.record(&c, attempt(Outcome::Mismatch, false));
    v.record(&c, never_ran(Outcome::Timeout));
    v.record(&c, attempt(Outcome::Error, false));
    assert_eq!(v.counts(&c), (1, 1));
    assert_eq!(v.attempts(&c), 3, "every attempt still caps the repeats");
    assert!((v.rate_bound(&c) - crate::model::stats::rate_bound(1, 1)).abs() < 1e-12);
    let p = scope("descriptor_model=descriptor_indexing,resource=storage_buffer,stage=raygen,index=spec_constant")[0];
    let mut v = Verdicts::default();
    v.record(&p, attempt(Outcome::Pass, false));
    for _ in 0..5 {
        v.record(&p, never_ran(Outcome::Crash));
    }
    assert_eq!(v.counts(&p), (0, 1));
    let l = isolation::line(
        &p,
        None,
        &v,
        isolation::Evidence { against: Some(0.6), max_miss: DEFAULT_MAX_MISS },
    );
    assert!(l.line.contains("passes (1 of 1;"), "{}", l.line);
}

/// A pass judged by the other-lane heuristic with `other` pixels reading another lane's value.
fn lenient_pass(other: usize) -> Attempt {
    let comparison = crate::model::Comparison {
        element_reads: Some(crate::model::ElementReads {
            outside_spec: "x".into(),
            own: 10,
            other,
            ..Default::default()
        }),
        ..Default::default()
    };
    let result = crate::model::CellResult {
        outcome: Outcome::Pass,
        detail: None,
        timings: Default::default(),
        comparison: Some(comparison),
        fault: None,
        validation_errors: 0,
    };
    Attempt { result: Some(result), ..attempt(Outcome::Pass, true) }
}

/// A driver that answers `undefined` for the reads without `nonuniformEXT` (dynamic index) and
/// `defined` for every other cell.
struct ByShape {
    undefined: fn() -> Attempt,
    defined: fn(&Cell) -> Outcome,
}

impl Oracle for ByShape {
    fn run(&mut self, cells: &[Cell], mode: Mode, on: &mut dyn FnMut(Event)) {
        for c in cells {
            let a = if crate::model::undefined_descriptor_read(c) {
                (self.undefined)()
            } else {
                attempt((self.defined)(c), mode != Mode::Shared)
            };
            on(Event::Attempt { cell: *c, attempt: a });
        }
    }
    fn can_run(&self) -> bool {
        true
    }
}

fn bisect_by_shape(driver: &mut ByShape, filter: &str) -> Bisection {
    let sc = scope(filter);
    let mut v = Verdicts::default();
    driver.run(&sc, Mode::Shared, &mut |ev| v.on_event(ev));
    v.runs = 0;
    Bisector::new(sc, v, driver, Settings::default(), vec![]).bisect(None, &|_| true).unwrap()
}

/// Issue 21, item 4: every defined read faults, the reads without `nonuniformEXT` pass leniently
/// with other-lane reads. Those passes are suspect (a defined sibling faults): bisection uses
/// none of them, and one conjunction covers the faults. Twin: the same passes with every lane
/// reading its own element are evidence, and no single conjunction separates.
#[test]
fn bisect_relies_on_no_suspect_lenient_pass() {
    let filter = "stage=closest_hit,resource=sampled_image,descriptor_model=descriptor_indexing,reorder=none";
    let mut suspect = ByShape { undefined: || lenient_pass(3), defined: |_| Outcome::Mismatch };
    let r = bisect_by_shape(&mut suspect, filter);
    assert!(r.separable && r.conjunctions.len() == 1, "{:?}", r.conjunctions);
    let undefined =
        scope(filter).iter().filter(|c| crate::model::undefined_descriptor_read(c)).count();
    assert!(undefined >= 3);
    assert_eq!(r.doubtful.len(), undefined, "{:?}", r.doubtful);
    assert!(r.doubtful.iter().all(|d| d.contains("lenient pass")), "{:?}", r.doubtful);
    let mut own = ByShape { undefined: || lenient_pass(0), defined: |_| Outcome::Mismatch };
    let r = bisect_by_shape(&mut own, filter);
    assert!(!r.separable && r.conjunctions.len() > 1, "{:?}", r.conjunctions);
    assert!(r.doubtful.is_empty());
}

/// Issue 21, item 4: the literal-index cells fault, and so do the reads without `nonuniformEXT`
/// (which the spec leaves undefined). Bisection does not count the undefined faults: the
/// description is the literal index alone, and they are listed as doubtful.
#[test]
fn bisect_does_not_count_faults_of_undefined_reads() {
    let filter = "stage=closest_hit|raygen,resource=storage_buffer,descriptor_model=descriptor_indexing,reorder=none";
    let mut driver = ByShape {
        undefined: || attempt(Outcome::Crash, true),
        defined: |c| {
            if c.index == crate::model::IndexSource::Literal {
                Outcome::Crash
            } else {
                Outcome::Pass
            }
        },
    };
    let r = bisect_by_shape(&mut driver, filter);
    assert_eq!(r.minimal, "index=literal", "{r:?}");
    assert!(!r.doubtful.is_empty() && r.doubtful.iter().all(|d| d.contains("undefined")));
}

/// A mismatch of a cell without `nonuniformEXT` is unsettled evidence (its read is undefined),
/// unless it fell on a subgroup the device's lane evidence proves uniform: that read is defined
/// (VUID-RuntimeSpirv-subgroupSize-10149, Vulkan 1.4.360), and bisect relies on its fault.
#[test]
fn a_mismatch_on_a_uniform_subgroup_is_a_fault_not_an_undefined_read() {
    let c = scope("stage=closest_hit,resource=storage_buffer,index=dynamic,nonuniform=false,descriptor_model=descriptor_indexing")[0];
    assert!(crate::model::undefined_descriptor_read(&c));
    let mismatch = |uniform_mismatched: usize| {
        let comparison = crate::model::Comparison {
            mismatched_pixels: 5,
            element_reads: Some(crate::model::ElementReads {
                outside_spec: "x".into(),
                own: 10,
                neither: 5,
                uniform: 8,
                uniform_mismatched,
                ..Default::default()
            }),
            ..Default::default()
        };
        let result = crate::model::CellResult {
            outcome: Outcome::Mismatch,
            detail: None,
            timings: Default::default(),
            comparison: Some(comparison),
            fault: None,
            validation_errors: 0,
        };
        Attempt { result: Some(result), ..attempt(Outcome::Mismatch, false) }
    };
    let mut v = Verdicts::default();
    v.record(&c, mismatch(0));
    assert_eq!(v.state(&c), State::Doubtful(Doubt::UndefinedFault));
    let mut v = Verdicts::default();
    v.record(&c, mismatch(2));
    assert_eq!(v.state(&c), State::Fault);
}
