//! The closed set of cell outcomes and what a worker reports for one cell. Every reporter
//! matches [`Outcome`] exhaustively (no wildcard arms), so a new outcome cannot be forgotten.
use crate::model::Comparison;
use crate::model::FaultInfo;
use serde::{Deserialize, Serialize};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// Every compared record matched the CPU reference.
    Pass,
    /// The cell ran but some records differ from the CPU reference.
    Mismatch,
    /// `VK_ERROR_DEVICE_LOST` (with VK_EXT_device_fault details where available).
    DeviceLost,
    /// The worker process died (signal or abnormal exit) while running the cell.
    Crash,
    /// The cell did not finish within its deadline.
    Timeout,
    /// The device cannot run the cell (reason from its queried features).
    Unsupported,
    /// The device could run the cell but rtprobe cannot yet (its own gap, with the reason).
    NotImplemented,
    /// rtprobe could not run the cell (compile error, Vulkan error other than device loss).
    Error,
}

impl Outcome {
    pub const ALL: &'static [Outcome] = &[
        Outcome::Pass,
        Outcome::Mismatch,
        Outcome::DeviceLost,
        Outcome::Crash,
        Outcome::Timeout,
        Outcome::Unsupported,
        Outcome::NotImplemented,
        Outcome::Error,
    ];

    pub fn as_str(self) -> &'static str {
        match self {
            Outcome::Pass => "pass",
            Outcome::Mismatch => "mismatch",
            Outcome::DeviceLost => "device_lost",
            Outcome::Crash => "crash",
            Outcome::Timeout => "timeout",
            Outcome::Unsupported => "unsupported",
            Outcome::NotImplemented => "not_implemented",
            Outcome::Error => "error",
        }
    }

    /// A finding: something the user must look at (run exits 1).
    pub fn is_finding(self) -> bool {
        match self {
            Outcome::Pass | Outcome::Unsupported | Outcome::NotImplemented => false,
            Outcome::Mismatch
            | Outcome::DeviceLost
            | Outcome::Crash
            | Outcome::Timeout
            | Outcome::Error => true,
        }
    }

    /// A fault of the driver or device that ends the worker (it must be replaced).
    pub fn ends_worker(self) -> bool {
        match self {
            Outcome::DeviceLost | Outcome::Crash | Outcome::Timeout => true,
            Outcome::Pass
            | Outcome::Mismatch
            | Outcome::Unsupported
            | Outcome::NotImplemented
            | Outcome::Error => false,
        }
    }

    /// How bad an attempt's outcome is: a cell's verdict is its worst attempt. Faults of the
    /// driver rank above a mismatch, which ranks above rtprobe's own errors.
    pub fn severity(self) -> u8 {
        match self {
            Outcome::Pass => 0,
            Outcome::Unsupported => 1,
            Outcome::NotImplemented => 2,
            Outcome::Error => 3,
            Outcome::Mismatch => 4,
            Outcome::Timeout => 5,
            Outcome::Crash => 6,
            Outcome::DeviceLost => 7,
        }
    }

    /// Worth re-running alone in a fresh worker (`--confirm`).
    pub fn worth_confirming(self) -> bool {
        match self {
            Outcome::Mismatch | Outcome::DeviceLost | Outcome::Crash | Outcome::Timeout => true,
            Outcome::Pass | Outcome::Unsupported | Outcome::NotImplemented | Outcome::Error => {
                false
            }
        }
    }
}

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Timings {
    /// GLSL → SPIR-V (0 when every source was cached).
    pub compile_ms: f64,
    /// Pipeline (and SBT) creation (0 when reused).
    pub pipeline_ms: f64,
    /// Scene / resources / descriptors created for this cell (0 when reused).
    pub setup_ms: f64,
    /// Submit to fence: the trace (on lavapipe it includes the lazy shader JIT).
    pub trace_ms: f64,
    /// Reading back and comparing the records.
    pub check_ms: f64,
    /// The readback alone (copying and decoding the records; part of `check_ms`; 0 in older
    /// reports).
    #[serde(default)]
    pub readback_ms: f64,
    pub total_ms: f64,
    /// Time the worker's cell thread spent on this cell's pipeline: creating it at the cell's
    /// turn (then equal to `pipeline_ms`, inside `total_ms`), or blocked waiting for the
    /// prebuild's threads to make it (before the turn, outside `total_ms`). 0 when the pipeline
    /// was ready (and in older reports).
    #[serde(default)]
    pub pipeline_wait_ms: f64,
}

/// What a worker reports for one cell.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CellResult {
    pub outcome: Outcome,
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub detail: Option<String>,
    pub timings: Timings,
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub comparison: Option<Comparison>,
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub fault: Option<FaultInfo>,
    /// Errors the validation layer reported while this cell ran (with `--validate`): rtprobe
    /// itself misused the API, so the cell's outcome is not evidence about the driver.
    #[serde(skip_serializing_if = "is_zero", default)]
    pub validation_errors: u64,
}

fn is_zero(n: &u64) -> bool {
    *n == 0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_match_serde() {
        for o in Outcome::ALL {
            assert_eq!(
                serde_json::to_value(o).unwrap(),
                serde_json::Value::String(o.as_str().into())
            );
        }
        assert!(!Outcome::Unsupported.is_finding());
        assert!(Outcome::Crash.ends_worker() && !Outcome::Mismatch.ends_worker());
        // Severity is a total order over every outcome, and every finding outranks a pass.
        let mut s: Vec<u8> = Outcome::ALL.iter().map(|o| o.severity()).collect();
        s.sort();
        s.dedup();
        assert_eq!(s.len(), Outcome::ALL.len());
        for o in Outcome::ALL {
            assert!(!o.is_finding() || o.severity() > Outcome::Pass.severity());
        }
    }
}
