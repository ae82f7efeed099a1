//! A repro bundle's `cell.json` (`rtprobe.cell/1`): what `run --cell-spec` needs to run exactly
//! one cell again (the data; `cli::repro` writes and loads it).
use super::{Cell, PipelineMode, SceneParams};
use serde::{Deserialize, Serialize};

pub const SCHEMA: &str = "rtprobe.cell/1";

/// `cell.json`: what `run --cell-spec` needs to run exactly this cell again.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct CellSpec {
    pub schema: String,
    pub id: String,
    pub description: String,
    pub cell: Cell,
    pub scene: SceneParams,
    /// The `--inject-fault` arguments of the original run that apply to this cell.
    pub inject: Vec<String>,
    pub timeout_s: f64,
    /// `RTPROBE_BINDING_STAGES` of the original run (it changes results: a re-run sets it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub binding_stages: Option<String>,
    /// How the original run made its ray tracing pipelines (`--pipelines`, resolved): a linked
    /// pipeline can fault where a whole one does not, so the re-run makes them the same way.
    /// Absent in bundles from before: the re-run's own `--pipelines` then.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pipelines: Option<PipelineMode>,
    /// The verdict in the original report (for comparison), and its device.
    pub original: serde_json::Value,
    /// The bundle's SPIR-V modules (`shaders/<file>`), as the worker runs them, and what made
    /// them: `run --cell-spec` runs these instead of compiling (so another machine's compiler
    /// does not change the binary). Empty in a cell.json without them: then it compiles.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub modules: Vec<BundleModule>,
}

/// One SPIR-V module of a bundle.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct BundleModule {
    /// Under `shaders/`: `<role file>.spv`.
    pub file: String,
    /// The compiler and its version (`shaderc-rs 0.10.1 …`, `glslangValidator 16.6.0 …`).
    pub compiler: String,
    /// SPIR-V patches applied after compiling, in order.
    #[serde(default)]
    pub patched: Vec<String>,
}
