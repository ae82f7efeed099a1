//! The bisection as people read it (`bisect`'s output, saved as the bisection file's `text`),
//! and the bisection file made from it.
use crate::model::{BisectFile, Bisection, Filter, Injection, RunReport};
use std::path::Path;

/// The bisection as text: the isolation list, the workarounds, the evidence, and as the last line
/// `minimal: PREDICATE`.
pub fn render(b: &Bisection, full_matrix: usize) -> String {
    let mut s = String::new();
    if b.separable {
        s += &format!(
            "{} faulting of {} cells in scope; one conjunction separates them.\n",
            b.faulting_cells, b.scope_cells
        );
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
    match b.fault_rate_bound {
        Some(p) => s += &format!(
            "evidence: the minimal failing cell's fault rate is p ≥ {p:.2} at {:.0}% (one-sided Clopper–Pearson); a pass held to it needs {} for a miss probability below {}; {} relied on, worst miss probability {} per pass, at most {} that any of them missed (union bound), given that the rate bound holds ({:.0}% confidence)\n",
            100.0 * b.confidence,
            crate::model::plural(b.attempts_per_pass as usize, "attempt"),
            super::isolation::percent(b.max_miss),
            passes(b.passes_relied_on),
            super::isolation::percent(b.worst_miss_probability),
            super::isolation::percent(b.union_miss_probability),
            100.0 * b.confidence
        ),
        None => s += "evidence: the minimal failing cell has no attempt: passes are not settled\n",
    }
    if !b.unsettled.is_empty() {
        s += &format!(
            "NOT CONCLUDED: {} relied on stay at or above a miss probability of {} (attempt cap or offline); the result rests on them: {}\n",
            passes(b.unsettled.len()),
            super::isolation::percent(b.max_miss),
            b.unsettled.join(", ")
        );
    }
    if !b.errored.is_empty() {
        s += &format!(
            "not evidence (rtprobe could not run them, `error`): {}\n",
            b.errored.join(", ")
        );
    }
    if !b.doubtful.is_empty() {
        s += &format!("not evidence (rtprobe doubts them): {}\n", b.doubtful.join(", "));
    }
    if !b.not_varied.is_empty() {
        s += &format!(
            "not varied in this scope (the result says nothing about them): {}\n",
            b.not_varied.join(", ")
        );
    }
    s += &format!(
        "runs: {} made by bisect; {} cells in scope ({} never run), full matrix {} cells\n",
        b.runs, b.scope_cells, b.not_run, full_matrix
    );
    s += &format!("minimal: {}\n", b.minimal);
    s
}

impl BisectFile {
    /// The file for `bisection` of the report at `path` (rendered as `bisect` prints it).
    pub fn new(
        path: &Path,
        report: &RunReport,
        scope: &[Filter],
        inject: &[Injection],
        offline: bool,
        bisection: Bisection,
    ) -> Self {
        let text = render(&bisection, report.plan.generated);
        BisectFile {
            schema: crate::model::bisection::SCHEMA.into(),
            report: path.to_path_buf(),
            report_started: report.started.clone(),
            device: report.device.clone(),
            scope: scope.iter().map(predicate).collect(),
            full_matrix: report.plan.generated,
            inject: inject.iter().map(|i| i.spec.clone()).collect(),
            offline,
            device_uuid_rerun: None,
            bisection,
            text,
        }
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

/// `1 pass`, `5 passes`.
fn passes(n: usize) -> String {
    if n == 1 {
        "1 pass".into()
    } else {
        format!("{n} passes")
    }
}
