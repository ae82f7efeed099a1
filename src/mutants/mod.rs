//! Emulated driver bugs (`run --mutants`): each `model::Mutant` is a SPIR-V mutation of the
//! probed stage's modules, a plain function over `rspirv::dr::Module` applied by the worker after
//! the cell's own workarounds. Drivers seldom write garbage; they read the wrong thing, so every
//! mutation but `value-bits` makes the probe read another descriptor, element, sampler or TLAS —
//! always inside the resource: indices wrap modulo the array, a doubled stride is taken on an
//! index kept in the lower half, packed reads move to element 0 (an out-of-bounds read would
//! emulate another bug, and can hang a GPU).
//!
//! [`site`] resolves what a mutant rewrites from the cell's probe spec (which array, heap,
//! sampler heap or address table the probe reads; `Err` with why where it has nothing to rewrite:
//! the kill matrix's "not applicable: no target"); [`apply`] finds it in a module ([`locate`])
//! and rewrites it ([`index`], [`element`], [`value`]), each file with the SPIR-V rules it relies
//! on. Only the read's own operands change: the slot the probe records is computed by separate
//! instructions, so the reference (run with the same mutation, `reference::mutation`) can tell
//! what the mutated probe must have read.
pub mod element;
pub mod index;
pub mod locate;
pub mod value;

#[cfg(test)]
mod tests;

pub use index::IndexFn;

use crate::model::Mutant;
use crate::patches::PatchError;
use crate::probe::spec::{Access, ArrayAt, Base, ElementMap, ProbeSpec, Sampler, SlotSource};
use rspirv::dr::Module;

/// What a mutant rewrites in a cell's probe ([`site`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mutation {
    /// The probed array's descriptor index: at binding 2, or into the resource heap (`heap`).
    DescriptorIndex { heap: bool, to: IndexFn },
    /// The packed buffer's element index becomes 0 (`index=dynamic_element` storage buffers).
    PackedElement { heap: bool },
    /// The array texture's layer becomes 0 (`index=dynamic_element` sampled images).
    Layer,
    /// The sampler heap index (direct-heap sampled images).
    SamplerIndex { to: IndexFn },
    /// The table index of an acceleration structure reached by address.
    AddressIndex { to: IndexFn },
    /// The probed value's last word, its low bits flipped ([`value::FLIPPED`]).
    ValueBits,
}

/// What mutant `m` rewrites in the probe `spec` describes, its array holding `slots` descriptors
/// (`probe::slot_count`); `Err`: why it has nothing to rewrite there.
pub fn site(spec: &ProbeSpec, m: Mutant, slots: u32) -> Result<Mutation, String> {
    if spec.canary.is_some() {
        return Err("a canary has no probe".into());
    }
    if spec.layout.is_some() {
        return layout_site(spec, m, slots);
    }
    let samplers = crate::probe::SAMPLER_MODES.len() as u32;
    match m {
        Mutant::IndexZero => descriptor(spec, IndexFn::Zero),
        Mutant::IndexNext => descriptor(spec, IndexFn::Next(slots)),
        Mutant::IndexBroadcast => descriptor(spec, IndexFn::Broadcast),
        Mutant::StrideDouble => descriptor(spec, IndexFn::Doubled(slots)),
        Mutant::BaseDropped => match (spec.base, spec.slot) {
            (Base::None, _) => {
                Err("no runtime base: only a hit stage's dynamic index adds one".into())
            }
            (Base::PushData | Base::ShaderRecord | Base::InstanceBuffer, SlotSource::Dynamic) => {
                descriptor(spec, IndexFn::DropBase)
            }
            (
                Base::PushData | Base::ShaderRecord | Base::InstanceBuffer,
                SlotSource::Literal | SlotSource::SpecConstant | SlotSource::PushConstant,
            ) => Err("the base is the dynamic sampler index's; the descriptor index adds none".into()),
        },
        Mutant::ElementZero => match spec.element {
            ElementMap::Packed => Ok(Mutation::PackedElement { heap: spec.array == ArrayAt::Heap }),
            ElementMap::Layer => Ok(Mutation::Layer),
            ElementMap::None | ElementMap::Own => {
                Err("not index=dynamic_element: no element offset inside one descriptor".into())
            }
        },
        Mutant::SamplerNext => match spec.sampler {
            Sampler::Constant | Sampler::Dynamic { .. } => {
                Ok(Mutation::SamplerIndex { to: IndexFn::Next(samplers) })
            }
            Sampler::None => Err("no separate sampler index (direct-heap sampled images have one)".into()),
        },
        Mutant::TlasOther if spec.addresses.as_table => {
            Ok(Mutation::AddressIndex { to: IndexFn::Next(slots) })
        }
        Mutant::TlasOther => Err("the acceleration structure is not reached by address (index-* mutants rewrite its descriptor index)".into()),
        Mutant::ValueBits => Ok(Mutation::ValueBits),
    }
}

/// What mutant `m` rewrites in a scene-layout cell (`scene_layout`): the descriptor index of the
/// array at binding 2 — the texture element of a texture cell, the mesh slot of a `per_mesh`
/// cell — which the reference predicts (`fetch_layout`: the record keeps the index the cell
/// computed, the fetch reads the rewritten texture, or the rewritten slot's mesh buffer, padded
/// so that it reads in bounds: `scene::layout`). A `shared_buffers` geometry cell reads no
/// descriptor; the other mutants have no prediction there.
fn layout_site(spec: &ProbeSpec, m: Mutant, slots: u32) -> Result<Mutation, String> {
    let to = match m {
        Mutant::IndexZero => IndexFn::Zero,
        Mutant::IndexNext => IndexFn::Next(slots),
        Mutant::IndexBroadcast => IndexFn::Broadcast,
        Mutant::StrideDouble => IndexFn::Doubled(slots),
        Mutant::BaseDropped => return Err("a scene-layout cell adds no runtime base to its index".into()),
        Mutant::ElementZero => return Err("not index=dynamic_element: no element offset inside one descriptor".into()),
        Mutant::SamplerNext => return Err("no separate sampler index (the texture cells read combined samplers with texelFetch)".into()),
        Mutant::TlasOther => return Err("a scene-layout cell reads no acceleration structure by address".into()),
        Mutant::ValueBits => return Err("a scene-layout cell: the reference does not predict a corrupted fetched word (not implemented)".into()),
    };
    if spec.layout_textures() || spec.layout == Some(crate::model::SceneLayout::PerMesh) {
        return Ok(Mutation::DescriptorIndex { heap: spec.array == ArrayAt::Heap, to });
    }
    Err("a shared_buffers geometry cell reads no descriptor: its buffers are reached by address through the SceneDesc (no mutant rewrites an address yet)".into())
}

/// The descriptor-index site of `spec`'s probe, rewritten with `to`.
fn descriptor(spec: &ProbeSpec, to: IndexFn) -> Result<Mutation, String> {
    if spec.addresses.as_table {
        return Err("the acceleration structure is reached by address: no descriptor index (tlas-other rewrites its table index)".into());
    }
    if spec.addresses.ssbo_table {
        return Err("ssbo-to-address left no descriptor index".into());
    }
    match spec.access {
        Access::Slot { .. } => {
            Ok(Mutation::DescriptorIndex { heap: spec.array == ArrayAt::Heap, to })
        }
        Access::Packed => Err("the packed descriptor is one of a kind: another slot's descriptor holds a smaller resource, which the packed read would overrun (element-zero rewrites the element)".into()),
        Access::AddressTable => Err("no descriptor: an address table".into()),
    }
}

/// Rewrite `mutation` in `m`: the count of sites rewritten (0: the module has none).
pub fn apply(m: &mut Module, mutation: Mutation) -> Result<usize, PatchError> {
    match mutation {
        Mutation::DescriptorIndex { heap, to } => {
            index::rewrite_all(m, locate::descriptor_indices(m, heap), to)
        }
        Mutation::PackedElement { heap } => {
            index::rewrite_all(m, locate::packed_elements(m, heap), IndexFn::Zero)
        }
        Mutation::Layer => element::layers_zero(m, locate::sample_coordinates(m)),
        Mutation::SamplerIndex { to } => index::rewrite_all(m, locate::sampler_indices(m), to),
        Mutation::AddressIndex { to } => index::rewrite_all(m, locate::address_indices(m), to),
        Mutation::ValueBits => value::apply(m),
    }
}

/// Apply `mutation` to one module's words: `Some(words)` when it had a site, `None` when not. A
/// failed rewrite leaves nothing half-done (it works on a copy) and is an error.
pub fn mutate_module(words: &[u32], mutation: Mutation) -> Result<Option<Vec<u32>>, PatchError> {
    let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
    let mut m = crate::patches::load(&bytes)?;
    let n = crate::patches::on_copy(&mut m, |w| apply(w, mutation))?;
    Ok((n > 0).then(|| crate::patches::assemble(&m)))
}
