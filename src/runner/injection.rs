//! The supervisor's fault-injection bookkeeping (`--inject-fault`): each worker gets a fresh seed
//! for its flaky dice, each cell remembers the seed of the worker it was last sent to, and every
//! attempt records the fault injected into it, worked out as the worker did, even when the worker
//! died before it could say.
use crate::model::{Attempt, Cell, Injection};
use std::collections::HashMap;

pub(super) struct Injections {
    inject: Vec<Injection>,
    /// The dice seed of the worker each cell was last sent to.
    seeds: HashMap<String, u64>,
}

impl Injections {
    pub fn new(inject: Vec<Injection>) -> Self {
        Injections { inject, seeds: HashMap::new() }
    }

    /// What every worker is told to inject.
    pub fn list(&self) -> &[Injection] {
        &self.inject
    }

    /// A fresh seed for worker `worker`, remembered for each of its `cells`.
    pub fn deal(&mut self, worker: u64, cells: &[Cell]) -> u64 {
        let seed = fresh_seed(worker);
        for c in cells {
            self.seeds.insert(c.id(), seed);
        }
        seed
    }

    /// Records in `attempt` what was injected into `cell` (nothing for a cell never dealt).
    pub fn tag(&self, cell: &Cell, attempt: &mut Attempt) {
        if let Some(&seed) = self.seeds.get(&cell.id()) {
            attempt.injected = crate::model::inject::roll(&self.inject, cell, seed);
        }
    }
}

/// A fresh seed for each worker's flaky-injection dice (recorded in every injected result).
fn fresh_seed(worker: u64) -> u64 {
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos() as u64)
        .unwrap_or(0);
    nanos ^ (u64::from(std::process::id()) << 32) ^ worker.wrapping_mul(0x9e37_79b9_7f4a_7c15)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{DescriptorModel, IndexSource, Outcome, Resource, Stage};

    #[test]
    fn an_attempt_records_the_injection_of_its_cells_worker() {
        let cell = Cell::new(
            Stage::Raygen,
            Resource::StorageBuffer,
            IndexSource::Dynamic,
            DescriptorModel::DescriptorIndexing,
        );
        let other = Cell { stage: Stage::Miss, ..cell };
        let mut inj = Injections::new(vec![Injection::parse("stage=raygen@device").unwrap()]);
        let mut a = Attempt::new(Outcome::Crash, false);
        inj.tag(&cell, &mut a);
        assert_eq!(a.injected, None, "a cell never sent to a worker has no dice");
        let seed = inj.deal(1, &[cell, other]);
        assert_ne!(seed, inj.deal(2, &[other]), "each worker rolls its own dice");
        inj.tag(&cell, &mut a);
        assert!(a.injected.is_some(), "the fault is recorded even though the worker died");
        let mut b = Attempt::new(Outcome::Pass, false);
        inj.tag(&other, &mut b);
        assert_eq!(b.injected, None, "the filter does not match");
    }
}
