//! What a pixel must hold: the record the reference expects, the rule its probed value is
//! judged by (exact, or any element of the array where the read is undefined), and the
//! tolerances of the hit fields.
use crate::model::Resource;
use crate::probe::{self, Record, MAX_AS_VARIANTS};

pub const T_REL_TOL: f64 = 1e-3;

pub const BARY_TOL: f64 = 1e-3;

/// How the probed value is checked.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ValueRule {
    Exact,
    /// An undefined read (a non-uniform set/binding index without `NonUniform`): the spec allows
    /// anything, and rtprobe's *heuristic* for a scalarizing driver accepts the value of the
    /// descriptor index some other lane computed — in the same subgroup where the device's lane
    /// evidence shows it, else anywhere in the dispatch (`compare` picks the slots) — at this
    /// lane's own element (`texel`: the texel this lane samples). For AS arrays the value is the
    /// probe ray through that slot's TLAS variant at this pixel (`as_values[slot]`, first
    /// component; `variants` of them).
    AnyElement {
        resource: Resource,
        texel: u32,
        as_values: [f32; MAX_AS_VARIANTS as usize],
        variants: u32,
    },
}

/// What the driver saw undefined in a cell's probed read: the descriptor index (a non-uniform
/// set/binding index without `NonUniform`). A separate sampler index is never undefined: only
/// `layout(descriptor_heap)` probes have one, and their modules declare `DescriptorHeapEXT`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Undefined {
    pub descriptor: bool,
}

#[derive(Clone, Copy, Debug)]
pub struct Expected {
    pub record: Record,
    pub ambiguous: bool,
    pub rule: ValueRule,
    /// Every other slot / element would have given another value here (exact rule only).
    pub discriminating: bool,
}

impl ValueRule {
    /// Whether `v` is what this pixel reads through the descriptor at one of `slots` (the slots
    /// other lanes computed).
    pub(super) fn allows(&self, v: [f32; 4], mut slots: impl Iterator<Item = u32>) -> bool {
        match *self {
            ValueRule::Exact => false,
            ValueRule::AnyElement {
                resource: Resource::AccelerationStructure,
                as_values,
                variants,
                ..
            } => {
                v[1..] == [0.0, 0.0, 1.0]
                    && slots.any(|s| s < variants && as_values[s as usize] == v[0])
            }
            ValueRule::AnyElement { resource, texel, .. } => {
                slots.any(|s| probe::resource_value(resource, s, texel) == v)
            }
        }
    }
}
