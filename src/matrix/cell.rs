//! One cell of the matrix and its stable id, built from the axes (never from run order):
//! `stage.resource.index[.nonuniform][.as_access].descriptor_model[.heap_access][.reorder][.patch-<name>]`,
//! or `canary.<name>`.
use super::axes::{AsAccess, DescriptorModel, HeapAccess, IndexSource, Reorder, Resource, Stage};
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
    pub const ALL: &'static [Workaround] = &[Workaround::Nonuniform, Workaround::PinIndex, Workaround::AsToAddress, Workaround::SsboToAddress];
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
    pub fn as_str(self) -> &'static str {
        match self {
            Pattern::Geometry => "geometry",
            Pattern::Materials => "materials",
        }
    }

    pub fn description(self) -> &'static str {
        match self {
            Pattern::Geometry => "one storage buffer at a spec-constant slot, dynamic element offset",
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
}

impl Cell {
    pub fn canary(c: Canary) -> Cell {
        Cell {
            stage: Stage::Raygen,
            resource: Resource::StorageBuffer,
            index: IndexSource::Literal,
            nonuniform: false,
            as_access: None,
            descriptor_model: DescriptorModel::DescriptorIndexing,
            heap_access: None,
            canary: Some(c),
            patch: None,
            reorder: None,
        }
    }

    /// Reordering before the probed read can only be observed by a closest-hit probe (the hit
    /// object's shader runs after the reorder; any-hit and intersection run during traversal,
    /// before it) whose index differs between invocations. Set-based descriptor models only: no
    /// driver offers both SER and descriptor heaps yet (the H100's 580 has SER, no heap; lavapipe
    /// 26 the heap, no SER), so heap × reorder cells could run nowhere.
    pub fn reorder_applies(&self) -> bool {
        self.canary.is_none() && self.stage == Stage::ClosestHit && self.index == IndexSource::Dynamic && self.descriptor_model != DescriptorModel::DescriptorHeap
    }

    /// `index=dynamic_element` exists for the engines' two recommended shapes only: geometry (an
    /// SSBO) and materials (a sampled image array texture).
    pub fn dynamic_element_applies(resource: Resource) -> bool {
        match resource {
            Resource::StorageBuffer | Resource::SampledImage => true,
            Resource::UniformBuffer | Resource::StorageImage | Resource::AccelerationStructure => false,
        }
    }

    /// The engines' recommended pattern nearest to this cell (same stage, model, heap access):
    /// the `index=dynamic_element` cell of its resource, or why there is none. What a finding's
    /// report says "works instead" is that cell's verdict (`report::recommended`).
    pub fn recommended_pattern(&self) -> Result<(Pattern, Cell), String> {
        if self.canary.is_some() {
            return Err("canaries have no recommended pattern".into());
        }
        let pattern = match self.resource {
            Resource::StorageBuffer => Pattern::Geometry,
            Resource::SampledImage => Pattern::Materials,
            Resource::UniformBuffer | Resource::StorageImage | Resource::AccelerationStructure => {
                return Err(format!("rtprobe has no recommended single-descriptor pattern for {} (only storage buffers: geometry, sampled images: materials)", self.resource));
            }
        };
        if self.index == IndexSource::DynamicElement && self.patch.is_none() {
            return Err(format!("this cell is the recommended pattern ({})", pattern.as_str()));
        }
        Ok((pattern, Cell { index: IndexSource::DynamicElement, nonuniform: false, patch: None, reorder: None, ..*self }))
    }

    /// The cell without its workaround.
    pub fn base(&self) -> Cell {
        Cell { patch: None, ..*self }
    }

    /// The workarounds that apply to this cell's shaders.
    pub fn applicable_patches(&self) -> Vec<Workaround> {
        // Direct heap reads are untyped access chains, which no workaround rewrites.
        if self.canary.is_some() || self.patch.is_some() || self.heap_access == Some(HeapAccess::Direct) {
            return vec![];
        }
        // After as-to-address (written or patched) there is no descriptor array left to decorate or pin.
        let descriptor_array = self.resource != Resource::AccelerationStructure || self.as_access == Some(AsAccess::Descriptor);
        let mut v = Vec::new();
        if self.index == IndexSource::Dynamic && !self.nonuniform && descriptor_array {
            v.push(Workaround::Nonuniform);
        }
        if self.index == IndexSource::Dynamic && descriptor_array {
            v.push(Workaround::PinIndex);
        }
        if self.resource == Resource::AccelerationStructure && self.as_access == Some(AsAccess::Descriptor) {
            v.push(Workaround::AsToAddress);
        }
        if self.resource == Resource::StorageBuffer && self.index == IndexSource::Dynamic {
            v.push(Workaround::SsboToAddress);
        }
        v
    }

    pub fn id(&self) -> String {
        if let Some(c) = self.canary {
            return format!("canary.{}", c.as_str());
        }
        let mut parts = vec![self.stage.as_str(), self.resource.as_str(), self.index.as_str()];
        if self.nonuniform {
            parts.push("nonuniform");
        }
        if let Some(a) = self.as_access {
            parts.push(a.as_str());
        }
        parts.push(self.descriptor_model.as_str());
        if let Some(h) = self.heap_access {
            parts.push(h.as_str());
        }
        if let Some(r) = self.reorder {
            parts.push(r.as_str());
        }
        let mut id = parts.join(".");
        if let Some(p) = self.patch {
            id.push_str(".patch-");
            id.push_str(p.as_str());
        }
        id
    }

    /// The value of an axis by its name, for filters.
    pub fn axis_value(&self, axis: &str) -> Option<String> {
        Some(match axis {
            "stage" => self.stage.as_str().into(),
            "resource" => self.resource.as_str().into(),
            "index" => self.index.as_str().into(),
            "nonuniform" => self.nonuniform.to_string(),
            "as_access" => self.as_access.map(|a| a.as_str()).unwrap_or("none").into(),
            "descriptor_model" => self.descriptor_model.as_str().into(),
            "heap_access" => self.heap_access.map(|h| h.as_str()).unwrap_or("none").into(),
            "canary" => self.canary.map(|c| c.as_str()).unwrap_or("none").into(),
            "patch" => self.patch.map(|p| p.as_str()).unwrap_or("none").into(),
            "reorder" => self.reorder.map(|r| r.as_str()).unwrap_or("none").into(),
            _ => return None,
        })
    }
}

pub const AXIS_NAMES: &[&str] = &["stage", "resource", "index", "nonuniform", "as_access", "descriptor_model", "heap_access", "canary", "patch", "reorder"];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_are_readable_and_stable() {
        let c = Cell {
            stage: Stage::ClosestHit,
            resource: Resource::StorageBuffer,
            index: IndexSource::Dynamic,
            nonuniform: true,
            as_access: None,
            descriptor_model: DescriptorModel::DescriptorIndexing,
            heap_access: None,
            canary: None,
            patch: None,
            reorder: None,
        };
        assert_eq!(c.id(), "closest_hit.storage_buffer.dynamic.nonuniform.descriptor_indexing");
        let r = Cell { reorder: Some(Reorder::ReorderHint), patch: Some(Workaround::PinIndex), ..c };
        assert_eq!(r.id(), "closest_hit.storage_buffer.dynamic.nonuniform.descriptor_indexing.reorder_hint.patch-pin-index");
        assert_eq!(r.axis_value("reorder").as_deref(), Some("reorder_hint"));
        assert!(c.reorder_applies() && !Cell { index: IndexSource::Literal, ..c }.reorder_applies());
        let p = Cell { nonuniform: false, patch: Some(Workaround::Nonuniform), ..c };
        assert_eq!(p.id(), "closest_hit.storage_buffer.dynamic.descriptor_indexing.patch-nonuniform");
        assert_eq!(p.base().applicable_patches(), vec![Workaround::Nonuniform, Workaround::PinIndex, Workaround::SsboToAddress]);
        let a = Cell { resource: Resource::AccelerationStructure, as_access: Some(AsAccess::Address), nonuniform: false, ..c };
        assert_eq!(a.id(), "closest_hit.acceleration_structure.dynamic.address.descriptor_indexing");
        assert_eq!(Cell::canary(Canary::InfiniteLoop).id(), "canary.infinite_loop");
        let h = Cell { descriptor_model: DescriptorModel::DescriptorHeap, heap_access: Some(HeapAccess::MappedPushIndex), ..c };
        assert_eq!(h.id(), "closest_hit.storage_buffer.dynamic.nonuniform.descriptor_heap.mapped_push_index");
        assert_eq!(h.axis_value("heap_access").as_deref(), Some("mapped_push_index"));
    }
}
