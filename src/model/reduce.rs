//! `rtprobe reduce`'s file (`rtprobe.reduce/1`): the finding it started from (report, cell,
//! the original module's hash and outcome), what spirv-reduce did (steps, interestingness
//! runs, wall time), function-body instruction counts before and after, and the remaining
//! descriptor accesses classified on the matrix's axes with the `--filter` predicate they make.
use super::{IndexSource, Outcome, Resource, Stage};
use serde::{Deserialize, Serialize};

pub const SCHEMA: &str = "rtprobe.reduce/1";

/// One remaining descriptor access, on the matrix's axes.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct AccessClass {
    pub stage: Stage,
    pub resource: Resource,
    pub index: IndexSource,
    /// What makes the index what it is: built-ins (`gl_InstanceCustomIndexEXT`), loads,
    /// `push_constant`, `spec_constant`, `literal`.
    pub index_from: Vec<String>,
    /// The access (or its index) is decorated `NonUniform`.
    pub nonuniform: bool,
    /// The variable's set and binding (`None`: a heap or address access).
    pub set: Option<u32>,
    pub binding: Option<u32>,
    pub variable: String,
    /// `descriptor` (a set/binding variable), `heap` (a descriptor heap), `address` (an
    /// acceleration structure from a 64-bit address).
    pub through: String,
    /// The instruction (`OpLoad`, `OpAtomicIAdd`, …).
    pub op: String,
}

impl AccessClass {
    /// The access in words: `closest_hit reads storage_buffer `buf` (dynamic index from
    /// gl_InstanceCustomIndexEXT, NonUniform), through descriptor`.
    pub fn sentence(&self) -> String {
        format!(
            "{} reads {} `{}` ({} index from {}{}), through {}",
            self.stage,
            self.resource,
            self.variable,
            self.index,
            self.index_from.join(", "),
            if self.nonuniform { ", NonUniform" } else { "" },
            self.through
        )
    }
}

/// The `--filter` predicate of accesses: each axis's values, joined by `|` where they differ.
pub fn predicate(accesses: &[AccessClass]) -> String {
    fn axis<T: Ord + Copy>(accesses: &[AccessClass], f: fn(&AccessClass) -> T) -> Vec<T> {
        let mut v: Vec<T> = accesses.iter().map(f).collect();
        v.sort();
        v.dedup();
        v
    }
    let join = |v: Vec<&str>| v.join("|");
    let stage = join(axis(accesses, |a| a.stage).iter().map(|s| s.as_str()).collect());
    let resource = join(axis(accesses, |a| a.resource).iter().map(|s| s.as_str()).collect());
    let index = join(axis(accesses, |a| a.index).iter().map(|s| s.as_str()).collect());
    if accesses.is_empty() {
        return String::new();
    }
    format!("stage={stage},resource={resource},index={index}")
}

/// Function-body instruction counts (`OpFunction` through `OpFunctionEnd`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Counts {
    pub before: usize,
    pub after: usize,
}

/// What `reduce` did.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ReduceReport {
    pub schema: String,
    pub rtprobe_version: String,
    /// The `run --shader` report reduced from.
    pub report: String,
    pub cell: String,
    pub device: String,
    /// The module reduced: its file and the FNV-1a 128 hash of its input.
    pub module: String,
    pub original_hash: String,
    /// Why this module (`the injection matched it`, `the faulting stage`, …).
    pub chosen_because: String,
    /// The finding's outcomes a candidate had to reproduce (`crash`, …).
    pub outcomes: Vec<Outcome>,
    /// `--inject-fault`'s request re-applied to every candidate.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub injection: Option<String>,
    /// Attempts per candidate, from the finding's incidence.
    pub attempts_per_candidate: u32,
    /// The chance that the final step's attempts all missed a fault of the finding's rate.
    pub final_miss_probability: f64,
    /// Candidates spirv-reduce found interesting (its steps that stuck).
    pub steps: u32,
    /// Times the interestingness test ran.
    pub interestingness_runs: u32,
    /// Of those, refused before any device run (spirv-val, an index not provably in bounds).
    pub refused_statically: u32,
    pub wall_s: f64,
    pub instructions: Counts,
    pub reducer: String,
    pub classification: Vec<AccessClass>,
    pub predicate: String,
    /// Each applicable patch run on the original modules (step 6), verified or not.
    #[serde(default)]
    pub workarounds: Vec<ReduceWorkaround>,
    /// Patches that do not apply to the original, and why.
    #[serde(default)]
    pub not_applicable: Vec<String>,
    /// The matrix's slice of the predicate (step 5); `None`: not run.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub slice: Option<Slice>,
}

impl ReduceReport {
    /// The reduction in words: instructions before and after, steps, runs, wall time.
    pub fn reduction_text(&self) -> String {
        let c = self.instructions;
        format!(
            "{} function-body instructions to {} ({:.0}%), {} steps, {} interestingness runs ({} refused before the device), {:.1} s",
            c.before,
            c.after,
            100.0 * c.after as f64 / c.before.max(1) as f64,
            self.steps,
            self.interestingness_runs,
            self.refused_statically,
            self.wall_s
        )
    }
}

/// One patch run on the user's original modules with the finding's evidence.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ReduceWorkaround {
    pub patch: String,
    /// No attempt faulted, none had a validation message or differed from the original's.
    pub verified: bool,
    /// The verdict in words.
    pub line: String,
    pub attempts: u32,
    pub faulted: u32,
    pub validation_messages: u64,
    /// The first difference from the original's outputs.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub differs: Option<String>,
    /// Whether the outputs were compared with the original's (false: it produced none).
    pub compared: bool,
    /// With an injected finding: the faults its request put into the patched original (0: the
    /// patch removed the shape).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub injected_faults: Option<usize>,
    /// What the host must bind or pass differently (`rtprobe patch`'s sentence).
    pub host_contract: String,
    /// The patched modules written into DIR (`patched-PATCH.spv (FILE)`), when verified.
    #[serde(default)]
    pub files: Vec<String>,
    /// The host contract's file in DIR (`rtprobe.patch-contract/1`), when verified.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub contract_file: Option<String>,
}

/// rtprobe's own cells of the predicate's shape, run (step 5).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Slice {
    /// The `rtprobe run` command that ran them.
    pub command: String,
    /// Its report, in DIR.
    pub report: String,
    /// Cells the predicate generates, and those this slice planned (a shard when capped).
    pub generated: u32,
    pub planned: u32,
    /// Cells that ran, and those that faulted.
    pub ran: u32,
    pub faulted: Vec<String>,
    /// The injection the slice ran with (the finding's predicate), when the finding was injected.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub injection: Option<String>,
    /// The verdict in words.
    pub line: String,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn access(stage: Stage, resource: Resource, index: IndexSource) -> AccessClass {
        AccessClass {
            stage,
            resource,
            index,
            index_from: vec![],
            nonuniform: false,
            set: Some(0),
            binding: Some(0),
            variable: "v".into(),
            through: "descriptor".into(),
            op: "OpLoad".into(),
        }
    }

    #[test]
    fn one_access_is_one_value_per_axis_and_others_are_alternatives() {
        let a = access(Stage::ClosestHit, Resource::StorageBuffer, IndexSource::Dynamic);
        assert_eq!(
            predicate(std::slice::from_ref(&a)),
            "stage=closest_hit,resource=storage_buffer,index=dynamic"
        );
        let b = access(Stage::ClosestHit, Resource::SampledImage, IndexSource::Literal);
        assert_eq!(
            predicate(&[a, b]),
            "stage=closest_hit,resource=storage_buffer|sampled_image,index=literal|dynamic"
        );
        assert_eq!(predicate(&[]), "");
    }

    #[test]
    fn an_access_sentence_names_its_index_sources_and_nonuniform() {
        let mut a = access(Stage::ClosestHit, Resource::StorageBuffer, IndexSource::Dynamic);
        a.index_from = vec!["gl_InstanceCustomIndexEXT".into(), "push_constant".into()];
        assert_eq!(
            a.sentence(),
            "closest_hit reads storage_buffer `v` (dynamic index from gl_InstanceCustomIndexEXT, push_constant), through descriptor"
        );
        a.nonuniform = true;
        assert!(a.sentence().contains("push_constant, NonUniform)"), "{}", a.sentence());
    }

    #[test]
    fn the_reduction_text_gives_the_share_left_and_survives_an_empty_original() {
        let text = |before, after| {
            let r: ReduceReport = serde_json::from_value(serde_json::json!({
                "schema": SCHEMA, "rtprobe_version": "0", "report": "r.json", "cell": "c",
                "device": "d", "module": "m", "original_hash": "h", "chosen_because": "b",
                "outcomes": ["crash"], "attempts_per_candidate": 3,
                "final_miss_probability": 0.001, "steps": 48, "interestingness_runs": 164,
                "refused_statically": 61, "wall_s": 55.96,
                "instructions": {"before": before, "after": after}, "reducer": "spirv-reduce",
                "classification": [], "predicate": ""
            }))
            .unwrap();
            r.reduction_text()
        };
        assert_eq!(
            text(61, 16),
            "61 function-body instructions to 16 (26%), 48 steps, 164 interestingness runs (61 refused before the device), 56.0 s"
        );
        assert!(text(0, 0).starts_with("0 function-body instructions to 0 (0%)"));
    }
}
