//! What a module asks of its host, read with rspirv: its stage and entry point, its descriptor
//! bindings (set, binding, type, array size; runtime arrays included) with the byte size of each
//! buffer, and the bytes its push-constant block reads. Only the binding types the harness can
//! make are accepted (acceleration structures, storage images, storage and uniform buffers); any
//! other is refused naming its set and binding.
use super::ints::{self, IntWords};
use super::scene::{INDEX_BOUND, TRACE_SIZE};
use crate::patches::layout::{self, Rules};
use crate::patches::pipeline::stage_of;
use crate::patches::{edit, push};
use rspirv::dr::{Module, Operand};
use rspirv::spirv::{Decoration, ImageFormat, Op, StorageClass, Word};

/// Elements given to a runtime-sized array of descriptors: one per index the harness scene can
/// produce (`super::scene::INDEX_BOUND`), so an array indexed by `gl_InstanceCustomIndexEXT` and
/// the like stays in bounds.
pub const RUNTIME_ELEMENTS: u32 = INDEX_BOUND;
/// Elements of a runtime array at the end of a buffer block: four per index the scene produces,
/// and at least one per traced pixel (engines index per-pixel buffers, accumulation or history,
/// with `gl_LaunchIDEXT.y * gl_LaunchSizeEXT.x + gl_LaunchIDEXT.x`).
pub const RUNTIME_MEMBERS: u32 = {
    let (per_index, per_pixel) = (4 * INDEX_BOUND, TRACE_SIZE * TRACE_SIZE);
    if per_index > per_pixel {
        per_index
    } else {
        per_pixel
    }
};

/// What a binding holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BindingKind {
    AccelerationStructure,
    /// A storage image of this format.
    StorageImage(ImageFormat),
    /// A storage buffer of this many bytes (each element).
    StorageBuffer(u32),
    /// A uniform buffer of this many bytes (each element).
    UniformBuffer(u32),
}

/// One descriptor binding.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Binding {
    pub set: u32,
    pub binding: u32,
    pub kind: BindingKind,
    /// Descriptors in it (runtime arrays get [`RUNTIME_ELEMENTS`]).
    pub count: u32,
    /// A runtime-sized array (needs runtimeDescriptorArray).
    pub runtime: bool,
    /// A storage buffer the module may write: neither the variable nor every member of its
    /// block is `NonWritable` (false for every other kind).
    pub writable: bool,
    /// The integer words of a buffer's block (empty for every other kind).
    pub ints: IntWords,
    /// A buffer the module applies an atomic instruction to (an append queue's counter): the
    /// order its words are filled in is the driver's scheduling.
    pub atomic: bool,
    /// A buffer block whose last member is an array: its byte offset and `ArrayStride` (the
    /// records an append queue fills), else `None`.
    pub records: Option<(u32, u32)>,
}

/// A module's interface.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Interface {
    /// raygen, closest_hit, any_hit, miss, intersection, callable, …
    pub stage: String,
    pub entry: String,
    pub bindings: Vec<Binding>,
    /// The end of the push-constant bytes it reads (0: none).
    pub push_end: u32,
    /// The integer words of its push-constant block (offsets in the push range).
    pub push_ints: IntWords,
}

/// What the harness cannot give a module.
#[derive(Debug, thiserror::Error, PartialEq)]
#[error("{0}")]
pub struct ReflectError(pub String);

/// The byte size of one buffer of block struct `st`: its members' ends, a runtime array at the
/// end given [`RUNTIME_MEMBERS`] elements; rounded up to 16.
fn buffer_size(m: &Module, st: Word) -> Option<u32> {
    let d = edit::def(m, st)?;
    let mut end = 0;
    for (k, o) in d.operands.iter().enumerate() {
        let ty = edit::id_from(o)?;
        let offset = edit::member_decoration(m, st, k as u32, Decoration::Offset)?;
        let t = edit::def(m, ty)?;
        let size = if t.class.opcode == Op::TypeRuntimeArray {
            RUNTIME_MEMBERS * edit::decoration_literal(m, ty, Decoration::ArrayStride)?
        } else {
            layout::extent(
                m,
                ty,
                edit::member_decoration(m, st, k as u32, Decoration::MatrixStride).map(|s| {
                    (s, edit::member_decoration(m, st, k as u32, Decoration::RowMajor).is_some())
                }),
            )?
        };
        end = end.max(offset + size);
    }
    Some(end.div_ceil(16) * 16)
}

/// The kind of one descriptor of type `ty` in storage class `sc`.
fn kind(m: &Module, sc: StorageClass, ty: Word) -> Option<BindingKind> {
    let d = edit::def(m, ty)?;
    match (sc, d.class.opcode) {
        (StorageClass::UniformConstant, Op::TypeAccelerationStructureKHR) => {
            Some(BindingKind::AccelerationStructure)
        }
        (StorageClass::UniformConstant, Op::TypeImage) => {
            let sampled = matches!(d.operands.get(5), Some(Operand::LiteralBit32(2)));
            match d.operands.get(6) {
                Some(Operand::ImageFormat(f)) if sampled => Some(BindingKind::StorageImage(*f)),
                _ => None,
            }
        }
        (StorageClass::StorageBuffer, Op::TypeStruct) => {
            Some(BindingKind::StorageBuffer(buffer_size(m, ty)?))
        }
        (StorageClass::Uniform, Op::TypeStruct) => {
            let size = buffer_size(m, ty)?;
            Some(if edit::has_decoration(m, ty, Decoration::BufferBlock) {
                BindingKind::StorageBuffer(size)
            } else {
                BindingKind::UniformBuffer(size)
            })
        }
        _ => None,
    }
}

/// One descriptor variable: its binding, or why the harness cannot make it.
fn binding(m: &Module, var: Word, ptr: Word) -> Result<Binding, ReflectError> {
    let set = edit::decoration_literal(m, var, Decoration::DescriptorSet).unwrap_or(0);
    let binding = edit::decoration_literal(m, var, Decoration::Binding).unwrap_or(0);
    let refuse = |what: &str| ReflectError(format!("set {set} binding {binding}: {what}"));
    let (sc, pointee) = edit::pointer_info(m, ptr).ok_or_else(|| refuse("not a pointer"))?;
    let d = edit::def(m, pointee).ok_or_else(|| refuse("type not found"))?;
    let (elem, count, runtime) = match d.class.opcode {
        Op::TypeArray => {
            let n = edit::array_length(m, d)
                .ok_or_else(|| refuse("an array sized by a spec constant"))?;
            (edit::id_operand(d, 0).unwrap_or(0), n, false)
        }
        Op::TypeRuntimeArray => (edit::id_operand(d, 0).unwrap_or(0), RUNTIME_ELEMENTS, true),
        _ => (pointee, 1, false),
    };
    let kind = kind(m, sc, elem).ok_or_else(|| {
        let op = edit::def(m, elem).map(|e| format!("Op{:?}", e.class.opcode)).unwrap_or_default();
        refuse(&format!("a {op} in {sc:?} storage, which the harness cannot make yet (acceleration structures, storage images, storage and uniform buffers)"))
    })?;
    let writable = matches!(kind, BindingKind::StorageBuffer(_)) && !non_writable(m, var, elem);
    let ints = match kind {
        BindingKind::StorageBuffer(_) | BindingKind::UniformBuffer(_) => {
            ints::of_block(m, elem).unwrap_or_default()
        }
        _ => IntWords::default(),
    };
    let atomic = writable && atomically_accessed(m, var);
    let records = if writable { last_array_member(m, elem) } else { None };
    Ok(Binding { set, binding, kind, count, runtime, writable, ints, atomic, records })
}

/// The byte offset and `ArrayStride` of block `st`'s last member when it is an array.
fn last_array_member(m: &Module, st: Word) -> Option<(u32, u32)> {
    let d = edit::def(m, st)?;
    let last = d.operands.len().checked_sub(1)?;
    let ty = edit::def(m, edit::id_operand(d, last)?)?;
    if !matches!(ty.class.opcode, Op::TypeArray | Op::TypeRuntimeArray) {
        return None;
    }
    let stride = edit::decoration_literal(m, ty.result_id?, Decoration::ArrayStride)?;
    let offset = edit::member_decoration(m, st, last as u32, Decoration::Offset)?;
    (stride > 0).then_some((offset, stride))
}

/// Whether an `OpAtomic*` instruction's pointer derives from `var` (through access chains and
/// copies).
fn atomically_accessed(m: &Module, var: Word) -> bool {
    let body = || m.functions.iter().flat_map(|f| &f.blocks).flat_map(|b| &b.instructions);
    let mut from: std::collections::BTreeSet<Word> = [var].into();
    loop {
        let before = from.len();
        for i in body() {
            let derives = matches!(
                i.class.opcode,
                Op::AccessChain | Op::InBoundsAccessChain | Op::PtrAccessChain | Op::CopyObject
            );
            if let (true, Some(id), Some(base)) = (derives, i.result_id, edit::id_operand(i, 0)) {
                if from.contains(&base) {
                    from.insert(id);
                }
            }
        }
        if from.len() == before {
            break;
        }
    }
    body().any(|i| {
        is_atomic(i.class.opcode) && edit::id_operand(i, 0).is_some_and(|p| from.contains(&p))
    })
}

fn is_atomic(op: Op) -> bool {
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

/// Whether a buffer variable is read-only: `NonWritable` on the variable (DXC, Slang) or on every
/// member of its block (glslang's `readonly buffer`).
fn non_writable(m: &Module, var: Word, block: Word) -> bool {
    if edit::has_decoration(m, var, Decoration::NonWritable) {
        return true;
    }
    let members = edit::def(m, block).map_or(0, |d| d.operands.len() as u32);
    members > 0
        && (0..members)
            .all(|k| edit::member_decoration(m, block, k, Decoration::NonWritable).is_some())
}

/// The interface of module `m`.
pub fn reflect(m: &Module) -> Result<Interface, ReflectError> {
    let (stage, entry) = stage_of(m).ok_or_else(|| ReflectError("no entry point".into()))?;
    let mut bindings = Vec::new();
    for v in m.types_global_values.iter().filter(|i| i.class.opcode == Op::Variable) {
        let (Some(id), Some(ptr)) = (v.result_id, v.result_type) else {
            continue;
        };
        if edit::has_decoration(m, id, Decoration::DescriptorSet) {
            bindings.push(binding(m, id, ptr)?);
        }
    }
    bindings.sort_by_key(|b| (b.set, b.binding));
    let push_end =
        push::end(m, Rules::Scalar, "harness").map_err(|e| ReflectError(e.to_string()))?;
    let block = push::block(m, "harness").map_err(|e| ReflectError(e.to_string()))?;
    let push_ints = block.and_then(|b| ints::of_block(m, b.st)).unwrap_or_default();
    Ok(Interface { stage, entry, bindings, push_end, push_ints })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn module(kind: shaderc::ShaderKind, glsl: &str) -> Module {
        crate::patches::compiled(kind, "t", glsl)
    }

    #[test]
    fn bindings_push_bytes_and_stage_are_read() {
        let glsl = "#version 460\n#extension GL_EXT_ray_tracing : require\n\
            #extension GL_EXT_nonuniform_qualifier : require\n\
            layout(set = 2, binding = 0) uniform accelerationStructureEXT tlas;\n\
            layout(set = 3, binding = 0) uniform accelerationStructureEXT shadows[2];\n\
            layout(set = 0, binding = 1, rgba32f) uniform image2D img;\n\
            layout(set = 1, binding = 0) readonly buffer V { vec4 head; float v[]; } verts[];\n\
            layout(set = 1, binding = 1) uniform Cam { mat4 view; } cam;\n\
            layout(set = 1, binding = 2) buffer Log { uint hits; vec4 last; } log;\n\
            layout(push_constant) uniform P { vec4 a; uint b; } pc;\n\
            layout(location = 0) rayPayloadEXT vec4 c;\n\
            void main() { traceRayEXT(shadows[pc.b], 0u, 0xFF, 0, 0, 0, vec3(0), 0.0, vec3(1), 1.0, 0);\n\
            traceRayEXT(tlas, 0u, 0xFF, 0, 0, 0, vec3(0), 0.0, vec3(1), 1.0, 0);\n\
            imageStore(img, ivec2(0), c + verts[nonuniformEXT(pc.b)].v[3] * cam.view[0] + pc.a);\n\
            log.last = c; }\n";
        let i = reflect(&module(shaderc::ShaderKind::RayGeneration, glsl)).unwrap();
        assert_eq!((i.stage.as_str(), i.entry.as_str(), i.push_end), ("raygen", "main", 20));
        let b: Vec<(u32, u32, BindingKind, u32, bool, bool)> = i
            .bindings
            .iter()
            .map(|b| (b.set, b.binding, b.kind, b.count, b.runtime, b.writable))
            .collect();
        let verts = BindingKind::StorageBuffer(16 + RUNTIME_MEMBERS * 4);
        assert_eq!(
            b,
            vec![
                (0, 1, BindingKind::StorageImage(ImageFormat::Rgba32f), 1, false, false),
                (1, 0, verts, RUNTIME_ELEMENTS, true, false),
                (1, 1, BindingKind::UniformBuffer(64), 1, false, false),
                (1, 2, BindingKind::StorageBuffer(32), 1, false, true),
                (2, 0, BindingKind::AccelerationStructure, 1, false, false),
                (3, 0, BindingKind::AccelerationStructure, 2, false, false),
            ]
        );
        // A sampled texture is not made yet: refused naming its binding.
        let tex = "#version 460\n#extension GL_EXT_ray_tracing : require\n\
            layout(set = 4, binding = 2) uniform sampler2D t;\nlayout(location = 0) rayPayloadInEXT vec4 c;\n\
            void main() { c = textureLod(t, vec2(0), 0.0); }\n";
        let e = reflect(&module(shaderc::ShaderKind::Miss, tex)).unwrap_err();
        assert!(e.0.starts_with("set 4 binding 2: a OpTypeSampledImage"), "{e}");
    }

    /// An append queue's buffer is atomic (its counter is); a buffer only stored to is not,
    /// nor one whose atomics go to another binding.
    #[test]
    fn buffers_written_through_atomics_are_marked() {
        let glsl = "#version 460\n#extension GL_EXT_ray_tracing : require\n\
            layout(set = 0, binding = 1) buffer Q { uint count; uvec4 rec[]; } q;\n\
            layout(set = 0, binding = 2) buffer Plain { uint last; } plain;\n\
            layout(set = 0, binding = 3) buffer Other { uint n; } other;\n\
            layout(location = 0) rayPayloadInEXT vec4 c;\n\
            void main() { uint k = atomicAdd(q.count, 1u); q.rec[k] = uvec4(gl_LaunchIDEXT, 0u);\n\
            plain.last = k + atomicOr(other.n, 0u); }\n";
        let i = reflect(&module(shaderc::ShaderKind::ClosestHit, glsl)).unwrap();
        let a: Vec<(u32, bool)> = i.bindings.iter().map(|b| (b.binding, b.atomic)).collect();
        assert_eq!(a, vec![(1, true), (2, false), (3, true)]);
        // The queue's records: uvec4 rec[] after the counter, at byte 16, 16 bytes each.
        let r: Vec<Option<(u32, u32)>> = i.bindings.iter().map(|b| b.records).collect();
        assert_eq!(r, vec![Some((16, 16)), None, None]);
    }
}
