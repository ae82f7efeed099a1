//! `rtprobe bisect`: from a run report with faults to the minimal description of the fault — a
//! 1-minimal conjunction (ddmin's guarantee: no term can be dropped) of `axis=value[|value…]`
//! terms (the `--inject-fault` predicate syntax) that holds for every faulting cell of the scope
//! and for no passing one.
//!
//! How ([`Bisector::bisect`]):
//! 1. Every verdict the report already has is used; a cell's verdict is its worst attempt, with
//!    "k of N" ([`Verdicts`]).
//! 2. **Flaky faults.** Every verdict is held to a bound, per cell. A faulting cell that faulted
//!    k of N has fault rate `p >= x` at 95%, `x` its one-sided Clopper–Pearson lower bound
//!    ([`confidence`]). A pass bisection relies on (the cell that refuses a wider conjunction, a
//!    sibling in the isolation list, a workaround) is held to one faulting cell — the region's
//!    best-evidenced one, or the minimal failing cell — and counts only when a fault of rate `x`
//!    would have missed all its N attempts with probability `(1 - x)^N` below `max_miss`
//!    (default 1%). Both are repeated, each alone in a fresh worker: the faulting cell until it
//!    has as many attempts as a pass then needs, the pass until it reaches the threshold or
//!    faults. A pass still above the threshold at the attempt cap (or offline) is not concluded
//!    on: it is listed as unsettled and the result says so. A fault is never reversed (the worst
//!    attempt wins). Passes nothing relies on are not repeated.
//! 3. The tightest conjunction holding for every faulting cell has, per axis, exactly the values
//!    the faulting cells have. If it already contains a passing cell, no conjunction separates
//!    the cells (every conjunction that holds for the faulting cells contains it): bisection says
//!    so and builds a disjunction instead (greedy cover: each conjunction grown over as many
//!    uncovered faulting cells as it can without taking in a pass, then reduced like the single
//!    one; small, not proven smallest).
//! 4. Terms that do not restrict the scope are dropped; then ddmin ([`ddmin`]) drops every term
//!    it can: a wider conjunction is kept when no cell of the scope in it passes. Cells in it
//!    without a verdict are run (in small batches, stopping at the first pass); when that turns
//!    up a faulting cell outside the conjunction, bisection starts over with it.
//! 5. Cells rtprobe could not run (`error`) are evidence of nothing: neither faulting nor
//!    passing; they are listed. So is evidence rtprobe itself doubts ([`Doubt`]): a fault of a
//!    read the spec leaves undefined (`model::NO_NONUNIFORM_VUID`) and a lenient pass that a
//!    faulting sibling makes suspect.
//! 6. The isolation list: the minimal failing cell and, per axis, its closest siblings in the
//!    scope (run if unknown); then each workaround patch that applies to it (verified by runs).
//!
//! Injection and the patch axis: `--inject-fault` predicates match the `patch` axis like any
//! other. A predicate with `patch=none` leaves patched cells alone, so every workaround "passes"
//! — a statement about the predicate, not about a driver; a predicate without a `patch` term
//! injects into patched cells too (the injected load survives every SPIR-V patch), so no
//! workaround passes. The workaround lines say when the verdict is decided by the injection.
pub mod ddmin;
pub mod isolation;
mod render;
pub mod scope;
mod verdicts;

pub use render::predicate;
pub use verdicts::{Doubt, State, Verdicts};

use crate::model::inject::for_cell;
use crate::model::registry;
use crate::model::Injection;
use crate::model::IsolationLine;
use crate::model::{Cell, Filter};
use std::collections::HashMap;

/// The axes bisection reduces over: every axis of a cell except `canary`.
pub fn axes() -> impl Iterator<Item = &'static str> {
    registry::AXES.iter().filter(|a| a.id != registry::AxisId::Canary).map(|a| a.name)
}
/// Default: a pass may hide a fault of its faulting cell's rate bound with at most this
/// probability.
pub use crate::model::stats::DEFAULT_MAX_MISS;
/// Default cap on the attempts of one cell.
pub const DEFAULT_MAX_ATTEMPTS: u32 = 50;

/// Runs cells for bisection, as for the run's rounds (`runner::oracle`). The CLI's runs them
/// through the supervisor; an offline one (for `report`, or `bisect --offline`) runs nothing.
pub use crate::runner::oracle::{Event, Mode, Oracle};

/// Runs nothing: bisection uses the report's verdicts alone.
pub struct Offline;

impl Oracle for Offline {
    fn run(&mut self, _: &[Cell], _: Mode, _: &mut dyn FnMut(Event)) {}
    fn can_run(&self) -> bool {
        false
    }
}

#[derive(Clone, Copy, Debug)]
pub struct Settings {
    pub max_miss: f64,
    pub max_attempts: u32,
    /// Cells run per batch while looking for a pass inside a wider conjunction.
    pub batch: usize,
}

impl Default for Settings {
    fn default() -> Self {
        Settings { max_miss: DEFAULT_MAX_MISS, max_attempts: DEFAULT_MAX_ATTEMPTS, batch: 4 }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum BisectError {
    #[error("no cell of the scope has a finding: nothing to bisect")]
    NoFault,
    /// Every finding of the scope is a read the spec leaves undefined: unsettled evidence.
    #[error("the scope's {} are all reads the spec leaves undefined (a dynamic index without nonuniformEXT: VUID-RuntimeSpirv-None-10148, Vulkan 1.4.360), judged by rtprobe's heuristic; bisect and report use only settled evidence, so there is nothing to bisect or file (what such findings show: docs/run.md, \"outside the spec\")", crate::model::plural(*.0, "finding"))]
    OnlyUndefined(usize),
    #[error("--cell {0}: not a faulting cell of the scope")]
    NotFaulting(String),
    /// A run of bisection's halted: no cell can run here, so no evidence can be had.
    #[error("bisection's runs halted: {0:?}")]
    Halted(crate::model::Halt),
}

/// A description with its isolation list and workarounds settled ([`Bisector::settle`]).
struct Settled {
    separable: bool,
    conjunctions: Vec<Filter>,
    /// The faulting cell the isolation list is built around.
    rep: Cell,
    /// Each sibling with the axes it is the sibling for.
    siblings: Vec<(String, Cell)>,
    /// The representative's workaround variants the device supports.
    patched: Vec<Cell>,
}

/// The passes bisection relied on ([`Bisector::reliance`]).
struct Reliance {
    /// The largest miss probability of one of them.
    worst_miss: f64,
    /// The union bound on any of them having missed, capped at 1.
    union_miss: f64,
    /// Those that did not reach the threshold.
    unsettled: Vec<String>,
    /// How many cells they are.
    passes: usize,
}

pub struct Bisector<'o> {
    /// The cells bisection may use, in plan order (all runnable on the device).
    pub scope: Vec<Cell>,
    pub verdicts: Verdicts,
    oracle: &'o mut dyn Oracle,
    settings: Settings,
    inject: Vec<Injection>,
    memo: HashMap<String, bool>,
    /// Passes a refused conjunction rests on, each with the faulting cell it is held to.
    relied: Vec<(Cell, Cell)>,
}

impl<'o> Bisector<'o> {
    pub fn new(
        scope: Vec<Cell>,
        verdicts: Verdicts,
        oracle: &'o mut dyn Oracle,
        settings: Settings,
        inject: Vec<Injection>,
    ) -> Self {
        Bisector {
            scope,
            verdicts,
            oracle,
            settings,
            inject,
            memo: HashMap::new(),
            relied: Vec::new(),
        }
    }

    fn faulting(&self) -> Vec<Cell> {
        self.scope.iter().filter(|c| self.verdicts.state(c) == State::Fault).copied().collect()
    }

    /// Attempts a pass held to faulting cell `fault` needs: `(1 - bound)^N < max_miss`.
    pub fn attempts_needed(&self, fault: &Cell) -> u32 {
        crate::model::stats::attempts_needed(
            self.verdicts.rate_bound(fault),
            self.settings.max_miss,
            self.settings.max_attempts,
        )
    }

    /// The faulting cell of `region` with the highest rate bound (most attempts on a tie): the
    /// fault a conjunction over `region` claims, which its passes are held to.
    fn reference(&self, region: &[Cell]) -> Option<Cell> {
        let mut best: Option<(f64, u32, Cell)> = None;
        for c in region.iter().filter(|c| self.verdicts.state(c) == State::Fault) {
            let (b, n) = (self.verdicts.rate_bound(c), self.verdicts.evidence(c));
            if best.is_none_or(|(bb, bn, _)| b > bb || (b == bb && n > bn)) {
                best = Some((b, n, *c));
            }
        }
        best.map(|(_, _, c)| c)
    }

    /// Run each of `cells` until `done` says it has enough, all of them together per round, each
    /// alone in a fresh worker; a round that adds no attempt (the oracle gave up) ends it.
    fn repeat_until(&mut self, cells: &[Cell], done: &dyn Fn(&Self, &Cell) -> bool) {
        if !self.oracle.can_run() {
            return;
        }
        loop {
            let more: Vec<Cell> = cells
                .iter()
                .filter(|c| {
                    !done(self, c) && self.verdicts.attempts(c) < self.settings.max_attempts
                })
                .copied()
                .collect();
            let before = self.verdicts.runs;
            if more.is_empty() {
                return;
            }
            let verdicts = &mut self.verdicts;
            self.oracle.run(&more, Mode::Alone, &mut |ev| verdicts.on_event(ev));
            if self.verdicts.runs == before {
                return;
            }
        }
    }

    /// Hold each pass of `cells` to faulting cell `fault`: first `fault` is repeated until it has
    /// as many attempts as a pass held to its bound then needs (cheap evidence: one cell), then
    /// every pass is repeated until a fault of that rate would have shown with probability above
    /// `1 - max_miss`, or it faults.
    fn settle_against(&mut self, cells: &[Cell], fault: Cell) {
        self.repeat_until(&[fault], &|b, f| {
            b.verdicts.state(f) != State::Fault || b.verdicts.evidence(f) >= b.attempts_needed(f)
        });
        self.repeat_until(cells, &|b, c| {
            b.verdicts.state(c) != State::Pass
                || b.verdicts.evidence(c) >= b.attempts_needed(&fault)
        });
    }

    /// Run the cells of `cells` without a verdict once (together, as a run would).
    fn run_unknown(&mut self, cells: &[Cell]) {
        let unknown: Vec<Cell> =
            cells.iter().filter(|c| self.verdicts.state(c) == State::Unknown).copied().collect();
        if !unknown.is_empty() && self.oracle.can_run() {
            let verdicts = &mut self.verdicts;
            self.oracle.run(&unknown, Mode::Shared, &mut |ev| verdicts.on_event(ev));
        }
    }

    /// Whether `region` has a pass that stays one when held to the region's fault: its passes,
    /// most attempts first, are settled until one holds (it is relied on) or every one faults.
    fn settled_pass(&mut self, region: &[Cell]) -> bool {
        let mut passes: Vec<Cell> =
            region.iter().filter(|c| self.verdicts.state(c) == State::Pass).copied().collect();
        passes.sort_by_key(|c| std::cmp::Reverse(self.verdicts.evidence(c)));
        for w in passes {
            let against = self.reference(region);
            if let Some(f) = against {
                self.settle_against(&[w], f);
            }
            if self.verdicts.state(&w) == State::Pass {
                if let Some(f) = against.filter(|_| !self.relied.iter().any(|(p, _)| *p == w)) {
                    self.relied.push((w, f));
                }
                return true;
            }
        }
        false
    }

    /// Whether the conjunction contains no passing cell of the scope (running the unknown ones it
    /// contains, in batches, until one passes; every pass found is settled first).
    fn holds(&mut self, f: &Filter) -> bool {
        let key = predicate(f);
        if let Some(v) = self.memo.get(&key) {
            return *v;
        }
        let region: Vec<Cell> = self.scope.iter().filter(|c| f.matches(c)).copied().collect();
        let mut ok = !self.settled_pass(&region);
        if ok {
            let unknown: Vec<Cell> = region
                .iter()
                .filter(|c| self.verdicts.state(c) == State::Unknown)
                .copied()
                .collect();
            if !unknown.is_empty() && !self.oracle.can_run() {
                ok = false; // offline: a conjunction is not widened over cells nobody ran
            }
            for batch in unknown.chunks(self.settings.batch.max(1)) {
                if !ok {
                    break;
                }
                self.run_unknown(batch);
                ok = !self.settled_pass(&region);
            }
        }
        self.memo.insert(key, ok);
        ok
    }

    /// Settle every pass relied on again (its fault's bound may have dropped since); whether one
    /// of them faulted.
    fn resettle(&mut self) -> bool {
        let relied = self.relied.clone();
        for (w, f) in &relied {
            self.settle_against(&[*w], *f);
        }
        let flipped = relied.iter().any(|(w, _)| self.verdicts.state(w) != State::Pass);
        self.relied.retain(|(w, _)| self.verdicts.state(w) == State::Pass);
        flipped
    }

    /// Per axis, the values `cells` have (in scope order).
    fn tight(&self, cells: &[Cell]) -> Filter {
        let mut terms = Vec::new();
        for axis in axes() {
            let mut vals: Vec<String> = Vec::new();
            for c in &self.scope {
                let v = c.axis_value(axis).expect("known axis");
                if !vals.contains(&v)
                    && cells.iter().any(|f| f.axis_value(axis).as_deref() == Some(v.as_str()))
                {
                    vals.push(v);
                }
            }
            terms.push((axis.to_string(), vals));
        }
        Filter { terms }
    }

    /// The values of `axis` in the scope.
    fn scope_values(&self, axis: &str) -> Vec<String> {
        let mut v: Vec<String> = Vec::new();
        for c in &self.scope {
            let x = c.axis_value(axis).expect("known axis");
            if !v.contains(&x) {
                v.push(x);
            }
        }
        v
    }

    /// Drop the terms that do not restrict the scope, then every term ddmin can.
    fn reduce(&mut self, f: Filter) -> Filter {
        // Reversed, so that among equivalent results ddmin keeps the primary axes (as_access=none
        // says resource≠acceleration_structure; nonuniform=true says index=dynamic).
        let mut terms: Vec<(String, Vec<String>)> = f
            .terms
            .into_iter()
            .rev()
            .filter(|(a, v)| self.scope_values(a).iter().any(|x| !v.contains(x)))
            .collect();
        // The optional axes' stand-in values (`base=none`: not a closest-hit dynamic buffer/image
        // cell; `sampler=none`: not a direct sampled image) restate other axes: described without
        // them when that still holds.
        let primary: Vec<(String, Vec<String>)> = terms
            .iter()
            .filter(|(a, _)| registry::axis(a).is_some_and(|d| d.rank == registry::Rank::Primary))
            .cloned()
            .collect();
        if primary.len() < terms.len()
            && self.holds(&Filter { terms: primary.iter().rev().cloned().collect() })
        {
            terms = primary;
        }
        let mut kept = ddmin::ddmin(&terms, &mut |sub| {
            let mut t = sub.to_vec();
            t.reverse();
            self.holds(&Filter { terms: t })
        });
        kept.reverse();
        Filter { terms: kept }
    }

    /// A small disjunction of conjunctions covering `faulting` without a passing cell.
    fn disjunction(&mut self, faulting: &[Cell]) -> Vec<Filter> {
        let mut uncovered: Vec<Cell> = faulting.to_vec();
        let mut out = Vec::new();
        while let Some(seed) = uncovered.first().copied() {
            let mut members = vec![seed];
            for g in uncovered.iter().skip(1) {
                let mut with = members.clone();
                with.push(*g);
                let t = self.tight(&with);
                if self.holds(&t) {
                    members = with;
                }
            }
            let c = self.tight(&members);
            let c = if self.holds(&c) { self.reduce(c) } else { c };
            uncovered.retain(|x| !c.matches(x));
            out.push(c);
        }
        out
    }

    /// Whether every faulting cell of the scope matches one of `cs`.
    fn covers(&self, cs: &[Filter]) -> bool {
        self.faulting().iter().all(|f| cs.iter().any(|c| c.matches(f)))
    }

    /// The minimal description of the faulting cells: one conjunction when one separates them
    /// from every pass (`true`), else a small disjunction; repeated until the runs made on the way
    /// change nothing.
    fn describe_faults(&mut self) -> Result<(bool, Vec<Filter>), BisectError> {
        loop {
            let start = self.verdicts.runs;
            let faulting = self.faulting();
            if faulting.is_empty() {
                let undefined = self
                    .scope
                    .iter()
                    .filter(|c| self.verdicts.state(c) == State::Doubtful(Doubt::UndefinedFault))
                    .count();
                return Err(match undefined {
                    0 => BisectError::NoFault,
                    n => BisectError::OnlyUndefined(n),
                });
            }
            let tight = self.tight(&faulting);
            let (separable, cs) = if self.holds(&tight) {
                (true, vec![self.reduce(tight)])
            } else {
                (false, self.disjunction(&faulting))
            };
            // Runs made on the way may have found faulting cells outside, or lowered a fault's
            // bound so that a pass relied on needs more attempts (and then faults): start over (a
            // "holds" stays true, since a fault is never reversed; a pass may turn into a fault).
            let flipped = self.resettle();
            let covered = self.covers(&cs);
            // (A round that ran nothing cannot change anything: the oracle gave up.)
            if (covered && !flipped) || self.verdicts.runs == start {
                return Ok((separable, cs));
            }
            self.memo.retain(|_, holds| *holds);
        }
    }

    /// Find the minimal description, then build the isolation list around `cell` (or the first
    /// faulting cell) and try its workarounds (`patch_supported` says which the device can run).
    pub fn bisect(
        &mut self,
        cell: Option<&str>,
        patch_supported: &dyn Fn(&Cell) -> bool,
    ) -> Result<Bisection, BisectError> {
        let Settled { separable, conjunctions, rep, siblings, patched } =
            self.settle(cell, patch_supported)?;
        if let Some(h) = self.verdicts.halt {
            return Err(BisectError::Halted(h));
        }
        let ev = self.evidence_against(&rep);
        let mut isolation = vec![isolation::line(&rep, None, &self.verdicts, ev)];
        isolation.extend(
            siblings.iter().map(|(axis, c)| isolation::line(c, Some(axis), &self.verdicts, ev)),
        );
        let workarounds: Vec<IsolationLine> =
            patched.iter().map(|c| self.workaround_line(&rep, c, ev)).collect();
        let reliance = self.reliance(siblings.iter().map(|(_, c)| c).chain(&patched), rep);
        let strings: Vec<String> = conjunctions.iter().map(predicate).collect();
        Ok(Bisection {
            separable,
            minimal: strings.join(";"),
            conjunctions: strings,
            representative: rep.id(),
            isolation,
            workarounds,
            fault_rate_bound: Some(self.verdicts.rate_bound(&rep)),
            confidence: crate::model::stats::CONFIDENCE,
            attempts_per_pass: self.attempts_needed(&rep),
            max_miss: self.settings.max_miss,
            worst_miss_probability: reliance.worst_miss,
            union_miss_probability: reliance.union_miss,
            passes_relied_on: reliance.passes,
            unsettled: reliance.unsettled,
            faulting_cells: self.faulting().len(),
            scope_cells: self.scope.len(),
            not_run: self.scope.iter().filter(|c| self.verdicts.state(c) == State::Unknown).count(),
            errored: self
                .scope
                .iter()
                .filter(|c| self.verdicts.state(c) == State::Error)
                .map(|c| c.id())
                .collect(),
            doubtful: self
                .scope
                .iter()
                .filter_map(|c| match self.verdicts.state(c) {
                    State::Doubtful(d) => Some(format!("{} ({})", c.id(), d.why())),
                    State::Fault | State::Pass | State::Error | State::Unknown => None,
                })
                .collect(),
            runs: self.verdicts.runs,
            not_varied: axes()
                .filter(|a| self.scope_values(a).len() < 2)
                .map(String::from)
                .collect(),
        })
    }

    /// The minimal description with its representative's siblings and workarounds run and
    /// settled. Settling them repeats them; one in the scope that faults there is a fault the
    /// description must cover too: then the search starts over (faults are never reversed, so
    /// this ends).
    fn settle(
        &mut self,
        cell: Option<&str>,
        patch_supported: &dyn Fn(&Cell) -> bool,
    ) -> Result<Settled, BisectError> {
        loop {
            let (separable, conjunctions) = self.describe_faults()?;
            let rep = self.representative(cell, &conjunctions)?;
            let siblings = self.siblings(&rep);
            let sib_cells: Vec<Cell> = siblings.iter().map(|(_, c)| *c).collect();
            let patched: Vec<Cell> = rep
                .applicable_patches()
                .into_iter()
                .map(|p| Cell { patch: Some(p), ..rep })
                .filter(|c| patch_supported(c))
                .collect();
            let start = self.verdicts.runs;
            self.run_unknown(&sib_cells);
            self.settle_against(&sib_cells, rep);
            // (Patched variants are in the scope when the report planned them: they count too.)
            self.run_unknown(&patched);
            self.settle_against(&patched, rep);
            if self.covers(&conjunctions) || self.verdicts.runs == start {
                return Ok(Settled { separable, conjunctions, rep, siblings, patched });
            }
            self.memo.retain(|_, holds| *holds);
        }
    }

    /// The faulting cell the isolation list is built around: `cell`, or the first faulting cell
    /// the first conjunction describes.
    fn representative(
        &self,
        cell: Option<&str>,
        conjunctions: &[Filter],
    ) -> Result<Cell, BisectError> {
        let faulting = self.faulting();
        Ok(match cell {
            Some(id) => *faulting
                .iter()
                .find(|c| c.id() == id)
                .ok_or_else(|| BisectError::NotFaulting(id.to_string()))?,
            None => *faulting
                .iter()
                .find(|c| conjunctions[0].matches(c))
                .expect("the first conjunction holds for a faulting cell"),
        })
    }

    /// The evidence a pass held to `fault`'s rate bound gives.
    fn evidence_against(&self, fault: &Cell) -> isolation::Evidence {
        isolation::Evidence {
            against: Some(self.verdicts.rate_bound(fault)),
            max_miss: self.settings.max_miss,
        }
    }

    /// Every pass relied on — the refused conjunctions' and `also`, held to `rep` — and how
    /// likely they are to have missed their fault.
    fn reliance<'c>(&self, also: impl Iterator<Item = &'c Cell>, rep: Cell) -> Reliance {
        let mut relied: Vec<(Cell, Cell)> = self.relied.clone();
        relied.extend(also.map(|c| (*c, rep)));
        relied.retain(|(c, _)| self.verdicts.state(c) == State::Pass);
        let miss_of = |(c, f): &(Cell, Cell)| {
            crate::model::stats::miss(self.verdicts.rate_bound(f), self.verdicts.evidence(c))
        };
        relied.sort_by_key(|(c, f)| (c.id(), f.id()));
        relied.dedup();
        let mut unsettled: Vec<String> = relied
            .iter()
            .filter(|r| miss_of(r) >= self.settings.max_miss)
            .map(|(c, _)| c.id())
            .collect();
        unsettled.sort();
        unsettled.dedup();
        let mut ids: Vec<String> = relied.iter().map(|(c, _)| c.id()).collect();
        ids.sort();
        ids.dedup();
        Reliance {
            worst_miss: relied.iter().map(miss_of).fold(0.0, f64::max),
            union_miss: relied.iter().map(miss_of).sum::<f64>().min(1.0),
            unsettled,
            passes: ids.len(),
        }
    }

    /// Per axis, per other value, the scope cell closest to `rep` (fewest other axes changed, at
    /// most one more: `index` drags `nonuniform` along, `resource` drags `as_access`), each cell
    /// once (with every axis it is the sibling for).
    fn siblings(&self, rep: &Cell) -> Vec<(String, Cell)> {
        let mut out: Vec<(String, Cell)> = Vec::new();
        for axis in axes() {
            let mine = rep.axis_value(axis);
            for v in self.scope_values(axis) {
                if Some(&v) == mine.as_ref() {
                    continue;
                }
                let best = self
                    .scope
                    .iter()
                    .filter(|c| c.axis_value(axis).as_ref() == Some(&v))
                    .map(|c| {
                        (
                            axes()
                                .filter(|a| *a != axis && c.axis_value(a) != rep.axis_value(a))
                                .count(),
                            c,
                        )
                    })
                    .filter(|(d, _)| *d <= 1)
                    .min_by_key(|(d, _)| *d);
                // One line per cell: a sibling that is closest for two axes names both.
                match (best, best.and_then(|(_, c)| out.iter_mut().find(|(_, o)| o.id() == c.id())))
                {
                    (_, Some(seen)) => seen.0 += &format!(", {axis}"),
                    (Some((_, c)), None) => out.push((axis.to_string(), *c)),
                    (None, None) => {}
                }
            }
        }
        out
    }

    fn workaround_line(
        &self,
        rep: &Cell,
        patched: &Cell,
        ev: isolation::Evidence,
    ) -> IsolationLine {
        let mut l = isolation::line(patched, Some("patch"), &self.verdicts, ev);
        let (inj_rep, inj_patched) = (for_cell(&self.inject, rep), for_cell(&self.inject, patched));
        let note = match (inj_rep, inj_patched, l.verdict.as_str()) {
            (_, _, "not_run") => "",
            (_, _, "error") => " — rtprobe could not run the patched cell: no evidence either way",
            (Some(_), None, _) => " — not a workaround: the injection predicate excludes patched cells (patch=none), so the fault is simply not injected",
            (Some(_), Some(_), _) => " — the injected fault survives the SPIR-V patch; this says nothing about a driver",
            (None, _, "pass") if l.settled() => " — verified workaround",
            (None, _, "pass") => " — not verified: too few passing attempts",
            (None, _, _) => "",
        };
        l.line += note;
        l
    }
}

use crate::model::Bisection;
pub use render::render;

#[cfg(test)]
mod tests;
