//! The isolation list in plain words: a cell as a sentence (`closest_hit reading storage_buffer
//! with dynamic index (nonuniformEXT), descriptor_indexing`) and a verdict with its evidence
//! (`❌ crash (2/2)`, `✅ passes (7/7; miss probability 0.78%)`).
use super::Verdicts;
use crate::matrix::{AsAccess, Cell, HeapAccess};
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
    /// For a pass: the chance that a fault of the observed rate missed all its attempts.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub miss_probability: Option<f64>,
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
}

/// The line for `cell` from what `verdicts` know; `rate` is the fault rate used for a pass's miss
/// probability (`None`: no estimate).
pub fn line(cell: &Cell, varied: Option<&str>, verdicts: &Verdicts, rate: Option<f64>) -> IsolationLine {
    let description = describe(cell);
    let report = verdicts.get(cell).filter(|r| !r.attempts.is_empty());
    let reason = report.filter(|r| r.outcome == crate::outcome::Outcome::Error).and_then(|r| r.reason.clone());
    let (verdict, agreeing, attempts, miss, injected) = match report {
        None => ("not_run".to_string(), 0, 0, None, None),
        Some(r) => {
            let n = r.attempts.len() as u32;
            let faulted = r.attempts.iter().filter(|a| a.outcome.is_finding()).count() as u32;
            if r.outcome.is_finding() {
                (r.outcome.as_str().to_string(), faulted, n, None, r.injected.clone())
            } else {
                let miss = rate.map(|p| crate::report::run_report::miss_probability(p, n));
                (r.outcome.as_str().to_string(), n - faulted, n, miss, r.injected.clone())
            }
        }
    };
    let evidence = match (verdict.as_str(), miss) {
        ("not_run", _) => "❔ not run".to_string(),
        ("pass", Some(m)) if m > 0.0 => format!("✅ passes ({agreeing}/{attempts}; miss probability {})", percent(m)),
        ("pass", _) => format!("✅ passes ({agreeing}/{attempts})"),
        ("error", _) => format!("⚠ error ({agreeing}/{attempts}): {}", reason.as_deref().unwrap_or("no detail")),
        (v, _) => format!("❌ {v} ({agreeing}/{attempts})"),
    };
    let line = format!("{description}: {evidence}");
    IsolationLine { cell: cell.id(), varied: varied.map(String::from), description, verdict, agreeing, attempts, miss_probability: miss, reason, injected, line }
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
        let c = Cell { stage: Stage::ClosestHit, resource: Resource::StorageBuffer, index: IndexSource::SpecConstant, nonuniform: false, as_access: None, descriptor_model: DescriptorModel::DescriptorIndexing, heap_access: None, canary: None, patch: None, reorder: None };
        assert_eq!(describe(&c), "closest_hit reading storage_buffer with spec_constant index, descriptor_indexing");
        let d = Cell { index: IndexSource::Dynamic, nonuniform: true, patch: Some(crate::matrix::cell::Workaround::SsboToAddress), ..c };
        assert_eq!(describe(&d), "closest_hit reading storage_buffer with dynamic index (nonuniformEXT), descriptor_indexing, patched with ssbo-to-address");
        assert_eq!(percent(0.0078125), "0.78%");
        assert_eq!(percent(1e-9), "< 0.01%");
    }
}
