//! `run --shader --inject-fault 'PREDICATE[@KIND]'`: a fault injected into a user's module at
//! each descriptor access whose stage, resource and index source match PREDICATE
//! ([`predicate`]; the accesses are found by [`sites`]), so a user can prove that rtprobe detects
//! a fault of their pipeline on their driver. [`inject`] is a plain function over
//! `&mut rspirv::dr::Module`.
//!
//! The fault sits right after the access and is fed by the access's value ([`emit`]): the
//! first scalar of the loaded or sampled value, as 32 bits, `& 0` — zero at run time, yet an
//! operand of the fault — so deleting the access deletes the fault, and a module without a
//! matching access gets none. The fault's result flows back into the access's value (its first
//! scalar plus a term that is zero at run time but not to a compiler) and so into what the
//! shader writes: on lavapipe, a fault whose result nothing used was dropped by the driver's
//! compiler, the load though `Volatile` and the loop though endless.
//!
//! An acceleration structure access (the `OpLoad` of an `accelerationStructureEXT` descriptor,
//! an array's element too) has no bits: its fault, right after the load, takes the constant 0
//! as `bits`, and its result feeds the cull mask of every ray the handle traces in that
//! function ([`handle`]); a handle that traces none gets no fault (listed as skipped). Deleting
//! the load deletes the site: a module whose AS comes from an address
//! (`OpConvertUToAccelerationStructureKHR`, what `as-to-address` writes) has no AS access. KIND:
//! - `device` (default): a `Volatile` load through the `PhysicalStorageBuffer` address
//!   `0xdead_0000_0000 + (bits & 0)`, outside every allocation; the term fed back is 1 where
//!   the loaded word equals `0x9e3779b9`, else 0. The module gets the
//!   `PhysicalStorageBufferAddresses` capability, `SPV_KHR_physical_storage_buffer` before
//!   SPIR-V 1.5, and `PhysicalStorageBuffer64` addressing. What an invalid address does is
//!   undefined (a device loss, a crash on CPU drivers, a hang where a driver spins): rtprobe
//!   counts each as a fault.
//! - `hang`: a structured loop counting by two from 0 until the count equals `bits | 1`, odd,
//!   so never; the term fed back is the final count minus `bits | 1`.
//!
//! Where an access's block is a loop header the hang is not inserted (its back edges must keep
//! reaching its `OpLoopMerge`): the access is listed as skipped, with why.
//!
//! The other kinds of `--inject-fault` (`value`, `nan`, `flaky`) are refused for a user's shader:
//! a wrong value is caught only against a CPU reference, which a user's shader has none of, and
//! `flaky` is armed through the generated probe's push constants.
pub mod emit;
pub mod handle;
pub mod predicate;
pub mod sites;
#[cfg(test)]
mod tests;
#[cfg(test)]
mod tests_as;

use crate::model::{FaultKind, Resource};
pub use predicate::{Access, Predicate, PredicateError};
use rspirv::dr::Module;

/// The faults a user's module can get.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fault {
    Device,
    Hang,
}

impl Fault {
    pub fn as_str(self) -> &'static str {
        match self {
            Fault::Device => "device",
            Fault::Hang => "hang",
        }
    }
}

/// One `--inject-fault` for `--shader`, parsed.
#[derive(Clone, Debug, PartialEq)]
pub struct Request {
    /// `PREDICATE@KIND`, as the user wrote the predicate.
    pub spec: String,
    pub predicate: Predicate,
    pub fault: Fault,
}

/// An `--inject-fault` that `--shader` cannot take.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum InjectError {
    #[error("--inject-fault {spec:?}: {error}")]
    Kind { spec: String, error: String },
    #[error("--inject-fault {spec:?}: {kind} needs a CPU reference to catch a wrong value, and a user's shader has none; use @device or @hang")]
    ValueKind { spec: String, kind: String },
    #[error("--inject-fault {spec:?}: flaky is armed through the generated probe's push constants, which a user's shader lacks; use @device or @hang")]
    Flaky { spec: String },
    #[error("--inject-fault {spec:?}: {error}")]
    Predicate { spec: String, error: PredicateError },
}

impl Request {
    pub fn parse(s: &str) -> Result<Request, InjectError> {
        let spec = s.trim().to_string();
        let (pred, kind) = match spec.rsplit_once('@') {
            Some((p, k)) => (p.trim(), k),
            None => (spec.as_str(), "device"),
        };
        let fault = match FaultKind::parse(kind)
            .map_err(|e| InjectError::Kind { spec: spec.clone(), error: e.to_string() })?
        {
            FaultKind::Device => Fault::Device,
            FaultKind::Hang => Fault::Hang,
            k @ (FaultKind::Value { .. } | FaultKind::Nan) => {
                return Err(InjectError::ValueKind { spec, kind: k.label() })
            }
            FaultKind::Flaky { .. } => return Err(InjectError::Flaky { spec }),
        };
        let predicate = Predicate::parse(pred)
            .map_err(|error| InjectError::Predicate { spec: spec.clone(), error })?;
        Ok(Request { spec: format!("{pred}@{}", fault.as_str()), predicate, fault })
    }
}

/// What [`inject`] did to one module.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Injected {
    /// Each access that got the fault, in words (`closest_hit reads storage_buffer materials
    /// (dynamic index)`).
    pub sites: Vec<String>,
    /// Matching accesses that could not get it, and why.
    pub skipped: Vec<String>,
}

fn describe(s: &sites::Site) -> String {
    let a = s.access;
    format!("{} reads {} {} ({} index)", a.stage, a.resource, s.var, a.index)
}

/// What the fault at site `s` is fed by and feeds, or why it gets none.
fn tie(m: &mut Module, s: &sites::Site) -> Result<emit::Tie, &'static str> {
    let (f, b, i) = s.at;
    match (s.access.resource, s.value) {
        (Resource::AccelerationStructure, _) => {
            let handle = m.functions[f].blocks[b].instructions[i].result_id;
            match handle.filter(|h| !handle::consumers(m, f, *h).is_empty()) {
                Some(h) => Ok(emit::Tie::Handle(h)),
                None => {
                    Err("its handle traces no ray in its function (nothing would use the fault)")
                }
            }
        }
        (
            Resource::StorageBuffer
            | Resource::UniformBuffer
            | Resource::SampledImage
            | Resource::StorageImage,
            Some(v),
        ) => match emit::bits(m, v) {
            Some(leaf) => Ok(emit::Tie::Value(v, leaf)),
            None => Err("its value has no scalar to feed a fault"),
        },
        (_, None) => Err("its value has no scalar to feed a fault"),
    }
}

/// Insert `r`'s fault after every access of `m` that its predicate matches.
pub fn inject(m: &mut Module, r: &Request) -> Injected {
    let mut found: Vec<sites::Site> =
        sites::find(m).into_iter().filter(|s| r.predicate.matches(&s.access)).collect();
    let mut out = Injected::default();
    // Last first: an insertion never moves an access still to do.
    found.sort_by_key(|s| std::cmp::Reverse(s.at));
    for s in &found {
        let (f, b, i) = s.at;
        let tie = match tie(m, s) {
            Ok(t) => t,
            Err(why) => {
                out.skipped.push(format!("{}: {why}", describe(s)));
                continue;
            }
        };
        let done = match r.fault {
            Fault::Device => {
                emit::device(m, (f, b, i), tie);
                true
            }
            Fault::Hang => emit::hang(m, (f, b, i), tie),
        };
        if done {
            out.sites.push(describe(s));
        } else {
            out.skipped.push(format!("{}: it is in a loop's header block", describe(s)));
        }
    }
    out.sites.reverse();
    out.skipped.reverse();
    out
}

/// How many injected faults `m` holds (after a patch rewrote it, say).
pub fn count(m: &Module) -> usize {
    m.debug_names
        .iter()
        .filter(|n| {
            matches!(n.operands.get(1), Some(rspirv::dr::Operand::LiteralString(s)) if s.starts_with(emit::MARKER))
        })
        .count()
}
