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

    /// `--cells-scale n`: exactly `n` probe cells to run — the first `n` of the plan's, or all of
    /// them and then copies of each in turn (copy 1 of every cell, then copy 2, ...; each
    /// [`Cell::copy`] has shaders and a pipeline of its own). Canaries and cells that do not run
    /// are kept as they are. Returns how many of the plan's cells were left out.
    pub fn scale_to(&mut self, n: usize) -> usize {
        let probe = |pc: &PlannedCell| pc.status == PlanStatus::Run && pc.cell.canary.is_none();
        let base: Vec<Cell> = self.cells.iter().filter(|pc| probe(pc)).map(|pc| pc.cell).collect();
        let (mut kept, mut dropped) = (0, 0);
        self.cells.retain(|pc| {
            if !probe(pc) {
                return true;
            }
            kept += 1;
            dropped += usize::from(kept > n);
            kept <= n
        });
        let copies = (1..).flat_map(|k| base.iter().map(move |c| Cell { copy: k, ..*c }));
        let more = n.saturating_sub(base.len());
        if !base.is_empty() {
            self.cells.extend(
                copies.take(more).map(|cell| PlannedCell { cell, status: PlanStatus::Run }),
            );
        }
        dropped
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{DescriptorModel, IndexSource, Resource, Stage};

    fn plan(n: usize) -> RunPlan {
        let cell = |i: usize| {
            let stage = [Stage::Raygen, Stage::Miss, Stage::ClosestHit][i % 3];
            let index = [IndexSource::Literal, IndexSource::Dynamic][i / 3 % 2];
            Cell::new(stage, Resource::StorageBuffer, index, DescriptorModel::DescriptorIndexing)
        };
        let mut cells: Vec<PlannedCell> =
            (0..n).map(|i| PlannedCell { cell: cell(i), status: PlanStatus::Run }).collect();
        cells.push(PlannedCell {
            cell: Cell::new(
                Stage::Raygen,
                Resource::UniformBuffer,
                IndexSource::Literal,
                DescriptorModel::DescriptorHeap,
            ),
            status: PlanStatus::Unsupported { reason: "no heap".into() },
        });
        RunPlan { generated: n + 1, cells, not_generated: vec![], filtered_out: 0 }
    }

    #[test]
    fn scaling_up_adds_distinct_copies_and_down_keeps_the_first() {
        let mut p = plan(4);
        assert_eq!(p.scale_to(10), 0);
        let run: Vec<Cell> = p.to_run().copied().collect();
        assert_eq!(run.len(), 10);
        let ids: std::collections::HashSet<String> = run.iter().map(Cell::id).collect();
        assert_eq!(ids.len(), 10, "every cell distinct");
        assert_eq!(run.iter().map(|c| c.copy).collect::<Vec<_>>(), [0, 0, 0, 0, 1, 1, 1, 1, 2, 2]);
        assert_eq!(run[4], Cell { copy: 1, ..run[0] });
        assert_eq!(p.unsupported_count(), 1, "cells that do not run are kept");
        let mut q = plan(6);
        assert_eq!(q.scale_to(2), 4);
        assert_eq!(q.to_run().count(), 2);
        assert!(q.to_run().all(|c| c.copy == 0));
        assert_eq!(q.unsupported_count(), 1);
        let mut same = plan(3);
        assert_eq!(same.scale_to(3), 0);
        assert_eq!(same, plan(3));
    }
}
