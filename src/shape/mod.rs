//! The shape of a module's descriptor accesses on the matrix's axes, for `rtprobe reduce`:
//! each read through a descriptor (a buffer load or atomic, an image, sampler or acceleration
//! structure handle load — a storage image's unless it is only written through —, an
//! acceleration structure made from an address) with its stage, resource, index source and
//! where the index comes from ([`index`]), `NonUniform`, and whether it goes through a
//! set/binding variable, a descriptor heap or an address ([`classify`]); whether every
//! descriptor index is provably in bounds ([`bounds`]); the accesses rendered GLSL-like
//! ([`render`]; an acceleration structure's as the call that traces with it, [`render_as`]);
//! function-body instruction counts ([`count`]); the dead decorated
//! instructions spirv-reduce leaves ([`dead`]).
//!
//! Independent of `harness::inject` by design (issue 25): the injected fault's trigger finds
//! its sites with its own code, so a reduction judged by this classifier cannot be circular.
pub mod bounds;
pub mod count;
pub mod dead;
pub mod defs;
pub mod heap;
pub mod index;
pub mod render;
pub mod render_as;

use crate::model::reduce::AccessClass;
use crate::model::{Resource, Stage};
use defs::Defs;
use rspirv::dr::{Instruction, Module, Operand};
use rspirv::spirv::{Decoration, ExecutionModel, Op, StorageClass, Word};

/// One access found: its class and the ids the renderer needs.
#[derive(Clone, Debug, PartialEq)]
pub struct Found {
    pub class: AccessClass,
    /// The root variable, and the descriptor index when the variable is an array.
    pub var: Word,
    pub index: Option<Word>,
}

/// The stage of the module's first entry point.
pub fn stage(m: &Module) -> Option<Stage> {
    let Some(Operand::ExecutionModel(e)) = m.entry_points.first()?.operands.first() else {
        return None;
    };
    Some(match e {
        ExecutionModel::RayGenerationKHR => Stage::Raygen,
        ExecutionModel::ClosestHitKHR => Stage::ClosestHit,
        ExecutionModel::AnyHitKHR => Stage::AnyHit,
        ExecutionModel::MissKHR => Stage::Miss,
        ExecutionModel::IntersectionKHR => Stage::Intersection,
        ExecutionModel::CallableKHR => Stage::Callable,
        ExecutionModel::Fragment => Stage::Fragment,
        ExecutionModel::GLCompute => Stage::Compute,
        _ => return None,
    })
}

/// The resource a descriptor variable holds (its element's, for an array), and whether it is
/// an array.
pub fn resource(d: &Defs, var: Word) -> Option<(Resource, bool)> {
    let sc = d.storage_class(var)?;
    let mut ty = d.pointee(var)?;
    let arrayed = matches!(ty.class.opcode, Op::TypeArray | Op::TypeRuntimeArray);
    if arrayed {
        ty = d.get(id_at(ty, 0)?)?;
    }
    let r = match (sc, ty.class.opcode) {
        (StorageClass::StorageBuffer, _) => Resource::StorageBuffer,
        (StorageClass::Uniform, _) if d.decorated(ty.result_id?, Decoration::BufferBlock) => {
            Resource::StorageBuffer
        }
        (StorageClass::Uniform, _) => Resource::UniformBuffer,
        (StorageClass::UniformConstant, Op::TypeAccelerationStructureKHR) => {
            Resource::AccelerationStructure
        }
        (StorageClass::UniformConstant, Op::TypeImage) => match ty.operands.get(5) {
            Some(Operand::LiteralBit32(2)) => Resource::StorageImage,
            _ => Resource::SampledImage,
        },
        (StorageClass::UniformConstant, Op::TypeSampledImage | Op::TypeSampler) => {
            Resource::SampledImage
        }
        _ => return None,
    };
    Some((r, arrayed))
}

fn id_at(i: &Instruction, n: usize) -> Option<Word> {
    match i.operands.get(n) {
        Some(Operand::IdRef(w)) => Some(*w),
        _ => None,
    }
}

/// Whether `op` reads through its pointer operand 0 (loads and the atomics that return the
/// old value).
fn reads(op: Op) -> bool {
    matches!(
        op,
        Op::Load
            | Op::AtomicLoad
            | Op::AtomicExchange
            | Op::AtomicCompareExchange
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
    )
}

/// Every descriptor access of `m`'s functions, classified.
pub fn classify(m: &Module) -> Vec<Found> {
    let d = Defs::new(m);
    let Some(stage) = stage(m) else { return vec![] };
    let heap = m.types_global_values.iter().any(|i| i.class.opcode == Op::UntypedVariableKHR);
    let mut out = Vec::new();
    let body = m.functions.iter().flat_map(|f| f.blocks.iter().flat_map(|b| &b.instructions));
    for i in body {
        if i.class.opcode == Op::ConvertUToAccelerationStructureKHR {
            out.push(address_access(&d, i, stage));
            continue;
        }
        if !reads(i.class.opcode) {
            continue;
        }
        if let Some(f) = i.operands.first().and_then(|o| descriptor_read(&d, i, o, stage, heap)) {
            if f.class.resource == Resource::StorageImage && only_written(m, i.result_id) {
                continue;
            }
            out.push(f);
        }
    }
    out
}

/// Whether the storage image handle `id` is only written through (`OpImageWrite`, a store
/// with no value): its load is no read (the raygen's colour target, issue 25).
fn only_written(m: &Module, id: Option<Word>) -> bool {
    let Some(id) = id else { return false };
    let body = m.functions.iter().flat_map(|f| f.blocks.iter().flat_map(|b| &b.instructions));
    let mut uses = body.filter(|i| i.operands.contains(&Operand::IdRef(id))).peekable();
    uses.peek().is_some()
        && uses.all(|i| i.class.opcode == Op::ImageWrite && id_at(i, 0) == Some(id))
}

/// A read through pointer operand `o` of `i`, when it is rooted at a descriptor variable or
/// the resource heap.
fn descriptor_read(
    d: &Defs,
    i: &Instruction,
    o: &Operand,
    stage: Stage,
    heap: bool,
) -> Option<Found> {
    let Operand::IdRef(ptr) = o else { return None };
    let (root, chains) = d.root(*ptr);
    let (var, set, binding, resource, index, variable) = match heap::access(d, root) {
        Some(h) => (h.heap, None, None, h.resource, Some(h.index), "resource_heap".to_string()),
        None => {
            let set = d.decoration(root, Decoration::DescriptorSet)?;
            let binding = d.decoration(root, Decoration::Binding);
            let (resource, arrayed) = resource(d, root)?;
            let index = if arrayed { chains.last().and_then(|c| c.first().copied()) } else { None };
            (root, Some(set), binding, resource, index, variable_name(d, root, set, binding))
        }
    };
    let leaves = index.map(|x| index::leaves(d, x)).unwrap_or_default();
    let source = if index.is_some() { leaves.source() } else { crate::model::IndexSource::Literal };
    let mut from = leaves.dynamic.clone();
    from.extend(leaves.push.then(|| "push_constant".to_string()));
    from.extend(leaves.spec.then(|| "spec_constant".to_string()));
    from.extend((source == crate::model::IndexSource::Literal).then(|| "literal".to_string()));
    let chain_ids = chains.iter().flatten().copied();
    let nonuniform = index.is_some_and(|x| index::nonuniform(d, x))
        || i.result_id.is_some_and(|r| index::nonuniform(d, r))
        || std::iter::once(*ptr).chain(chain_ids).any(|x| index::nonuniform(d, x));
    let class = AccessClass {
        stage,
        resource,
        index: source,
        index_from: from,
        nonuniform,
        set,
        binding,
        variable,
        through: if heap { "heap" } else { "descriptor" }.into(),
        op: format!("Op{:?}", i.class.opcode),
    };
    Some(Found { class, var, index })
}

/// A variable's name, else `set_S_binding_B` (spirv-reduce strips names).
fn variable_name(d: &Defs, var: Word, set: u32, binding: Option<u32>) -> String {
    let n = d.name(var);
    if !n.starts_with('%') {
        return n;
    }
    format!("set{set}_binding{}", binding.unwrap_or(0))
}

/// An acceleration structure made from a 64-bit address.
fn address_access(d: &Defs, i: &Instruction, stage: Stage) -> Found {
    let src = id_at(i, 0);
    let leaves = src.map(|x| index::leaves(d, x)).unwrap_or_default();
    let class = AccessClass {
        stage,
        resource: Resource::AccelerationStructure,
        index: leaves.source(),
        index_from: leaves.dynamic.clone(),
        nonuniform: i.result_id.is_some_and(|r| index::nonuniform(d, r)),
        set: None,
        binding: None,
        variable: src.map(|s| format!("%{s}")).unwrap_or_default(),
        through: "address".into(),
        op: format!("Op{:?}", i.class.opcode),
    };
    Found { class, var: src.unwrap_or(0), index: None }
}

#[cfg(test)]
mod tests;
