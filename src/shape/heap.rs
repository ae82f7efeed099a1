//! A read through the descriptor heap (SPV_EXT_descriptor_heap): its pointer derives from an
//! `OpBufferPointerEXT` of an `OpUntypedAccessChainKHR` into the `ResourceHeapEXT` variable (a
//! buffer), or is that chain itself (an image loaded from the heap). The chain's base type
//! (an array of `OpTypeBufferEXT`, images or samplers) says the resource, its first index is
//! the descriptor index.
use super::defs::Defs;
use crate::model::Resource;
use rspirv::dr::{Instruction, Operand};
use rspirv::spirv::{BuiltIn, Op, StorageClass, Word};

/// One heap access.
pub struct HeapAccess {
    /// The `ResourceHeapEXT` variable.
    pub heap: Word,
    pub resource: Resource,
    /// The descriptor index into the heap's array.
    pub index: Word,
}

fn id(i: &Instruction, n: usize) -> Option<Word> {
    match i.operands.get(n) {
        Some(Operand::IdRef(w)) => Some(*w),
        _ => None,
    }
}

/// The heap access a pointer's root (`Defs::root`) is, if it is one.
pub fn access(d: &Defs, root: Word) -> Option<HeapAccess> {
    let mut i = d.get(root)?;
    if i.class.opcode == Op::BufferPointerEXT {
        i = d.get(id(i, 0)?)?;
    }
    if !matches!(i.class.opcode, Op::UntypedAccessChainKHR | Op::UntypedInBoundsAccessChainKHR) {
        return None;
    }
    let (base_ty, heap, index) = (id(i, 0)?, id(i, 1)?, id(i, 2)?);
    if d.builtin(heap) != Some(BuiltIn::ResourceHeapEXT) {
        return None;
    }
    let mut ty = d.get(base_ty)?;
    if matches!(ty.class.opcode, Op::TypeArray | Op::TypeRuntimeArray) {
        ty = d.get(id(ty, 0)?)?;
    }
    let resource = match (ty.class.opcode, ty.operands.first()) {
        (Op::TypeBufferEXT, Some(Operand::StorageClass(StorageClass::Uniform))) => {
            Resource::UniformBuffer
        }
        (Op::TypeBufferEXT, _) => Resource::StorageBuffer,
        (Op::TypeImage, _) => match ty.operands.get(5) {
            Some(Operand::LiteralBit32(2)) => Resource::StorageImage,
            _ => Resource::SampledImage,
        },
        (Op::TypeSampledImage | Op::TypeSampler, _) => Resource::SampledImage,
        (Op::TypeAccelerationStructureKHR, _) => Resource::AccelerationStructure,
        _ => return None,
    };
    Some(HeapAccess { heap, resource, index })
}
