//! What a module asks of its host, the harness's view of its [`crate::reflect`]ion: its stage
//! and entry point, its descriptor bindings (set, binding, type, array size; runtime arrays
//! included) with the byte size of each buffer, and the bytes its push-constant block reads. Only the binding types the harness can
//! make are accepted (acceleration structures, storage images (RGBA32F where the shader gives no format), storage and
//! uniform buffers, and 2D float textures: sampled images, samplers, combined image samplers);
//! any other is refused naming its set and binding.
use super::ints::{self, IntWords};
use super::scene::{INDEX_BOUND, TRACE_SIZE};
use crate::patches::{edit, push};
use crate::reflect::{self, Count, Descriptor};
use rspirv::dr::{Module, Operand};
use rspirv::spirv::{Decoration, Dim, ImageFormat, Op, Word};

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
    /// A 2D float sampled image (`texture2D`): the harness's textures (`super::textures`).
    SampledImage,
    /// A sampler (`sampler`): the harness's one nearest, clamp-to-edge sampler.
    Sampler,
    /// A combined image sampler (`sampler2D`): a texture with that sampler.
    CombinedImageSampler,
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
    /// The end of its shader record block's fixed part (0: none).
    pub record_end: u32,
    /// The integer words of its shader record block.
    pub record_ints: IntWords,
    /// The whole reflection the harness's view was made from.
    pub reflection: reflect::Reflection,
}

/// What the harness cannot give a module.
#[derive(Debug, thiserror::Error, PartialEq)]
#[error("{0}")]
pub struct ReflectError(pub String);

/// The byte size of one buffer of block `b`: its fixed part's end, a trailing runtime array
/// given [`RUNTIME_MEMBERS`] elements; rounded up to 16.
fn buffer_size(b: &reflect::Block) -> u32 {
    let runtime = b.tail.filter(|t| t.runtime).map_or(0, |t| t.offset + RUNTIME_MEMBERS * t.stride);
    b.end.max(runtime).div_ceil(16) * 16
}

/// The harness's binding for reflected binding `b`, or why the harness cannot make it.
fn binding(m: &Module, b: &reflect::Binding) -> Result<Binding, ReflectError> {
    let (set, binding) = (b.set, b.binding);
    let refuse = |what: &str| ReflectError(format!("set {set} binding {binding}: {what}"));
    let size = || b.block.as_ref().map_or(0, buffer_size);
    let kind = match b.descriptor {
        Descriptor::AccelerationStructure => BindingKind::AccelerationStructure,
        Descriptor::StorageImage(f) if f != ImageFormat::Unknown => BindingKind::StorageImage(f),
        // No format in the shader (HLSL's `RWTexture2D<float4>`, Slang's, GLSL's `writeonly
        // image2D`): reads and writes go through the view's format, any storage format, with
        // shaderStorageImageRead/WriteWithoutFormat (the module's `StorageImage*WithoutFormat`
        // capabilities ask for them); rtprobe makes it RGBA32F, which holds any four components.
        Descriptor::StorageImage(_) => BindingKind::StorageImage(ImageFormat::Rgba32f),
        Descriptor::StorageBuffer => BindingKind::StorageBuffer(size()),
        Descriptor::UniformBuffer => BindingKind::UniformBuffer(size()),
        Descriptor::Sampler => BindingKind::Sampler,
        Descriptor::SampledImage | Descriptor::CombinedImageSampler => {
            if let Some(why) = texture_refusal(m, b) {
                return Err(refuse(&why));
            }
            match b.descriptor {
                Descriptor::SampledImage => BindingKind::SampledImage,
                _ => BindingKind::CombinedImageSampler,
            }
        }
        Descriptor::UniformTexelBuffer
        | Descriptor::StorageTexelBuffer
        | Descriptor::InputAttachment => {
            return Err(refuse(&format!("a {:?} descriptor, which the harness cannot make yet (acceleration structures, storage images, storage and uniform buffers, 2D float textures and samplers)", b.descriptor)))
        }
    };
    let (count, runtime) = match b.count {
        Count::One => (1, false),
        Count::Fixed(n) => (n, false),
        Count::Runtime => (RUNTIME_ELEMENTS, true),
    };
    let writable = matches!(kind, BindingKind::StorageBuffer(_)) && b.writable;
    let st = element_type(m, b);
    let ints = match kind {
        BindingKind::StorageBuffer(_) | BindingKind::UniformBuffer(_) => {
            st.and_then(|st| ints::of_block(m, st)).unwrap_or_default()
        }
        _ => IntWords::default(),
    };
    let records =
        b.block.as_ref().and_then(|k| k.tail).filter(|_| writable).map(|t| (t.offset, t.stride));
    Ok(Binding {
        set,
        binding,
        kind,
        count,
        runtime,
        writable,
        ints,
        atomic: writable && b.atomic,
        records,
    })
}

/// The element type of binding `b`'s variable: its pointee, arrays unwrapped (a buffer's block
/// struct, for [`ints::of_block`], which reads the module).
fn element_type(m: &Module, b: &reflect::Binding) -> Option<Word> {
    let var = m.types_global_values.iter().find(|v| {
        v.class.opcode == Op::Variable
            && v.result_id.is_some_and(|id| {
                edit::decoration_literal(m, id, Decoration::DescriptorSet) == Some(b.set)
                    && edit::decoration_literal(m, id, Decoration::Binding) == Some(b.binding)
            })
    })?;
    let (_, pointee) = edit::pointer_info(m, var.result_type?)?;
    let d = edit::def(m, pointee)?;
    match d.class.opcode {
        Op::TypeArray | Op::TypeRuntimeArray => edit::id_operand(d, 0),
        _ => Some(pointee),
    }
}

/// Why the harness cannot make the texture of binding `b` (`None`: a 2D, non-arrayed,
/// single-sampled, non-depth float image, which it makes).
fn texture_refusal(m: &Module, b: &reflect::Binding) -> Option<String> {
    let mut ty = edit::def(m, element_type(m, b)?)?;
    if ty.class.opcode == Op::TypeSampledImage {
        ty = edit::def(m, edit::id_operand(ty, 0)?)?;
    }
    let lit = |k: usize| match ty.operands.get(k) {
        Some(Operand::LiteralBit32(v)) => Some(*v),
        _ => None,
    };
    let dim = match ty.operands.get(1) {
        Some(Operand::Dim(d)) => *d,
        _ => return Some("an image type the harness cannot read".into()),
    };
    let float = edit::id_operand(ty, 0)
        .and_then(|t| edit::def(m, t))
        .is_some_and(|t| t.class.opcode == Op::TypeFloat);
    let shape = match (dim, lit(2), lit(3), lit(4)) {
        (Dim::Dim2D, Some(0 | 2), Some(0), Some(0)) if float => return None,
        (Dim::Dim2D, Some(1), ..) => "a depth (shadow) texture".to_string(),
        (Dim::Dim2D, _, Some(1), _) => "a 2D array texture".to_string(),
        (Dim::Dim2D, _, _, Some(1)) => "a multisampled texture".to_string(),
        (Dim::Dim2D, ..) => "an integer texture".to_string(),
        (Dim::Dim1D, ..) => "a 1D texture".to_string(),
        (Dim::Dim3D, ..) => "a 3D texture".to_string(),
        (Dim::DimCube, ..) => "a cube texture".to_string(),
        (d, ..) => format!("a {d:?} texture"),
    };
    Some(format!("{shape}, which the harness cannot make yet (it makes 2D float textures: texture2D, sampler2D)"))
}

/// The interface of module `m` (its only entry point).
pub fn reflect(m: &Module) -> Result<Interface, ReflectError> {
    let r = reflect::reflect(m, None).map_err(|e| ReflectError(e.to_string()))?;
    let bindings = r.bindings.iter().map(|b| binding(m, b)).collect::<Result<Vec<_>, _>>()?;
    let push_end = r.push.as_ref().map_or(0, |p| p.end);
    let block = push::block(m, "harness").map_err(|e| ReflectError(e.to_string()))?;
    let push_ints = block.and_then(|b| ints::of_block(m, b.st)).unwrap_or_default();
    let record_end = r.record.as_ref().map_or(0, |b| b.end);
    let record_ints = record_block(m).and_then(|st| ints::of_block(m, st)).unwrap_or_default();
    let (stage, entry) = (r.stage.clone(), r.entry.clone());
    Ok(Interface {
        stage,
        entry,
        bindings,
        push_end,
        push_ints,
        record_end,
        record_ints,
        reflection: r,
    })
}

/// The block struct of the module's `ShaderRecordBufferKHR` variable.
fn record_block(m: &Module) -> Option<Word> {
    let var = m.types_global_values.iter().find(|i| {
        i.class.opcode == Op::Variable
            && i.operands.first()
                == Some(&Operand::StorageClass(rspirv::spirv::StorageClass::ShaderRecordBufferKHR))
    })?;
    edit::pointer_info(m, var.result_type?).map(|(_, st)| st)
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
    }

    /// 2D float textures are made: a combined image sampler, a separate texture array and its
    /// sampler; their array counts as for buffers.
    #[test]
    fn two_d_float_textures_and_samplers_are_accepted() {
        let tex = "#version 460\n#extension GL_EXT_ray_tracing : require\n\
            #extension GL_EXT_nonuniform_qualifier : require\n\
            layout(set = 4, binding = 2) uniform sampler2D t;\n\
            layout(set = 4, binding = 3) uniform texture2D maps[];\n\
            layout(set = 4, binding = 4) uniform sampler nearest;\n\
            layout(set = 4, binding = 5) uniform sampler2D fixed4[4];\n\
            layout(location = 0) rayPayloadInEXT vec4 c;\n\
            void main() { uint k = uint(c.w);\n\
            c = textureLod(t, vec2(0), 0.0) + textureLod(fixed4[k & 3u], vec2(0), 0.0)\n\
            + textureLod(sampler2D(maps[nonuniformEXT(k)], nearest), vec2(0.5), 0.0); }\n";
        let i = reflect(&module(shaderc::ShaderKind::Miss, tex)).unwrap();
        let b: Vec<(u32, BindingKind, u32, bool)> =
            i.bindings.iter().map(|b| (b.binding, b.kind, b.count, b.runtime)).collect();
        assert_eq!(
            b,
            vec![
                (2, BindingKind::CombinedImageSampler, 1, false),
                (3, BindingKind::SampledImage, RUNTIME_ELEMENTS, true),
                (4, BindingKind::Sampler, 1, false),
                (5, BindingKind::CombinedImageSampler, 4, false),
            ]
        );
    }

    /// Twin: textures the harness does not make (3D, cube, integer, depth, arrayed) are refused
    /// in one line naming their set and binding.
    #[test]
    fn other_textures_are_refused_naming_their_binding() {
        for (decl, read, what) in [
            ("sampler3D", "vec3(0)", "a 3D texture"),
            ("samplerCube", "vec3(0, 0, 1)", "a cube texture"),
            ("sampler2DArray", "vec3(0)", "a 2D array texture"),
            ("usampler2D", "vec2(0)", "an integer texture"),
        ] {
            let tex = format!(
                "#version 460\n#extension GL_EXT_ray_tracing : require\n\
                layout(set = 4, binding = 2) uniform {decl} t;\n\
                layout(location = 0) rayPayloadInEXT vec4 c;\n\
                void main() {{ c = vec4(textureLod(t, {read}, 0.0)); }}\n"
            );
            let e = reflect(&module(shaderc::ShaderKind::Miss, &tex)).unwrap_err();
            assert!(e.0.starts_with(&format!("set 4 binding 2: {what}, ")), "{decl}: {e}");
            assert!(!e.0.contains('\n'), "{e}");
        }
    }

    /// A storage image without a format (GLSL `writeonly image2D`, HLSL `RWTexture2D<float4>`)
    /// is made RGBA32F; with one, that format.
    #[test]
    fn a_storage_image_without_a_format_is_rgba32f() {
        let glsl = "#version 460\n#extension GL_EXT_ray_tracing : require\n\
            layout(set = 0, binding = 1) writeonly uniform image2D out_;\n\
            layout(set = 0, binding = 2, r32f) uniform image2D depth;\n\
            void main() { imageStore(out_, ivec2(0), vec4(imageLoad(depth, ivec2(0)).x)); }\n";
        let r = reflect(&module(shaderc::ShaderKind::RayGeneration, glsl)).unwrap();
        let kinds: Vec<_> = r.bindings.iter().map(|b| (b.binding, b.kind)).collect();
        assert_eq!(
            kinds,
            vec![
                (1, BindingKind::StorageImage(ImageFormat::Rgba32f)),
                (2, BindingKind::StorageImage(ImageFormat::R32f))
            ]
        );
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
