//! One reflection of a SPIR-V module's interface, read with rspirv ([`reflect`]): for a chosen
//! entry point, its stage; its set/binding variables (descriptor kind, storage image format,
//! count — one, fixed, runtime —, a buffer's block layout with its trailing array, writable,
//! atomic); its descriptor heap use (built-ins, capability, the strides and offsets its accesses
//! state: [`heap`]); the push-constant and shader-record blocks with member offsets and types;
//! specialization constants (SpecId, type, default); ray payloads, callable data and the hit
//! attribute as type trees with Location and size; and every `PhysicalStorageBuffer` pointer
//! reachable from a block ([`pointers`]: typed pointer members only — an integer address the
//! shader converts to a pointer cannot be followed). A type tree ([`Ty`]) prints itself as GLSL
//! ([`glsl`]).
//!
//! A module with one entry point reads every global variable; with several, only those the
//! chosen entry point's functions name (`--entry`; none given is [`ReflectError::SeveralEntries`]).
//! Every lookup is checked: any bytes give a typed error or a reflection, never a panic
//! (`patches::load` parses).
//!
//! Files: the result's types (`reflection`), the type tree (`ty`) and its GLSL (`glsl`), ids by
//! definition, name and decoration (`index`), the entry point (`entry`), bindings and blocks
//! (`bindings`), pointer paths (`pointers`), heaps (`heap`), the rays traced (`traces`),
//! errors (`error`).
pub(crate) mod bindings;
mod entry;
mod error;
pub mod glsl;
mod heap;
mod index;
mod pointers;
mod reflection;
mod traces;
mod ty;

pub use entry::stage_name;
pub use error::ReflectError;
pub use reflection::{
    Binding, Block, Count, Descriptor, Heap, HeapAccess, HeapKind, HeapStride, Io, PointerPath,
    Reflection, SpecConstant, Tail,
};
pub use traces::{Trace, FLAG_OPAQUE, FLAG_SKIP_CLOSEST_HIT};
pub use ty::{Member, Scalar, Struct, Ty};

use index::Index;
use rspirv::dr::{Instruction, Module, Operand};
use rspirv::spirv::{Decoration, Op, StorageClass, Word};

/// Load SPIR-V words and reflect entry point `entry` (or the only one).
pub fn reflect_words(words: &[u32], entry: Option<&str>) -> Result<Reflection, ReflectError> {
    let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
    let m = crate::patches::load(&bytes).map_err(|e| ReflectError::NotSpirv(e.to_string()))?;
    reflect(&m, entry)
}

/// The interface of module `m` at entry point `entry` (or its only one).
pub fn reflect(m: &Module, entry: Option<&str>) -> Result<Reflection, ReflectError> {
    let e = entry::choose(m, entry)?;
    let x = Index::new(m);
    // Only the globals the entry point's call tree names: a linked module (or one `--entry`
    // reduced) keeps other entry points' globals, which are not this one's interface.
    let used = entry::used(m, e.function);
    let traces = traces::traces(m, &x, e.function)?;
    let mut r = Reflection {
        model: e.model,
        stage: entry::stage_name(e.model),
        entry: e.name,
        bindings: Vec::new(),
        heap: heap::heap(m, &x),
        push: None,
        record: None,
        spec_constants: Vec::new(),
        payloads: Vec::new(),
        incoming_payload: None,
        callable_data: Vec::new(),
        incoming_callable_data: None,
        hit_attribute: None,
        pointers: Vec::new(),
        traces,
    };
    for i in &m.types_global_values {
        let Some(id) = i.result_id else { continue };
        if !used.contains(&id) && is_variable(i) {
            continue;
        }
        match i.class.opcode {
            Op::Variable | Op::UntypedVariableKHR => variable(m, &x, i, id, &mut r)?,
            Op::SpecConstant | Op::SpecConstantTrue | Op::SpecConstantFalse => {
                r.spec_constants.extend(spec_constant(&x, i, id))
            }
            _ => {}
        }
    }
    r.bindings.sort_by_key(|b| (b.set, b.binding));
    r.spec_constants.sort_by_key(|s| s.spec_id);
    r.pointers = pointer_paths(&r);
    Ok(r)
}

fn is_variable(i: &Instruction) -> bool {
    matches!(i.class.opcode, Op::Variable | Op::UntypedVariableKHR)
}

/// The storage class and data type of a variable (`None`: an untyped one without data type).
fn storage(x: &Index, i: &Instruction) -> Option<(StorageClass, Word)> {
    let sc = match i.operands.first()? {
        Operand::StorageClass(c) => *c,
        _ => return None,
    };
    match i.class.opcode {
        Op::UntypedVariableKHR => Some((sc, index::id(i.operands.get(1))?)),
        _ => Some((sc, x.pointer(i.result_type?)?.1)),
    }
}

/// Record global variable `i` (id `id`) in `r`.
fn variable(
    m: &Module,
    x: &Index,
    i: &Instruction,
    id: Word,
    r: &mut Reflection,
) -> Result<(), ReflectError> {
    let Some((sc, ty)) = storage(x, i) else { return Ok(()) };
    let io = |x: &Index| -> Result<reflection::Io, ReflectError> {
        let t = x.ty(ty)?;
        Ok(reflection::Io {
            name: x.name(id).to_string(),
            location: x.literal(id, Decoration::Location),
            size: t.size(),
            ty: t,
        })
    };
    match sc {
        StorageClass::UniformConstant | StorageClass::Uniform | StorageClass::StorageBuffer
            if x.has(id, Decoration::DescriptorSet) || x.has(id, Decoration::Binding) =>
        {
            r.bindings.extend(bindings::binding(m, x, id, sc, ty)?);
        }
        StorageClass::PushConstant => r.push = Some(bindings::block(x, ty, "push")?),
        StorageClass::ShaderRecordBufferKHR => r.record = Some(bindings::block(x, ty, "record")?),
        StorageClass::RayPayloadKHR => r.payloads.push(io(x)?),
        StorageClass::IncomingRayPayloadKHR => r.incoming_payload = Some(io(x)?),
        StorageClass::CallableDataKHR => r.callable_data.push(io(x)?),
        StorageClass::IncomingCallableDataKHR => r.incoming_callable_data = Some(io(x)?),
        StorageClass::HitAttributeKHR => r.hit_attribute = Some(io(x)?),
        _ => {}
    }
    Ok(())
}

/// The specialization constant `i` (id `id`), if it has a SpecId.
fn spec_constant(x: &Index, i: &Instruction, id: Word) -> Option<SpecConstant> {
    let spec_id = x.literal(id, Decoration::SpecId)?;
    let scalar = x.scalar(i.result_type?)?;
    let lit = |n: usize| match i.operands.get(n) {
        Some(Operand::LiteralBit32(v)) => Some(*v as u64),
        Some(Operand::LiteralBit64(v)) => Some(*v),
        _ => None,
    };
    let default = match i.class.opcode {
        Op::SpecConstantTrue => 1,
        Op::SpecConstantFalse => 0,
        _ => lit(0)?,
    };
    Some(SpecConstant { spec_id, name: x.name(id).to_string(), scalar, default })
}

/// The pointer paths from the push block, the shader record and every buffer block.
fn pointer_paths(r: &Reflection) -> Vec<PointerPath> {
    let blocks = r.push.iter().chain(&r.record).map(|b| (b.name.clone(), b)).chain(
        r.bindings.iter().filter_map(|b| {
            Some((format!("set{}.binding{}", b.set, b.binding), b.block.as_ref()?))
        }),
    );
    blocks.flat_map(|(name, b)| pointers::paths(&name, &Ty::Struct(b.ty.clone()))).collect()
}

#[cfg(test)]
mod tests;
