//! The pipeline key: cells whose SPIR-V, descriptor model, heap access, layout key and ray
//! recursion depth agree share one pipeline, created by the first and reused by the others.
use super::bindings::LayoutKey;
use super::built::Compiled;
use crate::probe::spec::ProbeSpec;
use std::collections::hash_map::DefaultHasher;
use std::hash::{Hash, Hasher};

/// The key of the pipeline of a cell compiled as `c`, with spec `spec`, bound under `key`.
pub(super) fn of(c: &Compiled, spec: &ProbeSpec, key: LayoutKey) -> u64 {
    let mut hs = DefaultHasher::new();
    for s in &c.spirv {
        s.hash(&mut hs);
    }
    spec.model.hash(&mut hs);
    spec.heap.hash(&mut hs);
    key.hash(&mut hs);
    c.shaders.recursion_depth.hash(&mut hs);
    hs.finish()
}
