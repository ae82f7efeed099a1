//! `--shard I/N`: a deterministic, balanced split of the planned cells for a CI system's parallel
//! jobs (GitLab `parallel:`, a GitHub matrix). Cells are ordered by id (never by run order) and
//! dealt round-robin, so shard sizes differ by at most one and the same plan splits the same way
//! on every machine; workaround retries and confirmations follow their cell.
use crate::model::RunPlan;
use serde::{Deserialize, Serialize};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Shard {
    /// 1-based.
    pub index: u32,
    pub count: u32,
}

/// A `--shard` that is not `I/N` with 1 <= I <= N.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("--shard {0:?} is not I/N with 1 <= I <= N (e.g. 2/3)")]
pub struct ShardError(pub String);

impl Shard {
    pub fn parse(s: &str) -> Result<Shard, ShardError> {
        let bad = || ShardError(s.into());
        let (i, n) = s.split_once('/').ok_or_else(bad)?;
        let (index, count): (u32, u32) =
            (i.trim().parse().map_err(|_| bad())?, n.trim().parse().map_err(|_| bad())?);
        if count == 0 || index == 0 || index > count {
            return Err(bad());
        }
        Ok(Shard { index, count })
    }

    pub fn label(&self) -> String {
        format!("{}/{}", self.index, self.count)
    }

    /// Keep this shard's cells of `plan`; returns how many went to other shards.
    pub fn apply(&self, plan: &mut RunPlan) -> usize {
        let mut ids: Vec<String> = plan.cells.iter().map(|c| c.cell.id()).collect();
        ids.sort();
        let mine: std::collections::HashSet<String> = ids
            .into_iter()
            .enumerate()
            .filter(|(k, _)| *k as u32 % self.count == self.index - 1)
            .map(|(_, id)| id)
            .collect();
        let before = plan.cells.len();
        plan.cells.retain(|c| mine.contains(&c.cell.id()));
        before - plan.cells.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::matrix::plan::all_cells;
    use crate::model::{PlanStatus, PlannedCell};

    fn full() -> RunPlan {
        let (cells, not_generated) = all_cells();
        RunPlan {
            generated: cells.len(),
            cells: cells
                .into_iter()
                .map(|cell| PlannedCell { cell, status: PlanStatus::Run })
                .collect(),
            not_generated,
            filtered_out: 0,
        }
    }

    #[test]
    fn shards_partition_the_plan_and_are_balanced() {
        let total = full().cells.len();
        let mut seen = std::collections::HashSet::new();
        let mut sizes = vec![];
        for i in 1..=3 {
            let mut p = full();
            let out = Shard { index: i, count: 3 }.apply(&mut p);
            assert_eq!(out + p.cells.len(), total);
            sizes.push(p.cells.len());
            for c in &p.cells {
                assert!(seen.insert(c.cell.id()), "{} in two shards", c.cell.id());
            }
        }
        assert_eq!(seen.len(), total);
        assert!(sizes.iter().max().unwrap() - sizes.iter().min().unwrap() <= 1, "{sizes:?}");
        // Plan order inside a shard is kept (canaries stay last).
        let mut p = full();
        Shard { index: 2, count: 3 }.apply(&mut p);
        let mut q = full();
        Shard { index: 2, count: 3 }.apply(&mut q);
        assert_eq!(p, q);
    }

    #[test]
    fn parses() {
        assert_eq!(Shard::parse("2/3").unwrap(), Shard { index: 2, count: 3 });
        for bad in ["0/3", "4/3", "1/0", "x/2", "3"] {
            assert!(Shard::parse(bad).is_err(), "{bad}");
        }
    }
}
