//! The isolation list in plain words: a cell as a sentence (`closest_hit reading storage_buffer
//! with dynamic index (nonuniformEXT), descriptor_indexing`) and a verdict with its evidence
//! (`❌ crash (6 of 6, p ≥ 0.61 at 95%)`, `✅ passes (5 of 5; miss ≤ 0.94% for p ≥ 0.61)`).
use super::Verdicts;
use crate::matrix::{AsAccess, BaseSource, Cell, HeapAccess, IndexSource, SamplerIndex};
use serde::{Deserialize, Serialize};

/// One cell as a sentence a driver engineer can read without knowing rtprobe's ids.
pub fn describe(c: &Cell) -> String {
    if let Some(k) = c.canary {
        return format!("canary {}", k.as_str());
    }
    let mut s = format!("{} reading {} with {} index", c.stage, c.resource, c.index);
    if c.nonuniform {
        s += " (nonuniformEXT)";
    }
    if let Some(a) = c.as_access {
        s += match a {
            AsAccess::Descriptor => " through a descriptor",
            AsAccess::Address => " through a device address",
            AsAccess::AddressPatched => " through a device address (as-to-address applied to the descriptor variant)",
        };
    }
    s += &format!(", {}", c.descriptor_model);
    if let Some(h) = c.heap_access {
        s += match h {
            HeapAccess::MappedConstantOffset => " (set/binding mapped to the heap at a constant offset)",
            HeapAccess::MappedPushIndex => " (set/binding mapped to the heap, index in push data: HEAP_WITH_PUSH_INDEX)",
            HeapAccess::MappedIndirectIndex => " (set/binding mapped to the heap, index loaded from a buffer: HEAP_WITH_INDIRECT_INDEX)",
            HeapAccess::MappedShaderRecordIndex => " (set/binding mapped to the heap, index in the shader record: HEAP_WITH_SHADER_RECORD_INDEX)",
            HeapAccess::Direct => " (layout(descriptor_heap) GLSL)",
        };
    }
    if let Some(r) = c.reorder {
        s += &format!(", raygen reordering with {r}");
    }
    if let Some(b) = c.base {
        s += match b {
            BaseSource::ShaderRecord => ", base from the SBT shader record",
            BaseSource::Buffer => ", base loaded from a per-instance buffer (device address)",
        };
    }
    if let Some(k) = c.sampler {
        s += match k {
            SamplerIndex::Constant => ", separate sampler heap, constant sampler index",
            SamplerIndex::Dynamic => ", separate sampler heap, dynamic sampler index",
        };
    }
    if let Some(p) = c.patch {
        s += &format!(", patched with {}", p.as_str());
    }
    s
}

/// One line of an isolation list: a cell, what was varied, and its verdict with evidence.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct IsolationLine {
    pub cell: String,
    /// The axis varied from the minimal failing cell (`None` for that cell itself; `patch` for a
    /// workaround).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub varied: Option<String>,
    pub description: String,
    /// `pass`, a finding's outcome, or `not_run`.
    pub verdict: String,
    /// Attempts that agree with the verdict (faulted ones for a finding, passed ones for a pass).
    pub agreeing: u32,
    pub attempts: u32,
    /// For a finding: its own fault rate bound (Clopper–Pearson, 95%); for a pass: the bound of
    /// the faulting cell it is held to.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub rate_bound: Option<f64>,
    /// For a pass: the chance that a fault of rate `rate_bound` missed all its attempts.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub miss_probability: Option<f64>,
    /// For a pass: its miss probability is below the threshold (false: not concluded on).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub settled: Option<bool>,
    /// For a pass without `nonuniformEXT` on its dynamic index whose lanes read other elements
    /// (allowed: undefined) while a sibling with a defined index faults: that sibling's id. Such
    /// a pass is not clean evidence (it may hide the sibling's fault).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub suspect: Option<String>,
    /// The verdict's reason, for an `error` (rtprobe could not run the cell).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub reason: Option<String>,
    /// The `--inject-fault` argument that applied to the cell, if any.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub injected: Option<String>,
    pub line: String,
}

impl IsolationLine {
    pub fn faults(&self) -> bool {
        self.verdict != "pass" && self.verdict != "not_run"
    }

    /// A pass whose miss probability is below the threshold.
    pub fn settled(&self) -> bool {
        self.settled == Some(true)
    }
}

/// What a line's verdict is held to: the rate bound of the faulting cell a pass is compared
/// with (None: no faulting cell), and the threshold.
#[derive(Clone, Copy, Debug)]
pub struct Evidence {
    pub against: Option<f64>,
    pub max_miss: f64,
}

/// The line for `cell` from what `verdicts` know: a finding with its k of N and rate bound, a
/// pass with its miss probability against `ev.against`.
pub fn line(cell: &Cell, varied: Option<&str>, verdicts: &Verdicts, ev: Evidence) -> IsolationLine {
    let description = describe(cell);
    let report = verdicts.get(cell).filter(|r| !r.attempts.is_empty());
    let reason = report.filter(|r| r.outcome == crate::outcome::Outcome::Error).and_then(|r| r.reason.clone());
    let (k, n) = verdicts.counts(cell);
    let mut l = IsolationLine { cell: cell.id(), varied: varied.map(String::from), description, verdict: "not_run".into(), agreeing: 0, attempts: n, rate_bound: None, miss_probability: None, settled: None, suspect: None, reason, injected: None, line: String::new() };
    // A pass's faulting sibling that its lenient reads may hide (`suspect`).
    let mut sus = None;
    if let Some(r) = report {
        l.verdict = r.outcome.as_str().to_string();
        l.injected = r.injected.clone();
        if r.outcome.is_finding() {
            l.agreeing = k;
            l.rate_bound = Some(super::confidence::rate_bound(k, n));
        } else {
            l.agreeing = n - k;
            if r.outcome == crate::outcome::Outcome::Pass {
                l.rate_bound = ev.against;
                l.miss_probability = Some(ev.against.map_or(1.0, |p| super::confidence::miss(p, n)));
                l.settled = l.miss_probability.map(|m| m < ev.max_miss);
                sus = suspect(cell, verdicts);
                l.suspect = sus.map(|(sib, _)| sib.id());
            }
        }
    }
    let conf = format!("{:.0}%", 100.0 * super::confidence::CONFIDENCE);
    let evidence = match (l.verdict.as_str(), l.miss_probability, l.rate_bound) {
        ("not_run", _, _) => "❔ not run".to_string(),
        ("pass", Some(m), Some(p)) => {
            let weak = if l.settled() { "" } else { "; too little evidence, not concluded on" };
            format!("✅ passes ({} of {n}; miss ≤ {} for p ≥ {p:.2}{weak})", l.agreeing, percent(m))
        }
        ("pass", _, _) => format!("✅ passes ({} of {n}; no faulting cell to hold it to)", l.agreeing),
        ("error", _, _) => format!("⚠ error ({}/{n}): {}", l.agreeing, l.reason.as_deref().unwrap_or("no detail")),
        (v, _, Some(p)) => format!("❌ {v} ({k} of {n}, p ≥ {p:.2} at {conf})"),
        (v, _, None) => format!("❌ {v} ({k} of {n})"),
    };
    l.line = format!("{}: {evidence}", l.description);
    if let Some((sib, other)) = sus {
        l.line += &format!(" — suspect: {other} pixel(s) read another element (allowed without nonuniformEXT, undefined which), while {} faults", describe(&sib));
    }
    l
}

/// For a cell judged leniently (its dynamic index lacks `nonuniformEXT`, or the compiler dropped
/// it) whose attempts read other elements (the most in one attempt), a faulting sibling that
/// differs only in a defined index (another index source, or `nonuniformEXT`): the read of
/// "another element" may be that fault.
pub fn suspect(cell: &Cell, verdicts: &Verdicts) -> Option<(Cell, usize)> {
    let other = verdicts.get(cell)?.element_reads().map(|e| e.other).max().filter(|o| *o > 0)?;
    let defined = IndexSource::ALL.iter().filter(|i| **i != IndexSource::Dynamic).map(|i| Cell { index: *i, nonuniform: false, ..*cell }).chain(std::iter::once(Cell { nonuniform: true, ..*cell }));
    defined.into_iter().filter(|s| s != cell).find(|s| verdicts.state(s) == super::State::Fault).map(|s| (s, other))
}

/// A probability as a short percentage (`0.78%`, `< 0.01%`).
pub fn percent(p: f64) -> String {
    if p > 0.0 && p < 1e-4 {
        "< 0.01%".into()
    } else {
        format!("{:.2}%", 100.0 * p)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::matrix::{DescriptorModel, IndexSource, Resource, Stage};

    #[test]
    fn cells_read_as_sentences() {
        let c = Cell { stage: Stage::ClosestHit, resource: Resource::StorageBuffer, index: IndexSource::SpecConstant, nonuniform: false, as_access: None, descriptor_model: DescriptorModel::DescriptorIndexing, heap_access: None, canary: None, patch: None, reorder: None, base: None, sampler: None };
        assert_eq!(describe(&c), "closest_hit reading storage_buffer with spec_constant index, descriptor_indexing");
        let d = Cell { index: IndexSource::Dynamic, nonuniform: true, patch: Some(crate::matrix::cell::Workaround::SsboToAddress), ..c };
        assert_eq!(describe(&d), "closest_hit reading storage_buffer with dynamic index (nonuniformEXT), descriptor_indexing, patched with ssbo-to-address");
        assert_eq!(percent(0.0078125), "0.78%");
        assert_eq!(percent(1e-9), "< 0.01%");
    }
}
