//! One cell of the matrix: its axis values, where each optional axis applies, and its stable id,
//! built from the axes by the registry (never from run order):
//! `stage.resource.index[.nonuniform][.as_access].descriptor_model[.heap_access][.reorder][.base_<base>][.sampler_<sampler>][.scene_layout][.patch-<name>][.mutant-<name>]`,
//! or `canary.<name>`.
use super::axes::{
    AsAccess, BaseSource, DescriptorModel, HeapAccess, IndexSource, Reorder, Resource,
    SamplerIndex, SceneLayout, Stage,
};
use serde::{Deserialize, Serialize};

/// Deliberately faulting cells that prove fault detection works on the device at hand.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Canary {
    /// Raygen reads through a buffer reference at an unmapped address: expect `crash` (CPU
    /// drivers) or `device_lost`.
    InvalidAddress,
    /// Raygen loops forever: expect `timeout` (or `device_lost` where a watchdog fires).
    InfiniteLoop,
}

impl Canary {
    pub const ALL: &'static [Canary] = &[Canary::InvalidAddress, Canary::InfiniteLoop];
    pub const NAMES: &'static [&'static str] = &["invalid_address", "infinite_loop"];
    pub fn parse(s: &str) -> Option<Canary> {
        Canary::ALL.iter().copied().find(|c| c.as_str() == s)
    }
    pub fn as_str(self) -> &'static str {
        match self {
            Canary::InvalidAddress => "invalid_address",
            Canary::InfiniteLoop => "infinite_loop",
        }
    }
}

/// The `patch` axis: a SPIR-V workaround applied to the cell's compiled shaders.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Workaround {
    /// `nonuniform`: NonUniform on the dynamic descriptor access (for index=dynamic without it).
    Nonuniform,
    /// `pin-index`: the dynamic index becomes a spec constant (set to `probe::SPEC_SLOT`).
    PinIndex,
    /// `as-to-address`: the AS descriptor array read becomes an address-table read.
    AsToAddress,
    /// `ssbo-to-address`: the SSBO descriptor array read becomes a load through a buffer address.
    SsboToAddress,
}

impl Workaround {
    pub const ALL: &'static [Workaround] = &[
        Workaround::Nonuniform,
        Workaround::PinIndex,
        Workaround::AsToAddress,
        Workaround::SsboToAddress,
    ];
    pub const NAMES: &'static [&'static str] =
        &["nonuniform", "pin-index", "as-to-address", "ssbo-to-address"];
    pub fn parse(s: &str) -> Option<Workaround> {
        Workaround::ALL.iter().copied().find(|w| w.as_str() == s)
    }
    pub fn as_str(self) -> &'static str {
        match self {
            Workaround::Nonuniform => "nonuniform",
            Workaround::PinIndex => "pin-index",
            Workaround::AsToAddress => "as-to-address",
            Workaround::SsboToAddress => "ssbo-to-address",
        }
    }
}

/// The engines' recommended replacements for a dynamic descriptor index (`index=dynamic_element`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Pattern {
    /// One storage buffer at a spec-constant slot, read at a dynamic element offset.
    Geometry,
    /// One array texture (`texture2DArray`) at a spec-constant slot, sampled at a dynamic layer.
    Materials,
}

impl Pattern {
    /// The pattern of `resource`'s kind: geometry for storage buffers, materials for sampled
    /// images; none for the others.
    pub fn of(resource: Resource) -> Option<Pattern> {
        match resource {
            Resource::StorageBuffer => Some(Pattern::Geometry),
            Resource::SampledImage => Some(Pattern::Materials),
            Resource::UniformBuffer | Resource::StorageImage | Resource::AccelerationStructure => {
                None
            }
        }
    }

    pub fn as_str(self) -> &'static str {
        match self {
            Pattern::Geometry => "geometry",
            Pattern::Materials => "materials",
        }
    }

    pub fn description(self) -> &'static str {
        match self {
            Pattern::Geometry => {
                "one storage buffer at a spec-constant slot, dynamic element offset"
            }
            Pattern::Materials => "one texture2DArray at a spec-constant slot, dynamic layer",
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct Cell {
    pub stage: Stage,
    pub resource: Resource,
    pub index: IndexSource,
    pub nonuniform: bool,
    /// Only for `resource=acceleration_structure`.
    pub as_access: Option<AsAccess>,
    pub descriptor_model: DescriptorModel,
    /// How the shaders reach the heap; only (and always) for `descriptor_model=descriptor_heap`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub heap_access: Option<HeapAccess>,
    /// A canary cell (the other axes are then the canary's carrier shape).
    pub canary: Option<Canary>,
    /// The SPIR-V workaround applied (`patch` axis; none for plain cells).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub patch: Option<Workaround>,
    /// Shader execution reordering in raygen (`reorder` axis; only closest-hit cells with a
    /// dynamic index have it, see [`Cell::reorder_applies`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reorder: Option<Reorder>,
    /// Where a closest-hit dynamic index's base comes from (`base` axis; `None`: push data). Only
    /// where [`Cell::base_applies`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub base: Option<BaseSource>,
    /// The sampler index of a separate-sampler probe (`sampler` axis): always set on
    /// `heap_access=direct` sampled-image cells, never elsewhere ([`Cell::sampler_applies`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sampler: Option<SamplerIndex>,
    /// The emulated driver bug mutated into the probed stage's SPIR-V (`mutant` axis, `run
    /// --mutants`; none for plan cells): a mutant attempt's identity.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mutant: Option<super::mutant::Mutant>,
    /// How the closest-hit fetches the hit triangle's data (`scene_layout` axis); only where
    /// [`Cell::scene_layout_applies`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scene_layout: Option<SceneLayout>,
    /// `run --cells-scale`: copy k (≥ 1) of the cell, with shaders of its own (a constant in
    /// the first stage that never changes what it records), so that it makes a pipeline of its
    /// own; 0 for the matrix's cells. Id suffix `.copy-k`.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub copy: u32,
}

fn is_zero(v: &u32) -> bool {
    *v == 0
}

impl Cell {
    /// A probe cell with these four axes and every optional axis unset: the builder of tests and
    /// of the plan (`Cell { base: Some(b), ..Cell::new(…) }`), so a new optional axis touches
    /// neither.
    pub fn new(
        stage: Stage,
        resource: Resource,
        index: IndexSource,
        descriptor_model: DescriptorModel,
    ) -> Cell {
        Cell {
            stage,
            resource,
            index,
            nonuniform: false,
            as_access: None,
            descriptor_model,
            heap_access: None,
            canary: None,
            patch: None,
            reorder: None,
            base: None,
            sampler: None,
            mutant: None,
            scene_layout: None,
            copy: 0,
        }
    }

    pub fn canary(c: Canary) -> Cell {
        Cell {
            canary: Some(c),
            ..Cell::new(
                Stage::Raygen,
                Resource::StorageBuffer,
                IndexSource::Literal,
                DescriptorModel::DescriptorIndexing,
            )
        }
    }

    /// Reordering before the probed read can only be observed by a closest-hit probe (the hit
    /// object's shader runs after the reorder; any-hit and intersection run during traversal,
    /// before it) whose index differs between invocations. Set-based descriptor models only: no
    /// driver offers both SER and descriptor heaps yet (the H100's 580 has SER, no heap; lavapipe
    /// 26 the heap, no SER), so heap × reorder cells could run nowhere.
    pub fn reorder_applies(&self) -> bool {
        self.canary.is_none()
            && self.stage == Stage::ClosestHit
            && self.index == IndexSource::Dynamic
            && self.descriptor_model != DescriptorModel::DescriptorHeap
            && self.base.is_none()
            && self.scene_layout.is_none()
    }

    /// The `base` axis: the original fault's shape is a closest-hit shader indexing with `base +
    /// gl_InstanceCustomIndexEXT`, so where the base comes from varies on closest-hit cells with a
    /// dynamic index (or the recommended pattern's dynamic element) into buffers and images.
    /// Other hit stages keep the push-data base (their index has the same shape; the axis would
    /// triple their cells), and AS arrays are small and reached by their own access axis.
    pub fn base_applies(&self) -> bool {
        self.canary.is_none()
            && self.stage == Stage::ClosestHit
            && matches!(self.index, IndexSource::Dynamic | IndexSource::DynamicElement)
            && self.resource != Resource::AccelerationStructure
            && self.reorder.is_none()
            && self.scene_layout.is_none()
    }

    /// The `scene_layout` axis: a closest-hit that fetches its hit triangle's indices, positions
    /// and material the way engines lay scene geometry out. Its index is the custom index (a
    /// dynamic one); set/binding models only (heap cells would need a mesh array in the heap: not
    /// built), no base, reorder or sampler variant (the layout cells vary the layout only).
    pub fn scene_layout_applies(&self) -> bool {
        !self.planned_layouts().is_empty()
    }

    /// The scene layouts the plan gives this cell, where the axis applies: storage-buffer cells
    /// fetch geometry, `per_mesh` with `nonuniform` (without it its descriptor read is
    /// undefined), `shared_buffers` without (it indexes no descriptor); sampled-image cells with
    /// `nonuniform` are the texture cells, in both layouts, with the scene's textures in a
    /// descriptor array indexed by the fetched material (`scene::textures`; `per_mesh` reads the
    /// material through the mesh buffers, a second descriptor array at binding 3).
    pub fn planned_layouts(&self) -> &'static [SceneLayout] {
        let layouts: &'static [SceneLayout] = match (self.resource, self.nonuniform) {
            (Resource::StorageBuffer, true) => &[SceneLayout::PerMesh],
            (Resource::StorageBuffer, false) => &[SceneLayout::SharedBuffers],
            (Resource::SampledImage, true) => &[SceneLayout::SharedBuffers, SceneLayout::PerMesh],
            (Resource::SampledImage, false)
            | (Resource::UniformBuffer | Resource::StorageImage, _)
            | (Resource::AccelerationStructure, _) => return &[],
        };
        let applies = self.canary.is_none()
            && self.stage == Stage::ClosestHit
            && self.index == IndexSource::Dynamic
            && self.descriptor_model != DescriptorModel::DescriptorHeap
            && self.base.is_none()
            && self.reorder.is_none();
        if applies {
            layouts
        } else {
            &[]
        }
    }

    /// Whether a `sampler=dynamic` cell's sampler index carries `nonuniformEXT`: always, except in
    /// a cell whose own dynamic descriptor index goes without it (the original shape, unqualified
    /// throughout; judged as any element).
    pub fn sampler_nonuniform(&self) -> bool {
        self.sampler == Some(SamplerIndex::Dynamic)
            && (self.index != IndexSource::Dynamic || self.nonuniform)
    }

    /// The `sampler` axis: `layout(descriptor_heap)` GLSL has no combined image samplers, so a
    /// direct sampled-image probe always samples `sampler2D(probeTex[i], probeSampler[s])` with a
    /// separate sampler index. Set/binding shaders (every other model and mapped heap access)
    /// sample combined image samplers and have no sampler index of their own.
    pub fn sampler_applies(&self) -> bool {
        self.canary.is_none()
            && self.resource == Resource::SampledImage
            && self.heap_access == Some(HeapAccess::Direct)
    }

    /// `index=dynamic_element` exists for the engines' two recommended shapes only: geometry (an
    /// SSBO) and materials (a sampled image array texture).
    pub fn dynamic_element_applies(resource: Resource) -> bool {
        Pattern::of(resource).is_some()
    }

    /// The engines' recommended pattern nearest to this cell (same stage, model, heap access):
    /// the `index=dynamic_element` cell of its resource, or why there is none. What a finding's
    /// report says "works instead" is that cell's verdict (`report::recommended`). The `Err` is no
    /// failure but the reason the report records (`PatternStatus::NotApplicable`), so it is text.
    pub fn recommended_pattern(&self) -> Result<(Pattern, Cell), String> {
        if self.canary.is_some() {
            return Err("canaries have no recommended pattern".into());
        }
        if let Some(l) = self.scene_layout {
            return Err(format!("scene_layout={l} is itself an engine's layout (its alternative is the other scene_layout value)"));
        }
        let pattern = Pattern::of(self.resource)
            .ok_or_else(|| format!("rtprobe has no recommended single-descriptor pattern for {} (only storage buffers: geometry, sampled images: materials)", self.resource))?;
        if self.index == IndexSource::DynamicElement && self.patch.is_none() {
            return Err(format!("this cell is the recommended pattern ({})", pattern.as_str()));
        }
        // Same base and sampler: the pattern reads its dynamic value the way the finding did.
        Ok((
            pattern,
            Cell {
                index: IndexSource::DynamicElement,
                nonuniform: false,
                patch: None,
                reorder: None,
                ..*self
            },
        ))
    }

    /// The cell without its workaround.
    pub fn base(&self) -> Cell {
        Cell { patch: None, ..*self }
    }

    /// The cell without its mutant (what a mutant attempt is judged as).
    pub fn unmutated(&self) -> Cell {
        Cell { mutant: None, ..*self }
    }

    /// The workarounds that apply to this cell's shaders.
    pub fn applicable_patches(&self) -> Vec<Workaround> {
        // Direct heap reads are untyped access chains, which no workaround rewrites.
        // Scene-layout cells fetch through their own layout, which the workarounds do not know.
        if self.canary.is_some()
            || self.patch.is_some()
            || self.mutant.is_some()
            || self.scene_layout.is_some()
            || self.heap_access == Some(HeapAccess::Direct)
        {
            return vec![];
        }
        // After as-to-address (written or patched) there is no descriptor array left to decorate or pin.
        let descriptor_array = self.resource != Resource::AccelerationStructure
            || self.as_access == Some(AsAccess::Descriptor);
        let mut v = Vec::new();
        if self.index == IndexSource::Dynamic && !self.nonuniform && descriptor_array {
            v.push(Workaround::Nonuniform);
        }
        if self.index == IndexSource::Dynamic && descriptor_array {
            v.push(Workaround::PinIndex);
        }
        if self.resource == Resource::AccelerationStructure
            && self.as_access == Some(AsAccess::Descriptor)
        {
            v.push(Workaround::AsToAddress);
        }
        if self.resource == Resource::StorageBuffer && self.index == IndexSource::Dynamic {
            v.push(Workaround::SsboToAddress);
        }
        v
    }
}

/// The rule a dynamic set/binding descriptor index without `nonuniformEXT` breaks: an operand
/// for a resource that is not uniform must be decorated `NonUniform` where the module does not
/// declare `DescriptorHeapEXT` (Vulkan 1.4.360; these replaced VUID-RuntimeSpirv-NonUniform-06274
/// in 1.3.294, and gained the heap exemption in 1.4.340).
pub const NO_NONUNIFORM_VUID: &str =
    "VUID-RuntimeSpirv-None-10148 / VUID-RuntimeSpirv-subgroupSize-10149 (Vulkan 1.4.360)";

/// Whether `cell` indexes a set/binding descriptor array with a non-uniform value that carries no
/// `NonUniform` ([`NO_NONUNIFORM_VUID`]): not after the nonuniform / pin-index patches, not where
/// no descriptor is indexed any more (an address table, written so or patched), since a
/// non-uniform index into memory is well defined, and not from the heap (`heap_access=direct`:
/// the module declares `DescriptorHeapEXT`, whose heap accesses need no decoration).
pub fn undefined_descriptor_read(cell: &Cell) -> bool {
    let descriptor_indexed = match cell.as_access {
        None | Some(AsAccess::Descriptor) => true,
        Some(AsAccess::Address | AsAccess::AddressPatched) => false,
    };
    let patch_keeps_it = match cell.patch {
        None => true,
        Some(
            Workaround::Nonuniform
            | Workaround::PinIndex
            | Workaround::AsToAddress
            | Workaround::SsboToAddress,
        ) => false,
    };
    let set_binding = match cell.heap_access {
        None
        | Some(
            HeapAccess::MappedConstantOffset
            | HeapAccess::MappedPushIndex
            | HeapAccess::MappedIndirectIndex
            | HeapAccess::MappedShaderRecordIndex,
        ) => true,
        Some(HeapAccess::Direct) => false,
    };
    // `shared_buffers` reads memory through addresses: no descriptor is indexed.
    let layout_descriptor = match cell.scene_layout {
        None | Some(SceneLayout::PerMesh) => true,
        Some(SceneLayout::SharedBuffers) => cell.resource == Resource::SampledImage,
    };
    cell.index == IndexSource::Dynamic
        && !cell.nonuniform
        && layout_descriptor
        && descriptor_indexed
        && patch_keeps_it
        && set_binding
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_are_readable_and_stable() {
        let c = Cell {
            nonuniform: true,
            ..Cell::new(
                Stage::ClosestHit,
                Resource::StorageBuffer,
                IndexSource::Dynamic,
                DescriptorModel::DescriptorIndexing,
            )
        };
        assert_eq!(c.id(), "closest_hit.storage_buffer.dynamic.nonuniform.descriptor_indexing");
        assert_eq!(c.axis_value("base").as_deref(), Some("push_data"));
        let b = Cell { base: Some(BaseSource::ShaderRecord), ..c };
        assert_eq!(
            b.id(),
            "closest_hit.storage_buffer.dynamic.nonuniform.descriptor_indexing.base_shader_record"
        );
        assert!(!b.reorder_applies() && b.base_applies());
        assert_eq!(Cell { stage: Stage::AnyHit, ..c }.axis_value("base").as_deref(), Some("none"));
        let d = Cell {
            resource: Resource::SampledImage,
            descriptor_model: DescriptorModel::DescriptorHeap,
            heap_access: Some(HeapAccess::Direct),
            sampler: Some(SamplerIndex::Dynamic),
            ..c
        };
        assert_eq!(
            d.id(),
            "closest_hit.sampled_image.dynamic.nonuniform.descriptor_heap.direct.sampler_dynamic"
        );
        assert!(
            d.sampler_applies()
                && !Cell { heap_access: Some(HeapAccess::MappedPushIndex), ..d }.sampler_applies()
        );
        let r =
            Cell { reorder: Some(Reorder::ReorderHint), patch: Some(Workaround::PinIndex), ..c };
        assert_eq!(r.id(), "closest_hit.storage_buffer.dynamic.nonuniform.descriptor_indexing.reorder_hint.patch-pin-index");
        assert_eq!(r.axis_value("reorder").as_deref(), Some("reorder_hint"));
        assert!(
            c.reorder_applies() && !Cell { index: IndexSource::Literal, ..c }.reorder_applies()
        );
        let p = Cell { nonuniform: false, patch: Some(Workaround::Nonuniform), ..c };
        assert_eq!(
            p.id(),
            "closest_hit.storage_buffer.dynamic.descriptor_indexing.patch-nonuniform"
        );
        assert_eq!(
            p.base().applicable_patches(),
            vec![Workaround::Nonuniform, Workaround::PinIndex, Workaround::SsboToAddress]
        );
        let a = Cell {
            resource: Resource::AccelerationStructure,
            as_access: Some(AsAccess::Address),
            nonuniform: false,
            ..c
        };
        assert_eq!(
            a.id(),
            "closest_hit.acceleration_structure.dynamic.address.descriptor_indexing"
        );
        assert_eq!(Cell::canary(Canary::InfiniteLoop).id(), "canary.infinite_loop");
        let h = Cell {
            descriptor_model: DescriptorModel::DescriptorHeap,
            heap_access: Some(HeapAccess::MappedPushIndex),
            ..c
        };
        assert_eq!(
            h.id(),
            "closest_hit.storage_buffer.dynamic.nonuniform.descriptor_heap.mapped_push_index"
        );
        assert_eq!(h.axis_value("heap_access").as_deref(), Some("mapped_push_index"));
    }
}
