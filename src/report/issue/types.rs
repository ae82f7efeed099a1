//! The issue's data (`--format json`, schema [`SCHEMA`]) and what `rtprobe report` hands the
//! writer: the leaf the issue's files share.
use crate::model::{Attempt, Cell, CellReport, Injection, Outcome, RunReport};
use crate::report::shaders::ShaderError;
use serde::{Deserialize, Serialize};

/// What `rtprobe report` writes (`--format`'s names are in `cli::values`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    Md,
    Json,
}

/// `/2`: the one-screen fields, unified diffs (`/1`'s diffs were `- `/`+ ` lines without hunks).
pub const SCHEMA: &str = "rtprobe.issue/2";

/// What writing the issue, or its shader comparison, fails with.
#[derive(Debug, thiserror::Error)]
pub enum IssueError {
    /// The bisection's representative cell id does not parse.
    #[error("the bisection's minimal failing cell {0:?} is not a cell id")]
    NotACell(String),
    /// A compared cell's shaders could not be made (`cell`: its id).
    #[error("{cell}: {err}")]
    Shaders { cell: String, err: ShaderError },
    /// The cell's shaders lack the one that does the probed read (`cell`: its id).
    #[error("{cell}: no probed shader")]
    NoProbedShader { cell: String },
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Environment {
    pub gpu: String,
    pub vendor: String,
    pub device_id: String,
    pub driver: String,
    pub driver_version: String,
    pub api_version: String,
    pub conformance_version: String,
    pub os: String,
    pub kernel: String,
    pub rtprobe: String,
    /// The driver's `driverInfo` (Mesa: its version and LLVM).
    #[serde(default)]
    pub driver_info: String,
    /// What compiled the failing cell's SPIR-V (`shadergen::compile::compiler_for`).
    #[serde(default)]
    pub compiler: String,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ShaderComparison {
    pub failing_cell: String,
    pub passing_cell: Option<String>,
    pub file: String,
    pub glsl: String,
    /// The unified diff from the passing sibling's GLSL to the failing one's.
    pub glsl_diff: Option<String>,
    /// `spirv-dis` output, or why there is none.
    pub spirv: String,
    /// The unified diff of the disassemblies (numeric ids masked when matching lines).
    pub spirv_diff: Option<String>,
    /// The probed read and its declarations, from the failing shader's GLSL.
    #[serde(default)]
    pub excerpt: String,
}

/// The failing cell re-run once alone under VK_LAYER_KHRONOS_validation by `rtprobe report`, or
/// why it was not.
#[derive(Clone, Debug)]
pub enum ValidationRun {
    NotRun(String),
    /// `layer`: the layer and its version; `attempt`: what the run recorded; `control`: where
    /// the cell never ran (its worker failed in setup, before the cell's turn), a cell that
    /// passed in the run, re-run alone under the same layer: what it did is shown as observed.
    Ran {
        layer: String,
        attempt: Box<Attempt>,
        control: Option<ControlRun>,
    },
}

/// A control cell re-run alone under the validation layer, and what it recorded.
#[derive(Clone, Debug)]
pub struct ControlRun {
    pub cell: String,
    pub attempt: Box<Attempt>,
}

/// The device's ray tracing pipeline properties the SBT layout depends on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct SbtProps {
    pub handle_size: u32,
    pub handle_alignment: u32,
    pub base_alignment: u32,
    pub max_recursion_depth: u32,
}

/// What `rtprobe report` adds to the run report and its bisection.
#[derive(Clone, Debug)]
pub struct Extras<'a> {
    /// A report of the same device made with `--lane-evidence force` (lane evidence of a stage
    /// the device lists no subgroups in), for the Lane evidence line.
    pub lanes: Option<&'a RunReport>,
    pub validation: ValidationRun,
    /// The device's SBT properties, when the device is on the machine writing the issue.
    pub sbt: Option<SbtProps>,
}

impl Default for Extras<'_> {
    fn default() -> Self {
        Extras { lanes: None, validation: ValidationRun::NotRun("not asked for".into()), sbt: None }
    }
}

/// The one-screen facts a driver engineer checks first.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct Facts {
    /// Expected against actual values (the first mismatching pixel), or what happened instead.
    pub values: String,
    /// The descriptor layout: binding, type, array size and binding flags; for heaps the mapping,
    /// the shader record bytes and the byte offsets.
    pub layout: String,
    /// The index values the probe uses and whether they are in bounds.
    pub index: String,
    /// The SBT layout and recursion depth (ray tracing cells; empty otherwise).
    pub sbt: String,
}

/// The one-line reproducer, what it prints, and the reproducer without rtprobe (an Amber script,
/// or why none).
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct Reproducer {
    pub command: String,
    pub prints: String,
    pub without_rtprobe: String,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Issue {
    pub schema: String,
    pub title: String,
    /// Set when the fault was injected with `--inject-fault`: not a driver bug.
    pub injected: Option<String>,
    /// One sentence of what the evidence says the driver does (`diagnosis`), empty where it
    /// supports none.
    #[serde(default)]
    pub diagnosis: String,
    pub environment: Environment,
    pub summary: String,
    /// The fault-rate statistics (in the collapsed isolation section).
    pub incidence: String,
    /// The minimal failing cell's attempts, stated once: "6 of 6 attempts faulted, every one".
    #[serde(default)]
    pub attempts: String,
    pub expected: String,
    pub actual: String,
    #[serde(default)]
    pub facts: Facts,
    #[serde(default)]
    pub reproducer: Reproducer,
    pub minimal: String,
    pub separable: bool,
    /// The bisection's isolation lines, with their statistics.
    pub isolation: Vec<String>,
    /// The isolation list on one screen: per varied axis, the siblings' values and verdicts.
    #[serde(default)]
    pub isolation_summary: Vec<String>,
    pub shader: Option<ShaderComparison>,
    pub shader_error: Option<String>,
    pub device_fault: String,
    pub validation: String,
    pub reproduce: Vec<String>,
    /// The workaround patches, one count each (or that none applies).
    pub workarounds: Vec<String>,
    /// The bisection's workaround lines, with their statistics.
    #[serde(default)]
    pub workaround_details: Vec<String>,
    /// Whether the engines' recommended pattern nearest the minimal failing cell works on this
    /// driver (`report::recommended`): "recommended pattern X (…): passes (k/N)" / fails / not run.
    #[serde(default)]
    pub recommended_pattern: String,
    /// How the minimal failing cell's mismatching pixels split by their subgroup lane evidence,
    /// or why there is none (`model::lanes`).
    #[serde(default)]
    pub lanes: String,
    /// For a descriptor-heap cell: binding 2's mapping, the shader record bytes and where the
    /// probed descriptors sit in the heap.
    #[serde(default)]
    pub heap: String,
    pub not_tested: Vec<String>,
}

/// The representative cell, its report entry, outcome, injection and attempts (agreeing, all).
pub(super) struct Representative<'a> {
    pub(super) cell: Cell,
    pub(super) entry: Option<&'a CellReport>,
    pub(super) outcome: Outcome,
    pub(super) injection: Option<&'a Injection>,
    pub(super) agree: u32,
    pub(super) n: u32,
}
