//! `run --shader --inject-fault 'PREDICATE[@KIND]'`: a fault injected into a user's module at
//! each descriptor access whose stage, resource and index source match PREDICATE
//! ([`predicate`]; the accesses are found by [`sites`]), so a user can prove that rtprobe detects
//! a fault of their pipeline on their driver. [`inject`] is a plain function over
//! `&mut rspirv::dr::Module`.
//!
//! The fault sits right after the access and is fed by the access's value ([`emit`]): the
//! first scalar of the loaded or sampled value, as 32 bits, `& 0` — zero at run time, yet an
//! operand of the fault — so deleting the access deletes the fault, and a module without a
//! matching access gets none. KIND:
//! - `device` (default): a `Volatile` load through the `PhysicalStorageBuffer` address
//!   `0xdead_0000_0000 + (bits & 0)`, outside every allocation. The module gets the
//!   `PhysicalStorageBufferAddresses` capability, `SPV_KHR_physical_storage_buffer` before
//!   SPIR-V 1.5, and `PhysicalStorageBuffer64` addressing; `Volatile` keeps the driver's
//!   compiler from dropping a load whose value is unused (SPIR-V 1.6 rev. 2, Memory Operands:
//!   a volatile access "cannot be eliminated, duplicated, or combined with other accesses").
//!   What an invalid address does is undefined (a device loss, a crash on CPU drivers, a hang
//!   where a driver spins): rtprobe counts each as a fault.
//! - `hang`: a structured loop counting by two from 0 until the count equals `bits | 1`, odd,
//!   so never. Whether or not a driver's compiler proves it endless, it does not end.
//!
//! The other kinds of `--inject-fault` (`value`, `nan`, `flaky`) are refused for a user's shader:
//! a wrong value is caught only against a CPU reference, which a user's shader has none of, and
//! `flaky` is armed through the generated probe's push constants.
pub mod emit;
pub mod predicate;
pub mod sites;
#[cfg(test)]
mod tests;

use crate::model::FaultKind;
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
    Kind { spec: String, error: crate::model::InjectError },
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
            .map_err(|error| InjectError::Kind { spec: spec.clone(), error })?
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

/// Insert `r`'s fault after every access of `m` that its predicate matches.
pub fn inject(m: &mut Module, r: &Request) -> Injected {
    let mut found: Vec<sites::Site> =
        sites::find(m).into_iter().filter(|s| r.predicate.matches(&s.access)).collect();
    let mut out = Injected::default();
    // Last first: an insertion never moves an access still to do.
    found.sort_by_key(|s| std::cmp::Reverse(s.at));
    for s in &found {
        let (f, b, i) = s.at;
        let Some((code, bits)) = s.value.and_then(|v| emit::bits(m, v)) else {
            out.skipped.push(format!("{}: its value has no scalar to feed a fault", describe(s)));
            continue;
        };
        let done = match r.fault {
            Fault::Device => {
                let code = emit::device(m, code, bits);
                let at = &mut m.functions[f].blocks[b].instructions;
                at.splice(i + 1..i + 1, code);
                true
            }
            Fault::Hang => emit::hang(m, f, (b, i), code, bits),
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
