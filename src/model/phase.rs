//! What a worker is doing, as it tells the supervisor: the supervisor keeps the last phase of each
//! worker, so a `timeout` or `crash` says where it happened (a hang inside
//! vkCreateRayTracingPipelinesKHR is a compiler hang in `pipeline`, not a GPU hang in `trace`).
use serde::{Deserialize, Serialize};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Phase {
    /// Instance, device, scene acceleration structures, resource arrays and address tables:
    /// everything the worker's cells need, built before it reports `ready`.
    Setup,
    /// Building a batch of cells ahead of their turns: their GLSL → SPIR-V and bindings, then
    /// their pipelines on several threads. A fault here is no one cell's: the batch is run again
    /// without prebuilding.
    Prebuild,
    /// GLSL → SPIR-V and SPIR-V workarounds.
    Compile,
    /// Descriptor layouts and sets, pipeline (and SBT) creation.
    Pipeline,
    /// Recording the command buffer.
    Record,
    /// Submitted; waiting for the fence.
    Trace,
    /// Reading the records back.
    Readback,
    /// Comparing the records with the CPU reference.
    Check,
    /// After a cell's result, before the next cell starts.
    BetweenCells,
    /// After the last cell: destroying resources, vkDeviceWaitIdle, process exit.
    Teardown,
}

impl Phase {
    pub const ALL: &'static [Phase] = &[
        Phase::Setup,
        Phase::Prebuild,
        Phase::Compile,
        Phase::Pipeline,
        Phase::Record,
        Phase::Trace,
        Phase::Readback,
        Phase::Check,
        Phase::BetweenCells,
        Phase::Teardown,
    ];

    pub fn as_str(self) -> &'static str {
        match self {
            Phase::Setup => "setup",
            Phase::Prebuild => "prebuild",
            Phase::Compile => "compile",
            Phase::Pipeline => "pipeline",
            Phase::Record => "record",
            Phase::Trace => "trace",
            Phase::Readback => "readback",
            Phase::Check => "check",
            Phase::BetweenCells => "between_cells",
            Phase::Teardown => "teardown",
        }
    }

    /// One of a cell's own steps, from its compile to its check: a fault there is the cell's. The
    /// others are the worker's, before its first cell (setup, prebuild) or after a result.
    pub fn in_cell(self) -> bool {
        match self {
            Phase::Compile
            | Phase::Pipeline
            | Phase::Record
            | Phase::Trace
            | Phase::Readback
            | Phase::Check => true,
            Phase::Setup | Phase::Prebuild | Phase::BetweenCells | Phase::Teardown => false,
        }
    }

    pub fn parse(s: &str) -> Option<Phase> {
        Phase::ALL.iter().copied().find(|p| p.as_str() == s)
    }
}

impl std::fmt::Display for Phase {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_match_serde_and_parse() {
        for p in Phase::ALL {
            assert_eq!(
                serde_json::to_value(p).unwrap(),
                serde_json::Value::String(p.as_str().into())
            );
            assert_eq!(Phase::parse(p.as_str()), Some(*p));
        }
        assert_eq!(Phase::parse("nope"), None);
    }
}
