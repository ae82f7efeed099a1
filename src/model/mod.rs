//! The data layer: everything rtprobe writes down or reads back — axes and cells, outcomes,
//! comparisons, attempts, plans, run reports with their typed options, baselines, bisections —
//! and the statistics they are judged by. Serde types and pure functions only: this module
//! imports nothing else of the crate, and everything above reads and writes through it (as
//! nextest keeps its schema below its runner).
pub mod attempt;
pub mod axes;
pub mod base64;
pub mod baseline;
pub mod bisection;
pub mod bundle;
pub mod cell;
pub mod comparison;
pub mod contract;
pub mod count;
pub mod driver_cache;
pub mod fault;
pub mod filter;
pub mod findings;
pub mod index_bounds;
pub mod inject;
pub mod lanes;
pub mod load;
pub mod mutant;
pub mod native_backtrace;
pub mod options;
pub mod outcome;
pub mod phase;
pub mod plan;
pub mod profile;
pub mod reduce;
pub mod registry;
pub mod report;
pub mod scene;
pub mod shader_gpu_av;
pub mod shader_injection;
pub mod shader_options;
pub mod shader_outputs;
pub mod shader_run;
pub mod stats;
pub mod text;
pub mod validation_message;

pub use attempt::{signal_name, Attempt, Halt, Isolation, WorkerEvent, WorkerExit};
pub use axes::{
    AsAccess, BaseSource, DescriptorModel, HeapAccess, IndexSource, Reorder, Resource,
    SamplerIndex, SceneLayout, Stage,
};
pub use baseline::{
    Baseline, BaselineCheck, CellCheck, Expectation, PerfBound, Status, WorkerFault,
};
pub use bisection::{BisectFile, Bisection, IsolationLine};
pub use cell::{undefined_descriptor_read, Canary, Cell, Pattern, Workaround, NO_NONUNIFORM_VUID};
pub use comparison::{Comparison, ElementReads, Mismatch, MutantPrediction, OTHER_LANE_HEURISTIC};
pub use driver_cache::{DriverCache, DriverCacheSummary};
pub use fault::{FaultAddress, FaultInfo, FaultVendorInfo};
pub use filter::{Filter, FilterError};
pub use findings::{GpuAvResult, GpuAvVerdict, PatternResult, PatternStatus};
pub use inject::{FaultKind, InjectError, InjectedFault, Injection};
pub use lanes::{LaneEvidence, LaneMode, LaneSplit, Split};
pub use load::LoadError;
pub use mutant::{Mutant, MutantEntry, MutantReport, MutantStatus};
pub use options::PipelineMode;
pub use outcome::{CellResult, Outcome, Timings};
pub use phase::Phase;
pub use plan::{NotGenerated, PatchMode, PlanStatus, PlannedCell, RunPlan};
pub use report::{CellReport, Incidence, RunReport, WorkaroundResult};
pub use scene::{SceneCost, SceneError, SceneFile, SceneLimit, SceneParams};
pub use text::{nearest, plural};
