//! `nonuniform`: decorate every dynamically indexed descriptor-array access `NonUniform`, as
//! `nonuniformEXT(index)` would have — or, with `strip`, remove every `NonUniform` decoration.
//!
//! SPIR-V rules relied on (Vulkan "Uniformity" and SPV_EXT_descriptor_indexing, core in 1.5):
//! a descriptor array index that is not dynamically uniform must reach the resource through an
//! object decorated `NonUniform`; glslang decorates the index, the access chain and the objects
//! derived from it (loaded handles, member chains, loaded values), and that is what is added here.
//! The module must declare `ShaderNonUniform` and the per-type capability
//! (`StorageBufferArrayNonUniformIndexing`, `UniformBufferArrayNonUniformIndexing`,
//! `SampledImageArrayNonUniformIndexing`, `StorageImageArrayNonUniformIndexing`).
use super::dynamic_access;
use super::edit;
use super::PatchError;
use rspirv::dr::{Module, Operand};
use rspirv::spirv::{Capability, Decoration, Op, StorageClass, Word};
use std::collections::HashSet;

#[derive(Clone, Debug, PartialEq)]
pub struct Report {
    pub decorated: usize,
    pub stripped: usize,
}

fn capability_for(m: &Module, storage: StorageClass, element: Word) -> Option<Capability> {
    match storage {
        StorageClass::StorageBuffer => {
            return Some(Capability::StorageBufferArrayNonUniformIndexing)
        }
        StorageClass::Uniform => {
            return Some(if edit::has_decoration(m, element, Decoration::BufferBlock) {
                Capability::StorageBufferArrayNonUniformIndexing
            } else {
                Capability::UniformBufferArrayNonUniformIndexing
            })
        }
        _ => {}
    }
    let d = edit::def(m, element)?;
    match d.class.opcode {
        Op::TypeSampledImage => Some(Capability::SampledImageArrayNonUniformIndexing),
        Op::TypeImage => match d.operands.get(5) {
            Some(Operand::LiteralBit32(2)) => Some(Capability::StorageImageArrayNonUniformIndexing),
            _ => Some(Capability::SampledImageArrayNonUniformIndexing),
        },
        _ => None,
    }
}

const NAME: &str = "nonuniform";

/// Decorate every dynamically indexed descriptor access `NonUniform`, declaring the capabilities
/// that needs; with `strip`, remove every `NonUniform` decoration instead.
pub fn apply(m: &mut Module, strip: bool) -> Result<Report, PatchError> {
    if strip {
        return strip_all(m);
    }
    let accesses = dynamic_access::find(m);
    if accesses.is_empty() {
        return Err(PatchError::NothingToPatch {
            patch: NAME,
            what: "no dynamically indexed descriptor array".into(),
        });
    }
    let mut targets: HashSet<Word> = HashSet::new();
    let mut caps = Vec::new();
    for a in &accesses {
        targets.insert(a.index);
        targets.insert(a.chain);
        derived_objects(m, a.chain, &mut targets);
        if let Some(c) = capability_for(m, a.storage, a.element) {
            caps.push(c);
        }
    }
    let mut new: Vec<Word> = targets
        .into_iter()
        .filter(|t| !edit::has_decoration(m, *t, Decoration::NonUniform))
        .collect();
    if new.is_empty() {
        return Err(PatchError::NothingToPatch {
            patch: NAME,
            what: "every dynamic descriptor access is already NonUniform".into(),
        });
    }
    new.sort_unstable();
    edit::add_capability(m, Capability::ShaderNonUniform);
    for c in caps {
        edit::add_capability(m, c);
    }
    if edit::version(m) < (1, 5) {
        edit::add_extension(m, "SPV_EXT_descriptor_indexing");
    }
    for id in &new {
        edit::decorate(m, *id, Decoration::NonUniform, &[]);
    }
    Ok(Report { decorated: new.len(), stripped: 0 })
}

/// `strip`: remove every `NonUniform` decoration.
fn strip_all(m: &mut Module) -> Result<Report, PatchError> {
    let before = m.annotations.len();
    m.annotations.retain(|a| {
        !(a.class.opcode == Op::Decorate
            && matches!(a.operands.get(1), Some(Operand::Decoration(Decoration::NonUniform))))
    });
    let stripped = before - m.annotations.len();
    if stripped == 0 {
        return Err(PatchError::NothingToPatch {
            patch: NAME,
            what: "no NonUniform decoration to strip".into(),
        });
    }
    Ok(Report { decorated: 0, stripped })
}

/// Add to `targets` the objects derived from the access chain `chain`, three steps deep: loads,
/// member chains, their loads, sampled images and images.
pub(super) fn derived_objects(m: &Module, chain: Word, targets: &mut HashSet<Word>) {
    let mut frontier = vec![chain];
    for _ in 0..3 {
        let mut next = Vec::new();
        for id in frontier {
            for u in edit::users(m, id) {
                let op = edit::def(m, u).map(|d| d.class.opcode);
                if matches!(
                    op,
                    Some(
                        Op::Load
                            | Op::AccessChain
                            | Op::InBoundsAccessChain
                            | Op::SampledImage
                            | Op::Image
                    )
                ) && targets.insert(u)
                {
                    next.push(u);
                }
            }
        }
        frontier = next;
    }
}
