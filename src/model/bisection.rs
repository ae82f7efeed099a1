//! The bisection file (`bisect --json FILE`, schema `rtprobe.bisect/1`) that `report --bisect`
//! reads: the [`Bisection`] with where it came from.
use serde::{Deserialize, Serialize};
use serde_json::Value;
use std::path::{Path, PathBuf};

pub const SCHEMA: &str = "rtprobe.bisect/1";

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct BisectFile {
    pub schema: String,
    pub report: PathBuf,
    /// The bisected report's `started` stamp: `report --bisect` refuses another report.
    #[serde(default)]
    pub report_started: String,
    pub device: Value,
    /// The scope's filters (empty: the whole matrix).
    pub scope: Vec<String>,
    pub full_matrix: usize,
    pub inject: Vec<String>,
    pub offline: bool,
    /// The device UUID of the card the bisection re-ran cells on when the report's card was not
    /// on the machine (another card of the same name and driver build); absent on the same card.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub device_uuid_rerun: Option<String>,
    #[serde(flatten)]
    pub bisection: Bisection,
    /// The text `bisect` printed.
    pub text: String,
}

impl BisectFile {
    pub fn load(path: &Path) -> Result<BisectFile, super::LoadError> {
        let f: BisectFile = super::load::read_json(path, "bisection")?;
        super::load::check_schema(path, &f.schema, SCHEMA)?;
        Ok(f)
    }
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
    /// The minimal failing cell's fault rate: the one-sided Clopper–Pearson lower bound at
    /// `confidence` from its k of N (None: it has no attempt).
    #[serde(default)]
    pub fault_rate_bound: Option<f64>,
    #[serde(default = "default_confidence")]
    pub confidence: f64,
    /// Attempts a pass held to that bound needs for a miss probability below `max_miss`.
    pub attempts_per_pass: u32,
    pub max_miss: f64,
    /// The largest miss probability of a pass bisection relied on (per pass, not for the result
    /// as a whole).
    pub worst_miss_probability: f64,
    /// The union (Bonferroni) bound on the chance that any pass relied on missed its fault: the
    /// sum of the per-pass miss probabilities, capped at 1.
    #[serde(default)]
    pub union_miss_probability: f64,
    /// Passes bisection relied on (each the reason a wider conjunction was refused, a sibling in
    /// the isolation list, or a workaround).
    #[serde(default)]
    pub passes_relied_on: usize,
    /// Passes relied on that could not reach the threshold (attempt cap, or offline): the result
    /// is not concluded while any is listed.
    pub unsettled: Vec<String>,
    pub faulting_cells: usize,
    pub scope_cells: usize,
    /// Cells of the scope with no verdict (never needed, or offline).
    pub not_run: usize,
    /// Cells of the scope rtprobe could not run (`error`): used neither as faults nor as passes.
    #[serde(default)]
    pub errored: Vec<String>,
    /// Cells of the scope whose verdict rtprobe doubts (a fault of a read the spec leaves
    /// undefined, a suspect lenient pass), each with why: used neither as faults nor as passes.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub doubtful: Vec<String>,
    /// Attempts bisection ran itself.
    pub runs: usize,
    /// Axes with a single value in the scope: the conjunction says nothing about them.
    pub not_varied: Vec<String>,
}

fn default_confidence() -> f64 {
    super::stats::CONFIDENCE
}

impl Bisection {
    /// Every pass relied on reached the threshold.
    pub fn concluded(&self) -> bool {
        self.unsettled.is_empty()
    }
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
