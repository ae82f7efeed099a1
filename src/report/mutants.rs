//! The kill matrix of `run --mutants`: which (cell, mutant) pairs run ([`schedule`]: every cell
//! that ran and passed, each mutant that can apply to it; an optional seeded sample for CI), and
//! each pair's verdict ([`verdict`]): **killed** (a `mismatch`), **survived** (a pass: a *probe
//! defect* where the reference, run with the same mutation, says the comparison must flag it;
//! *allowed* with the spec rule where the cell's read is undefined and its lenient rule accepts
//! what the mutant read), **not applicable** (no target in the probe, or equivalent: the
//! reference predicts the same records), **fault** (a crash, device loss or timeout: reported
//! apart, never a kill) or **not run**. Mutant attempts never join a cell's own attempts.
use crate::model::mutant::MutantCounts;
use crate::model::{
    Attempt, Cell, Mutant, MutantEntry, MutantPrediction, MutantReport, MutantStatus, Outcome,
    RunReport, SceneParams, NO_NONUNIFORM_VUID,
};
use crate::probe::spec::{ProbeSpec, ReadIndex};
use crate::reference::{SceneReference, Undefined};
use crate::scene::Scene;

/// Whether a mutant can apply to a cell, before anything ran: `Err(why)` when the probe has
/// nothing it rewrites, else the reference's prediction (`differing == 0`: equivalent).
pub type Applies<'a> = &'a dyn Fn(&Cell) -> Result<MutantPrediction, String>;

/// The CLI's [`Applies`]: the run's scene traced on the CPU once, each mutant cell's site
/// (`mutants::site`) and the reference's prediction before the run
/// (`reference::mutant_before_run`, judged as its shape says).
pub struct Prefilter {
    scene: Scene,
    sref: SceneReference,
}

impl Prefilter {
    /// The run's scene (a `--scene` file loaded again: its one-line error) traced on the CPU.
    pub fn new(params: &SceneParams) -> Result<Prefilter, crate::scene::gltf::LoadError> {
        let scene = Scene::of(params)?;
        let sref = SceneReference::compute(&scene);
        Ok(Prefilter { scene, sref })
    }

    /// Whether mutant cell `c` can apply ([`Applies`]).
    pub fn applies(&self, c: &Cell) -> Result<MutantPrediction, String> {
        let m = c.mutant.ok_or("not a mutant cell")?;
        let spec = ProbeSpec::of(c);
        let slots = crate::probe::slot_count(spec.resource, self.scene.params.instances);
        let site = crate::mutants::site(&spec, m, slots)?;
        let undefined = Undefined { descriptor: spec.read == ReadIndex::Undefined };
        let world = (&self.scene, &self.sref);
        Ok(crate::reference::mutant_before_run(&c.unmutated(), world, undefined, site))
    }
}

/// `--mutants-sample N:SEED`: run N of the applicable pairs, chosen by a hash of their id and SEED.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Sample {
    pub n: usize,
    pub seed: u64,
}

impl Sample {
    /// `N` or `N:SEED` (seed 1 by default).
    pub fn parse(s: &str) -> Result<Sample, String> {
        let (n, seed) = s.split_once(':').unwrap_or((s, "1"));
        let bad = || format!("--mutants-sample {s:?} is not N[:SEED] (e.g. 40:7)");
        let n: usize = n.trim().parse().map_err(|_| bad())?;
        let seed: u64 = seed.trim().parse().map_err(|_| bad())?;
        if n == 0 {
            return Err(format!("--mutants-sample {s:?}: N must be at least 1"));
        }
        Ok(Sample { n, seed })
    }

    fn key(&self, id: &str) -> u64 {
        // FNV-1a of the id, mixed with the seed (splitmix64): stable across releases.
        let mut h = 0xcbf2_9ce4_8422_2325u64;
        for b in id.bytes() {
            h = (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
        }
        let mut z = h ^ self.seed.wrapping_mul(0x9e37_79b9_7f4a_7c15);
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
}

fn entry(cell: &Cell, mutant: Mutant, status: MutantStatus, why: impl Into<String>) -> MutantEntry {
    MutantEntry {
        cell: cell.id(),
        mutant,
        status,
        why: why.into(),
        outcome: None,
        prediction: None,
        probe_defect: false,
        allowed_by: None,
        wall_ms: 0.0,
    }
}

/// What to run: the mutant cells (with the reference's prediction before the run), and the
/// entries decided without running (no target, equivalent, the device cannot, the cell itself
/// did not pass). Cells are the report's probe cells (no canary, no workaround variant) that
/// ran, in report order; `done`: pairs of a resumed run's matrix, not again.
pub fn schedule(
    report: &RunReport,
    mutants: &[Mutant],
    sample: Option<Sample>,
    (applies, supported): (Applies, &dyn Fn(&Cell) -> bool),
) -> (Vec<(Cell, MutantPrediction)>, Vec<MutantEntry>) {
    let done: std::collections::HashSet<(String, Mutant)> = report
        .mutants
        .iter()
        .flat_map(|r| r.entries.iter().map(|e| (e.cell.clone(), e.mutant)))
        .collect();
    let mut run = vec![];
    let mut decided = vec![];
    let cells = report.cells.iter().filter(|c| {
        c.cell.canary.is_none()
            && c.cell.patch.is_none()
            && c.cell.mutant.is_none()
            && c.attempts.iter().any(|a| !a.not_run())
    });
    for c in cells {
        for &m in mutants.iter().filter(|m| !done.contains(&(c.id.clone(), **m))) {
            let mc = Cell { mutant: Some(m), ..c.cell };
            match applies(&mc) {
                Err(why) => decided.push(entry(&c.cell, m, MutantStatus::NoTarget, why)),
                Ok(p) if !p.applicable() => decided.push(MutantEntry {
                    prediction: Some(p),
                    ..entry(&c.cell, m, MutantStatus::Equivalent, equivalent_why(m))
                }),
                Ok(_) if c.outcome != Outcome::Pass => decided.push(entry(&c.cell, m, MutantStatus::NotRun, format!("the cell itself did not pass ({}): a kill could not be told from its own fault", c.outcome.as_str()))),
                Ok(_) if !supported(&mc) => decided.push(entry(&c.cell, m, MutantStatus::NotRun, unsupported_why(m, &c.cell))),
                Ok(p) => run.push((mc, p)),
            }
        }
    }
    if let Some(s) = sample {
        run.sort_by_key(|(c, _)| s.key(&c.id()));
        run.truncate(s.n);
        let order: std::collections::HashMap<String, usize> =
            report.cells.iter().enumerate().map(|(i, c)| (c.id.clone(), i)).collect();
        run.sort_by_key(|(c, _)| (order.get(&c.unmutated().id()).copied(), c.mutant));
        // Only the sampled pairs' cells keep their decided entries: the matrix is the sample's.
        let kept: std::collections::HashSet<String> =
            run.iter().map(|(c, _)| c.unmutated().id()).collect();
        decided.retain(|e| kept.contains(&e.cell));
    }
    (run, decided)
}

/// Why mutant `m` is equivalent before the run: for a broadcast, the cell's data select one
/// descriptor index on every checked pixel, so lane 0's index for all lanes cannot be told from
/// each lane's own (undiscriminating here, never counted killed).
fn equivalent_why(m: Mutant) -> &'static str {
    match m {
        Mutant::IndexBroadcast => "undiscriminating: every checked pixel selects the same descriptor index, so lane 0's index for all lanes reads what each lane reads (the scene's data cannot tell this mutant apart)",
        Mutant::IndexZero
        | Mutant::IndexNext
        | Mutant::BaseDropped
        | Mutant::ElementZero
        | Mutant::StrideDouble
        | Mutant::SamplerNext
        | Mutant::TlasOther
        | Mutant::ValueBits => "the reference predicts the same records on every checked pixel",
    }
}

/// Why the device cannot run mutant `m` on `cell` (its support is `caps::support::mutant`'s).
fn unsupported_why(m: Mutant, cell: &Cell) -> String {
    match m {
        Mutant::IndexBroadcast => format!("the device lists no subgroup ballot in {} ({}): no broadcast there, and no lane evidence to predict it", cell.stage, crate::model::lanes::SUBGROUP_STAGE_VUID),
        Mutant::IndexZero
        | Mutant::IndexNext
        | Mutant::BaseDropped
        | Mutant::ElementZero
        | Mutant::StrideDouble
        | Mutant::SamplerNext
        | Mutant::TlasOther
        | Mutant::ValueBits => "the device cannot run this mutant (`rtprobe caps`, axis mutant)".into(),
    }
}

/// The verdict of mutant `m` of `cell` (its unmutated cell), predicted `before` the run, from
/// its `attempt` (`None`: none came back).
pub fn verdict(
    (cell, m): (&Cell, Mutant),
    before: MutantPrediction,
    attempt: Option<&Attempt>,
) -> MutantEntry {
    let base = cell.unmutated();
    let Some(a) = attempt else {
        return MutantEntry {
            prediction: Some(before),
            ..entry(
                &base,
                m,
                MutantStatus::NotRun,
                "no attempt came back (the run stopped, or no worker could run it)",
            )
        };
    };
    let cmp = a.result.as_ref().and_then(|r| r.comparison.as_ref());
    let prediction = cmp.and_then(|c| c.mutant).unwrap_or(before);
    let detail = a.detail.clone().unwrap_or_else(|| a.outcome.as_str().to_string());
    let status = if a.not_run() {
        MutantStatus::NotRun
    } else {
        match a.outcome {
            Outcome::Mismatch => MutantStatus::Killed,
            Outcome::Pass if !prediction.applicable() => MutantStatus::Equivalent,
            Outcome::Pass => MutantStatus::Survived,
            Outcome::DeviceLost | Outcome::Crash | Outcome::Timeout => MutantStatus::Fault,
            Outcome::Error | Outcome::Unsupported | Outcome::NotImplemented => MutantStatus::NotRun,
        }
    };
    let survived = status == MutantStatus::Survived;
    // Only pixels judged exactly bind the driver: where the cell's read is undefined the mutated
    // read is undefined too (no NonUniform on it either), whatever the reference predicted.
    let probe_defect = survived && prediction.caught_exactly() > 0;
    let allowed_by = (survived && !probe_defect).then(|| {
        cmp.and_then(|c| c.element_reads.as_ref())
            .map(|r| r.outside_spec.clone())
            .unwrap_or_else(|| NO_NONUNIFORM_VUID.to_string())
    });
    let why = match status {
        MutantStatus::Survived if probe_defect => format!("PROBE DEFECT: the reference predicts {} of {} differing pixels the comparison must flag, and it flagged none", prediction.caught_exactly(), prediction.differing),
        MutantStatus::Survived if prediction.caught_by_heuristic > 0 => format!("allowed: the spec leaves this read undefined ({}), and the mutated read too (no NonUniform on it either): a per-lane read of it would be caught on {} of {} differing pixels, but the driver may read through any lane's index, and rtprobe's lenient rule (an index another lane of the subgroup computed) accepted what it read", allowed_by.as_deref().unwrap_or(""), prediction.caught_by_heuristic, prediction.differing),
        MutantStatus::Survived => format!("allowed: the spec leaves this read undefined ({}); rtprobe's lenient rule for it (an index another lane computed) accepts what the mutant read on all {} differing pixels", allowed_by.as_deref().unwrap_or(""), prediction.differing),
        MutantStatus::Equivalent => "undiscriminating: the device's lane evidence shows every subgroup computed one descriptor index, so the reference predicts the same records".into(),
        MutantStatus::Killed
        | MutantStatus::Fault
        | MutantStatus::NotRun
        | MutantStatus::NoTarget => detail,
    };
    MutantEntry {
        outcome: Some(a.outcome),
        prediction: Some(prediction),
        probe_defect,
        allowed_by,
        wall_ms: a.wall_ms,
        ..entry(&base, m, status, why)
    }
}

/// One verdict into the report's kill matrix as its attempt comes back (counted; [`annotate`]
/// orders the matrix at the round's end).
pub fn record(report: &mut RunReport, e: MutantEntry) {
    let r = report.mutants.get_or_insert_with(MutantReport::default);
    r.entries.push(e);
    r.recount();
}

/// The kill matrix into the report: `entries` added to what a resumed run had, in report order
/// (mutants in `Mutant::ALL` order), counted; `wall_ms` added.
pub fn annotate(
    report: &mut RunReport,
    mutants: &[Mutant],
    sample: Option<&str>,
    entries: Vec<MutantEntry>,
    wall_ms: f64,
) {
    let order: std::collections::HashMap<String, usize> =
        report.cells.iter().enumerate().map(|(i, c)| (c.id.clone(), i)).collect();
    let r = report.mutants.get_or_insert_with(MutantReport::default);
    r.mutants = mutants.to_vec();
    r.sample = sample.map(String::from);
    r.wall_ms += wall_ms;
    r.entries.extend(entries);
    r.entries.sort_by_key(|e| (order.get(&e.cell).copied().unwrap_or(usize::MAX), e.mutant));
    r.recount();
}

/// The terminal summary's lines: per mutant applicable / killed / survived / equivalent / no
/// target / faults, each probe defect loudly, and the survivors the spec allows with their rule.
pub fn render(r: &MutantReport) -> String {
    let t = r.total();
    let mut s = format!(
        "mutants: {} pairs, {} applicable: {} killed, {} survived ({} allowed by the spec, {} probe defects), {} faults; not applicable: {} equivalent, {} no target; {} not run ({:.1} s)\n",
        t.cells, t.applicable, t.killed, t.survived, t.allowed, t.probe_defects, t.faults, t.equivalent, t.no_target, t.not_run, r.wall_ms / 1e3
    );
    for m in &r.mutants {
        let c = r.counts.get(m.as_str()).cloned().unwrap_or_default();
        s += &format!("  {:<16} {}\n", m.as_str(), counts_line(&c));
    }
    for e in r.probe_defects() {
        s += &format!("  ❗ PROBE DEFECT {} × {}: {}\n", e.cell, e.mutant.as_str(), e.why);
    }
    let allowed = r.entries.iter().filter(|e| e.allowed_by.is_some()).count();
    if allowed > 0 {
        let rule = r.entries.iter().find_map(|e| e.allowed_by.clone()).unwrap_or_default();
        s += &format!("  {allowed} survivors in cells whose read is undefined ({rule}): allowed there, listed in the report\n");
    }
    s
}

/// `applicable 12: killed 12, survived 0; equivalent 3, no target 40`
fn counts_line(c: &MutantCounts) -> String {
    let rate = c
        .kill_rate()
        .map(|r| format!(" ({:.0}% of what must be caught)", 100.0 * r))
        .unwrap_or_default();
    format!(
        "applicable {}: killed {}{rate}, survived {} (allowed {}, probe defects {}), faults {}; equivalent {}, no target {}, not run {}",
        c.applicable, c.killed, c.survived, c.allowed, c.probe_defects, c.faults, c.equivalent, c.no_target, c.not_run
    )
}

#[cfg(test)]
mod tests;
