//! What a module lets a driver assume about its descriptor indices (an analysis, no rewrite): whether
//! it declares `DescriptorHeapEXT`, and whether its dynamically indexed descriptor-array accesses
//! carry `NonUniform`.
//!
//! The rules (Vulkan 1.4.360, checked against Vulkan-Docs):
//! - `VUID-RuntimeSpirv-None-10148` and `VUID-RuntimeSpirv-subgroupSize-10149` ("Validation Rules
//!   within a Module"): where an instruction accesses memory through a resource that is not
//!   uniform (within the invocation group; with subgroups larger than 1, nor within the subgroup),
//!   the operand for that resource *must* be decorated `NonUniform` — since 1.4.340 only "if the
//!   `DescriptorHeapEXT` capability is not declared". (They replaced
//!   `VUID-RuntimeSpirv-NonUniform-06274` in 1.3.294.)
//! - "Descriptor Heap Interface" (chapter Shader Interfaces): the `ResourceHeapEXT` /
//!   `SamplerHeapEXT` built-ins "can be accessed non-uniformly, with no further decoration
//!   required"; glslang ≥ 16.4 omits the decoration on heap accesses on purpose.
//!
//! So a module declaring `DescriptorHeapEXT` needs no `NonUniform` anywhere and is judged
//! exactly, without a scan; any other module is scanned for dynamically indexed set/binding
//! array accesses (`OpAccessChain` on a `DescriptorSet`-decorated array variable whose first index
//! is not a constant) and whether each carries `NonUniform` on its index, its chain or an object
//! loaded from it (where glslang puts it for `nonuniformEXT`).
use super::dynamic_access;
use super::edit;
use rspirv::spirv::Decoration;
use std::collections::HashSet;

/// SPIR-V `OpCapability` and `Capability DescriptorHeapEXT` (SPV_EXT_descriptor_heap).
const OP_CAPABILITY: u32 = 17;
const CAPABILITY_DESCRIPTOR_HEAP: u32 = 5128;

/// What a module lets the driver assume about its descriptor indices.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Uniformity {
    /// The module declares `DescriptorHeapEXT`: no access of it needs `NonUniform`.
    pub heap_capability: bool,
    /// Its dynamically indexed set/binding array accesses: `Some(true)` when every one carries
    /// `NonUniform`, `Some(false)` when one does not, `None` without any (or not scanned: the
    /// heap capability, or a module rspirv cannot read).
    pub dynamic_decorated: Option<bool>,
}

/// Whether the module's words declare `DescriptorHeapEXT` (a word scan: rspirv cannot read every
/// heap module).
pub fn declares_heap_capability(words: &[u32]) -> bool {
    let mut i = 5;
    while let Some(&first) = words.get(i) {
        let (count, op) = ((first >> 16) as usize, first & 0xffff);
        if count == 0 {
            return false;
        }
        if op == OP_CAPABILITY && words.get(i + 1) == Some(&CAPABILITY_DESCRIPTOR_HEAP) {
            return true;
        }
        i += count;
    }
    false
}

/// The module's [`Uniformity`]. Never panics.
pub fn of_words(words: &[u32]) -> Uniformity {
    if declares_heap_capability(words) {
        return Uniformity { heap_capability: true, dynamic_decorated: None };
    }
    let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
    let Ok(m) = super::load(&bytes) else {
        return Uniformity::default();
    };
    let accesses = dynamic_access::find(&m);
    let dynamic_decorated =
        (!accesses.is_empty()).then(|| accesses.iter().all(|a| decorated(&m, a)));
    Uniformity { heap_capability: false, dynamic_decorated }
}

/// Whether `a` carries `NonUniform` on its index, its chain or an object loaded from it.
pub(super) fn decorated(m: &rspirv::dr::Module, a: &dynamic_access::Access) -> bool {
    let mut ids: HashSet<u32> = [a.index, a.chain].into();
    super::nonuniform::derived_objects(m, a.chain, &mut ids);
    ids.iter().any(|id| edit::has_decoration(m, *id, Decoration::NonUniform))
}

/// The (set, binding)s of the module's dynamically indexed accesses without `NonUniform`,
/// sorted, each once; none for a module declaring `DescriptorHeapEXT` or one rspirv cannot
/// read. Never panics.
pub fn undecorated(words: &[u32]) -> Vec<(u32, u32)> {
    if declares_heap_capability(words) {
        return vec![];
    }
    let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
    let Ok(m) = super::load(&bytes) else {
        return vec![];
    };
    let lit = |v, d| edit::decoration_literal(&m, v, d).unwrap_or(0);
    let mut out: Vec<(u32, u32)> = dynamic_access::find(&m)
        .iter()
        .filter(|a| !decorated(&m, a))
        .map(|a| (lit(a.var, Decoration::DescriptorSet), lit(a.var, Decoration::Binding)))
        .collect();
    out.sort_unstable();
    out.dedup();
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shadergen::{compile::Compiler, generate, Role};

    fn probed(cell: &crate::model::Cell) -> Vec<u32> {
        let shaders = generate(cell);
        let s = shaders.get(Role::probed(cell.stage)).unwrap();
        Compiler::new().unwrap().compile(s.role, &s.glsl).unwrap().0.to_vec()
    }

    /// Set/binding modules: a dynamic index with `nonuniformEXT` is decorated, one without is
    /// not, a literal one has no dynamic access; stripping the decoration (what a compiler that
    /// drops it would emit) shows as undecorated. None declares the heap capability.
    #[test]
    fn set_binding_accesses_are_scanned_for_their_decoration() {
        use crate::model::{Cell, DescriptorModel, IndexSource, Resource, Stage};
        for resource in [Resource::StorageBuffer, Resource::SampledImage] {
            let c = Cell::new(
                Stage::ClosestHit,
                resource,
                IndexSource::Dynamic,
                DescriptorModel::DescriptorIndexing,
            );
            let plain = of_words(&probed(&c));
            assert_eq!(
                plain,
                Uniformity { heap_capability: false, dynamic_decorated: Some(false) }
            );
            let words = probed(&Cell { nonuniform: true, ..c });
            assert_eq!(of_words(&words).dynamic_decorated, Some(true), "{resource:?}");
            let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
            let mut m = crate::patches::load(&bytes).unwrap();
            crate::patches::nonuniform::apply(&mut m, true).unwrap();
            let stripped = crate::patches::assemble(&m);
            assert_eq!(of_words(&stripped).dynamic_decorated, Some(false), "{resource:?}");
            assert_eq!(undecorated(&probed(&c)).len(), 1, "{resource:?}");
            assert_eq!(undecorated(&words), [], "{resource:?}");
            assert_eq!(undecorated(&stripped).len(), 1, "{resource:?}");
            let literal = of_words(&probed(&Cell { index: IndexSource::Literal, ..c }));
            assert_eq!(literal.dynamic_decorated, None);
        }
    }

    /// A module declaring `DescriptorHeapEXT` is not scanned (its accesses need no decoration),
    /// whatever follows; malformed words never panic.
    #[test]
    fn the_heap_capability_exempts_a_module_from_the_scan() {
        let header = [0x0723_0203, 0x0001_0600, 0, 40, 0];
        let cap = |c: u32| [(2 << 16) | OP_CAPABILITY, c];
        let m: Vec<u32> =
            header.iter().chain(&cap(1)).chain(&cap(CAPABILITY_DESCRIPTOR_HEAP)).copied().collect();
        assert_eq!(of_words(&m), Uniformity { heap_capability: true, dynamic_decorated: None });
        let m: Vec<u32> = header.iter().chain(&cap(1)).chain(&cap(4473)).copied().collect();
        assert!(!declares_heap_capability(&m));
        assert!(!declares_heap_capability(&[0x0723_0203, 0, 0, 0, 0, 0, 5128]));
        assert_eq!(of_words(&[1, 2, 3]), Uniformity::default());
    }
}
