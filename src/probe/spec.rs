//! The resolved probe spec of a cell: [`ProbeSpec::of`] is the one exhaustive `match` from the
//! cell's axis values to what its probe needs — the slot it records, how it reaches the probed
//! resource (a descriptor at that slot, the packed descriptor at the spec-constant slot, or an
//! address table), where the element sits, where a hit stage's dynamic value takes its base, which
//! sampler it samples with, the SPIR-V workarounds applied after compiling, what the driver then
//! reads, and the address tables it needs.
//!
//! Shader generation, the reference, the executor's resources and bindings, the worker's device
//! requirements and the Amber writer read the spec, never the raw axes, so they cannot disagree on
//! what an axis value means; a writer that cannot express a spec refuses it with a reason drawn
//! from the spec. Cells outside the plan's rules (`matrix::plan::all_cells`) still get a spec:
//! what their generated GLSL does, which the reference then checks.
use crate::model::{
    AsAccess, BaseSource, Canary, Cell, DescriptorModel, HeapAccess, IndexSource, Mutant, Reorder,
    Resource, SamplerIndex, SceneLayout, Stage, Workaround,
};
use serde::Serialize;

/// What the probe records as its slot (`probeSlot`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SlotSource {
    /// A literal in the GLSL ([`super::LITERAL_SLOT`]).
    Literal,
    /// Specialization constant 0 (`SPEC_SLOT`), set to [`super::SPEC_SLOT`].
    SpecConstant,
    /// The push block's `pushSlot` ([`super::PUSH_SLOT`]).
    PushConstant,
    /// The stage's runtime value ([`super::dynamic_slot`]).
    Dynamic,
}

impl SlotSource {
    /// The slot, where it is the same on every pixel.
    pub fn fixed(self) -> Option<u32> {
        match self {
            SlotSource::Literal => Some(super::LITERAL_SLOT),
            SlotSource::SpecConstant => Some(super::SPEC_SLOT),
            SlotSource::PushConstant => Some(super::PUSH_SLOT),
            SlotSource::Dynamic => None,
        }
    }
}

/// How the GLSL reaches the probed resource (before any SPIR-V workaround).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Access {
    /// The descriptor at the recorded slot, `array[probeSlot]` (`nonuniformEXT` on the index when
    /// `nonuniform`).
    Slot { nonuniform: bool },
    /// The packed descriptor at the spec-constant slot [`super::PACKED_SLOT`]
    /// (`index=dynamic_element`): a uniform index, the slot selecting inside it ([`ElementMap`]).
    Packed,
    /// No descriptor: the acceleration structure at `probeSlot` of the address table whose
    /// address is push constant `asTable` (`as_access=address`).
    AddressTable,
}

/// Where the probed array is declared.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ArrayAt {
    /// Set 0, binding 2, bound under the cell's descriptor model (`mapped_*` heap access: that
    /// binding mapped into the heap).
    Binding,
    /// `layout(descriptor_heap)` (`heap_access=direct`): the shader's index is the heap index,
    /// and sampled images sample with a separate sampler from the sampler heap.
    Heap,
}

/// Where the element the probe reads sits in the descriptor it reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ElementMap {
    /// No element: an acceleration structure, whose value is the probe ray's hit.
    None,
    /// Element `probeElement` of the descriptor's own resource (also where `Access::Packed`
    /// meets a kind without a packed resource: `exec` refuses those as not implemented).
    Own,
    /// `v[packedElement(probeSlot, probeElement)]` of the packed buffer ([`super::packed_element`]).
    Packed,
    /// Texel `probeElement` of layer `probeSlot` of the packed array texture.
    Layer,
}

/// Where a hit stage's dynamic value (`base + (gl_InstanceCustomIndexEXT & dynMask)`) takes its
/// base.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Base {
    /// The probe computes no dynamic value in a hit stage.
    None,
    /// Push constant `dynBase` ([`super::DYNAMIC_BASE`]).
    PushData,
    /// The hit group's SBT shader record ([`super::ShaderRecordData::dyn_base`]).
    ShaderRecord,
    /// The per-instance bases buffer at `gl_InstanceID`, its address push constant `baseAddress`
    /// ([`super::base_buffer`]).
    InstanceBuffer,
}

impl Base {
    /// The base a hit shader adds to the masked custom index, for a hit on instance
    /// `instance_id` (`sphere`: the procedural hit group): push data's [`super::DYNAMIC_BASE`],
    /// the hit group's record base, or the instance's entry of the bases buffer (`Base::None`,
    /// where no dynamic value is computed: push data's, never read).
    pub fn value(self, instance_id: u32, sphere: bool) -> u32 {
        match self {
            Base::None | Base::PushData => super::DYNAMIC_BASE,
            Base::ShaderRecord if sphere => super::RECORD_BASE_PROCEDURAL,
            Base::ShaderRecord => super::RECORD_BASE_TRIANGLES,
            Base::InstanceBuffer => super::instance_base(instance_id),
        }
    }
}

/// The sampler a sampled-image probe samples with.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Sampler {
    /// No separate sampler index: not a sampled image, or a combined image sampler (sampler 0 at
    /// the texel centre, which reads the element itself).
    None,
    /// `probeSampler[SAMPLER_LITERAL]` of the sampler heap ([`super::SAMPLER_LITERAL`]).
    Constant,
    /// `probeSampler[dynamic % samplers]` ([`super::sampler_slot`]), `nonuniformEXT` when
    /// `nonuniform`.
    Dynamic { nonuniform: bool },
}

/// Which descriptor the driver reads once the workarounds are applied (what the reference checks).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ReadIndex {
    /// The recorded slot's, exactly.
    Defined,
    /// A non-uniform index into a set/binding descriptor array without `NonUniform`: which
    /// element is read is undefined (`model::NO_NONUNIFORM_VUID`). Never a `layout(descriptor_heap)`
    /// array: its module declares `DescriptorHeapEXT`, whose heap "can be accessed non-uniformly,
    /// with no further decoration required" (Vulkan 1.4.360, Descriptor Heap Interface; the
    /// VUIDs apply only where that capability is not declared).
    Undefined,
    /// `pin-index`: [`super::SPEC_SLOT`]'s, whatever slot the shader computed and records.
    Pinned,
}

/// The device-address tables a probe reads.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize)]
pub struct AddressTables {
    /// The AS address table (`as_access=address`, written or patched, and the as-to-address
    /// patch): push constant `asTable`, and the patched-table address after the push block.
    pub as_table: bool,
    /// The SSBO address table of the ssbo-to-address patch, at the patched-table address.
    pub ssbo_table: bool,
}

/// Everything a cell's probe needs, resolved from its axes once.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
pub struct ProbeSpec {
    /// The probed stage, as the axis says.
    pub stage: Stage,
    /// The probed resource kind, as the axis says.
    pub resource: Resource,
    /// How descriptors are bound, as the axis says.
    pub model: DescriptorModel,
    /// How a heap cell's shaders reach the heap, as the axis says (`exec::heap`'s mapping).
    pub heap: Option<HeapAccess>,
    /// A canary: its own shaders, no probe (the other fields describe its carrier).
    pub canary: Option<Canary>,
    /// Shader execution reordering in raygen before the probed closest-hit read.
    pub reorder: Option<Reorder>,
    pub slot: SlotSource,
    pub access: Access,
    pub array: ArrayAt,
    pub element: ElementMap,
    pub base: Base,
    pub sampler: Sampler,
    /// The SPIR-V workarounds applied to the compiled GLSL, in order ([`ProbeSpec::workarounds`]).
    pub workarounds: [Option<Workaround>; 2],
    pub read: ReadIndex,
    pub addresses: AddressTables,
    /// The emulated driver bug mutated into the probed stage's SPIR-V after the workarounds
    /// (`run --mutants`; `mutants::site` says what it rewrites). Nothing else in the spec
    /// changes: the GLSL, the resources and the reference are the unmutated cell's, so a mutant
    /// is judged against what the probe must read.
    pub mutant: Option<Mutant>,
    /// A scene-layout cell: the closest-hit fetches the hit triangle's data through this layout
    /// (`scene::layout`) instead of reading a probe resource; `per_mesh` through the descriptor at
    /// the recorded slot of binding 2 (the mesh array), `shared_buffers` through the `SceneDesc`
    /// address in push constant `sceneDesc`, no descriptor at all.
    pub layout: Option<SceneLayout>,
}

/// Whether the stage has a hit (its dynamic value adds a base to the custom index).
fn hit_stage(stage: Stage) -> bool {
    match stage {
        Stage::ClosestHit | Stage::AnyHit | Stage::Intersection => true,
        Stage::Raygen | Stage::Miss | Stage::Callable | Stage::Fragment | Stage::Compute => false,
    }
}

/// Whether a workaround makes the shader load through a device address from push constants.
fn loads_address(w: Workaround) -> bool {
    match w {
        Workaround::AsToAddress | Workaround::SsboToAddress => true,
        Workaround::Nonuniform | Workaround::PinIndex => false,
    }
}

impl ProbeSpec {
    /// The spec of `cell`: the one place an axis value is given its meaning.
    ///
    /// Longer than 80 lines on purpose, not split: it is the one exhaustive match from every
    /// axis value to what the probe reads, and keeping each value's meaning beside the others is
    /// what lets the compiler point here when an axis gains a value (split, a new value could be
    /// handled in one helper and forgotten in another).
    pub fn of(cell: &Cell) -> ProbeSpec {
        let Cell {
            stage,
            resource,
            index,
            nonuniform,
            as_access,
            descriptor_model,
            heap_access,
            canary,
            patch,
            reorder,
            base,
            sampler,
            mutant,
            scene_layout,
            // A `--cells-scale` copy reads what its base cell reads (only its first stage's
            // shader has a constant of its own, shadergen::copy_constant).
            copy: _,
        } = *cell;
        let slot = match index {
            IndexSource::Literal => SlotSource::Literal,
            IndexSource::SpecConstant => SlotSource::SpecConstant,
            IndexSource::PushConstant => SlotSource::PushConstant,
            IndexSource::Dynamic | IndexSource::DynamicElement => SlotSource::Dynamic,
        };
        // address_patched is the descriptor variant's GLSL, rewritten by as-to-address after.
        let (written_by_address, patched_to_address) = match as_access {
            None | Some(AsAccess::Descriptor) => (false, None),
            Some(AsAccess::Address) => (resource == Resource::AccelerationStructure, None),
            Some(AsAccess::AddressPatched) => (false, Some(Workaround::AsToAddress)),
        };
        let access = if written_by_address {
            Access::AddressTable
        } else {
            match index {
                IndexSource::DynamicElement => Access::Packed,
                IndexSource::Literal
                | IndexSource::SpecConstant
                | IndexSource::PushConstant
                | IndexSource::Dynamic => Access::Slot { nonuniform },
            }
        };
        let array = match heap_access {
            Some(HeapAccess::Direct) => ArrayAt::Heap,
            None
            | Some(
                HeapAccess::MappedConstantOffset
                | HeapAccess::MappedPushIndex
                | HeapAccess::MappedIndirectIndex
                | HeapAccess::MappedShaderRecordIndex,
            ) => ArrayAt::Binding,
        };
        let element = match resource {
            Resource::AccelerationStructure => ElementMap::None,
            Resource::StorageBuffer if access == Access::Packed => ElementMap::Packed,
            Resource::SampledImage if access == Access::Packed => ElementMap::Layer,
            Resource::StorageBuffer
            | Resource::UniformBuffer
            | Resource::SampledImage
            | Resource::StorageImage => ElementMap::Own,
        };
        // Only direct heap GLSL samples with a separate sampler (set/binding shaders sample
        // combined image samplers); without a sampler value it samples with the constant one.
        let separate = resource == Resource::SampledImage && array == ArrayAt::Heap;
        let sampler = match (separate, sampler) {
            (false, None | Some(SamplerIndex::Constant | SamplerIndex::Dynamic)) => Sampler::None,
            (true, None | Some(SamplerIndex::Constant)) => Sampler::Constant,
            (true, Some(SamplerIndex::Dynamic)) => {
                Sampler::Dynamic { nonuniform: cell.sampler_nonuniform() }
            }
        };
        let hit_dynamic = hit_stage(stage)
            && (slot == SlotSource::Dynamic || matches!(sampler, Sampler::Dynamic { .. }));
        let base = match (hit_dynamic, base) {
            (false, None | Some(BaseSource::ShaderRecord | BaseSource::Buffer)) => Base::None,
            (true, None) => Base::PushData,
            (true, Some(BaseSource::ShaderRecord)) => Base::ShaderRecord,
            (true, Some(BaseSource::Buffer)) => Base::InstanceBuffer,
        };
        let read = match patch {
            Some(Workaround::PinIndex) => ReadIndex::Pinned,
            Some(Workaround::Nonuniform | Workaround::AsToAddress | Workaround::SsboToAddress) => {
                ReadIndex::Defined
            }
            // Once as-to-address rewrote it, a non-uniform index reads memory: well defined; a
            // heap array needs no NonUniform (the DescriptorHeapEXT exemption).
            None if slot == SlotSource::Dynamic
                && access == (Access::Slot { nonuniform: false })
                && patched_to_address.is_none()
                && array == ArrayAt::Binding
                // shared_buffers' geometry indexes no descriptor; its texture cell's does
                && !(scene_layout == Some(SceneLayout::SharedBuffers)
                    && resource != Resource::SampledImage) =>
            {
                ReadIndex::Undefined
            }
            None => ReadIndex::Defined,
        };
        let workarounds = [patched_to_address, patch];
        let patched = |w: Workaround| workarounds.contains(&Some(w));
        let addresses = AddressTables {
            as_table: resource == Resource::AccelerationStructure
                && (access == Access::AddressTable || patched(Workaround::AsToAddress)),
            ssbo_table: patched(Workaround::SsboToAddress),
        };
        ProbeSpec {
            stage,
            resource,
            model: descriptor_model,
            heap: heap_access,
            canary,
            reorder,
            slot,
            access,
            array,
            element,
            base,
            sampler,
            workarounds,
            read,
            addresses,
            mutant,
            layout: scene_layout,
        }
    }

    /// Whether the probe is a scene-layout texture cell: its closest-hit samples the hit
    /// primitive's material's base-colour texture from the descriptor array at binding 2
    /// (`scene::textures`), after fetching the material through the layout (`per_mesh`: the
    /// mesh buffers at binding 3).
    pub fn layout_textures(&self) -> bool {
        self.layout.is_some() && self.resource == Resource::SampledImage
    }

    /// Whether the probe reads its `SceneDesc` address: the `shared_buffers` layout, and the
    /// material table of every texture cell.
    pub fn scene_desc(&self) -> bool {
        self.layout == Some(SceneLayout::SharedBuffers) || self.layout_textures()
    }

    /// The SPIR-V workarounds applied to the compiled GLSL, in order: as-to-address for
    /// `as_access=address_patched`, then the cell's `patch`.
    pub fn workarounds(&self) -> impl Iterator<Item = Workaround> {
        self.workarounds.into_iter().flatten()
    }

    /// The GLSL declares specialization constant 0 (`SPEC_SLOT`); every pipeline sets it to
    /// [`super::SPEC_SLOT`].
    pub fn spec_constant(&self) -> bool {
        self.slot == SlotSource::SpecConstant || self.access == Access::Packed
    }

    /// The packed resource sits at [`super::PACKED_SLOT`] of the probed array.
    pub fn packed(&self) -> bool {
        self.access == Access::Packed
    }

    /// The per-instance bases buffer exists and its address is push constant `baseAddress`.
    pub fn instance_bases(&self) -> bool {
        self.base == Base::InstanceBuffer
    }

    /// The shaders use 64-bit integers: an address table (written or patched in) or the
    /// invalid-address canary's load.
    pub fn int64(&self) -> bool {
        self.access == Access::AddressTable
            || self.workarounds().any(loads_address)
            || self.canary == Some(Canary::InvalidAddress)
    }

    /// The push-constant fields holding a device address the probe reads (GLSL names; the
    /// patched-table address after the block is `patchedTable`).
    pub fn push_addresses(&self) -> Vec<&'static str> {
        let mut v = Vec::new();
        if self.access == Access::AddressTable {
            v.push("asTable");
        }
        if self.instance_bases() {
            v.push("baseAddress");
        }
        if self.scene_desc() {
            v.push("sceneDesc");
        }
        if self.workarounds().any(loads_address) {
            v.push("patchedTable");
        }
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cell(stage: Stage, resource: Resource, index: IndexSource) -> Cell {
        let as_access =
            (resource == Resource::AccelerationStructure).then_some(AsAccess::Descriptor);
        Cell { as_access, ..Cell::new(stage, resource, index, DescriptorModel::DescriptorIndexing) }
    }

    #[test]
    fn fixed_index_sources_read_their_constant_slots() {
        let s = ProbeSpec::of(&cell(Stage::Raygen, Resource::StorageBuffer, IndexSource::Literal));
        assert_eq!(
            (s.slot, s.access, s.element, s.base, s.sampler, s.read),
            (
                SlotSource::Literal,
                Access::Slot { nonuniform: false },
                ElementMap::Own,
                Base::None,
                Sampler::None,
                ReadIndex::Defined
            )
        );
        assert_eq!(s.slot.fixed(), Some(crate::probe::LITERAL_SLOT));
        let s = ProbeSpec::of(&cell(
            Stage::Compute,
            Resource::UniformBuffer,
            IndexSource::SpecConstant,
        ));
        assert!(s.spec_constant() && !s.packed() && s.push_addresses().is_empty() && !s.int64());
        assert_eq!(
            ProbeSpec::of(&cell(Stage::Miss, Resource::StorageImage, IndexSource::PushConstant))
                .slot
                .fixed(),
            Some(crate::probe::PUSH_SLOT)
        );
    }

    #[test]
    fn dynamic_element_reads_the_packed_descriptor_at_the_spec_slot() {
        let s = ProbeSpec::of(&cell(
            Stage::Compute,
            Resource::StorageBuffer,
            IndexSource::DynamicElement,
        ));
        assert_eq!(
            (s.slot, s.access, s.element, s.read),
            (SlotSource::Dynamic, Access::Packed, ElementMap::Packed, ReadIndex::Defined)
        );
        assert!(s.spec_constant() && s.packed());
        let closest = Cell {
            base: Some(BaseSource::Buffer),
            ..cell(Stage::ClosestHit, Resource::SampledImage, IndexSource::DynamicElement)
        };
        let s = ProbeSpec::of(&closest);
        assert_eq!(
            (s.element, s.base, s.sampler),
            (ElementMap::Layer, Base::InstanceBuffer, Sampler::None)
        );
        assert_eq!(s.push_addresses(), ["baseAddress"]);
    }

    #[test]
    fn dynamic_indices_without_nonuniform_are_undefined_until_a_workaround_defines_them() {
        let plain = cell(Stage::ClosestHit, Resource::StorageBuffer, IndexSource::Dynamic);
        let s = ProbeSpec::of(&plain);
        assert_eq!((s.base, s.read), (Base::PushData, ReadIndex::Undefined));
        assert_eq!(ProbeSpec::of(&Cell { nonuniform: true, ..plain }).read, ReadIndex::Defined);
        assert_eq!(
            ProbeSpec::of(&Cell { patch: Some(Workaround::PinIndex), ..plain }).read,
            ReadIndex::Pinned
        );
        let ssbo = ProbeSpec::of(&Cell { patch: Some(Workaround::SsboToAddress), ..plain });
        assert_eq!(
            (ssbo.read, ssbo.addresses, ssbo.int64()),
            (ReadIndex::Defined, AddressTables { as_table: false, ssbo_table: true }, true)
        );
        assert_eq!(ssbo.workarounds().collect::<Vec<_>>(), [Workaround::SsboToAddress]);
    }

    #[test]
    fn as_cells_reach_the_table_written_or_patched() {
        let d = cell(Stage::Raygen, Resource::AccelerationStructure, IndexSource::Dynamic);
        let s = ProbeSpec::of(&d);
        assert_eq!(
            (s.access, s.element, s.read, s.addresses.as_table),
            (Access::Slot { nonuniform: false }, ElementMap::None, ReadIndex::Undefined, false)
        );
        let a = ProbeSpec::of(&Cell { as_access: Some(AsAccess::Address), ..d });
        assert_eq!(
            (a.access, a.read, a.addresses.as_table, a.push_addresses()),
            (Access::AddressTable, ReadIndex::Defined, true, vec!["asTable"])
        );
        // address_patched: the descriptor variant's GLSL, then as-to-address.
        let p = ProbeSpec::of(&Cell { as_access: Some(AsAccess::AddressPatched), ..d });
        assert_eq!((p.access, p.read, p.addresses.as_table), (s.access, ReadIndex::Defined, true));
        assert_eq!(p.workarounds().collect::<Vec<_>>(), [Workaround::AsToAddress]);
        assert!(p.int64() && !s.int64());
    }

    /// Over the whole plan (every workaround variant): each optional axis shows in the spec
    /// exactly where the plan sets it, and every packed descriptor has a packed resource (no
    /// planned cell reaches `ElementMap::Own` through `Access::Packed`).
    #[test]
    fn planned_cells_resolve_to_specs_their_consumers_can_run() {
        let (cells, _) = crate::matrix::plan::all_cells();
        for base in cells {
            for c in std::iter::once(base).chain(
                base.applicable_patches().into_iter().map(|p| Cell { patch: Some(p), ..base }),
            ) {
                let s = ProbeSpec::of(&c);
                assert_eq!(s.sampler != Sampler::None, c.sampler.is_some(), "{}", c.id());
                assert_eq!(
                    matches!(s.base, Base::ShaderRecord | Base::InstanceBuffer),
                    c.base.is_some(),
                    "{}",
                    c.id()
                );
                assert_eq!(s.packed(), c.index == IndexSource::DynamicElement, "{}", c.id());
                assert_eq!(
                    s.packed(),
                    matches!(s.element, ElementMap::Packed | ElementMap::Layer),
                    "{}",
                    c.id()
                );
                assert_eq!(
                    s.element == ElementMap::None,
                    c.resource == Resource::AccelerationStructure,
                    "{}",
                    c.id()
                );
                assert_eq!(
                    s.workarounds().count(),
                    usize::from(c.as_access == Some(AsAccess::AddressPatched))
                        + usize::from(c.patch.is_some()),
                    "{}",
                    c.id()
                );
                // The data layer's copy of the rule (the report's outside-the-spec note) agrees.
                assert_eq!(
                    s.read == ReadIndex::Undefined,
                    crate::model::undefined_descriptor_read(&c),
                    "{}",
                    c.id()
                );
            }
        }
        let canary = ProbeSpec::of(&Cell::canary(Canary::InvalidAddress));
        assert!(canary.int64() && !ProbeSpec::of(&Cell::canary(Canary::InfiniteLoop)).int64());
    }

    /// A `layout(descriptor_heap)` read is defined with or without `nonuniformEXT` (its module
    /// declares DescriptorHeapEXT); the mapped (set/binding) twin without it is not.
    #[test]
    fn heap_reads_are_defined_and_mapped_ones_follow_the_nonuniform_rule() {
        let direct = Cell {
            descriptor_model: DescriptorModel::DescriptorHeap,
            heap_access: Some(HeapAccess::Direct),
            ..cell(Stage::ClosestHit, Resource::StorageBuffer, IndexSource::Dynamic)
        };
        assert_eq!(ProbeSpec::of(&direct).read, ReadIndex::Defined);
        assert!(!crate::model::undefined_descriptor_read(&direct));
        let mapped = Cell { heap_access: Some(HeapAccess::MappedShaderRecordIndex), ..direct };
        assert_eq!(ProbeSpec::of(&mapped).read, ReadIndex::Undefined);
        assert!(crate::model::undefined_descriptor_read(&mapped));
    }

    #[test]
    fn direct_sampled_images_sample_with_the_sampler_axis() {
        let c = Cell {
            descriptor_model: DescriptorModel::DescriptorHeap,
            heap_access: Some(HeapAccess::Direct),
            sampler: Some(SamplerIndex::Dynamic),
            ..cell(Stage::AnyHit, Resource::SampledImage, IndexSource::Literal)
        };
        let s = ProbeSpec::of(&c);
        // The literal descriptor index leaves the dynamic sampler index qualified; its base is push data.
        assert_eq!(
            (s.array, s.sampler, s.base),
            (ArrayAt::Heap, Sampler::Dynamic { nonuniform: true }, Base::PushData)
        );
        let unqualified = ProbeSpec::of(&Cell { index: IndexSource::Dynamic, ..c });
        assert_eq!(unqualified.sampler, Sampler::Dynamic { nonuniform: false });
        assert_eq!(
            ProbeSpec::of(&Cell { sampler: Some(SamplerIndex::Constant), ..c }).base,
            Base::None
        );
        // Mapped heap access samples a combined image sampler.
        assert_eq!(
            ProbeSpec::of(&Cell {
                heap_access: Some(HeapAccess::MappedPushIndex),
                sampler: None,
                ..c
            })
            .sampler,
            Sampler::None
        );
    }
}
