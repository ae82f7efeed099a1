//! The `OpTraceRayKHR` instructions an entry point's call tree executes ([`traces`]): the ray
//! flags, SBT record offset and stride and miss index where they are `OpConstant`s — directly,
//! or loaded from a function-local variable whose only write stores one (glslang's unoptimized
//! `uint flags = …; traceRayEXT(…, flags, …)`) — a spec constant or a computed value is `None`:
//! the harness cannot know it before the pipeline runs,
//! and the payload's type — the `RayPayloadKHR` or `IncomingRayPayloadKHR` variable the
//! instruction names (SPIR-V 1.6 rev. 4, OpTraceRayKHR: "Payload must be the result of an
//! OpVariable with a storage class of RayPayloadKHR or IncomingRayPayloadKHR"). The harness
//! supplies a miss shader per miss index and holds every stage a ray can invoke to the ray's
//! payload with them (`harness::traces`).
use super::index::{self, Index};
use super::ty::Ty;
use super::ReflectError;
use rspirv::dr::{Function, Instruction, Module};
use rspirv::spirv::{Op, Word};

/// `gl_RayFlagsOpaqueEXT`: no any-hit shader runs for the ray.
pub const FLAG_OPAQUE: u32 = 0x1;
/// `gl_RayFlagsSkipClosestHitShaderEXT`: no closest-hit shader runs for the ray.
pub const FLAG_SKIP_CLOSEST_HIT: u32 = 0x8;

/// One `OpTraceRayKHR`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Trace {
    pub flags: Option<u32>,
    pub sbt_offset: Option<u32>,
    pub sbt_stride: Option<u32>,
    pub miss_index: Option<u32>,
    /// The payload variable's name ("" when none) and type.
    pub payload_name: String,
    pub payload: Ty,
}

impl Trace {
    /// The ray's flags certainly include `flag` (a constant with the bit set).
    pub fn has_flag(&self, flag: u32) -> bool {
        self.flags.is_some_and(|f| f & flag != 0)
    }
}

/// The value of `OpConstant` `id`, or of the one constant stored to the function variable that
/// `id` loads, in function `f`; spec constants are `None` (`--spec` may change them).
fn constant(x: &Index, f: &Function, id: Option<Word>) -> Option<u32> {
    let id = id?;
    if let Some(d) = x.def(id) {
        return match d.class.opcode {
            Op::Constant => x.constant(id),
            _ => None,
        };
    }
    let body = || f.blocks.iter().flat_map(|b| &b.instructions);
    let load = body().find(|i| i.result_id == Some(id) && i.class.opcode == Op::Load)?;
    let var = index::id(load.operands.first())?;
    let local = body().any(|i| i.result_id == Some(var) && i.class.opcode == Op::Variable);
    let mut stored = None;
    for i in body().filter(|i| i.operands.iter().any(|o| index::id(Some(o)) == Some(var))) {
        match (i.class.opcode, index::id(i.operands.first()) == Some(var)) {
            (Op::Load, true) => {}
            (Op::Store, true) if stored.is_none() => stored = index::id(i.operands.get(1)),
            // A second store, or the variable passed on (a call, a copy): not one value.
            _ => return None,
        }
    }
    let d = x.def(stored.filter(|_| local)?)?;
    match d.class.opcode {
        Op::Constant => x.constant(d.result_id?),
        _ => None,
    }
}

/// The trace `i` (an `OpTraceRayKHR`) of function `f`.
fn trace(x: &Index, f: &Function, i: &Instruction) -> Result<Trace, ReflectError> {
    let op = |k: usize| index::id(i.operands.get(k));
    let var = op(10).and_then(|v| x.def(v)).filter(|d| d.class.opcode == Op::Variable);
    let Some(var) = var else {
        return Err(ReflectError::Malformed(
            "an OpTraceRayKHR whose payload is no variable".into(),
        ));
    };
    let ty = var.result_type.and_then(|t| x.pointer(t)).map(|(_, t)| t);
    let Some(ty) = ty else {
        return Err(ReflectError::Malformed("an OpTraceRayKHR payload without a type".into()));
    };
    Ok(Trace {
        flags: constant(x, f, op(1)),
        sbt_offset: constant(x, f, op(3)),
        sbt_stride: constant(x, f, op(4)),
        miss_index: constant(x, f, op(5)),
        payload_name: var.result_id.map(|v| x.name(v).to_string()).unwrap_or_default(),
        payload: x.ty(ty)?,
    })
}

/// Every `OpTraceRayKHR` of `function` and the functions it calls.
pub fn traces(m: &Module, x: &Index, function: Word) -> Result<Vec<Trace>, ReflectError> {
    let mut out = Vec::new();
    for func in super::entry::call_tree(m, function) {
        for i in func.blocks.iter().flat_map(|b| &b.instructions) {
            if i.class.opcode == Op::TraceRayKHR {
                out.push(trace(x, func, i)?);
            }
        }
    }
    Ok(out)
}
