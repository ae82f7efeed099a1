//! The options a run was made with, typed (the report's `options`), and which of them change
//! results (what `--resume` and `merge` compare).
use super::{Isolation, PatchMode};
use serde::{Deserialize, Serialize};
use serde_json::Value;
use std::path::PathBuf;

/// The options a run was made with (the report's `options`): what `--resume`, `merge`, `bisect`,
/// `repro` and the renderers read back. Any field a report lacks takes the default an untyped
/// read gave it before (`Default`: jobs unknown, worker isolation, 20 s, confirm, `--patches faults`),
/// and keys this release does not know are kept (`extra`), so rewriting a report (merge,
/// `--resume`) loses nothing.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(default)]
pub struct RunOptions {
    /// Workers at once (`None`: a report without it, or with `null`: readers pick their own
    /// default, as bisect picks the device's).
    pub jobs: Option<usize>,
    /// Fresh workers at once for cells re-run alone (confirm, repeats, verifying repeats): `jobs`
    /// at most one per core on CPU devices, 1 on GPUs (absent in reports before it; changes no
    /// result: each re-run is still alone in its process).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rerun_jobs: Option<usize>,
    /// Threads a worker creates pipelines on (absent in reports before the prebuild).
    #[serde(default)]
    pub threads: Option<usize>,
    /// The persisted pipeline cache folder (`None`: off).
    #[serde(default)]
    pub pipeline_cache: Option<PathBuf>,
    /// The cache re-runs load (always `None`: re-runs start cold).
    #[serde(default)]
    pub rerun_pipeline_cache: Option<PathBuf>,
    pub isolation: Isolation,
    pub timeout_s: f64,
    /// The worker setup deadline (absent in the first reports).
    #[serde(default)]
    pub setup_timeout_s: Option<f64>,
    pub confirm: bool,
    pub canaries: bool,
    /// `--filter` arguments as given.
    pub filters: Vec<String>,
    /// `--skips` patterns (regular expressions over cell ids), read from its file.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub skips: Vec<String>,
    pub patches: PatchMode,
    pub validate: bool,
    #[serde(default)]
    pub gpu_av: bool,
    /// `--inject-fault` arguments as given.
    pub inject: Vec<String>,
    pub repeat: Option<u32>,
    /// `--shard I/N` as given.
    pub shard: Option<String>,
    /// How ray tracing pipelines were made (`--pipelines`, resolved for the device; absent in
    /// reports before it: whole).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pipelines: Option<PipelineMode>,
    /// `--cells-scale N`: the probe cells were cut or copied to exactly N.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cells_scale: Option<usize>,
    /// `RTPROBE_BINDING_STAGES` as set for the run.
    pub binding_stages: Option<String>,
    /// `--lane-evidence`: where the probe measured its subgroup lane evidence (absent: `auto`).
    #[serde(default)]
    pub lane_evidence: super::LaneMode,
    /// A repro bundle's `shaders/` the workers ran (`run --cell-spec`).
    #[serde(default)]
    pub spirv_from: Option<PathBuf>,
    /// The reports `merge` joined into this one.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub merged_from: Vec<String>,
    /// `--mutants` / `--mutant NAME`: the mutants the run tries on its passing cells (empty:
    /// none). They add the kill matrix; no cell's verdict depends on them.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub mutants: Vec<super::mutant::Mutant>,
    /// `--mutants-sample N:SEED` as given: the run tried a seeded sample of N (cell, mutant)
    /// pairs.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mutants_sample: Option<String>,
    /// Options of another release this one does not read, kept as they were.
    #[serde(flatten)]
    pub extra: serde_json::Map<String, Value>,
}

/// How a run makes its ray tracing pipelines (`--pipelines`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PipelineMode {
    /// `linked` on GPUs that have VK_KHR_pipeline_library, `whole` on CPU devices.
    Auto,
    /// Each pipeline linked from one library per shader group, shared between cells.
    Linked,
    /// Each pipeline made from all its stages.
    Whole,
}

impl Default for RunOptions {
    fn default() -> RunOptions {
        RunOptions {
            jobs: None,
            rerun_jobs: None,
            threads: None,
            pipeline_cache: None,
            rerun_pipeline_cache: None,
            isolation: Isolation::Worker,
            timeout_s: 20.0,
            setup_timeout_s: None,
            confirm: true,
            canaries: false,
            filters: vec![],
            skips: vec![],
            patches: PatchMode::Faults,
            validate: false,
            gpu_av: false,
            inject: vec![],
            repeat: None,
            shard: None,
            pipelines: None,
            cells_scale: None,
            binding_stages: None,
            lane_evidence: super::LaneMode::Auto,
            spirv_from: None,
            merged_from: vec![],
            mutants: vec![],
            mutants_sample: None,
            extra: serde_json::Map::new(),
        }
    }
}

impl RunOptions {
    /// The options of a plain `rtprobe run` (unit tests of reporters and fleet tools).
    #[cfg(test)]
    pub fn for_tests() -> RunOptions {
        RunOptions { threads: Some(1), setup_timeout_s: Some(120.0), ..RunOptions::default() }
    }
}

/// The options that change results: runs that differ in one of them are not continued
/// (`--resume`), merged or compared like-for-like. `jobs`, `threads`, `shard` and paths do not.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ResultOption {
    Patches,
    Inject,
    Filters,
    /// `--skips` (absent: none).
    Skips,
    Canaries,
    Validate,
    Timeout,
    Confirm,
    Repeat,
    Isolation,
    BindingStages,
    /// The subgroup code in the probe changes its code generation.
    LaneEvidence,
    /// Not result-changing for `merge` (shards are what it joins), but `--resume` keeps it.
    Shard,
}

impl ResultOption {
    /// Every option `merge` compares.
    pub const MERGED: &'static [ResultOption] = &[
        ResultOption::Patches,
        ResultOption::Inject,
        ResultOption::Filters,
        ResultOption::Skips,
        ResultOption::Canaries,
        ResultOption::Validate,
        ResultOption::Timeout,
        ResultOption::Confirm,
        ResultOption::Repeat,
        ResultOption::Isolation,
        ResultOption::BindingStages,
        ResultOption::LaneEvidence,
    ];

    /// The flag (or variable) the option comes from, for messages.
    pub fn flag(self) -> &'static str {
        match self {
            ResultOption::Patches => "--patches",
            ResultOption::Inject => "--inject-fault",
            ResultOption::Filters => "--filter",
            ResultOption::Skips => "--skips",
            ResultOption::Canaries => "--canaries",
            ResultOption::Validate => "--validate",
            ResultOption::Timeout => "--timeout",
            ResultOption::Confirm => "--no-confirm",
            ResultOption::Repeat => "--repeat",
            ResultOption::Isolation => "--isolation",
            ResultOption::BindingStages => "RTPROBE_BINDING_STAGES",
            ResultOption::LaneEvidence => "--lane-evidence",
            ResultOption::Shard => "--shard",
        }
    }

    /// The option's value in `o`, as the report writes it.
    pub fn value(self, o: &RunOptions) -> Value {
        let v = match self {
            ResultOption::Patches => serde_json::to_value(o.patches),
            ResultOption::Inject => serde_json::to_value(&o.inject),
            ResultOption::Filters => serde_json::to_value(&o.filters),
            ResultOption::Skips => serde_json::to_value(&o.skips),
            ResultOption::Canaries => serde_json::to_value(o.canaries),
            ResultOption::Validate => serde_json::to_value(o.validate),
            ResultOption::Timeout => serde_json::to_value(o.timeout_s),
            ResultOption::Confirm => serde_json::to_value(o.confirm),
            ResultOption::Repeat => serde_json::to_value(o.repeat),
            ResultOption::Isolation => serde_json::to_value(o.isolation),
            ResultOption::BindingStages => serde_json::to_value(&o.binding_stages),
            ResultOption::LaneEvidence => serde_json::to_value(o.lane_evidence),
            ResultOption::Shard => serde_json::to_value(&o.shard),
        };
        v.unwrap_or(Value::Null)
    }
}
