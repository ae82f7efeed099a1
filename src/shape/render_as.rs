//! `access.txt`'s line for an acceleration structure read: the handle is used, not assigned, so
//! it is rendered as the GLSL call that traces with it — `traceRayEXT(tlas, ...)`,
//! `rayQueryInitializeEXT(q, tlas, ...)` — found by the instruction whose AS operand is the
//! descriptor's load (its pointer rooted at the variable) or the address's
//! `OpConvertUToAccelerationStructureKHR`.
use super::defs::Defs;
use rspirv::dr::Operand;
use rspirv::spirv::{Op, Word};

/// The GLSL call of an instruction that traces with an acceleration structure, and where its
/// acceleration structure operand is.
fn call(op: Op) -> Option<(&'static str, usize)> {
    match op {
        Op::TraceRayKHR => Some(("traceRayEXT(", 0)),
        Op::TraceNV => Some(("traceNV(", 0)),
        Op::TraceRayMotionNV | Op::TraceMotionNV => Some(("traceRayMotionNV(", 0)),
        Op::RayQueryInitializeKHR => Some(("rayQueryInitializeEXT(q, ", 1)),
        Op::HitObjectTraceRayNV | Op::HitObjectTraceRayEXT => Some(("hitObjectTraceRayEXT(h, ", 1)),
        _ => None,
    }
}

/// Whether AS value `h` is read from `var` (a descriptor load rooted at it, or made from the
/// address `var`).
fn from(d: &Defs, h: Word, var: Word) -> bool {
    let Some(i) = d.get(h) else { return false };
    let first = match i.operands.first() {
        Some(Operand::IdRef(x)) => *x,
        _ => return false,
    };
    match i.class.opcode {
        Op::Load => d.root(first).0 == var,
        Op::ConvertUToAccelerationStructureKHR => first == var,
        Op::CopyObject => from(d, first, var),
        _ => false,
    }
}

/// The use of the acceleration structure `handle` (its GLSL text, index included) read from
/// `var`: `traceRayEXT(handle, ...);`, or `... handle ...;` where no trace uses it.
pub fn use_line(d: &Defs, var: Word, handle: &str) -> String {
    let body = d.m.functions.iter().flat_map(|f| f.blocks.iter().flat_map(|b| &b.instructions));
    for i in body {
        let Some((name, at)) = call(i.class.opcode) else { continue };
        if let Some(Operand::IdRef(h)) = i.operands.get(at) {
            if from(d, *h, var) {
                return format!("{name}{handle}, ...);\n\n");
            }
        }
    }
    format!("... {handle} ...;\n\n")
}
