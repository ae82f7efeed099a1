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
    let failing: Vec<&Comparison> = comparisons(entry).filter(|c| !c.passed()).collect();
    let Some(read) = decode(cell, &failing, instances) else {
        return String::new();
    };
    let clauses = axis_clauses(cell, bi);
    match clauses.is_empty() {
        true => format!("{read}."),
        false => format!("{read}; {}, one axis changed at a time.", clauses.join("; ")),
    }
}

/// Which descriptor every decoded example pixel of every failing attempt (`cmps`) read instead
/// of its own: the same number of slots before or after it (with the heap's bytes where the
/// comparison has them), whether at the right element, and the sample that rests on (the
/// examples are the first few mismatching pixels of each attempt, `reference::compare`). `None`
/// when a field other than the value mismatched, an attempt has no example, or one does not
/// decode or reads another slot.
fn decode(cell: &Cell, cmps: &[&Comparison], instances: u32) -> Option<String> {
    let bad = |c: &Comparison| c.by_field.keys().any(|f| f != "value") || c.examples.is_empty();
    if cmps.is_empty() || cmps.iter().any(|c| bad(c)) {
        return None;
    }
    let slots = probe::slot_count(cell.resource, instances);
    let whose = |s: &str| parse_value(s).and_then(|v| whose(cell.resource, slots, v));
    let examples: Vec<_> = cmps.iter().flat_map(|c| &c.examples).collect();
    let decoded: Vec<((u32, u32), (u32, u32))> = examples
        .iter()
        .map(|m| Some((whose(&m.expected)?, whose(&m.actual)?)))
        .collect::<Option<_>>()?;
    let shift = |(e, a): &((u32, u32), (u32, u32))| a.0 as i64 - e.0 as i64;
    let first = shift(&decoded[0]);
    if first == 0 || decoded.iter().any(|d| shift(d) != first) {
        return None;
    }
    let k = first.unsigned_abs();
    let side = if first < 0 { "before" } else { "after" };
    let plural = if k == 1 { "" } else { "s" };
    let what = match cmps[0].heap.as_ref() {
        Some(h) => format!(
            "Reads the descriptor {} bytes ({k} descriptor{plural}) {side} the right one",
            k * h.probe_stride as u64
        ),
        None => format!("Reads the descriptor {k} array element{plural} {side} the right one"),
    };
    let other = decoded.iter().filter(|(e, a)| e.1 != a.1).count();
    let element = match other {
        0 => "at the right element".to_string(),
        n => format!("at another element in {n} of {}", decoded.len()),
    };
    Some(format!("{what}, {element}, {}", sample(cmps, &examples)))
}

/// The sample a decode rests on: "in all 8 decoded example pixels of 926 that differ", with the
/// examples' count over the report's failing attempts where more than one kept examples (the
/// bisection's attempts keep none).
fn sample(cmps: &[&Comparison], examples: &[&crate::model::comparison::Mismatch]) -> String {
    let pixels: std::collections::BTreeSet<[u32; 2]> = examples.iter().map(|m| m.pixel).collect();
    let differ = cmps.iter().map(|c| c.mismatched_pixels);
    let (lo, hi) = (differ.clone().min().unwrap_or(0), differ.max().unwrap_or(0));
    let differ = if lo == hi { lo.to_string() } else { format!("{lo}–{hi}") };
    let mut t = format!("in all {} decoded example pixels of {differ} that differ", pixels.len());
    if cmps.len() > 1 {
        let n = (examples.len(), cmps.len());
        t += &format!(" ({} examples from the run report's {} failing attempts)", n.0, n.1);
    }
    t
}

/// Per axis the isolation list varied alone: where some sibling passes and every other one
/// faults as the minimal failing cell does, the values it faults and passes with, as the list
/// shows them ("fails in closest_hit/any_hit/miss, passes in raygen"), never a claim about the
/// values it did not run.
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
        .map(|(axis, fail, pass, _)| match axis.as_str() {
            "stage" => format!("fails in {}, passes in {}", fail.join("/"), pass.join("/")),
            _ => format!(
                "fails with {axis}={}, passes with {axis}={}",
                fail.join("|"),
                pass.join("|")
            ),
        })
        .collect()
}
