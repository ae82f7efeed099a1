//! The probe contract shared by the GPU side (`shadergen`) and the CPU side (`reference`): the
//! record every probe writes per pixel, its flags, which slot each index source selects, and the
//! value each resource slot holds. Change one side only through this file.
use crate::matrix::{Resource, Stage};

/// One record per pixel (std430, 48 bytes): what the ray hit and what the probed stage read.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Record {
    pub flags: u32,
    /// `gl_InstanceCustomIndexEXT` of the committed hit.
    pub instance: u32,
    pub primitive: u32,
    pub t: f32,
    pub bary: [f32; 2],
    /// The descriptor slot the probe read.
    pub slot: u32,
    pub pad: u32,
    pub value: [f32; 4],
}

pub const RECORD_SIZE: usize = 48;
const _: () = assert!(std::mem::size_of::<Record>() == RECORD_SIZE);

impl Record {
    pub fn from_bytes(b: &[u8]) -> Record {
        let u = |i: usize| u32::from_le_bytes(b[i * 4..i * 4 + 4].try_into().expect("4 bytes"));
        let f = |i: usize| f32::from_bits(u(i));
        Record {
            flags: u(0),
            instance: u(1),
            primitive: u(2),
            t: f(3),
            bary: [f(4), f(5)],
            slot: u(6),
            pad: u(7),
            value: [f(8), f(9), f(10), f(11)],
        }
    }
}

/// The primary ray hit something.
pub const FLAG_HIT: u32 = 1;
/// The probed stage ran for this pixel and wrote `slot` and `value`.
pub const FLAG_PROBE: u32 = 2;

/// Slot read with `index=literal` (a literal in the GLSL).
pub const LITERAL_SLOT: u32 = 3;
/// Slot read with `index=spec_constant` (specialization constant 0 is set to this; its default is 0).
pub const SPEC_SLOT: u32 = 5;
/// Slot read with `index=push_constant`.
pub const PUSH_SLOT: u32 = 7;
/// The runtime base added to `gl_InstanceCustomIndexEXT` with `index=dynamic` in hit stages.
pub const DYNAMIC_BASE: u32 = 1;
/// Fragment probes draw one quad per TILE×TILE pixels; its flat varying is the tile number.
pub const TILE: u32 = 8;

/// Number of descriptors in the probed array (and of addresses in the AS address table).
pub fn slot_count(instances: u32) -> u32 {
    DYNAMIC_BASE + instances
}

/// The value a buffer or image slot holds (exact in f32), distinct per resource kind and slot.
pub fn resource_value(resource: Resource, slot: u32) -> [f32; 4] {
    let r = Resource::ALL.iter().position(|x| *x == resource).unwrap_or(0) as f32;
    [slot as f32 + 1.0, r * 16.0 + 1.0, 1000.0 + slot as f32, 0.25]
}

/// Which TLAS an acceleration-structure slot refers to: 0 = the whole scene, 1 = the instances
/// with an even custom index.
pub fn as_slot_tlas(slot: u32) -> usize {
    (slot % 2) as usize
}

/// The slot `index=dynamic` selects in `stage` for pixel (x, y).
pub fn dynamic_slot(stage: Stage, x: u32, y: u32, width: u32, hit_instance: u32, slots: u32) -> u32 {
    match stage {
        Stage::ClosestHit | Stage::AnyHit | Stage::Intersection => DYNAMIC_BASE + hit_instance,
        Stage::Raygen | Stage::Miss | Stage::Callable | Stage::Compute => (x + y * width) % slots,
        Stage::Fragment => ((y / TILE) * (width / TILE) + x / TILE) % slots,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn record_round_trips_through_bytes() {
        let r = Record { flags: 3, instance: 7, primitive: 9, t: 1.5, bary: [0.25, 0.5], slot: 4, pad: 0, value: [1.0, 2.0, 3.0, 0.25] };
        let bytes: Vec<u8> = [r.flags, r.instance, r.primitive, r.t.to_bits(), r.bary[0].to_bits(), r.bary[1].to_bits(), r.slot, r.pad]
            .iter()
            .chain(r.value.iter().map(|v| v.to_bits()).collect::<Vec<_>>().iter())
            .flat_map(|u| u.to_le_bytes())
            .collect();
        assert_eq!(Record::from_bytes(&bytes), r);
    }

    #[test]
    fn slots_fit_the_array() {
        let n = slot_count(16);
        assert!(LITERAL_SLOT < n && SPEC_SLOT < n && PUSH_SLOT < n);
        assert_eq!(dynamic_slot(Stage::ClosestHit, 0, 0, 64, 15, n), 16);
        assert!(dynamic_slot(Stage::Fragment, 63, 63, 64, 0, n) < n);
        assert_ne!(resource_value(Resource::StorageBuffer, 1), resource_value(Resource::UniformBuffer, 1));
    }
}
