//! Phase `compile` of a cell: its GLSL generated (with its injected fault), compiled to SPIR-V
//! (cached per source) or read from a repro bundle, patched by the spec's workarounds (then a
//! mutant cell's mutation, `super::mutant`), written out with `--dump`, and what the driver saw
//! of it (`seen`). Where the probe measures its lane evidence is decided here
//! ([`Executor::lane_evidence`]).
use super::built::{Compiled, Seen};
use super::error::CellError;
use super::executor::Executor;
use super::files;
use crate::model::{Cell, InjectedFault, LaneEvidence, LaneMode, Timings, Workaround};
use crate::patches::{workaround, PatchError};
use crate::probe::spec::{ArrayAt, ProbeSpec};
use crate::shadergen::{self, CellShaders};
use std::sync::Arc;
use std::time::Instant;

/// A cell's shaders and their SPIR-V modules, in the same order.
pub(super) type Modules = (CellShaders, Vec<Arc<Vec<u32>>>);

/// SPIR-V `OpCapability` and `Capability GroupNonUniformBallot` (SPIR-V 1.6 unified spec).
const OP_CAPABILITY: u32 = 17;
const CAPABILITY_GROUP_NON_UNIFORM_BALLOT: u32 = 64;

/// Whether a module declares `GroupNonUniformBallot` (what the probe's lane evidence needs).
fn declares_ballot(words: &[u32]) -> bool {
    let mut i = 5;
    while let Some(&first) = words.get(i) {
        let (count, op) = ((first >> 16) as usize, first & 0xffff);
        if count == 0 {
            return false;
        }
        if op == OP_CAPABILITY && words.get(i + 1) == Some(&CAPABILITY_GROUP_NON_UNIFORM_BALLOT) {
            return true;
        }
        i += count;
    }
    false
}

impl Executor {
    /// What `cell`'s probe records as lane evidence under the run's `--lane-evidence`: the device
    /// says whether subgroup ballot works in its probed stage (`vk::features`).
    pub(super) fn lane_evidence(&self, cell: &Cell) -> LaneEvidence {
        self.opts.lanes.evidence(self.gpu.info.subgroup_ballot(cell.stage))
    }

    /// The GLSL of every shader `cell` needs, with its injected fault (if any) appended and its
    /// lane evidence where [`Executor::lane_evidence`] says.
    pub(super) fn cell_shaders(
        &self,
        cell: &Cell,
        injected: Option<&InjectedFault>,
    ) -> CellShaders {
        let (fault, lanes) = self.generation(cell, injected);
        shadergen::generate_with(cell, fault, lanes)
    }

    /// What `cell`'s GLSL is generated with ([`shadergen::generate_with`]): its injected fault,
    /// and whether it records lane evidence.
    pub(super) fn generation(
        &self,
        cell: &Cell,
        injected: Option<&InjectedFault>,
    ) -> (Option<crate::model::FaultKind>, bool) {
        let lanes = cell.canary.is_none() && self.lane_evidence(cell).recorded();
        (injected.map(|i| i.fault), lanes)
    }

    /// GLSL → SPIR-V (cached per source), the cell's workarounds, `--dump`: phase `compile`.
    pub(super) fn compile_cell(
        &mut self,
        cell: &Cell,
        shaders: CellShaders,
        timings: &mut Timings,
    ) -> Result<Compiled, CellError> {
        let spec = ProbeSpec::of(cell);
        let (shaders, mut spirv) = self.look_up(cell, shaders, timings)?;
        patch_workarounds(cell, &mut spirv, self.opts.spirv_dir.is_none(), timings)?;
        // Then a mutant's mutation (`run --mutants`).
        if let (Some(m), Some(mutation)) = (spec.mutant, self.mutation(&spec)?) {
            super::mutant::mutate_all(&mut spirv, mutation, m.as_str(), timings)?;
        }
        self.dump(cell, &shaders, &spirv)?;
        let lanes = self.recorded_lanes(cell, &shaders, &spirv);
        let seen = Seen::of(cell, &shaders, &spirv, lanes);
        Ok(Compiled { shaders, spirv, seen, keys: None })
    }

    /// The executor's part of phase `compile`: the cell's modules, compiled (or taken from the
    /// compiler's cache) or read from a bundle, unpatched.
    pub(super) fn look_up(
        &mut self,
        cell: &Cell,
        shaders: CellShaders,
        timings: &mut Timings,
    ) -> Result<Modules, CellError> {
        if ProbeSpec::of(cell).array == ArrayAt::Heap && shadergen::glslang::find().is_none() {
            return Err(CellError::NotImplemented(shadergen::glslang::missing_reason()));
        }
        let spirv = self.spirv(&shaders, timings)?;
        Ok((shaders, spirv))
    }

    /// `--dump`: the cell's GLSL and SPIR-V written out.
    pub(super) fn dump(
        &self,
        cell: &Cell,
        shaders: &CellShaders,
        spirv: &[Arc<Vec<u32>>],
    ) -> Result<(), CellError> {
        match &self.opts.dump {
            Some(dir) => files::dump(dir, cell, shaders, spirv).map_err(CellError::Io),
            None => Ok(()),
        }
    }

    /// The lane evidence the cell's records will carry: as generated, or for a bundle's SPIR-V,
    /// whether its probed module measures it (declares `GroupNonUniformBallot`).
    pub(super) fn recorded_lanes(
        &self,
        cell: &Cell,
        shaders: &CellShaders,
        spirv: &[Arc<Vec<u32>>],
    ) -> LaneEvidence {
        if cell.canary.is_some() {
            return LaneEvidence::Absent;
        }
        let wanted = self.lane_evidence(cell);
        if self.opts.spirv_dir.is_none() {
            return wanted;
        }
        let role = shadergen::Role::probed(cell.stage);
        let probed = shaders.shaders.iter().position(|s| s.role == role);
        let ballot = probed.and_then(|k| spirv.get(k)).is_some_and(|w| declares_ballot(w));
        match (ballot, wanted) {
            (false, _) => LaneEvidence::Absent,
            (true, LaneEvidence::Supported) => LaneEvidence::Supported,
            (true, LaneEvidence::Absent | LaneEvidence::Forced) => {
                LaneMode::Force.evidence(self.gpu.info.subgroup_ballot(cell.stage))
            }
        }
    }

    /// Every shader's SPIR-V, in order: compiled from its GLSL (the time added to
    /// `timings.compile_ms`), or read from the bundle's `shaders/` with `spirv_dir`.
    fn spirv(
        &mut self,
        shaders: &CellShaders,
        timings: &mut Timings,
    ) -> Result<Vec<Arc<Vec<u32>>>, CellError> {
        let mut spirv = Vec::new();
        for s in &shaders.shaders {
            let words = match &self.opts.spirv_dir {
                Some(dir) => Arc::new(files::bundle_spirv(dir, s.role).map_err(CellError::Io)?),
                None => {
                    let (words, ms) = self.compiler.compile(s.role, &s.glsl)?;
                    timings.compile_ms += ms;
                    words
                }
            };
            spirv.push(words);
        }
        Ok(spirv)
    }
}

/// The spec's workarounds patched into `spirv`: as-to-address for address_patched cells, then
/// the cell's own patch (`patch`: false for a bundle's SPIR-V, patched already). Needs nothing of
/// the executor: the prebuild runs it on its threads.
pub(super) fn patch_workarounds(
    cell: &Cell,
    spirv: &mut [Arc<Vec<u32>>],
    patch: bool,
    timings: &mut Timings,
) -> Result<(), CellError> {
    for w in ProbeSpec::of(cell).workarounds().filter(|_| patch) {
        patch_all(spirv, w, timings)?;
    }
    Ok(())
}

/// Apply workaround `w` to every module that has the access it rewrites (the time added to
/// `timings.compile_ms`); no module having it is an error, as is a failed patch.
fn patch_all(
    spirv: &mut [Arc<Vec<u32>>],
    w: Workaround,
    timings: &mut Timings,
) -> Result<(), CellError> {
    let t = Instant::now();
    let mut patched_any = false;
    for words in spirv.iter_mut() {
        match workaround::patch_module(words, w) {
            Ok(Some(p)) => {
                *words = Arc::new(p);
                patched_any = true;
            }
            Ok(None) => {}
            Err(e) => return Err(e.into()),
        }
    }
    timings.compile_ms += t.elapsed().as_secs_f64() * 1e3;
    if !patched_any {
        return Err(PatchError::NothingToPatch {
            patch: w.as_str(),
            what: "no module of the cell has the access this workaround rewrites".into(),
        }
        .into());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ballot_capability_is_found_and_its_absence_too() {
        let header = [0x0723_0203, 0x0001_0600, 0, 40, 0];
        let cap = |c: u32| [(2 << 16) | OP_CAPABILITY, c];
        let m: Vec<u32> = header.iter().chain(&cap(1)).chain(&cap(64)).copied().collect();
        assert!(declares_ballot(&m));
        let m: Vec<u32> = header.iter().chain(&cap(1)).chain(&cap(61)).copied().collect();
        assert!(!declares_ballot(&m));
        // truncated or zero word counts end the scan
        assert!(!declares_ballot(&[0x0723_0203, 0, 0, 0, 0, 0, 64]));
        assert!(!declares_ballot(&header));
    }
}
