//! Every round against a scripted oracle (no GPU): which cells it runs, how, and how often. Each
//! round's check is also run against a broken policy (its twin), which the check must reject.
use super::*;
use crate::model::{
    Attempt, Canary, DescriptorModel, GpuAvVerdict, Halt, IndexSource, Mutant, MutantPrediction,
    MutantStatus, Outcome, PlanStatus, PlannedCell, Resource, RunPlan, RunReport, Stage,
};
use crate::report::gpu_av;
use crate::report::writer::ReportWriter;
use std::collections::{BTreeSet, HashMap};
use std::rc::Rc;

/// Outcomes per cell id: a cell's n-th attempt gets the n-th outcome, the last one repeating;
/// under GPU-AV, `gpu_av`'s. Unscripted cells pass. Every batch is kept.
#[derive(Default)]
struct Script {
    plain: HashMap<String, Vec<Outcome>>,
    gpu_av: HashMap<String, Vec<Outcome>>,
    seen: HashMap<(String, bool), usize>,
    batches: Vec<(Mode, Vec<Cell>)>,
}

impl Script {
    fn with(mut self, c: Cell, outcomes: &[Outcome]) -> Self {
        self.plain.insert(c.id(), outcomes.to_vec());
        self
    }
    fn under_gpu_av(mut self, c: Cell, outcomes: &[Outcome]) -> Self {
        self.gpu_av.insert(c.id(), outcomes.to_vec());
        self
    }
}

impl Oracle for Script {
    fn run(&mut self, cells: &[Cell], mode: Mode, on: &mut dyn FnMut(Event)) {
        self.batches.push((mode, cells.to_vec()));
        for c in cells {
            let av = mode == Mode::GpuAv;
            let n = self.seen.entry((c.id(), av)).or_insert(0);
            let k = *n;
            *n += 1;
            let script = if av { &self.gpu_av } else { &self.plain };
            let outcome =
                script.get(&c.id()).map(|s| s[k.min(s.len() - 1)]).unwrap_or(Outcome::Pass);
            on(Event::Attempt {
                cell: *c,
                attempt: Attempt::for_tests(outcome, mode != Mode::Shared),
            });
        }
    }
}

/// Runs nothing (a supervisor that could not start a worker, say).
struct Deaf(usize);

impl Oracle for Deaf {
    fn run(&mut self, _: &[Cell], _: Mode, _: &mut dyn FnMut(Event)) {
        self.0 += 1;
    }
}

/// `Script`, but its batch number `.1` (from 0) ends in a halt after its first cell.
struct Halting(Script, usize);

impl Oracle for Halting {
    fn run(&mut self, cells: &[Cell], mode: Mode, on: &mut dyn FnMut(Event)) {
        if self.0.batches.len() != self.1 {
            return self.0.run(cells, mode, on);
        }
        self.0.run(&cells[..1], mode, on);
        on(Event::Halt(Halt::NoShaderCompiler));
    }
}

/// Attempts the progress was told of, and attempts it saw end.
#[derive(Default)]
struct Counts {
    scheduled: std::cell::Cell<u64>,
    ended: std::cell::Cell<u64>,
    /// The rounds announced: name, attempts, alone.
    rounds: std::cell::RefCell<Vec<(&'static str, u64, bool)>>,
}

impl Progress for Rc<Counts> {
    fn scheduled(&self, n: u64) {
        self.scheduled.set(self.scheduled.get() + n);
    }
    fn round(&self, name: &'static str, n: u64, alone: bool) {
        self.rounds.borrow_mut().push((name, n, alone));
    }
    fn ended(&self, _: &Cell, _: Option<Outcome>) {
        self.ended.set(self.ended.get() + 1);
    }
}

struct World {
    _dir: crate::tempdir::TempDir,
    oracle: Script,
    rec: Recorder,
    counts: Rc<Counts>,
}

fn world(plan: &[Cell], oracle: Script) -> World {
    let dir = crate::tempdir::tempdir().unwrap();
    let p = RunPlan {
        generated: plan.len(),
        cells: plan.iter().map(|c| PlannedCell { cell: *c, status: PlanStatus::Run }).collect(),
        not_generated: vec![],
        filtered_out: 0,
    };
    let writer =
        ReportWriter::new(dir.path().join("report.json"), RunReport::for_tests(vec![]), &p);
    let counts = Rc::new(Counts::default());
    World { _dir: dir, oracle, rec: Recorder::new(writer, Box::new(counts.clone())), counts }
}

impl World {
    fn campaign<'a>(&'a mut self, supported: &'a dyn Fn(&Cell) -> bool) -> Campaign<'a> {
        Campaign { oracle: &mut self.oracle, rec: &mut self.rec, supported, applies: &applies }
    }
    fn report(&self) -> &RunReport {
        &self.rec.writer.report
    }
    /// The outcomes of `c`'s own attempts (empty: not in the report).
    fn attempts(&self, c: &Cell) -> Vec<Outcome> {
        self.report()
            .cells
            .iter()
            .find(|x| x.cell == *c)
            .map(|x| x.attempts.iter().map(|a| a.outcome).collect())
            .unwrap_or_default()
    }
}

fn all(_: &Cell) -> bool {
    true
}

/// Every mutant applies (10 pixels differ, all to be caught) but `sampler-next`, which has no
/// target, and `index-zero` on literal-index cells, which is equivalent there.
fn applies(c: &Cell) -> Result<MutantPrediction, String> {
    match c.mutant {
        Some(Mutant::SamplerNext) => Err("no separate sampler index".into()),
        Some(Mutant::IndexZero) if c.index == IndexSource::Literal => {
            Ok(MutantPrediction::default())
        }
        _ => Ok(MutantPrediction {
            differing: 10,
            caught: 10,
            from_lanes: false,
            caught_by_heuristic: 0,
        }),
    }
}

fn cell(stage: Stage, index: IndexSource) -> Cell {
    Cell::new(stage, Resource::StorageBuffer, index, DescriptorModel::DescriptorIndexing)
}

fn ids(cells: &[Cell]) -> BTreeSet<String> {
    cells.iter().map(Cell::id).collect()
}

/// Each batch of `got` has `want`'s mode and cells (in any order).
fn same_batches(got: &[(Mode, Vec<Cell>)], want: &[(Mode, Vec<Cell>)]) -> Result<(), String> {
    let show = |b: &[(Mode, Vec<Cell>)]| {
        b.iter().map(|(m, c)| format!("{m:?} {:?}", ids(c))).collect::<Vec<_>>()
    };
    let same = got.len() == want.len()
        && got.iter().zip(want).all(|((gm, gc), (wm, wc))| gm == wm && ids(gc) == ids(wc));
    if same {
        Ok(())
    } else {
        Err(format!("batches {:?}, expected {:?}", show(got), show(want)))
    }
}

fn expect<T: PartialEq + std::fmt::Debug>(what: &str, got: T, want: T) -> Result<(), String> {
    if got == want {
        Ok(())
    } else {
        Err(format!("{what}: {got:?}, expected {want:?}"))
    }
}

// ---- confirm ----

/// A crash, a mismatch, a pass, an `error` and a canary that crashed, each run once; a crash
/// whose only attempt is a worker that never got its device up (not run), and a crash already
/// run twice (a resumed report's confirmed fault).
fn confirm_world() -> (World, Vec<Cell>) {
    let (crash, mismatch) =
        (cell(Stage::ClosestHit, IndexSource::Dynamic), cell(Stage::Raygen, IndexSource::Dynamic));
    let (pass, error, canary) = (
        cell(Stage::ClosestHit, IndexSource::Literal),
        cell(Stage::ClosestHit, IndexSource::PushConstant),
        Cell::canary(Canary::InvalidAddress),
    );
    let (unrun, twice) =
        (cell(Stage::Miss, IndexSource::Dynamic), cell(Stage::AnyHit, IndexSource::Dynamic));
    let cells = vec![crash, mismatch, pass, error, canary, unrun, twice];
    let script = Script::default()
        .with(crash, &[Outcome::Crash])
        .with(mismatch, &[Outcome::Mismatch])
        .with(error, &[Outcome::Error])
        .with(canary, &[Outcome::Crash])
        .with(twice, &[Outcome::Crash]);
    let mut w = world(&cells, script);
    w.campaign(&all).matrix(&cells[..5]);
    w.campaign(&all).matrix(&[twice, twice]);
    let mut setup = Attempt::for_tests(Outcome::Crash, true);
    setup.phase = Some(crate::model::Phase::Setup);
    w.rec.writer.record(&unrun, setup);
    (w, cells)
}

/// Confirmation ran the two faults, alone, once: nothing else ran again.
fn check_confirm(w: &World, cells: &[Cell]) -> Result<(), String> {
    same_batches(&w.oracle.batches[2..], &[(Mode::Alone, vec![cells[0], cells[1]])])?;
    let before = [1, 1, 1, 1, 2];
    cells[2..].iter().zip(before).try_for_each(|(c, n)| expect(&c.id(), w.attempts(c).len(), n))
}

#[test]
fn confirm_reruns_each_fault_alone_once() {
    let (mut w, cells) = confirm_world();
    w.campaign(&all).confirm();
    check_confirm(&w, &cells).unwrap();
    // The progress heard of the round by name (the matrix is not a round it announces).
    assert_eq!(*w.counts.rounds.borrow(), vec![("confirm", 2, true)]);
    assert_eq!(w.attempts(&cells[0]), vec![Outcome::Crash, Outcome::Crash]);
    assert_eq!(
        w.counts.scheduled.get(),
        2,
        "the matrix's cells are the run's to count; the round adds its own"
    );
}

#[test]
fn confirm_twin_rerunning_passes_or_running_faults_together_is_caught() {
    let (mut w, cells) = confirm_world();
    let once: Vec<Cell> =
        w.report().cells.iter().filter(|c| c.attempts.len() == 1).map(|c| c.cell).collect();
    w.campaign(&all).round("test", &once, Mode::Alone);
    assert!(check_confirm(&w, &cells).is_err());
    let (mut w, cells) = confirm_world();
    let faults = confirm_cells(w.report());
    w.campaign(&all).round("test", &faults, Mode::Shared);
    assert!(check_confirm(&w, &cells).is_err());
}

// ---- repeat ----

/// A steady crash, a flaky one (crash, then passes) and a pass.
fn repeat_world() -> (World, [Cell; 3]) {
    let (steady, flaky, pass) = (
        cell(Stage::ClosestHit, IndexSource::Dynamic),
        cell(Stage::Raygen, IndexSource::Dynamic),
        cell(Stage::ClosestHit, IndexSource::Literal),
    );
    let mut w = world(
        &[steady, flaky, pass],
        Script::default()
            .with(steady, &[Outcome::Crash])
            .with(flaky, &[Outcome::Crash, Outcome::Pass]),
    );
    w.campaign(&all).matrix(&[steady, flaky, pass]);
    (w, [steady, flaky, pass])
}

/// Every faulting cell has `n` attempts, each repeat alone; the pass ran once.
fn check_repeat(w: &World, [steady, flaky, pass]: [Cell; 3], n: usize) -> Result<(), String> {
    expect("steady crash attempts", w.attempts(&steady).len(), n)?;
    expect(
        "flaky crash attempts",
        w.attempts(&flaky),
        [vec![Outcome::Crash], vec![Outcome::Pass; n - 1]].concat(),
    )?;
    expect("pass attempts", w.attempts(&pass).len(), 1)?;
    w.oracle.batches[1..].iter().try_for_each(|(m, c)| {
        expect("repeat batch", (*m, c.contains(&pass)), (Mode::Alone, false))
    })
}

#[test]
fn repeat_gives_every_faulting_cell_n_attempts_alone() {
    let (mut w, cells) = repeat_world();
    w.campaign(&all).repeat(4);
    check_repeat(&w, cells, 4).unwrap();
    assert_eq!(w.oracle.batches.len(), 4, "one batch per missing attempt");
}

#[test]
fn repeat_twin_a_single_round_is_caught() {
    let (mut w, cells) = repeat_world();
    let more = repeat_cells(w.report(), 4);
    w.campaign(&all).round("test", &more, Mode::Alone);
    assert!(check_repeat(&w, cells, 4).is_err());
}

// ---- workarounds ----

/// A steady crash repeated to 3 attempts, and a pass that workarounds would apply to. The crash's
/// first workaround always passes, its second passes once then mismatches, its third the device
/// cannot run.
fn workaround_world() -> (World, Cell, Vec<Cell>) {
    let (finding, pass) =
        (cell(Stage::ClosestHit, IndexSource::Dynamic), cell(Stage::Raygen, IndexSource::Dynamic));
    let variants: Vec<Cell> = finding
        .applicable_patches()
        .into_iter()
        .map(|p| Cell { patch: Some(p), ..finding })
        .collect();
    assert!(variants.len() >= 3, "{variants:?}");
    let mut w = world(
        &[finding, pass],
        Script::default()
            .with(finding, &[Outcome::Crash])
            .with(variants[1], &[Outcome::Pass, Outcome::Mismatch]),
    );
    w.campaign(&all).matrix(&[finding, pass]);
    w.campaign(&all).repeat(3);
    w.oracle.batches.clear();
    (w, finding, variants)
}

fn check_workarounds(w: &World, finding: Cell, v: &[Cell]) -> Result<(), String> {
    let (first, verify) = w.oracle.batches.split_first().ok_or("no batch")?;
    same_batches(std::slice::from_ref(first), &[(Mode::Shared, vec![v[0], v[1]])])?;
    expect("verifying batches run alone", verify.iter().all(|(m, _)| *m == Mode::Alone), true)?;
    expect(
        "the passing workaround, as often as its finding",
        w.attempts(&v[0]),
        vec![Outcome::Pass; w.attempts(&finding).len()],
    )?;
    expect(
        "the one that faulted stops",
        w.attempts(&v[1]),
        vec![Outcome::Pass, Outcome::Mismatch],
    )?;
    expect("the unsupported one never ran", w.attempts(&v[2]), vec![])
}

#[test]
fn workarounds_retry_applicable_supported_patches_until_as_many_attempts_as_the_finding() {
    let (mut w, finding, v) = workaround_world();
    let supported = |c: &Cell| c.patch != v[2].patch;
    w.campaign(&supported).workarounds();
    w.campaign(&supported).verify();
    check_workarounds(&w, finding, &v).unwrap();
    // After a resume, a variant that already ran is not run again.
    let done = [v[0].id()].into_iter().collect();
    assert_eq!(ids(&workaround_cells(w.report(), &done, &all)), ids(&v[1..]));
}

#[test]
fn workarounds_twin_unverified_or_unsupported_variants_are_caught() {
    let (mut w, finding, v) = workaround_world();
    let supported = |c: &Cell| c.patch != v[2].patch;
    w.campaign(&supported).workarounds();
    assert!(check_workarounds(&w, finding, &v).is_err(), "no verifying repeats");
    let (mut w, finding, v) = workaround_world();
    let every = workaround_cells(w.report(), &w.rec.writer.done(), &all);
    w.campaign(&all).round("test", &every, Mode::Shared);
    w.campaign(&all).verify();
    assert!(check_workarounds(&w, finding, &v).is_err(), "a variant the device cannot run");
}

// ---- recommended patterns ----

/// Two steady crashes with 3 attempts each; the device runs the first one's pattern only.
fn pattern_world() -> (World, [Cell; 4]) {
    let (f, h) =
        (cell(Stage::ClosestHit, IndexSource::Dynamic), cell(Stage::Raygen, IndexSource::Dynamic));
    let (pf, ph) = (f.recommended_pattern().unwrap().1, h.recommended_pattern().unwrap().1);
    let mut w =
        world(&[f, h], Script::default().with(f, &[Outcome::Crash]).with(h, &[Outcome::Crash]));
    w.campaign(&all).matrix(&[f, h]);
    w.campaign(&all).repeat(3);
    w.oracle.batches.clear();
    (w, [f, h, pf, ph])
}

fn check_patterns(w: &World, [f, _, pf, ph]: [Cell; 4]) -> Result<(), String> {
    let (first, verify) = w.oracle.batches.split_first().ok_or("no batch")?;
    same_batches(std::slice::from_ref(first), &[(Mode::Shared, vec![pf])])?;
    expect("verifying batches", verify.iter().all(|(m, c)| *m == Mode::Alone && c == &[pf]), true)?;
    expect(
        "the pattern, as often as its finding",
        w.attempts(&pf),
        vec![Outcome::Pass; w.attempts(&f).len()],
    )?;
    expect("the unsupported pattern never ran", w.attempts(&ph), vec![])
}

#[test]
fn patterns_run_where_missing_and_supported_then_as_often_as_their_finding() {
    let (mut w, cells) = pattern_world();
    let supported = |c: &Cell| *c != cells[3];
    w.campaign(&supported).patterns();
    w.campaign(&supported).verify();
    check_patterns(&w, cells).unwrap();
}

#[test]
fn patterns_twin_unsupported_or_unverified_patterns_are_caught() {
    let (mut w, cells) = pattern_world();
    w.campaign(&all).patterns();
    w.campaign(&all).verify();
    assert!(check_patterns(&w, cells).is_err(), "a pattern the device cannot run");
    let (mut w, cells) = pattern_world();
    let supported = |c: &Cell| *c != cells[3];
    w.campaign(&supported).patterns();
    assert!(check_patterns(&w, cells).is_err(), "no verifying repeats");
}

// ---- GPU-AV ----

/// Two crashes with their controls (literal, passing): the first passes under GPU-AV (seen once,
/// so even the cap of passes is inconclusive), the second still crashes.
fn gpu_av_world() -> (World, [Cell; 4]) {
    let (f, fc) = (
        cell(Stage::ClosestHit, IndexSource::Dynamic),
        cell(Stage::ClosestHit, IndexSource::Literal),
    );
    let (g, gc) =
        (cell(Stage::Raygen, IndexSource::Dynamic), cell(Stage::Raygen, IndexSource::Literal));
    let script = Script::default()
        .with(f, &[Outcome::Crash])
        .with(g, &[Outcome::Crash])
        .under_gpu_av(g, &[Outcome::Crash]);
    let mut w = world(&[f, fc, g, gc], script);
    w.campaign(&all).matrix(&[f, fc, g, gc]);
    w.oracle.batches.clear();
    (w, [f, fc, g, gc])
}

const LAYER: Option<u32> = Some(ash::vk::make_api_version(0, 1, 4, 363));

fn check_gpu_av(w: &World, [f, fc, g, gc]: [Cell; 4]) -> Result<(), String> {
    let needed =
        gpu_av::passes_needed(w.report().cells.iter().find(|c| c.cell == f).ok_or("no finding")?)
            as usize;
    let (first, more) = w.oracle.batches.split_first().ok_or("no batch")?;
    same_batches(std::slice::from_ref(first), &[(Mode::GpuAv, vec![f, fc, g, gc])])?;
    same_batches(more, &vec![(Mode::GpuAv, vec![f]); needed - 1])?;
    [f, fc, g, gc]
        .iter()
        .try_for_each(|c| expect("own attempts, untouched by GPU-AV", w.attempts(c).len(), 1))?;
    let verdict = |c: &Cell| {
        w.report()
            .cells
            .iter()
            .find(|x| x.cell == *c)
            .and_then(|x| x.gpu_av.as_ref())
            .map(|r| (r.verdict, r.attempts as usize))
    };
    expect("inconclusive finding", verdict(&f), Some((GpuAvVerdict::Inconclusive, needed)))?;
    expect("finding that still faults", verdict(&g), Some((GpuAvVerdict::StillFaults, 1)))
}

#[test]
fn gpu_av_runs_findings_next_to_controls_apart_and_repeats_passes_until_enough() {
    let (mut w, cells) = gpu_av_world();
    w.campaign(&all).gpu_av(LAYER);
    check_gpu_av(&w, cells).unwrap();
    assert_eq!(
        w.counts.scheduled.get() + 4,
        w.counts.ended.get(),
        "the progress ends full (the matrix's 4 are the run's to count)"
    );
}

#[test]
fn gpu_av_twin_attempts_recorded_as_the_cells_own_are_caught() {
    let (mut w, cells) = gpu_av_world();
    let (again, _) = gpu_av::schedule(w.report(), LAYER);
    w.campaign(&all).round("test", &again, Mode::GpuAv);
    assert!(check_gpu_av(&w, cells).is_err());
}

// ---- a whole run: the order, canaries last ----

/// A steady crash (masked under GPU-AV), its control, a pass, and a canary.
fn full_world() -> (World, Vec<Cell>, Vec<Cell>) {
    let (f, fc, p) = (
        cell(Stage::ClosestHit, IndexSource::Dynamic),
        cell(Stage::ClosestHit, IndexSource::Literal),
        cell(Stage::Raygen, IndexSource::Literal),
    );
    let canary = Cell::canary(Canary::InvalidAddress);
    let w = world(
        &[f, fc, p, canary],
        Script::default().with(f, &[Outcome::Crash]).with(canary, &[Outcome::Crash]),
    );
    (w, vec![f, fc, p], vec![canary])
}

fn full() -> Policy {
    Policy {
        confirm: true,
        repeat: Some(3),
        workarounds: true,
        gpu_av: Some(LAYER),
        mutants: Some(MutantPolicy { mutants: vec![Mutant::ValueBits], sample: None }),
    }
}

/// The rounds each batch belongs to, in order, repeats of one round folded.
fn rounds_of(batches: &[(Mode, Vec<Cell>)]) -> Vec<&'static str> {
    let mut out: Vec<&'static str> = Vec::new();
    for (i, (mode, cells)) in batches.iter().enumerate() {
        let patched = cells.iter().any(|c| c.patch.is_some());
        let pattern = cells.iter().any(|c| c.index == IndexSource::DynamicElement);
        let round = match (mode, patched || pattern) {
            _ if cells.iter().any(|c| c.canary.is_some()) => "canaries",
            _ if cells.iter().any(|c| c.mutant.is_some()) => "mutants",
            (Mode::Shared, _) if i == 0 => "matrix",
            (Mode::Shared, _) if patched => "workarounds",
            (Mode::Shared, _) => "patterns",
            (Mode::Alone, false) => "again",
            (Mode::Alone, true) => "verify",
            (Mode::GpuAv, _) => "gpu_av",
        };
        if out.last() != Some(&round) {
            out.push(round);
        }
    }
    out
}

fn check_order(w: &World) -> Result<(), String> {
    expect(
        "rounds",
        rounds_of(&w.oracle.batches),
        vec![
            "matrix",
            "again",
            "workarounds",
            "patterns",
            "verify",
            "mutants",
            "gpu_av",
            "canaries",
        ],
    )?;
    let (last, rest) = w.oracle.batches.split_last().ok_or("no batch")?;
    expect(
        "the last batch",
        (last.0, last.1.iter().all(|c| c.canary.is_some())),
        (Mode::Shared, true),
    )?;
    expect(
        "canaries before the last batch",
        rest.iter().any(|(_, c)| c.iter().any(|c| c.canary.is_some())),
        false,
    )
}

#[test]
fn a_run_makes_its_rounds_in_order_and_canaries_last() {
    let (mut w, cells, canaries) = full_world();
    w.campaign(&all).run(&full(), &cells, &canaries);
    check_order(&w).unwrap();
    let attempts = w.oracle.batches.iter().map(|(_, c)| c.len() as u64).sum::<u64>();
    assert_eq!(
        (w.counts.scheduled.get(), w.counts.ended.get()),
        (attempts, attempts),
        "the progress ends full"
    );
    let f = w.report().cells.iter().find(|c| c.cell == cells[0]).unwrap();
    assert!(
        f.recommended.is_some() && !f.workarounds.is_empty(),
        "findings are annotated at the end"
    );
    assert_eq!(w.report().undetected_canaries().count(), 0);
}

#[test]
fn run_twin_canaries_with_the_matrix_are_caught() {
    let (mut w, cells, canaries) = full_world();
    w.campaign(&all).run(&full(), &[canaries, cells].concat(), &[]);
    assert!(check_order(&w).is_err());
}

#[test]
fn an_oracle_that_runs_nothing_ends_every_round() {
    let (mut w, cells, canaries) = full_world();
    let f = cells[0];
    w.rec.writer.record(&f, Attempt::for_tests(Outcome::Crash, false));
    let mut deaf = Deaf(0);
    Campaign { oracle: &mut deaf, rec: &mut w.rec, supported: &all, applies: &applies }.run(
        &full(),
        &cells,
        &canaries,
    );
    // The matrix, the confirmation, one repeat, the workarounds, the pattern, one GPU-AV batch
    // and the canaries: no round asks again after a batch that added nothing.
    assert_eq!(deaf.0, 7);
}

#[test]
fn a_halt_ends_the_run_in_any_round() {
    // Where each round's first batch is, from a run that does not halt.
    let (mut w, cells, canaries) = full_world();
    w.campaign(&all).run(&full(), &cells, &canaries);
    assert_eq!(w.rec.halted, None);
    let gpu_av = w.oracle.batches.iter().position(|(m, _)| *m == Mode::GpuAv).unwrap();
    for at in [0, 1, gpu_av] {
        let (mut w, cells, canaries) = full_world();
        let script = Script::default().with(cells[0], &[Outcome::Crash]);
        let mut halting = Halting(script, at);
        Campaign { oracle: &mut halting, rec: &mut w.rec, supported: &all, applies: &applies }.run(
            &full(),
            &cells,
            &canaries,
        );
        assert_eq!(halting.0.batches.len(), at + 1, "nothing runs after the halt (batch {at})");
        assert_eq!(w.rec.halted, Some(Halt::NoShaderCompiler));
        assert!(w.attempts(&canaries[0]).is_empty(), "not even the canaries");
    }
    // In the matrix: the cells after the halting one stay without an attempt, for `--resume`.
    let (mut w, cells, canaries) = full_world();
    let mut halting = Halting(Script::default(), 0);
    Campaign { oracle: &mut halting, rec: &mut w.rec, supported: &all, applies: &applies }.run(
        &full(),
        &cells,
        &canaries,
    );
    assert_eq!(w.attempts(&cells[0]), [Outcome::Pass]);
    assert!(cells[1..].iter().all(|c| w.attempts(c).is_empty()));
}

#[test]
fn the_policy_follows_the_options() {
    let mut o = crate::model::report::RunOptions::for_tests();
    o.repeat = Some(5);
    let p = Policy::of(&o, || panic!("the layer is asked only under GPU-AV"));
    assert_eq!(
        p,
        Policy { confirm: true, repeat: Some(5), workarounds: true, gpu_av: None, mutants: None }
    );
    o.confirm = false;
    assert!(!Policy::of(&o, || None).confirm, "--no-confirm confirms nothing");
    o.confirm = true;
    o.isolation = crate::model::Isolation::ProcessPerCell;
    o.patches = crate::model::PatchMode::None;
    o.gpu_av = true;
    o.mutants = vec![Mutant::IndexZero, Mutant::ValueBits];
    o.mutants_sample = Some("5:9".into());
    let sample = Some(crate::report::mutants::Sample { n: 5, seed: 9 });
    assert_eq!(
        Policy::of(&o, || None),
        Policy {
            confirm: false,
            repeat: Some(5),
            workarounds: false,
            gpu_av: Some(None),
            mutants: Some(MutantPolicy { mutants: o.mutants.clone(), sample }),
        }
    );
}

#[test]
fn the_recorder_saves_a_fault_at_once() {
    let (mut w, cells, _) = full_world();
    w.campaign(&all).matrix(&cells[..1]);
    let saved = std::fs::read_to_string(&w.rec.writer.path).unwrap();
    assert!(saved.contains(&cells[0].id()) && saved.contains("\"crash\""), "{saved}");
    assert!(w.rec.save_error.is_none());
}

// ---- mutants ----

/// Three cells: `a` passes (its index-zero mutant is killed, its value-bits mutant survives), `b`
/// mismatches, `c` passes with a literal index (index-zero equivalent, its value-bits mutant
/// crashes).
fn mutants_world() -> (World, [Cell; 3]) {
    let (a, b, c) = (
        cell(Stage::ClosestHit, IndexSource::Dynamic),
        cell(Stage::Raygen, IndexSource::Dynamic),
        cell(Stage::Raygen, IndexSource::Literal),
    );
    let m = |x: Cell, k: Mutant| Cell { mutant: Some(k), ..x };
    let script = Script::default()
        .with(b, &[Outcome::Mismatch])
        .with(m(a, Mutant::IndexZero), &[Outcome::Mismatch])
        .with(m(c, Mutant::ValueBits), &[Outcome::Crash]);
    let mut w = world(&[a, b, c], script);
    w.campaign(&all).matrix(&[a, b, c]);
    (w, [a, b, c])
}

fn policy() -> MutantPolicy {
    MutantPolicy {
        mutants: vec![Mutant::IndexZero, Mutant::SamplerNext, Mutant::ValueBits],
        sample: None,
    }
}

/// One shared batch of exactly the applicable pairs of the passing cells; the cells' own
/// attempts untouched (no mutant cell in the report's cells); each pair's verdict.
fn check_mutants(w: &World, [a, b, c]: [Cell; 3]) -> Result<(), String> {
    let m = |x: Cell, k: Mutant| Cell { mutant: Some(k), ..x };
    same_batches(
        &w.oracle.batches[1..],
        &[(
            Mode::Shared,
            vec![m(a, Mutant::IndexZero), m(a, Mutant::ValueBits), m(c, Mutant::ValueBits)],
        )],
    )?;
    expect("cells in the report", w.report().cells.len(), 3)?;
    for x in [a, b, c] {
        expect(&x.id(), w.attempts(&x).len(), 1)?;
    }
    expect("findings", w.report().tally.findings, 1)?;
    let r = w.report().mutants.as_ref().ok_or("no kill matrix")?;
    let status = |x: Cell, k: Mutant| {
        r.entries
            .iter()
            .find(|e| e.cell == x.id() && e.mutant == k)
            .map(|e| (e.status, e.probe_defect))
    };
    use MutantStatus::*;
    let want = [
        (a, Mutant::IndexZero, Killed, false),
        (a, Mutant::SamplerNext, NoTarget, false),
        (a, Mutant::ValueBits, Survived, true),
        (b, Mutant::IndexZero, NotRun, false),
        (b, Mutant::SamplerNext, NoTarget, false),
        (c, Mutant::IndexZero, Equivalent, false),
        (c, Mutant::ValueBits, Fault, false),
    ];
    for (x, k, st, defect) in want {
        expect(&format!("{} × {}", x.id(), k.as_str()), status(x, k), Some((st, defect)))?;
    }
    expect("entries", r.entries.len(), 9)?;
    let z = &r.counts["index-zero"];
    expect("index-zero counts", (z.applicable, z.killed, z.equivalent, z.not_run), (1, 1, 1, 1))?;
    let v = &r.counts["value-bits"];
    expect("value-bits counts", (v.applicable, v.survived, v.probe_defects, v.faults), (2, 1, 1, 1))
}

#[test]
fn mutants_run_each_applicable_pair_apart_and_fill_the_kill_matrix() {
    let (mut w, cells) = mutants_world();
    w.campaign(&all).mutants(&policy());
    check_mutants(&w, cells).unwrap();
    let scheduled = w.oracle.batches.iter().map(|(_, c)| c.len() as u64).sum::<u64>();
    assert_eq!(w.counts.scheduled.get(), scheduled - 3, "the round counts its own attempts");
}

#[test]
fn mutants_twin_recording_mutant_attempts_as_cells_or_running_every_pair_is_caught() {
    // A round that records its attempts among the cells' own.
    let (mut w, cells) = mutants_world();
    let run: Vec<Cell> = [Mutant::IndexZero, Mutant::ValueBits]
        .iter()
        .flat_map(|k| [cells[0], cells[2]].map(|c| Cell { mutant: Some(*k), ..c }))
        .collect();
    w.campaign(&all).round("test", &run, Mode::Shared);
    w.campaign(&all).mutants(&MutantPolicy { mutants: vec![], sample: None });
    assert!(check_mutants(&w, cells).is_err());
    // A round that ignores the reference (runs the equivalent pair too).
    let (mut w, cells) = mutants_world();
    let every = |_: &Cell| {
        Ok(MutantPrediction { differing: 1, caught: 1, from_lanes: false, caught_by_heuristic: 0 })
    };
    Campaign { oracle: &mut w.oracle, rec: &mut w.rec, supported: &all, applies: &every }
        .mutants(&policy());
    assert!(check_mutants(&w, cells).is_err());
}

#[test]
fn a_mutants_sample_runs_n_pairs_chosen_by_its_seed() {
    let run = |seed: u64| {
        let (mut w, _) = mutants_world();
        let sample = Some(crate::report::mutants::Sample { n: 1, seed });
        w.campaign(&all).mutants(&MutantPolicy { sample, ..policy() });
        let batch = w.oracle.batches[1].1.clone();
        (batch, w.report().mutants.clone().unwrap())
    };
    let (one, r) = run(7);
    assert_eq!(one.len(), 1);
    assert_eq!(run(7).0, one, "the same seed picks the same pair");
    assert!((1..40).any(|s| run(s).0 != one), "another seed picks another pair");
    // The matrix holds the sampled cell's pairs only.
    assert!(r.entries.iter().all(|e| e.cell == one[0].unmutated().id()));
}

#[test]
fn a_halt_in_the_mutants_round_keeps_what_came_back_and_says_the_rest_did_not_run() {
    let (w, cells) = mutants_world();
    let World { _dir, oracle, mut rec, counts: _ } = w;
    // Batch 1 (the mutants round's) halts after its first pair.
    let mut halting = Halting(oracle, 1);
    Campaign { oracle: &mut halting, rec: &mut rec, supported: &all, applies: &applies }
        .mutants(&policy());
    let r = rec.writer.report.mutants.as_ref().unwrap();
    let ran: Vec<_> = r.entries.iter().filter(|e| e.outcome.is_some()).collect();
    assert_eq!(ran.len(), 1, "the first pair's verdict was recorded as it came");
    let not_run: Vec<_> = r
        .entries
        .iter()
        .filter(|e| e.status == MutantStatus::NotRun && e.why.contains("no attempt came back"))
        .collect();
    assert_eq!(not_run.len(), 2, "{:?}", r.entries);
    assert_eq!(rec.halted, Some(Halt::NoShaderCompiler));
    // Saved: the report on disk has the kill matrix so far.
    let saved = std::fs::read_to_string(&rec.writer.path).unwrap();
    assert!(saved.contains("\"mutants\"") && saved.contains(&cells[0].id()), "{saved}");
}
