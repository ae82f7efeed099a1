//! Which `nonuniformEXT` of a `direct` heap cell the GLSL compiler dropped (from the word scan),
//! and the note that says so in the cell's result.
use super::nonuniform::{heap_nonuniform, HeapNonUniform};
use crate::probe::spec::{Access, ArrayAt, ProbeSpec, Sampler};

/// The heaps of a `direct` cell whose non-uniform index reached the driver without `NonUniform`
/// although the GLSL asked for it: the compiler dropped `nonuniformEXT` (glslang 16.6 does on
/// `layout(descriptor_heap)` arrays; reports/lavapipe-26/FINDINGS.md #3). The driver then saw an
/// undecorated non-uniform index, which the spec leaves undefined, so that part of the read is
/// judged as undefined (`reference::Undefined`: a descriptor index any element of the array, a
/// sampler index any of the heap's samplers).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DroppedNonUniform {
    pub resource: bool,
    pub sampler: bool,
}

impl DroppedNonUniform {
    pub fn note(&self) -> String {
        let which = match (self.resource, self.sampler) {
            (true, true) => "the resource and the sampler heap index",
            (true, false) => "the resource heap index",
            (false, _) => "the sampler heap index",
        };
        format!(
            "the GLSL compiler dropped nonuniformEXT on {which}: no NonUniform decoration reached the driver, so that index is judged as undefined ({}; {})",
            if self.resource { "any element of the array" } else { "any of the heap's samplers, slot and element exact" },
            crate::model::NO_NONUNIFORM_VUID
        )
    }
}

/// For a `direct` heap cell: which heap accesses lost the `nonuniformEXT` the GLSL gave them
/// (where the spec qualifies them: the descriptor index, the dynamic sampler index).
pub fn dropped_nonuniform(
    spec: &ProbeSpec,
    spirv: &[std::sync::Arc<Vec<u32>>],
) -> Option<DroppedNonUniform> {
    if spec.array != ArrayAt::Heap {
        return None;
    }
    let wants_resource = spec.access == (Access::Slot { nonuniform: true });
    let wants_sampler = spec.sampler == (Sampler::Dynamic { nonuniform: true });
    let scans: Vec<HeapNonUniform> = spirv.iter().map(|w| heap_nonuniform(w)).collect();
    let lost =
        |get: fn(&HeapNonUniform) -> Option<bool>| scans.iter().any(|h| get(h) == Some(false));
    let d = DroppedNonUniform {
        resource: wants_resource && lost(|h| h.resource),
        sampler: wants_sampler && lost(|h| h.sampler),
    };
    (d.resource || d.sampler).then_some(d)
}
