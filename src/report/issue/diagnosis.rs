//! The one-line diagnosis under its title: what the evidence says the driver does, built
//! only from facts the issue holds — the expected-vs-actual decode of the mismatching pixels
//! (which descriptor was read instead of the right one) and the isolation list's siblings that
//! change one axis only (which values of an axis fault and which pass). Where the evidence does
//! not support a sentence (no decode, pixels that disagree, other fields wrong), it says nothing.
use super::facts::{parse_value, whose};
use super::text::comparisons;
use crate::model::{Bisection, Cell, CellReport, Comparison};
use crate::probe;

/// The diagnosis, or an empty string where the evidence does not support one.
pub(super) fn of(
    cell: &Cell,
    entry: Option<&CellReport>,
    instances: u32,
    bi: &Bisection,
) -> String {
    let Some(read) =
        comparisons(entry).find(|c| !c.passed()).and_then(|c| decode(cell, c, instances))
    else {
        return String::new();
    };
    let mut clauses = vec![read];
    clauses.extend(axis_clauses(cell, bi));
    if let Some(last) = clauses.len().checked_sub(1).filter(|&k| k >= 2) {
        clauses[last] = format!("and {}", clauses[last]);
    }
    format!("{}.", clauses.join(", "))
}

/// Which descriptor every decoded mismatching pixel read instead of its own: the same number of
/// slots before or after it (with the heap's bytes where the comparison has them). `None` when a
/// field other than the value mismatched, no example decodes, or the examples disagree.
fn decode(cell: &Cell, cmp: &Comparison, instances: u32) -> Option<String> {
    if cmp.by_field.keys().any(|f| f != "value") || cmp.examples.is_empty() {
        return None;
    }
    let slots = probe::slot_count(cell.resource, instances);
    let slot = |s: &str| parse_value(s).and_then(|v| whose(cell.resource, slots, v)).map(|x| x.0);
    let shifts: Vec<i64> = cmp
        .examples
        .iter()
        .map(|m| Some(slot(&m.actual)? as i64 - slot(&m.expected)? as i64))
        .collect::<Option<_>>()?;
    let shift = shifts[0];
    if shift == 0 || shifts.iter().any(|&d| d != shift) {
        return None;
    }
    let k = shift.unsigned_abs();
    let side = if shift < 0 { "before" } else { "after" };
    let plural = if k == 1 { "" } else { "s" };
    Some(match cmp.heap.as_ref() {
        Some(h) => format!(
            "Reads the descriptor {} bytes ({k} descriptor{plural}) {side} the right one",
            k * h.probe_stride as u64
        ),
        None => format!("Reads the descriptor {k} array element{plural} {side} the right one"),
    })
}

/// Per axis the isolation list varied alone: where some sibling passes and every other one
/// faults as the minimal failing cell does, the values it faults with ("in closest_hit/any_hit/miss
/// shaders only", "only with heap_access=mapped_shader_record_index").
fn axis_clauses(cell: &Cell, bi: &Bisection) -> Vec<String> {
    let rep_verdict = bi.isolation.first().map(|l| l.verdict.as_str()).unwrap_or("");
    let doubtful = |id: &str| bi.doubtful.iter().any(|d| d.starts_with(&format!("{id} (")));
    let mut axes: Vec<(String, Vec<String>, Vec<String>, bool)> = Vec::new();
    for l in bi.isolation.iter().filter(|l| !doubtful(&l.cell)) {
        let (Some(axis), Some(c)) = (l.varied.as_deref(), Cell::parse_id(&l.cell).ok()) else {
            continue;
        };
        let differ: Vec<&str> = crate::model::registry::names()
            .filter(|a| c.axis_value(a) != cell.axis_value(a))
            .collect();
        // Only a sibling that changes this one axis and nothing else speaks for it.
        if differ != [axis] {
            continue;
        }
        let value = c.axis_value(axis).unwrap_or_default();
        let at = match axes.iter().position(|(a, ..)| a == axis) {
            Some(k) => k,
            None => {
                let own = cell.axis_value(axis).unwrap_or_default();
                axes.push((axis.to_string(), vec![own], vec![], false));
                axes.len() - 1
            }
        };
        match l.verdict.as_str() {
            "pass" if l.settled != Some(false) && l.suspect.is_none() => axes[at].2.push(value),
            v if v == rep_verdict => axes[at].1.push(value),
            // Another outcome, or a pass not to conclude on: no clean split on this axis.
            _ => axes[at].3 = true,
        }
    }
    axes.into_iter()
        .filter(|(_, _, pass, murky)| !pass.is_empty() && !murky)
        .map(|(axis, fail, _, _)| match axis.as_str() {
            "stage" => format!("in {} shaders only", fail.join("/")),
            _ => format!("only with {axis}={}", fail.join("|")),
        })
        .collect()
}
