//! A mutant cell's part of its run (`run --mutants`): the mutation applied to the probed stage's
//! modules after the cell's workarounds (phase `compile`), and the reference's prediction for it
//! added to the comparison, which judges the records against the unmutated probe.
use super::check::World;
use super::error::CellError;
use super::executor::Executor;
use crate::model::{Cell, LaneEvidence, Mutant, MutantPrediction, Timings};
use crate::mutants::{self, Mutation};
use crate::patches::PatchError;
use crate::probe::spec::ProbeSpec;
use crate::probe::{self, Record};
use crate::reference::{self, Expected, Undefined};
use std::sync::Arc;
use std::time::Instant;

impl Executor {
    /// What `spec`'s mutant rewrites ([`World::mutation`]).
    pub(super) fn mutation(&self, spec: &ProbeSpec) -> Result<Option<Mutation>, CellError> {
        self.world().mutation(spec)
    }
}

impl World<'_> {
    /// What `spec`'s mutant rewrites (`None`: no mutant); one with nothing to rewrite in this
    /// cell is an error (the mutants round never schedules one), and so is a broadcast whose
    /// prediction would lack the device's lane evidence (its leaders): it needs evidence the
    /// device supports in the stage (`LaneEvidence::Supported`; forced evidence is never judged
    /// by, `model::lanes`).
    pub(super) fn mutation(&self, spec: &ProbeSpec) -> Result<Option<Mutation>, CellError> {
        let Some(m) = spec.mutant else { return Ok(None) };
        let slots = probe::slot_count(spec.resource, self.scene.params.instances);
        let refuse = |what: String| {
            CellError::Mutant(PatchError::NothingToPatch { patch: m.as_str(), what })
        };
        let site = mutants::site(spec, m, slots).map_err(refuse)?;
        let lanes = self.opts.lanes.evidence(self.ballot.contains(&spec.stage));
        if m == Mutant::IndexBroadcast && lanes != LaneEvidence::Supported {
            return Err(refuse(format!(
                "its prediction needs the device's lane evidence in {} (subgroup ballot listed for the stage, --lane-evidence auto; {})",
                spec.stage,
                crate::model::lanes::SUBGROUP_STAGE_VUID
            )));
        }
        Ok(Some(site))
    }

    /// The reference's prediction for a mutant cell's records (`None`: not a mutant cell):
    /// judged as `undefined` says, with the lane evidence the records carry; `expected` is the
    /// unmutated probe's, `records` the device's (a broadcast's leaders).
    pub(super) fn predict_mutant(
        &self,
        cell: &Cell,
        judged: (Undefined, LaneEvidence),
        expected: &[Expected],
        records: &[Record],
    ) -> Option<MutantPrediction> {
        let site = self.mutation(&ProbeSpec::of(cell)).ok().flatten()?;
        let world = (self.scene, self.sref);
        Some(reference::mutant_after_run(cell, world, judged, site, (expected, records)))
    }
}

/// Apply `mutation` (mutant `name`) to every module that has its site (the time added to
/// `timings.compile_ms`); no module having one is an error, as is a failed rewrite.
pub(super) fn mutate_all(
    spirv: &mut [Arc<Vec<u32>>],
    mutation: Mutation,
    name: &'static str,
    timings: &mut Timings,
) -> Result<(), CellError> {
    let t = Instant::now();
    let mut mutated = 0;
    for words in spirv.iter_mut() {
        if let Some(m) = mutants::mutate_module(words, mutation).map_err(CellError::Mutant)? {
            *words = Arc::new(m);
            mutated += 1;
        }
    }
    timings.compile_ms += t.elapsed().as_secs_f64() * 1e3;
    if mutated == 0 {
        return Err(CellError::Mutant(PatchError::NothingToPatch {
            patch: name,
            what: "no module of the cell has what this mutant rewrites".into(),
        }));
    }
    Ok(())
}
