//! What the driver saw of a cell's shape that judging its records needs ([`Seen`]): whether its
//! probed modules declare `DescriptorHeapEXT` (then no index of theirs needs `NonUniform`, and the
//! read is judged exactly), whether a `nonuniformEXT` of the GLSL did not reach the driver (a
//! dynamic set/binding access left undecorated: then that read is undefined), and the lane
//! evidence the records carry. The rules are `patches::uniformity`'s.
use crate::model::{Cell, LaneEvidence, NO_NONUNIFORM_VUID};
use crate::patches::uniformity::{self, Uniformity};
use crate::probe::spec::{Access, ProbeSpec, ReadIndex, SlotSource};
use crate::shadergen::{CellShaders, Role};
use std::sync::Arc;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Seen {
    /// Every probed module declares `DescriptorHeapEXT`.
    pub(super) heap_capability: bool,
    /// The GLSL qualified the descriptor index `nonuniformEXT`, and a probed module's dynamic
    /// access reached the driver without `NonUniform` (the compiler dropped it).
    pub(super) dropped: bool,
    pub(super) lanes: LaneEvidence,
}

/// Whether a shader of role `role` does the probed read of `stage` (closest-hit: both hit groups'
/// shaders).
fn probes(role: Role, stage: crate::model::Stage) -> bool {
    role == Role::probed(stage)
        || (stage == crate::model::Stage::ClosestHit && role == Role::ClosestHitProcedural)
}

impl Seen {
    /// What `cell`'s compiled modules (`spirv`, in the order of `shaders`) show the driver.
    pub(super) fn of(
        cell: &Cell,
        shaders: &CellShaders,
        spirv: &[Arc<Vec<u32>>],
        lanes: LaneEvidence,
    ) -> Seen {
        let probed: Vec<Uniformity> = shaders
            .shaders
            .iter()
            .zip(spirv)
            .filter(|(s, _)| probes(s.role, cell.stage))
            .map(|(_, w)| uniformity::of_words(w))
            .collect();
        let heap_capability = !probed.is_empty() && probed.iter().all(|u| u.heap_capability);
        let wanted = ProbeSpec::of(cell).access == (Access::Slot { nonuniform: true });
        let dropped = wanted && probed.iter().any(|u| u.dynamic_decorated == Some(false));
        Seen { heap_capability, dropped, lanes }
    }

    /// The driver saw the cell's descriptor index as undefined: a non-uniform set/binding index
    /// without `NonUniform`, by the cell's shape or because the compiler dropped it; never in a
    /// module that declares `DescriptorHeapEXT`.
    pub(super) fn undefined(&self, cell: &Cell) -> bool {
        !self.heap_capability && (ProbeSpec::of(cell).read == ReadIndex::Undefined || self.dropped)
    }

    /// The note a cell's result carries about what the driver saw, if any.
    pub(super) fn note(&self, cell: &Cell) -> Option<String> {
        if self.dropped && !self.heap_capability {
            return Some(format!(
                "the GLSL compiler dropped nonuniformEXT on the descriptor index: no NonUniform decoration reached the driver, so the read is judged as undefined ({NO_NONUNIFORM_VUID})"
            ));
        }
        // A dynamic index without nonuniformEXT: undefined on a set/binding array, exact here.
        let spec = ProbeSpec::of(cell);
        let unqualified = spec.read == ReadIndex::Undefined
            || (spec.slot == SlotSource::Dynamic
                && spec.access == (Access::Slot { nonuniform: false }));
        (self.heap_capability && unqualified).then(|| {
            "judged exactly: the module declares DescriptorHeapEXT, whose accesses need no NonUniform decoration (VUID-RuntimeSpirv-None-10148 / -subgroupSize-10149 exempt it, Vulkan 1.4.360)".to_string()
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{DescriptorModel, IndexSource, Resource, Stage};
    use crate::shadergen::{compile::Compiler, generate};

    fn compiled(cell: &Cell) -> (CellShaders, Vec<Arc<Vec<u32>>>) {
        let shaders = generate(cell);
        let mut c = Compiler::new().unwrap();
        let spirv = shaders.shaders.iter().map(|s| c.compile(s.role, &s.glsl).unwrap().0).collect();
        (shaders, spirv)
    }

    /// Set/binding: undefined by shape, or with a stripped decoration (a compiler's drop); a
    /// module declaring DescriptorHeapEXT is exact whatever its decorations.
    #[test]
    fn the_probed_modules_decide_what_is_undefined() {
        let c = Cell::new(
            Stage::ClosestHit,
            Resource::StorageBuffer,
            IndexSource::Dynamic,
            DescriptorModel::DescriptorIndexing,
        );
        let (shaders, spirv) = compiled(&c);
        let seen = Seen::of(&c, &shaders, &spirv, LaneEvidence::Absent);
        assert!(!seen.heap_capability && !seen.dropped && seen.undefined(&c));
        let nu = Cell { nonuniform: true, ..c };
        let (shaders, mut spirv) = compiled(&nu);
        let seen = Seen::of(&nu, &shaders, &spirv, LaneEvidence::Absent);
        assert!(!seen.undefined(&nu) && seen.note(&nu).is_none());
        // strip the probed modules' NonUniform: what a dropping compiler hands the driver
        for (s, w) in shaders.shaders.iter().zip(spirv.iter_mut()) {
            if probes(s.role, nu.stage) {
                let bytes: Vec<u8> = w.iter().flat_map(|x| x.to_le_bytes()).collect();
                let mut m = crate::patches::load(&bytes).unwrap();
                crate::patches::nonuniform::apply(&mut m, true).unwrap();
                *w = Arc::new(crate::patches::assemble(&m));
            }
        }
        let seen = Seen::of(&nu, &shaders, &spirv, LaneEvidence::Absent);
        assert!(seen.dropped && seen.undefined(&nu), "{seen:?}");
        assert!(seen.note(&nu).is_some_and(|n| n.contains("VUID-RuntimeSpirv-None-10148")));
        // the heap capability exempts it
        let heap = Seen { heap_capability: true, ..seen };
        assert!(!heap.undefined(&nu) && !heap.undefined(&c));
        assert!(heap.note(&c).is_some_and(|n| n.contains("judged exactly")));
    }
}
