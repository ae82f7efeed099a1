//! The plan's data: planned cells with their status, the rules that kept combinations out,
//! and which workaround cells are planned.
use crate::model::Cell;
use serde::{Deserialize, Serialize};

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "status", rename_all = "snake_case")]
pub enum PlanStatus {
    Run,
    /// The device's features say it cannot run the cell.
    Unsupported {
        reason: String,
    },
    /// The device could run the cell; rtprobe cannot yet (never blamed on the device).
    NotImplemented {
        reason: String,
    },
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PlannedCell {
    pub cell: Cell,
    #[serde(flatten)]
    pub status: PlanStatus,
}

/// A rule that kept some axis combinations from being generated, and how many.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct NotGenerated {
    pub rule: String,
    pub count: usize,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RunPlan {
    /// Cells of the full matrix (before filters, support checks and workaround variants).
    pub generated: usize,
    pub cells: Vec<PlannedCell>,
    pub not_generated: Vec<NotGenerated>,
    pub filtered_out: usize,
}

impl RunPlan {
    pub fn to_run(&self) -> impl Iterator<Item = &Cell> {
        self.cells.iter().filter(|c| c.status == PlanStatus::Run).map(|c| &c.cell)
    }

    /// Cells the device cannot run (its features say so).
    pub fn unsupported_count(&self) -> usize {
        self.cells.iter().filter(|c| matches!(c.status, PlanStatus::Unsupported { .. })).count()
    }

    /// Cells rtprobe itself cannot run yet: planned and reported, never dropped.
    pub fn not_implemented_count(&self) -> usize {
        self.cells.iter().filter(|c| matches!(c.status, PlanStatus::NotImplemented { .. })).count()
    }
}

/// Which cells of the `patch` axis run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PatchMode {
    /// No patched cells.
    None,
    /// After the run, retry each faulting cell with every workaround that applies to it.
    Faults,
    /// Plan every cell with every workaround that applies to it.
    All,
}
