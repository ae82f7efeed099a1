//! Set/binding variables ([`binding`]): the descriptor kind, array count and buffer block of
//! one, whether the module may write it and whether it applies atomics to it; and a block's
//! layout ([`block`]).
use super::error::ReflectError;
use super::index::{id, Index};
use super::reflection::{Binding, Block, Count, Descriptor, Tail};
use super::ty::Ty;
use rspirv::dr::{Module, Operand};
use rspirv::spirv::{Decoration, ImageFormat, Op, StorageClass, Word};
use std::collections::BTreeSet;

/// The descriptor of type `ty` in storage class `sc` (`None`: no descriptor type holds it).
fn descriptor(x: &Index, sc: StorageClass, ty: Word) -> Option<Descriptor> {
    let d = x.def(ty)?;
    let lit = |n: usize| match d.operands.get(n) {
        Some(Operand::LiteralBit32(v)) => Some(*v),
        _ => None,
    };
    Some(match (sc, d.class.opcode) {
        (StorageClass::UniformConstant, Op::TypeAccelerationStructureKHR) => {
            Descriptor::AccelerationStructure
        }
        (StorageClass::UniformConstant, Op::TypeSampler) => Descriptor::Sampler,
        (StorageClass::UniformConstant, Op::TypeSampledImage) => Descriptor::CombinedImageSampler,
        (StorageClass::UniformConstant, Op::TypeImage) => {
            let dim = match d.operands.get(1) {
                Some(Operand::Dim(dim)) => *dim,
                _ => return None,
            };
            let sampled = lit(5)?;
            match (dim, sampled) {
                (rspirv::spirv::Dim::DimSubpassData, _) => Descriptor::InputAttachment,
                (rspirv::spirv::Dim::DimBuffer, 1) => Descriptor::UniformTexelBuffer,
                (rspirv::spirv::Dim::DimBuffer, _) => Descriptor::StorageTexelBuffer,
                (_, 1) => Descriptor::SampledImage,
                (_, _) => Descriptor::StorageImage(match d.operands.get(6) {
                    Some(Operand::ImageFormat(f)) => *f,
                    _ => ImageFormat::Unknown,
                }),
            }
        }
        (StorageClass::StorageBuffer, Op::TypeStruct) => Descriptor::StorageBuffer,
        (StorageClass::Uniform, Op::TypeStruct) if x.has(ty, Decoration::BufferBlock) => {
            Descriptor::StorageBuffer
        }
        (StorageClass::Uniform, Op::TypeStruct) => Descriptor::UniformBuffer,
        _ => return None,
    })
}

/// The layout of block struct `st` held by variable `name`.
pub fn block(x: &Index, st: Word, name: &str) -> Result<Block, ReflectError> {
    let Ty::Struct(ty) = x.ty(st)? else {
        return Err(ReflectError::Malformed(format!("block %{st} is not a struct")));
    };
    let start = ty.members.iter().filter_map(|m| m.offset).min().unwrap_or(0);
    let tail = ty.members.last().and_then(|m| match &m.ty {
        Ty::Array { stride: Some(s), .. } => {
            Some(Tail { offset: m.offset?, stride: *s, runtime: false })
        }
        Ty::RuntimeArray { stride: Some(s), .. } => {
            Some(Tail { offset: m.offset?, stride: *s, runtime: true })
        }
        _ => None,
    });
    let mut end = 0;
    for m in &ty.members {
        if !matches!(m.ty, Ty::RuntimeArray { .. }) {
            let size = m.ty.extent(m.matrix).unwrap_or_else(|| m.ty.size());
            end = end.max(m.offset.unwrap_or(0) + size);
        }
    }
    end = end.max(tail.filter(|t| t.runtime).map_or(0, |t| t.offset));
    Ok(Block { name: name.to_string(), ty, start, end, tail: tail.filter(|t| t.stride > 0) })
}

/// The binding of descriptor variable `var` of pointer type `ptr` (`data`: an untyped
/// variable's data type); `Ok(None)` for a variable no descriptor type holds.
pub fn binding(
    m: &Module,
    x: &Index,
    var: Word,
    sc: StorageClass,
    pointee: Word,
) -> Result<Option<Binding>, ReflectError> {
    let set = x.literal(var, Decoration::DescriptorSet).unwrap_or(0);
    let binding = x.literal(var, Decoration::Binding).unwrap_or(0);
    let d = x.def(pointee).ok_or_else(|| {
        ReflectError::Malformed(format!("set {set} binding {binding}: type %{pointee} not defined"))
    })?;
    let (elem, count) = match d.class.opcode {
        Op::TypeArray => {
            let len = id(d.operands.get(1)).and_then(|l| x.constant(l)).ok_or_else(|| {
                ReflectError::Malformed(format!(
                    "set {set} binding {binding}: array length not a constant"
                ))
            })?;
            (id(d.operands.first()).unwrap_or(0), Count::Fixed(len))
        }
        Op::TypeRuntimeArray => (id(d.operands.first()).unwrap_or(0), Count::Runtime),
        _ => (pointee, Count::One),
    };
    let Some(descriptor) = descriptor(x, sc, elem) else { return Ok(None) };
    let name = x.name(var);
    let block = match descriptor {
        Descriptor::StorageBuffer | Descriptor::UniformBuffer => Some(block(x, elem, name)?),
        _ => None,
    };
    let writable = matches!(
        descriptor,
        Descriptor::StorageBuffer | Descriptor::StorageImage(_) | Descriptor::StorageTexelBuffer
    ) && !non_writable(x, var, elem);
    let atomic = atomically_accessed(m, var);
    Ok(Some(Binding {
        set,
        binding,
        name: name.to_string(),
        descriptor,
        count,
        block,
        writable,
        atomic,
    }))
}

/// Whether a variable is read-only: `NonWritable` on the variable (DXC, Slang) or on every
/// member of its block (glslang's `readonly buffer`).
fn non_writable(x: &Index, var: Word, block: Word) -> bool {
    if x.has(var, Decoration::NonWritable) {
        return true;
    }
    let members = x
        .def(block)
        .filter(|d| d.class.opcode == Op::TypeStruct)
        .map_or(0, |d| d.operands.len() as u32);
    members > 0 && (0..members).all(|k| x.member(block, k, Decoration::NonWritable).is_some())
}

/// Whether an `OpAtomic*` instruction's pointer derives from `var` (through access chains and
/// copies).
fn atomically_accessed(m: &Module, var: Word) -> bool {
    let body = || m.functions.iter().flat_map(|f| &f.blocks).flat_map(|b| &b.instructions);
    let mut from: BTreeSet<Word> = [var].into();
    loop {
        let before = from.len();
        for i in body() {
            let derives = matches!(
                i.class.opcode,
                Op::AccessChain
                    | Op::InBoundsAccessChain
                    | Op::PtrAccessChain
                    | Op::CopyObject
                    | Op::ImageTexelPointer
            );
            if let (true, Some(r), Some(base)) = (derives, i.result_id, id(i.operands.first())) {
                if from.contains(&base) {
                    from.insert(r);
                }
            }
        }
        if from.len() == before {
            break;
        }
    }
    body().any(|i| {
        is_atomic(i.class.opcode) && id(i.operands.first()).is_some_and(|p| from.contains(&p))
    })
}

/// Every atomic instruction (its pointer is operand 0).
pub(crate) fn is_atomic(op: Op) -> bool {
    matches!(
        op,
        Op::AtomicLoad
            | Op::AtomicStore
            | Op::AtomicExchange
            | Op::AtomicCompareExchange
            | Op::AtomicCompareExchangeWeak
            | Op::AtomicIIncrement
            | Op::AtomicIDecrement
            | Op::AtomicIAdd
            | Op::AtomicISub
            | Op::AtomicSMin
            | Op::AtomicUMin
            | Op::AtomicSMax
            | Op::AtomicUMax
            | Op::AtomicAnd
            | Op::AtomicOr
            | Op::AtomicXor
            | Op::AtomicFAddEXT
            | Op::AtomicFMinEXT
            | Op::AtomicFMaxEXT
    )
}
