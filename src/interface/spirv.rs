//! A SPIR-V module's interface, read from its words (no SPIR-V library, so modules rspirv cannot
//! read — untyped pointers, descriptor heaps — are read too, and nothing panics): its entry
//! point's stage, its set/binding resource variables, its push-constant block and its ray tracing
//! interface blocks (payloads, callable data, hit attributes) with their sizes.
use super::error::InterfaceError;
use super::layout::DescriptorKind;
use ash::vk;
use std::collections::HashMap;

const OP_ENTRY_POINT: u32 = 15;
const OP_TYPE_BOOL: u32 = 20;
const OP_TYPE_INT: u32 = 21;
const OP_TYPE_FLOAT: u32 = 22;
const OP_TYPE_VECTOR: u32 = 23;
const OP_TYPE_MATRIX: u32 = 24;
const OP_TYPE_IMAGE: u32 = 25;
const OP_TYPE_SAMPLER: u32 = 26;
const OP_TYPE_SAMPLED_IMAGE: u32 = 27;
const OP_TYPE_ARRAY: u32 = 28;
const OP_TYPE_RUNTIME_ARRAY: u32 = 29;
const OP_TYPE_STRUCT: u32 = 30;
const OP_TYPE_POINTER: u32 = 32;
const OP_CONSTANT: u32 = 43;
const OP_VARIABLE: u32 = 59;
const OP_DECORATE: u32 = 71;
const OP_MEMBER_DECORATE: u32 = 72;
const OP_TYPE_ACCELERATION_STRUCTURE: u32 = 5341;

const DECORATION_BLOCK: u32 = 2;
const DECORATION_BUFFER_BLOCK: u32 = 3;
const DECORATION_ARRAY_STRIDE: u32 = 6;
const DECORATION_BINDING: u32 = 33;
const DECORATION_DESCRIPTOR_SET: u32 = 34;
const DECORATION_OFFSET: u32 = 35;

const SC_UNIFORM_CONSTANT: u32 = 0;
const SC_UNIFORM: u32 = 2;
const SC_PUSH_CONSTANT: u32 = 9;
const SC_STORAGE_BUFFER: u32 = 12;
const SC_CALLABLE_DATA: u32 = 5328;
const SC_INCOMING_CALLABLE_DATA: u32 = 5329;
const SC_RAY_PAYLOAD: u32 = 5338;
const SC_HIT_ATTRIBUTE: u32 = 5339;
const SC_INCOMING_RAY_PAYLOAD: u32 = 5342;

/// A set/binding resource variable: its kind, and its array length (`None`: not an array;
/// `Some(0)`: a runtime array).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Resource {
    pub set: u32,
    pub binding: u32,
    pub kind: DescriptorKind,
    pub array: Option<u32>,
}

/// What one module declares that a pipeline's layout and its other stages must agree with.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ModuleInterface {
    /// The entry point's stage (the first entry point).
    pub stage: vk::ShaderStageFlags,
    pub resources: Vec<Resource>,
    /// The push-constant block's byte range `(first member offset, end)`, if declared.
    pub push: Option<(u32, u32)>,
    /// Outgoing ray payloads and callable data, incoming ones, and the hit attribute: sizes in
    /// bytes (scalar alignment, as `maxPipelineRayPayloadSize` counts them).
    pub payloads: Vec<u32>,
    pub incoming_payload: Option<u32>,
    pub callable_data: Vec<u32>,
    pub incoming_callable_data: Option<u32>,
    pub hit_attribute: Option<u32>,
}

/// The module's instructions as (opcode, operands); a malformed word count is an error.
fn instructions(words: &[u32]) -> Result<Vec<(u32, &[u32])>, InterfaceError> {
    if words.len() < 5 || words[0] != 0x0723_0203 {
        return Err(InterfaceError::NotSpirv("no SPIR-V header".into()));
    }
    let mut out = Vec::new();
    let mut i = 5;
    while i < words.len() {
        let (count, op) = ((words[i] >> 16) as usize, words[i] & 0xffff);
        let operands = words.get(i + 1..i + count).filter(|_| count > 0).ok_or_else(|| {
            InterfaceError::NotSpirv(format!("instruction at word {i} runs past the end"))
        })?;
        out.push((op, operands));
        i += count;
    }
    Ok(out)
}

/// Types, constants and decorations by id.
#[derive(Default)]
struct Ids<'a> {
    types: HashMap<u32, (u32, &'a [u32])>,
    constants: HashMap<u32, u32>,
    decorations: HashMap<u32, Vec<(u32, u32)>>,
    member_offsets: HashMap<(u32, u32), u32>,
}

impl<'a> Ids<'a> {
    fn new(insts: &[(u32, &'a [u32])]) -> Ids<'a> {
        let mut ids = Ids::default();
        for &(op, o) in insts {
            match (op, o) {
                (OP_DECORATE, [id, d, rest @ ..]) => {
                    ids.decorations.entry(*id).or_default().push((*d, *rest.first().unwrap_or(&0)))
                }
                (OP_MEMBER_DECORATE, [st, m, d, v, ..]) if *d == DECORATION_OFFSET => {
                    ids.member_offsets.insert((*st, *m), *v);
                }
                (OP_CONSTANT, [_, id, v, ..]) => {
                    ids.constants.insert(*id, *v);
                }
                (op, [id, ..]) if is_type(op) => {
                    ids.types.insert(*id, (op, o));
                }
                _ => {}
            }
        }
        ids
    }

    fn decoration(&self, id: u32, d: u32) -> Option<u32> {
        self.decorations.get(&id)?.iter().find(|(x, _)| *x == d).map(|(_, v)| *v)
    }

    /// Size in bytes of type `id`: explicit offsets and strides where the module gives them, else
    /// packed at scalar alignment (the rule `maxPipelineRayPayloadSize` counts by).
    fn size(&self, id: u32, depth: u32) -> u32 {
        let Some(&(op, o)) = self.types.get(&id) else { return 0 };
        if depth > 32 {
            return 0;
        }
        match (op, o) {
            (OP_TYPE_BOOL, _) => 4,
            (OP_TYPE_INT | OP_TYPE_FLOAT, [_, width, ..]) => width / 8,
            (OP_TYPE_VECTOR | OP_TYPE_MATRIX, [_, elem, n, ..]) => n * self.size(*elem, depth + 1),
            (OP_TYPE_ARRAY, [_, elem, len, ..]) => {
                let stride = self
                    .decoration(id, DECORATION_ARRAY_STRIDE)
                    .unwrap_or_else(|| self.size(*elem, depth + 1));
                stride * self.constants.get(len).copied().unwrap_or(0)
            }
            (OP_TYPE_STRUCT, [_, members @ ..]) => {
                let mut end = 0;
                let mut packed = 0;
                for (k, m) in members.iter().enumerate() {
                    let s = self.size(*m, depth + 1);
                    match self.member_offsets.get(&(id, k as u32)) {
                        Some(off) => end = end.max(off + s),
                        None => packed += s,
                    }
                }
                end.max(packed)
            }
            _ => 0,
        }
    }

    /// The descriptor kind of a resource of type `ty` in storage class `sc`, with its array
    /// length (`Some(0)`: runtime array).
    fn kind(&self, ty: u32, sc: u32) -> Option<(DescriptorKind, Option<u32>)> {
        let &(op, o) = self.types.get(&ty)?;
        match (op, o) {
            (OP_TYPE_ARRAY, [_, elem, len, ..]) => {
                let (k, _) = self.kind(*elem, sc)?;
                Some((k, Some(self.constants.get(len).copied().unwrap_or(0))))
            }
            (OP_TYPE_RUNTIME_ARRAY, [_, elem, ..]) => Some((self.kind(*elem, sc)?.0, Some(0))),
            (OP_TYPE_STRUCT, _) => {
                let buffer_block = self.decoration(ty, DECORATION_BUFFER_BLOCK).is_some();
                let kind = match sc {
                    SC_STORAGE_BUFFER => DescriptorKind::StorageBuffer,
                    SC_UNIFORM if buffer_block => DescriptorKind::StorageBuffer,
                    SC_UNIFORM if self.decoration(ty, DECORATION_BLOCK).is_some() => {
                        DescriptorKind::UniformBuffer
                    }
                    _ => return None,
                };
                Some((kind, None))
            }
            (OP_TYPE_IMAGE, [_, _, dim, _, _, _, sampled, ..]) => {
                Some((DescriptorKind::of_image(*dim, *sampled), None))
            }
            (OP_TYPE_SAMPLER, _) => Some((DescriptorKind::Sampler, None)),
            (OP_TYPE_SAMPLED_IMAGE, _) => Some((DescriptorKind::CombinedImageSampler, None)),
            (OP_TYPE_ACCELERATION_STRUCTURE, _) => {
                Some((DescriptorKind::AccelerationStructure, None))
            }
            _ => None,
        }
    }
}

fn is_type(op: u32) -> bool {
    (19..=39).contains(&op) || op == OP_TYPE_ACCELERATION_STRUCTURE
}

/// The shader stage of SPIR-V execution model `model`.
fn stage(model: u32) -> vk::ShaderStageFlags {
    match model {
        0 => vk::ShaderStageFlags::VERTEX,
        4 => vk::ShaderStageFlags::FRAGMENT,
        5 => vk::ShaderStageFlags::COMPUTE,
        5313 => vk::ShaderStageFlags::RAYGEN_KHR,
        5314 => vk::ShaderStageFlags::INTERSECTION_KHR,
        5315 => vk::ShaderStageFlags::ANY_HIT_KHR,
        5316 => vk::ShaderStageFlags::CLOSEST_HIT_KHR,
        5317 => vk::ShaderStageFlags::MISS_KHR,
        5318 => vk::ShaderStageFlags::CALLABLE_KHR,
        _ => vk::ShaderStageFlags::empty(),
    }
}

impl ModuleInterface {
    /// Read the interface of the module `words`.
    pub fn read(words: &[u32]) -> Result<ModuleInterface, InterfaceError> {
        let insts = instructions(words)?;
        let ids = Ids::new(&insts);
        let mut m = ModuleInterface::default();
        for &(op, o) in &insts {
            match (op, o) {
                (OP_ENTRY_POINT, [model, ..]) if m.stage.is_empty() => m.stage = stage(*model),
                (OP_VARIABLE, [ptr, id, sc, ..]) => m.variable(&ids, *ptr, *id, *sc),
                _ => {}
            }
        }
        Ok(m)
    }

    /// Record variable `id` (of pointer type `ptr`, storage class `sc`).
    fn variable(&mut self, ids: &Ids, ptr: u32, id: u32, sc: u32) {
        let pointee = match ids.types.get(&ptr) {
            Some(&(OP_TYPE_POINTER, [_, _, t, ..])) => *t,
            _ => return,
        };
        let size = || ids.size(pointee, 0);
        match sc {
            SC_UNIFORM_CONSTANT | SC_UNIFORM | SC_STORAGE_BUFFER => {
                let (Some(set), Some(binding)) = (
                    ids.decoration(id, DECORATION_DESCRIPTOR_SET),
                    ids.decoration(id, DECORATION_BINDING),
                ) else {
                    return;
                };
                if let Some((kind, array)) = ids.kind(pointee, sc) {
                    self.resources.push(Resource { set, binding, kind, array });
                }
            }
            SC_PUSH_CONSTANT => {
                let first = match ids.types.get(&pointee) {
                    Some(&(OP_TYPE_STRUCT, [_, members @ ..])) => (0..members.len() as u32)
                        .filter_map(|k| ids.member_offsets.get(&(pointee, k)).copied())
                        .min()
                        .unwrap_or(0),
                    _ => 0,
                };
                self.push = Some((first, size()));
            }
            SC_RAY_PAYLOAD => self.payloads.push(size()),
            SC_INCOMING_RAY_PAYLOAD => self.incoming_payload = Some(size()),
            SC_CALLABLE_DATA => self.callable_data.push(size()),
            SC_INCOMING_CALLABLE_DATA => self.incoming_callable_data = Some(size()),
            SC_HIT_ATTRIBUTE => self.hit_attribute = Some(size()),
            _ => {}
        }
    }
}
