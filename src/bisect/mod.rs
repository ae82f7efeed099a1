//! `rtprobe bisect`: from a run report with faults to the minimal description of the fault — the
//! smallest conjunction of `axis=value[|value…]` terms (the `--inject-fault` predicate syntax)
//! that holds for every faulting cell of the scope and for no passing one.
//!
//! How ([`Bisector::bisect`]):
//! 1. Every verdict the report already has is used; a cell's verdict is its worst attempt, with
//!    "k of N" ([`Verdicts`]).
//! 2. **Flaky faults.** A pass is only a pass when a fault of the observed rate would have shown
//!    in its attempts with probability at least `1 - max_miss` (default 1%): passing cells are
//!    re-run, each alone in a fresh worker, until `(1 - rate)^N < max_miss`. The rate is pooled
//!    over the faulting cells with each cell's first fault left out (that attempt is why the cell
//!    is a faulting one, so counting it would inflate the rate); it needs
//!    [`MIN_RATE_ATTEMPTS`] such attempts, re-running faulting cells to get them. A fault is never
//!    reversed (the worst attempt wins), so faulting cells need no more than that.
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
//!    passing; they are listed.
//! 6. The isolation list: the minimal failing cell and, per axis, its closest siblings in the
//!    scope (run if unknown); then each workaround patch that applies to it (verified by runs).
//!
//! Injection and the patch axis: `--inject-fault` predicates match the `patch` axis like any
//! other. A predicate with `patch=none` leaves patched cells alone, so every workaround "passes"
//! — a statement about the predicate, not about a driver; a predicate without a `patch` term
//! injects into patched cells too (the injected load survives every SPIR-V patch), so no
//! workaround passes. The workaround lines say when the verdict is decided by the injection.
pub mod ddmin;
pub mod file;
pub mod isolation;
pub mod scope;

use crate::matrix::inject::{for_cell, Injection};
use crate::matrix::{Cell, Filter};
use crate::outcome::Outcome;
use crate::report::run_report::{CellReport, RunReport};
use crate::runner::supervisor::Attempt;
use isolation::IsolationLine;
use serde::{Deserialize, Serialize};
use std::collections::HashMap;

/// The axes bisection reduces over: every axis of a cell except `canary`.
pub fn axes() -> impl Iterator<Item = &'static str> {
    crate::matrix::cell::AXIS_NAMES.iter().copied().filter(|a| *a != "canary")
}
/// Default: a pass may hide a fault of the observed rate with at most this probability.
pub const DEFAULT_MAX_MISS: f64 = 0.01;
/// Default cap on the attempts of one cell.
pub const DEFAULT_MAX_ATTEMPTS: u32 = 50;
/// Attempts (beyond each faulting cell's first fault) the fault rate is estimated from.
pub const MIN_RATE_ATTEMPTS: u32 = 8;

/// What a cell's verdict says, for bisection.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum State {
    Fault,
    Pass,
    /// rtprobe could not run it (`error`): no evidence about the driver either way, so it is
    /// neither a faulting cell nor a passing one, and is not run again.
    Error,
    /// Never ran (or unsupported).
    Unknown,
}

/// Every cell's attempts, keyed by id: the report's, then bisection's own.
#[derive(Clone, Debug, Default)]
pub struct Verdicts {
    cells: HashMap<String, CellReport>,
    /// Attempts bisection added.
    pub runs: usize,
}

impl Verdicts {
    pub fn from_report(r: &RunReport) -> Self {
        let cells = r.cells.iter().filter(|c| !c.attempts.is_empty()).map(|c| (c.id.clone(), c.clone())).collect();
        Verdicts { cells, runs: 0 }
    }

    pub fn record(&mut self, cell: &Cell, attempt: Attempt) {
        self.runs += 1;
        match self.cells.get_mut(&cell.id()) {
            Some(c) => {
                c.attempts.push(attempt);
                c.refresh();
            }
            None => {
                self.cells.insert(cell.id(), CellReport::new(cell, attempt));
            }
        }
    }

    pub fn get(&self, c: &Cell) -> Option<&CellReport> {
        self.cells.get(&c.id())
    }

    pub fn attempts(&self, c: &Cell) -> u32 {
        self.get(c).map(|r| r.attempts.len() as u32).unwrap_or(0)
    }

    pub fn state(&self, c: &Cell) -> State {
        match self.get(c).filter(|r| !r.attempts.is_empty()) {
            None => State::Unknown,
            Some(r) => match r.outcome {
                Outcome::Error => State::Error,
                Outcome::Mismatch | Outcome::DeviceLost | Outcome::Crash | Outcome::Timeout => State::Fault,
                Outcome::Pass => State::Pass,
                Outcome::Unsupported | Outcome::NotImplemented => State::Unknown,
            },
        }
    }
}

/// Runs cells for bisection. The CLI's runs them through the supervisor; an offline one (for
/// `report`, or `bisect --offline`) runs nothing.
pub trait Oracle {
    /// Run each of `cells` once more (each alone in a fresh worker when `isolated`), recording
    /// every attempt in `verdicts`.
    fn run(&mut self, cells: &[Cell], isolated: bool, verdicts: &mut Verdicts);
    fn can_run(&self) -> bool;
}

/// Runs nothing: bisection uses the report's verdicts alone.
pub struct Offline;

impl Oracle for Offline {
    fn run(&mut self, _: &[Cell], _: bool, _: &mut Verdicts) {}
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

/// A conjunction as an `--inject-fault` / `--filter` predicate (`canary=none` when it has no
/// term: every probe cell).
pub fn predicate(f: &Filter) -> String {
    if f.terms.is_empty() {
        return "canary=none".into();
    }
    f.terms.iter().map(|(a, v)| format!("{a}={}", v.join("|"))).collect::<Vec<_>>().join(",")
}

/// What bisection found.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Bisection {
    /// One conjunction separates the faulting cells from the passing ones.
    pub separable: bool,
    /// The minimal conjunction (one), or the disjunction's conjunctions.
    pub conjunctions: Vec<String>,
    /// `minimal: …` as printed: the conjunctions joined by `;` (RTPROBE_INJECT_FAULT's list).
    pub minimal: String,
    /// The minimal failing cell the isolation list is built around.
    pub representative: String,
    pub isolation: Vec<IsolationLine>,
    pub workarounds: Vec<IsolationLine>,
    /// The pooled fault rate (None: no estimate) and the attempts a pass then needs.
    pub fault_rate: Option<f64>,
    pub attempts_per_pass: u32,
    pub max_miss: f64,
    /// The largest miss probability of a pass bisection relied on.
    pub worst_miss_probability: f64,
    /// Passes that could not reach the threshold (attempt cap, or offline).
    pub unsettled: Vec<String>,
    pub faulting_cells: usize,
    pub scope_cells: usize,
    /// Cells of the scope with no verdict (never needed, or offline).
    pub not_run: usize,
    /// Cells of the scope rtprobe could not run (`error`): used neither as faults nor as passes.
    #[serde(default)]
    pub errored: Vec<String>,
    /// Attempts bisection ran itself.
    pub runs: usize,
    /// Axes with a single value in the scope: the conjunction says nothing about them.
    pub not_varied: Vec<String>,
}

#[derive(Debug, thiserror::Error)]
pub enum BisectError {
    #[error("no cell of the scope has a finding: nothing to bisect")]
    NoFault,
    #[error("--cell {0}: not a faulting cell of the scope")]
    NotFaulting(String),
}

pub struct Bisector<'o> {
    /// The cells bisection may use, in plan order (all runnable on the device).
    pub scope: Vec<Cell>,
    pub verdicts: Verdicts,
    oracle: &'o mut dyn Oracle,
    settings: Settings,
    inject: Vec<Injection>,
    memo: HashMap<String, bool>,
}

impl<'o> Bisector<'o> {
    pub fn new(scope: Vec<Cell>, verdicts: Verdicts, oracle: &'o mut dyn Oracle, settings: Settings, inject: Vec<Injection>) -> Self {
        Bisector { scope, verdicts, oracle, settings, inject, memo: HashMap::new() }
    }

    fn faulting(&self) -> Vec<Cell> {
        self.scope.iter().filter(|c| self.verdicts.state(c) == State::Fault).copied().collect()
    }

    /// The pooled fault rate with each faulting cell's first fault left out, and how many
    /// attempts it rests on.
    pub fn fault_rate(&self) -> (Option<f64>, u32) {
        let (mut k, mut n) = (0u32, 0u32);
        for c in self.faulting() {
            let r = self.verdicts.get(&c).expect("faulting cells have attempts");
            let faulted = r.attempts.iter().filter(|a| a.outcome.is_finding()).count() as u32;
            k += faulted - 1;
            n += r.attempts.len() as u32 - 1;
        }
        ((n > 0).then(|| k as f64 / n as f64), n)
    }

    /// Attempts a pass needs so that a fault of `rate` would have shown with probability at least
    /// `1 - max_miss`.
    pub fn attempts_needed(&self, rate: Option<f64>) -> u32 {
        match rate {
            Some(p) if p >= 1.0 => 1,
            Some(p) if p > 0.0 => ((self.settings.max_miss.ln() / (1.0 - p).ln()).ceil() as u32).clamp(1, self.settings.max_attempts),
            Some(_) | None => self.settings.max_attempts,
        }
    }

    /// Give every cell of `cells` a verdict that a flaky attempt cannot reverse: unknown ones run
    /// once, the fault rate gets its minimum evidence, passes are repeated to the threshold.
    fn settle(&mut self, cells: &[Cell]) {
        if !self.oracle.can_run() {
            return;
        }
        let unknown: Vec<Cell> = cells.iter().filter(|c| self.verdicts.state(c) == State::Unknown).copied().collect();
        if !unknown.is_empty() {
            self.oracle.run(&unknown, false, &mut self.verdicts);
        }
        let mut last = usize::MAX;
        // Each round adds attempts; one that adds none (the oracle gave up) ends it.
        while std::mem::replace(&mut last, self.verdicts.runs) != self.verdicts.runs {
            let (rate, evidence) = self.fault_rate();
            if evidence < MIN_RATE_ATTEMPTS {
                let mut f: Vec<Cell> = self.faulting().into_iter().filter(|c| self.verdicts.attempts(c) < self.settings.max_attempts).collect();
                if !f.is_empty() {
                    f.sort_by_key(|c| self.verdicts.attempts(c));
                    f.truncate((MIN_RATE_ATTEMPTS - evidence) as usize);
                    self.oracle.run(&f, true, &mut self.verdicts);
                    continue;
                }
            }
            let need = self.attempts_needed(rate);
            let more: Vec<Cell> = cells.iter().filter(|c| self.verdicts.state(c) == State::Pass && self.verdicts.attempts(c) < need).copied().collect();
            if more.is_empty() {
                return;
            }
            self.oracle.run(&more, true, &mut self.verdicts);
        }
    }

    /// Whether the conjunction contains no passing cell of the scope (running the unknown ones it
    /// contains, in batches, until one passes).
    fn holds(&mut self, f: &Filter) -> bool {
        let key = predicate(f);
        if let Some(v) = self.memo.get(&key) {
            return *v;
        }
        let region: Vec<Cell> = self.scope.iter().filter(|c| f.matches(c)).copied().collect();
        let mut ok = !region.iter().any(|c| self.verdicts.state(c) == State::Pass);
        if ok {
            let unknown: Vec<Cell> = region.iter().filter(|c| self.verdicts.state(c) == State::Unknown).copied().collect();
            if !unknown.is_empty() && !self.oracle.can_run() {
                ok = false; // offline: a conjunction is not widened over cells nobody ran
            }
            for batch in unknown.chunks(self.settings.batch.max(1)) {
                if !ok {
                    break;
                }
                self.settle(batch);
                ok = !batch.iter().any(|c| self.verdicts.state(c) == State::Pass);
            }
        }
        self.memo.insert(key, ok);
        ok
    }

    /// Per axis, the values `cells` have (in scope order).
    fn tight(&self, cells: &[Cell]) -> Filter {
        let mut terms = Vec::new();
        for axis in axes() {
            let mut vals: Vec<String> = Vec::new();
            for c in &self.scope {
                let v = c.axis_value(axis).expect("known axis");
                if !vals.contains(&v) && cells.iter().any(|f| f.axis_value(axis).as_deref() == Some(v.as_str())) {
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
        let terms: Vec<(String, Vec<String>)> = f.terms.into_iter().rev().filter(|(a, v)| self.scope_values(a).iter().any(|x| !v.contains(x))).collect();
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

    /// Find the minimal description, then build the isolation list around `cell` (or the first
    /// faulting cell) and try its workarounds (`patch_supported` says which the device can run).
    pub fn bisect(&mut self, cell: Option<&str>, patch_supported: &dyn Fn(&Cell) -> bool) -> Result<Bisection, BisectError> {
        let (separable, conjunctions) = loop {
            let start = self.verdicts.runs;
            let known: Vec<Cell> = self.scope.iter().filter(|c| self.verdicts.state(c) != State::Unknown).copied().collect();
            self.settle(&known);
            let faulting = self.faulting();
            if faulting.is_empty() {
                return Err(BisectError::NoFault);
            }
            let tight = self.tight(&faulting);
            let (separable, cs) = if self.holds(&tight) { (true, vec![self.reduce(tight)]) } else { (false, self.disjunction(&faulting)) };
            // Runs made on the way may have found faulting cells outside, or lowered the fault
            // rate so that earlier passes need more attempts: then start over (a "holds" stays
            // true, since a fault is never reversed; a pass may still turn into a fault).
            let covered = self.faulting().iter().all(|f| cs.iter().any(|c| c.matches(f)));
            let need = self.attempts_needed(self.fault_rate().0);
            let settled = !self.oracle.can_run() || self.scope.iter().all(|c| self.verdicts.state(c) != State::Pass || self.verdicts.attempts(c) >= need);
            // (A round that ran nothing cannot change anything: the oracle gave up.)
            if (covered && settled) || self.verdicts.runs == start {
                break (separable, cs);
            }
            self.memo.retain(|_, holds| *holds);
        };
        let faulting = self.faulting();
        let rep = match cell {
            Some(id) => *faulting.iter().find(|c| c.id() == id).ok_or_else(|| BisectError::NotFaulting(id.to_string()))?,
            None => *faulting.iter().find(|c| conjunctions[0].matches(c)).expect("the first conjunction holds for a faulting cell"),
        };
        let siblings = self.siblings(&rep);
        let sib_cells: Vec<Cell> = siblings.iter().map(|(_, c)| *c).collect();
        self.settle(&sib_cells);
        let patched: Vec<Cell> = rep.applicable_patches().into_iter().map(|p| Cell { patch: Some(p), ..rep }).filter(|c| patch_supported(c)).collect();
        self.settle(&patched);
        let (rate, _) = self.fault_rate();
        let mut isolation = vec![isolation::line(&rep, None, &self.verdicts, rate)];
        isolation.extend(siblings.iter().map(|(axis, c)| isolation::line(c, Some(axis), &self.verdicts, rate)));
        let workarounds = patched.iter().map(|c| self.workaround_line(&rep, c, rate)).collect();
        let need = self.attempts_needed(rate);
        let passes: Vec<&Cell> = self.scope.iter().filter(|c| self.verdicts.state(c) == State::Pass).collect();
        let worst_miss = passes.iter().map(|c| rate.map(|p| crate::report::run_report::miss_probability(p, self.verdicts.attempts(c))).unwrap_or(1.0)).fold(0.0, f64::max);
        let unsettled = passes.iter().filter(|c| self.verdicts.attempts(c) < need).map(|c| c.id()).collect();
        let strings: Vec<String> = conjunctions.iter().map(predicate).collect();
        Ok(Bisection {
            separable,
            minimal: strings.join(";"),
            conjunctions: strings,
            representative: rep.id(),
            isolation,
            workarounds,
            fault_rate: rate,
            attempts_per_pass: need,
            max_miss: self.settings.max_miss,
            worst_miss_probability: worst_miss,
            unsettled,
            faulting_cells: faulting.len(),
            scope_cells: self.scope.len(),
            not_run: self.scope.iter().filter(|c| self.verdicts.state(c) == State::Unknown).count(),
            errored: self.scope.iter().filter(|c| self.verdicts.state(c) == State::Error).map(|c| c.id()).collect(),
            runs: self.verdicts.runs,
            not_varied: axes().filter(|a| self.scope_values(a).len() < 2).map(String::from).collect(),
        })
    }

    /// Per axis, per other value, the scope cell closest to `rep` (fewest other axes changed, at
    /// most one more: `index` drags `nonuniform` along, `resource` drags `as_access`).
    fn siblings(&self, rep: &Cell) -> Vec<(String, Cell)> {
        let mut out = Vec::new();
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
                    .map(|c| (axes().filter(|a| *a != axis && c.axis_value(a) != rep.axis_value(a)).count(), c))
                    .filter(|(d, _)| *d <= 1)
                    .min_by_key(|(d, _)| *d);
                if let Some((_, c)) = best {
                    out.push((axis.to_string(), *c));
                }
            }
        }
        out
    }

    fn workaround_line(&self, rep: &Cell, patched: &Cell, rate: Option<f64>) -> IsolationLine {
        let mut l = isolation::line(patched, Some("patch"), &self.verdicts, rate);
        let (inj_rep, inj_patched) = (for_cell(&self.inject, rep), for_cell(&self.inject, patched));
        let note = match (inj_rep, inj_patched, l.verdict.as_str()) {
            (_, _, "not_run") => "",
            (_, _, "error") => " — rtprobe could not run the patched cell: no evidence either way",
            (Some(_), None, _) => " — not a workaround: the injection predicate excludes patched cells (patch=none), so the fault is simply not injected",
            (Some(_), Some(_), _) => " — the injected fault survives the SPIR-V patch; this says nothing about a driver",
            (None, _, "pass") => " — verified workaround",
            (None, _, _) => "",
        };
        l.line += note;
        l
    }
}

/// The bisection as text: the isolation list, the workarounds, the evidence, and as the last line
/// `minimal: PREDICATE`.
pub fn render(b: &Bisection, full_matrix: usize) -> String {
    let mut s = String::new();
    if b.separable {
        s += &format!("{} faulting of {} cells in scope; one conjunction separates them.\n", b.faulting_cells, b.scope_cells);
    } else {
        s += &format!(
            "{} faulting of {} cells in scope; NO single conjunction separates them from the passing cells (the tightest one holding for every faulting cell contains a passing cell). Smallest disjunction found ({} conjunctions, greedy cover):\n",
            b.faulting_cells,
            b.scope_cells,
            b.conjunctions.len()
        );
        for c in &b.conjunctions {
            s += &format!("  {c}\n");
        }
    }
    s += &format!("\nisolation (around {}):\n", b.representative);
    for l in &b.isolation {
        s += &format!("  {}\n", l.line);
    }
    if !b.workarounds.is_empty() {
        s += "\nworkarounds for the minimal failing cell:\n";
        for l in &b.workarounds {
            s += &format!("  {}\n", l.line);
        }
    }
    s += "\n";
    match b.fault_rate {
        Some(p) => s += &format!(
            "fault rate {:.2} (pooled, each faulting cell's first fault left out); a pass needs {} attempt(s) for a miss probability below {}; worst miss probability relied on: {}\n",
            p,
            b.attempts_per_pass,
            isolation::percent(b.max_miss),
            isolation::percent(b.worst_miss_probability)
        ),
        None => s += "fault rate unknown (no repeated attempt of a faulting cell): passes are not settled\n",
    }
    if !b.unsettled.is_empty() {
        s += &format!("WARNING: {} passing cell(s) below the threshold (attempt cap or offline): {}\n", b.unsettled.len(), b.unsettled.join(", "));
    }
    if !b.errored.is_empty() {
        s += &format!("not evidence (rtprobe could not run them, `error`): {}\n", b.errored.join(", "));
    }
    if !b.not_varied.is_empty() {
        s += &format!("not varied in this scope (the result says nothing about them): {}\n", b.not_varied.join(", "));
    }
    s += &format!(
        "runs: {} made by bisect; {} cells in scope ({} never run), full matrix {} cells\n",
        b.runs, b.scope_cells, b.not_run, full_matrix
    );
    s += &format!("minimal: {}\n", b.minimal);
    s
}

#[cfg(test)]
mod tests;
