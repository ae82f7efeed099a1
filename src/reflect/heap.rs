//! Descriptor heap use (SPV_EXT_descriptor_heap, [`heap`]): the `DescriptorHeapEXT`
//! capability, the `ResourceHeapEXT` / `SamplerHeapEXT` built-in variables, and each kind of
//! access into them — an untyped access chain whose base type is the array indexed
//! (`OpTypeRuntimeArray %T` with `ArrayStrideIdEXT` of `OpConstantSizeOfEXT %T`, or a literal
//! `ArrayStride`) or a struct holding it at an `OffsetIdEXT` member offset (glslang 16's
//! `layout(descriptor_heap)` arrays). Strides and offsets are reported as far as the module states
//! them: a spec constant or an expression reads as [`HeapStride::Unknown`].
use super::index::{id, Index};
use super::reflection::{Heap, HeapAccess, HeapKind, HeapStride};
use rspirv::dr::{Module, Operand};
use rspirv::spirv::{BuiltIn, Capability, Decoration, Op, Word};

/// The heap built-in variable `var` is, if any.
fn builtin(x: &Index, var: Word) -> Option<HeapKind> {
    match x.decoration(var, Decoration::BuiltIn)? {
        Some(Operand::BuiltIn(BuiltIn::ResourceHeapEXT)) => Some(HeapKind::Resource),
        Some(Operand::BuiltIn(BuiltIn::SamplerHeapEXT)) => Some(HeapKind::Sampler),
        _ => None,
    }
}

/// The module's heap use.
pub fn heap(m: &Module, x: &Index) -> Heap {
    let capability = m
        .capabilities
        .iter()
        .any(|c| c.operands.first() == Some(&Operand::Capability(Capability::DescriptorHeapEXT)));
    let heaps: Vec<(Word, HeapKind)> = m
        .types_global_values
        .iter()
        .filter(|i| matches!(i.class.opcode, Op::Variable | Op::UntypedVariableKHR))
        .filter_map(|i| Some((i.result_id?, builtin(x, i.result_id?)?)))
        .collect();
    let mut h = Heap {
        capability,
        resource: heaps.iter().any(|(_, k)| *k == HeapKind::Resource),
        sampler: heaps.iter().any(|(_, k)| *k == HeapKind::Sampler),
        accesses: Vec::new(),
    };
    for i in m.functions.iter().flat_map(|f| &f.blocks).flat_map(|b| &b.instructions) {
        let chain = matches!(
            i.class.opcode,
            Op::UntypedAccessChainKHR
                | Op::UntypedInBoundsAccessChainKHR
                | Op::UntypedPtrAccessChainKHR
                | Op::UntypedInBoundsPtrAccessChainKHR
        );
        let Some(kind) = chain
            .then(|| id(i.operands.get(1)))
            .flatten()
            .and_then(|b| heaps.iter().find(|(v, _)| *v == b).map(|(_, k)| *k))
        else {
            continue;
        };
        let Some(base) = id(i.operands.first()) else { continue };
        let a = access(x, kind, base);
        if !h.accesses.contains(&a) {
            h.accesses.push(a);
        }
    }
    h
}

/// The access of an untyped chain into heap `heap` with base type `base`.
fn access(x: &Index, heap: HeapKind, base: Word) -> HeapAccess {
    let (array, offset) = match x.def(base).map(|d| d.class.opcode) {
        Some(Op::TypeStruct) => {
            let member = x.def(base).and_then(|d| id(d.operands.first())).unwrap_or(0);
            (member, member_offset(x, base))
        }
        _ => (base, None),
    };
    let elem = x.def(array).and_then(|d| match d.class.opcode {
        Op::TypeRuntimeArray | Op::TypeArray => id(d.operands.first()),
        _ => None,
    });
    let element = elem.map_or_else(|| "unknown".to_string(), |e| type_name(x, e));
    let stride = match (
        x.decoration(array, Decoration::ArrayStrideIdEXT),
        x.literal(array, Decoration::ArrayStride),
    ) {
        (_, Some(s)) => HeapStride::Bytes(s),
        (Some(Some(Operand::IdRef(s))), None) => stride_of(x, *s),
        _ => HeapStride::Unknown,
    };
    HeapAccess { heap, element, stride, offset }
}

/// Member 0's `OffsetIdEXT` (or `Offset`) in struct `st`, when a plain constant.
fn member_offset(x: &Index, st: Word) -> Option<u32> {
    if let Some(o) = x.member(st, 0, Decoration::Offset) {
        return Some(o);
    }
    x.member_id(st, 0, Decoration::OffsetIdEXT).and_then(|c| x.constant(c))
}

/// A stride given by id `s`: a constant, or the size of a type.
fn stride_of(x: &Index, s: Word) -> HeapStride {
    match x.def(s) {
        Some(d) if d.class.opcode == Op::Constant => {
            x.constant(s).map_or(HeapStride::Unknown, HeapStride::Bytes)
        }
        Some(d) if d.class.opcode == Op::ConstantSizeOfEXT => id(d.operands.first())
            .map_or(HeapStride::Unknown, |t| HeapStride::SizeOf(type_name(x, t))),
        _ => HeapStride::Unknown,
    }
}

/// A heap element's type in words: `OpTypeBufferEXT StorageBuffer` → "StorageBuffer buffer".
fn type_name(x: &Index, t: Word) -> String {
    let Some(d) = x.def(t) else { return "unknown".into() };
    match d.class.opcode {
        Op::TypeBufferEXT => match d.operands.first() {
            Some(Operand::StorageClass(c)) => format!("{c:?} buffer"),
            _ => "buffer".into(),
        },
        Op::TypeImage => match d.operands.get(5) {
            Some(Operand::LiteralBit32(2)) => "storage image".into(),
            _ => "sampled image".into(),
        },
        Op::TypeSampler => "sampler".into(),
        Op::TypeSampledImage => "combined image sampler".into(),
        Op::TypeAccelerationStructureKHR => "acceleration structure".into(),
        other => format!("Op{other:?}"),
    }
}
