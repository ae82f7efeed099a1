//! The descriptor accesses of a user's module ([`find`]): each instruction that reads through a
//! descriptor variable (decorated `DescriptorSet`) and has a value — `OpLoad` and the atomics of
//! a storage or uniform buffer, the sample / fetch / gather / read of an image whose handle was
//! loaded from one — with what it is on the predicate's axes ([`Access`]). The stage is the entry
//! point's; the index is how the descriptor array's index is produced, from its definitions
//! (through local variables' stores): only constants `literal` (a descriptor that is no array
//! too), a spec constant among them `spec_constant`, push constants among them `push_constant`,
//! anything else (built-ins, other loads, parameters) `dynamic`. An acceleration structure's
//! handle load is one too but carries no value a fault could take ([`Site::value`] is `None`:
//! its fault ties to the handle's rays instead, `super::handle`); an acceleration structure
//! made from an address (`OpConvertUToAccelerationStructureKHR`) reads no descriptor and is none. A descriptor heap
//! access (`layout(descriptor_heap)`: an untyped access chain into `ResourceHeapEXT`) is one
//! too, the chain's index its descriptor index.
use super::predicate::Access;
use crate::model::{IndexSource, Resource, Stage};
use crate::patches::edit::{self, id_operand};
use rspirv::dr::{Instruction, Module, Operand};
use rspirv::spirv::{BuiltIn, Decoration, ExecutionModel, Op, StorageClass, Word};
use std::collections::HashMap;

/// One access: where it is (function, block, instruction) and its value.
#[derive(Clone, Debug, PartialEq)]
pub struct Site {
    pub at: (usize, usize, usize),
    /// The access's result (`None` for an acceleration structure's load).
    pub value: Option<Word>,
    pub access: Access,
    /// The variable's name (or `%id`), for the report.
    pub var: String,
}

/// The stage of the module's first entry point, as the registry names it.
pub fn stage(m: &Module) -> Option<Stage> {
    let model = match m.entry_points.first()?.operands.first()? {
        Operand::ExecutionModel(e) => *e,
        _ => return None,
    };
    Some(match model {
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

/// The resource a descriptor variable's (element) type is, if it is one of the registry's.
fn resource(m: &Module, var: Word) -> Option<(Resource, bool)> {
    let ty = edit::def(m, var)?.result_type?;
    let (class, mut pointee) = edit::pointer_info(m, ty)?;
    let mut arrayed = false;
    let mut d = edit::def(m, pointee)?;
    if matches!(d.class.opcode, Op::TypeArray | Op::TypeRuntimeArray) {
        arrayed = true;
        pointee = id_operand(d, 0)?;
        d = edit::def(m, pointee)?;
    }
    let r = match (class, d.class.opcode) {
        (StorageClass::StorageBuffer, _) => Resource::StorageBuffer,
        (StorageClass::Uniform, _) if edit::has_decoration(m, pointee, Decoration::BufferBlock) => {
            Resource::StorageBuffer
        }
        (StorageClass::Uniform, _) => Resource::UniformBuffer,
        (StorageClass::UniformConstant, Op::TypeSampledImage) => Resource::SampledImage,
        (StorageClass::UniformConstant, Op::TypeImage) => match d.operands.get(5) {
            Some(Operand::LiteralBit32(2)) => Resource::StorageImage,
            _ => Resource::SampledImage,
        },
        (StorageClass::UniformConstant, Op::TypeAccelerationStructureKHR) => {
            Resource::AccelerationStructure
        }
        _ => return None,
    };
    Some((r, arrayed))
}

/// Image instructions that read a texel (their operand 0 is the image).
fn reads_image(op: Op) -> bool {
    matches!(
        op,
        Op::ImageSampleImplicitLod
            | Op::ImageSampleExplicitLod
            | Op::ImageSampleDrefImplicitLod
            | Op::ImageSampleDrefExplicitLod
            | Op::ImageSampleProjImplicitLod
            | Op::ImageSampleProjExplicitLod
            | Op::ImageSampleProjDrefImplicitLod
            | Op::ImageSampleProjDrefExplicitLod
            | Op::ImageFetch
            | Op::ImageGather
            | Op::ImageDrefGather
            | Op::ImageRead
            | Op::ImageSparseSampleImplicitLod
            | Op::ImageSparseSampleExplicitLod
            | Op::ImageSparseFetch
            | Op::ImageSparseGather
            | Op::ImageSparseRead
    )
}

/// Buffer instructions that read through a pointer (operand 0) and have a value: a load or
/// any atomic but a store.
fn reads_buffer(op: Op) -> bool {
    op == Op::Load || (crate::reflect::bindings::is_atomic(op) && op != Op::AtomicStore)
}

/// What a pointer or handle derives from: its descriptor variable and array index.
type Origin = (Word, Option<Word>);

/// Every descriptor access of `m`, in instruction order.
pub fn find(m: &Module) -> Vec<Site> {
    let Some(stage) = stage(m) else { return vec![] };
    let mut vars: HashMap<Word, (Resource, bool)> = edit::descriptor_variables(m)
        .into_iter()
        .filter_map(|v| Some((v, resource(m, v)?)))
        .collect();
    let index = IndexClass::new(m);
    let (mut ptrs, mut handles): (HashMap<Word, Origin>, HashMap<Word, Origin>) =
        Default::default();
    let mut out = Vec::new();
    for (fi, f) in m.functions.iter().enumerate() {
        for (bi, b) in f.blocks.iter().enumerate() {
            for (ii, i) in b.instructions.iter().enumerate() {
                if let Some((r, resource, at)) = heap_chain(m, i) {
                    vars.insert(r, (resource, true));
                    ptrs.insert(r, (r, Some(at)));
                    continue;
                }
                let (Some(r), Some(a)) = (i.result_id, id_operand(i, 0)) else { continue };
                let from_var = vars.get(&a).map(|(_, arrayed)| (a, *arrayed));
                match i.class.opcode {
                    Op::AccessChain | Op::InBoundsAccessChain | Op::PtrAccessChain => {
                        if let Some((v, arrayed)) = from_var {
                            ptrs.insert(r, (v, if arrayed { id_operand(i, 1) } else { None }));
                        } else if let Some(o) = ptrs.get(&a).copied() {
                            ptrs.insert(r, o);
                        }
                        continue;
                    }
                    Op::CopyObject | Op::BufferPointerEXT if ptrs.contains_key(&a) => {
                        ptrs.insert(r, ptrs[&a]);
                        continue;
                    }
                    Op::SampledImage | Op::Image | Op::CopyObject if handles.contains_key(&a) => {
                        handles.insert(r, handles[&a]);
                        continue;
                    }
                    _ => {}
                }
                let origin = from_var.map(|(v, _)| (v, None)).or_else(|| ptrs.get(&a).copied());
                let site = |origin: Origin, value| {
                    let (resource, _) = vars[&origin.0];
                    let index = origin.1.map_or(IndexSource::Literal, |x| index.of(x));
                    let name = match heap_chain(m, edit::def(m, origin.0).unwrap_or(i)) {
                        Some(_) => "resource_heap".to_string(),
                        None => name_of(m, origin.0),
                    };
                    Site {
                        at: (fi, bi, ii),
                        value,
                        access: Access { stage, resource, index },
                        var: if name.is_empty() { format!("%{}", origin.0) } else { name },
                    }
                };
                match (i.class.opcode, origin) {
                    (Op::Load, Some(o)) if !is_buffer(vars[&o.0].0) => {
                        handles.insert(r, o);
                        if vars[&o.0].0 == Resource::AccelerationStructure {
                            out.push(site(o, None));
                        }
                    }
                    (op, Some(o)) if reads_buffer(op) => out.push(site(o, Some(r))),
                    (op, _) if reads_image(op) => {
                        if let Some(o) = handles.get(&a).copied() {
                            out.push(site(o, Some(r)));
                        }
                    }
                    _ => {}
                }
            }
        }
    }
    out
}

/// An `OpUntypedAccessChainKHR` into the `ResourceHeapEXT` variable (SPV_EXT_descriptor_heap):
/// its result, the resource its base type's element is (`OpTypeBufferEXT`, an image, a
/// sampler) and its descriptor index. A buffer is then read through the `OpBufferPointerEXT`
/// of it, an image loaded from it.
fn heap_chain(m: &Module, i: &Instruction) -> Option<(Word, Resource, Word)> {
    if !matches!(i.class.opcode, Op::UntypedAccessChainKHR | Op::UntypedInBoundsAccessChainKHR) {
        return None;
    }
    let (ty, heap, at) = (id_operand(i, 0)?, id_operand(i, 1)?, id_operand(i, 2)?);
    let is_heap = m.annotations.iter().any(|a| {
        id_operand(a, 0) == Some(heap)
            && a.operands.get(2) == Some(&Operand::BuiltIn(BuiltIn::ResourceHeapEXT))
    });
    if !is_heap {
        return None;
    }
    let mut d = edit::def(m, ty)?;
    if matches!(d.class.opcode, Op::TypeArray | Op::TypeRuntimeArray) {
        d = edit::def(m, id_operand(d, 0)?)?;
    }
    let r = match (d.class.opcode, d.operands.first()) {
        (Op::TypeBufferEXT, Some(Operand::StorageClass(StorageClass::Uniform))) => {
            Resource::UniformBuffer
        }
        (Op::TypeBufferEXT, _) => Resource::StorageBuffer,
        (Op::TypeImage, _) => match d.operands.get(5) {
            Some(Operand::LiteralBit32(2)) => Resource::StorageImage,
            _ => Resource::SampledImage,
        },
        (Op::TypeSampledImage, _) => Resource::SampledImage,
        _ => return None,
    };
    Some((i.result_id?, r, at))
}

/// The `OpName` of `id`, or nothing.
fn name_of(m: &Module, id: Word) -> String {
    m.debug_names
        .iter()
        .find_map(|n| match n.operands.as_slice() {
            [Operand::IdRef(t), Operand::LiteralString(s)] if *t == id => Some(s.clone()),
            _ => None,
        })
        .unwrap_or_default()
}

fn is_buffer(r: Resource) -> bool {
    match r {
        Resource::StorageBuffer | Resource::UniformBuffer => true,
        Resource::SampledImage | Resource::StorageImage | Resource::AccelerationStructure => false,
    }
}

/// How an index value is produced, from its definitions.
struct IndexClass<'m> {
    m: &'m Module,
    defs: HashMap<Word, &'m Instruction>,
    /// The values stored to each function or private variable (through access chains too).
    stores: HashMap<Word, Vec<Word>>,
}

impl<'m> IndexClass<'m> {
    fn new(m: &'m Module) -> IndexClass<'m> {
        let all = m.types_global_values.iter().chain(
            m.functions.iter().flat_map(|f| f.blocks.iter().flat_map(|b| b.instructions.iter())),
        );
        let defs: HashMap<Word, &Instruction> =
            all.filter_map(|i| Some((i.result_id?, i))).collect();
        let mut x = IndexClass { m, defs, stores: HashMap::new() };
        for f in &m.functions {
            for i in f.blocks.iter().flat_map(|b| b.instructions.iter()) {
                if let (Op::Store, Some(p), Some(v)) =
                    (i.class.opcode, id_operand(i, 0), id_operand(i, 1))
                {
                    let root = x.root(p);
                    x.stores.entry(root).or_default().push(v);
                }
            }
        }
        x
    }

    /// The variable a pointer is derived from by access chains.
    fn root(&self, mut p: Word) -> Word {
        for _ in 0..64 {
            match self.defs.get(&p) {
                Some(d) if matches!(d.class.opcode, Op::AccessChain | Op::InBoundsAccessChain) => {
                    p = id_operand(d, 0).unwrap_or(p)
                }
                _ => break,
            }
        }
        p
    }

    fn of(&self, id: Word) -> IndexSource {
        let mut seen = std::collections::HashSet::new();
        self.walk(id, &mut seen)
    }

    /// The highest class among the leaves of `id`'s definition tree.
    fn walk(&self, id: Word, seen: &mut std::collections::HashSet<Word>) -> IndexSource {
        if !seen.insert(id) {
            return IndexSource::Literal;
        }
        let Some(d) = self.defs.get(&id) else { return IndexSource::Dynamic };
        match d.class.opcode {
            Op::SpecConstant | Op::SpecConstantOp | Op::SpecConstantComposite => {
                IndexSource::SpecConstant
            }
            Op::SpecConstantTrue | Op::SpecConstantFalse => IndexSource::SpecConstant,
            _ if edit::is_constant(self.m, id) || d.class.opcode == Op::Undef => {
                IndexSource::Literal
            }
            Op::Load => {
                let root = self.root(id_operand(d, 0).unwrap_or(0));
                match self.storage(root) {
                    Some(StorageClass::PushConstant) => IndexSource::PushConstant,
                    Some(StorageClass::Function | StorageClass::Private) => {
                        let values = self.stores.get(&root).cloned().unwrap_or_default();
                        if values.is_empty() {
                            return IndexSource::Dynamic;
                        }
                        values
                            .into_iter()
                            .map(|v| self.walk(v, seen))
                            .max()
                            .unwrap_or(IndexSource::Literal)
                    }
                    _ => IndexSource::Dynamic,
                }
            }
            Op::FunctionParameter | Op::Variable | Op::FunctionCall => IndexSource::Dynamic,
            _ => d
                .operands
                .iter()
                .filter_map(edit::id_from)
                .filter(|o| !self.is_label(*o) && !self.is_import(*o))
                .map(|o| self.walk(o, seen))
                .max()
                .unwrap_or(IndexSource::Literal),
        }
    }

    fn storage(&self, var: Word) -> Option<StorageClass> {
        let d = self.defs.get(&var)?;
        match (d.class.opcode, d.operands.first()) {
            (Op::Variable, Some(Operand::StorageClass(c))) => Some(*c),
            _ => None,
        }
    }

    /// An `OpExtInstImport` (the set an `OpExtInst` names).
    fn is_import(&self, id: Word) -> bool {
        self.m.ext_inst_imports.iter().any(|i| i.result_id == Some(id))
    }

    /// Labels have no definition among values (an `OpPhi`'s parents).
    fn is_label(&self, id: Word) -> bool {
        !self.defs.contains_key(&id)
            && self.m.functions.iter().any(|f| f.blocks.iter().any(|b| b.label_id() == Some(id)))
    }
}
