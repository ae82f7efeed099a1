//! One cell of the matrix and its stable id, built from the axes (never from run order):
//! `stage.resource.index[.nonuniform][.as_access].descriptor_model`, or `canary.<name>`.
use super::axes::{AsAccess, DescriptorModel, IndexSource, Resource, Stage};
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

#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct Cell {
    pub stage: Stage,
    pub resource: Resource,
    pub index: IndexSource,
    pub nonuniform: bool,
    /// Only for `resource=acceleration_structure`.
    pub as_access: Option<AsAccess>,
    pub descriptor_model: DescriptorModel,
    /// A canary cell (the other axes are then the canary's carrier shape).
    pub canary: Option<Canary>,
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
            canary: Some(c),
        }
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
        parts.join(".")
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
            "canary" => self.canary.map(|c| c.as_str()).unwrap_or("none").into(),
            _ => return None,
        })
    }
}

pub const AXIS_NAMES: &[&str] = &["stage", "resource", "index", "nonuniform", "as_access", "descriptor_model", "canary"];

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
            canary: None,
        };
        assert_eq!(c.id(), "closest_hit.storage_buffer.dynamic.nonuniform.descriptor_indexing");
        let a = Cell { resource: Resource::AccelerationStructure, as_access: Some(AsAccess::Address), nonuniform: false, ..c };
        assert_eq!(a.id(), "closest_hit.acceleration_structure.dynamic.address.descriptor_indexing");
        assert_eq!(Cell::canary(Canary::InfiniteLoop).id(), "canary.infinite_loop");
    }
}
