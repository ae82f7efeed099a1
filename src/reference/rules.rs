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
    /// Any element of the probed array is allowed (non-uniform index without NonUniform); for AS
    /// arrays, the first component of any probe TLAS variant's value (`as_values[..variants]`).
    AnyElement {
        resource: Resource,
        slots: u32,
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
    /// Whether `v` is the value of some element of the array.
    pub(super) fn allows(&self, v: [f32; 4]) -> bool {
        match *self {
            ValueRule::Exact => false,
            ValueRule::AnyElement {
                resource: Resource::AccelerationStructure,
                as_values,
                variants,
                ..
            } => v[1..] == [0.0, 0.0, 1.0] && as_values[..variants as usize].contains(&v[0]),
            ValueRule::AnyElement { resource, slots, .. } => {
                let (s, e) = (v[0] - 1.0, v[3] - 0.25);
                let whole = |x: f32, n: u32| x >= 0.0 && x.fract() == 0.0 && (x as u32) < n;
                whole(s, slots)
                    && whole(e, probe::ELEMENTS)
                    && probe::resource_value(resource, s as u32, e as u32) == v
            }
        }
    }
}
