//! `run --shader`'s descriptor heap model (VK_EXT_descriptor_heap): a pipeline whose modules
//! index the resource heap themselves (`layout(descriptor_heap)` arrays, read by
//! `crate::reflect::heap`) runs on heaps laid out from what the modules use. Each heap array
//! ([`arrays`]) starts at its member offset and strides by what the module states (a literal
//! `ArrayStride`, or `OpConstantSizeOfEXT` of its type: the device's descriptor size for that
//! class) and gets [`HEAP_ELEMENTS`] descriptors, one per index `base + custom index` can reach
//! in the harness scene (a base read from push data or a buffer is a small integer below
//! `INDEX_BOUND`, as is every custom index); each buffer element its own data. The set/binding
//! descriptors the pipeline still has (the supplied raygen's TLAS and output, the module's own)
//! sit after the arrays, each binding mapped HEAP_WITH_CONSTANT_OFFSET. The heaps are made,
//! written and bound by `exec::heap` (the generated cells' code: [`PlacedHeaps`]).
use super::error::HarnessError;
use super::reflect::{Binding, BindingKind};
use super::resources::{self, Element};
use super::scene::INDEX_BOUND;
use super::UserModule;
use crate::exec::heap::{descriptor_stride, PipelineMapping, Placed, PlacedHeaps};
use crate::exec::resources::Target;
use crate::reflect::{HeapKind, HeapStride};
use crate::scene::gpu::SceneGpu;
use crate::vk::memory::{Buffer, Location};
use crate::vk::Gpu;
use ash::vk;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Descriptors in each heap array: every index `base + gl_InstanceCustomIndexEXT` reaches when
/// both are below `INDEX_BOUND`.
pub const HEAP_ELEMENTS: u32 = 2 * INDEX_BOUND;
/// Bytes of each storage buffer in a heap array (a vec4 per traced pixel), and of each uniform
/// buffer (Vulkan's guaranteed `maxUniformBufferRange`).
const STORAGE_BYTES: u32 = 64 * 1024;
const UNIFORM_BYTES: u32 = 16 * 1024;

/// What a heap array holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Held {
    StorageBuffer,
    UniformBuffer,
    AccelerationStructure,
}

impl Held {
    fn descriptor_type(self) -> vk::DescriptorType {
        match self {
            Held::StorageBuffer => vk::DescriptorType::STORAGE_BUFFER,
            Held::UniformBuffer => vk::DescriptorType::UNIFORM_BUFFER,
            Held::AccelerationStructure => vk::DescriptorType::ACCELERATION_STRUCTURE_KHR,
        }
    }
}

/// How far apart an array's descriptors are.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Stride {
    Bytes(u32),
    /// The device's descriptor size of the held type.
    Descriptor,
}

/// Where an array starts: a byte offset (what a module states), or a heap index in units of
/// the held type's descriptor size (what a `--heap-layout` range gives).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum First {
    Byte(u32),
    Index(u32),
}

/// One heap array the modules index: where it starts, its stride, what it holds, how many
/// descriptors it gets.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Array {
    pub first: First,
    pub stride: Stride,
    pub held: Held,
    pub count: u32,
}

/// A `--heap-layout` file: the resource heap's ranges, each `{"kind": "storage_buffer" |
/// "uniform_buffer" | "acceleration_structure", "first": INDEX, "count": N}` (heap index in
/// units of the kind's descriptor size).
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LayoutFile {
    pub resource: Vec<Range>,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Range {
    pub kind: Held,
    pub first: u32,
    pub count: u32,
}

/// The most descriptors one `--heap-layout` range may ask for.
pub const MAX_RANGE: u32 = 4096;

/// The arrays a `--heap-layout` file's `text` gives, or what is wrong with it (one line).
pub fn layout_file(text: &str) -> Result<Vec<Array>, String> {
    let f: LayoutFile = serde_json::from_str(text).map_err(|e| {
        format!("{e}; give {{\"resource\": [{{\"kind\": \"storage_buffer\", \"first\": 0, \"count\": 128}}]}}")
    })?;
    if f.resource.is_empty() {
        return Err("no ranges: give at least one under \"resource\"".into());
    }
    let mut out: Vec<Array> = Vec::new();
    for r in &f.resource {
        if r.count == 0 || r.count > MAX_RANGE {
            return Err(format!(
                "a {:?} range of {} descriptors: give 1 to {MAX_RANGE}",
                r.kind, r.count
            ));
        }
        let clash = out.iter().find(|o| {
            let (First::Index(a), First::Index(b)) = (o.first, First::Index(r.first)) else {
                return false;
            };
            o.held == r.kind && a < b + r.count && b < a + o.count
        });
        if clash.is_some() {
            return Err(format!(
                "two {:?} ranges overlap at index {}: give each index once",
                r.kind, r.first
            ));
        }
        out.push(Array {
            first: First::Index(r.first),
            stride: Stride::Descriptor,
            held: r.kind,
            count: r.count,
        });
    }
    Ok(out)
}

/// Whether any of `modules` reads a descriptor heap (the `DescriptorHeapEXT` capability or a
/// heap built-in).
pub fn uses_heap(modules: &[UserModule]) -> bool {
    modules.iter().any(|m| {
        let h = &m.iface.reflection.heap;
        h.capability || h.resource || h.sampler
    })
}

/// The heap arrays `modules` index, one per distinct place, or why the layout cannot be told
/// from the modules.
pub fn arrays(modules: &[UserModule]) -> Result<Vec<Array>, HarnessError> {
    let mut out: Vec<Array> = Vec::new();
    for m in modules {
        for a in &m.iface.reflection.heap.accesses {
            let refuse = |why: String| HarnessError::Unsupported(format!("{}: {why}", m.name));
            if a.heap == HeapKind::Sampler {
                return Err(refuse(format!("reads the sampler heap ({}); the harness fills heap arrays of storage buffers, uniform buffers and acceleration structures", a.element)));
            }
            let held = match a.element.as_str() {
                "StorageBuffer buffer" => Held::StorageBuffer,
                "Uniform buffer" => Held::UniformBuffer,
                "acceleration structure" => Held::AccelerationStructure,
                other => return Err(refuse(format!("indexes a heap array of {other}; the harness fills heap arrays of storage buffers, uniform buffers and acceleration structures"))),
            };
            let stride = match &a.stride {
                HeapStride::Bytes(b) => Stride::Bytes(*b),
                HeapStride::SizeOf(_) => Stride::Descriptor,
                HeapStride::Unknown => return Err(refuse(format!("the heap layout cannot be told from the module: its {} array's stride is a spec constant or an expression; give the heap's ranges with --heap-layout FILE (docs/your-shader.md)", a.element))),
            };
            let array = Array {
                first: First::Byte(a.offset.unwrap_or(0)),
                stride,
                held,
                count: HEAP_ELEMENTS,
            };
            if let Some(o) = out.iter().find(|o| o.first == array.first && *o != &array) {
                return Err(refuse(format!("the heap layout cannot be told from the modules: one heap offset starts an array of {:?} and one of {:?}; give the heap's ranges with --heap-layout FILE (docs/your-shader.md)", o.held, array.held)));
            }
            if !out.contains(&array) {
                out.push(array);
            }
        }
    }
    Ok(out)
}

fn align(x: u64, a: u64) -> u64 {
    x.div_ceil(a.max(1)) * a.max(1)
}

/// The harness's heaps: the heap arrays' own buffers, the heaps, and the set/binding mapping.
pub struct HeapModel {
    buffers: Vec<Buffer>,
    pub heaps: PlacedHeaps,
    pub mapping: Box<PipelineMapping>,
}

/// The descriptor of element `e` of a set/binding binding of kind `kind`, and its view format;
/// a texture or sampler is not placed in a heap or descriptor buffer yet: an error saying so.
pub(super) fn target(e: &Element, kind: BindingKind) -> Result<(Target, vk::Format), HarnessError> {
    let format = match kind {
        BindingKind::StorageImage(f) => resources::format(f).map_or(vk::Format::UNDEFINED, |x| x.0),
        BindingKind::AccelerationStructure
        | BindingKind::StorageBuffer(_)
        | BindingKind::UniformBuffer(_)
        | BindingKind::SampledImage
        | BindingKind::Sampler
        | BindingKind::CombinedImageSampler => vk::Format::UNDEFINED,
    };
    let t = match e {
        Element::Tlas(raw, address) => Target::Accel { raw: *raw, address: *address },
        Element::Image(i) => {
            Target::Image { image: i.raw, view: i.view, sampler: vk::Sampler::null(), layers: None }
        }
        Element::Buffer(b) => Target::Buffer { raw: b.raw, address: b.address, range: b.size },
        Element::Texture(_) | Element::Sampler => {
            return Err(HarnessError::Unsupported("textures and samplers are bound with descriptor sets only for now: run without --descriptor-model (descriptor_indexing)".into()))
        }
    };
    Ok((t, format))
}

/// The set/binding descriptors of `bindings` placed after the heap arrays (which end at byte
/// `end`), each binding at a 256-byte aligned base: the mapping's (set, binding, base, stride).
fn place_bindings(
    gpu: &Gpu,
    bindings: &BTreeMap<(u32, u32), (Binding, Vec<Element>)>,
    mut end: u64,
    placed: &mut Vec<Placed>,
) -> Result<Vec<(u32, u32, u32, u32)>, HarnessError> {
    let mut entries = Vec::new();
    for ((set, binding), (b, elems)) in bindings {
        let ty = resources::descriptor_type(b.kind);
        let stride = descriptor_stride(gpu, ty);
        let base = align(end, 256);
        for (k, e) in elems.iter().enumerate() {
            let (target, format) = target(e, b.kind)?;
            let offset = (base + k as u64 * stride as u64) as usize;
            placed.push(Placed { offset, ty, target, format });
        }
        entries.push((*set, *binding, base as u32, stride));
        end = base + elems.len() as u64 * stride as u64;
    }
    Ok(entries)
}

impl HeapModel {
    /// Heaps for `arrays` (buffers numbered from `first_data`, so their data is their own) and
    /// the set/binding `bindings` after them, TLASes from `scene`.
    pub fn new(
        gpu: &Gpu,
        arrays: &[Array],
        bindings: &BTreeMap<(u32, u32), (Binding, Vec<Element>)>,
        scene: &SceneGpu,
        (first_data, sink): (u32, u64),
    ) -> Result<HeapModel, HarnessError> {
        let mut placed = Vec::new();
        let mut buffers = Vec::new();
        let mut end = 0u64;
        let mut d = first_data;
        for a in arrays {
            let ty = a.held.descriptor_type();
            let stride = match a.stride {
                Stride::Bytes(b) => b,
                Stride::Descriptor => descriptor_stride(gpu, ty),
            };
            let start = match a.first {
                First::Byte(b) => b,
                First::Index(i) => i * descriptor_stride(gpu, ty),
            };
            for k in 0..a.count {
                let offset = start as usize + (k * stride) as usize;
                let target = match a.held {
                    Held::AccelerationStructure => Target::Accel {
                        raw: scene.scene_tlas.raw,
                        address: scene.scene_tlas.address,
                    },
                    Held::StorageBuffer | Held::UniformBuffer => {
                        let size = if a.held == Held::UniformBuffer {
                            UNIFORM_BYTES
                        } else {
                            STORAGE_BYTES
                        };
                        let usage = vk::BufferUsageFlags::STORAGE_BUFFER
                            | vk::BufferUsageFlags::UNIFORM_BUFFER
                            | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS;
                        let b =
                            Buffer::new(gpu, size as u64, usage, Location::Host, "heap buffer")?;
                        b.write(0, &resources::buffer_data(d, size, &Default::default(), sink));
                        d += 1;
                        let t =
                            Target::Buffer { raw: b.raw, address: b.address, range: size as u64 };
                        buffers.push(b);
                        t
                    }
                };
                placed.push(Placed { offset, ty, target, format: vk::Format::UNDEFINED });
            }
            end = end.max(start as u64 + (a.count * stride) as u64);
        }
        let made = place_bindings(gpu, bindings, end, &mut placed)
            .and_then(|entries| Ok((PlacedHeaps::create(gpu, &placed)?, entries)));
        let (heaps, entries) = match made {
            Ok(m) => m,
            Err(e) => {
                for b in &buffers {
                    b.destroy(gpu);
                }
                return Err(e);
            }
        };
        Ok(HeapModel { buffers, heaps, mapping: PipelineMapping::constant_offsets(&entries) })
    }

    pub fn destroy(&self, gpu: &Gpu) {
        self.heaps.destroy(gpu);
        for b in &self.buffers {
            b.destroy(gpu);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn heap_module(glsl: &str) -> Option<UserModule> {
        match crate::shadergen::glslang::compile_with(
            "h.rchit",
            "rchit",
            glsl,
            "GL_EXT_descriptor_heap",
            &["--target-env", "vulkan1.3"],
        ) {
            Ok(w) => Some(UserModule::new("h.rchit", &w).unwrap()),
            Err(e) => {
                eprintln!("skipped: {e}");
                None
            }
        }
    }

    const HEAD: &str = "#version 460\n#extension GL_EXT_ray_tracing : require\n\
        #extension GL_EXT_nonuniform_qualifier : require\n\
        #extension GL_EXT_descriptor_heap : require\n\
        layout(location = 0) rayPayloadInEXT vec4 c;\n";

    /// A closest-hit reading a storage-buffer heap array by its instance's custom index.
    const MATS: &str = "layout(descriptor_heap) readonly buffer M { vec4 v[]; } mats[];\n\
        void main() { c = mats[nonuniformEXT(gl_InstanceCustomIndexEXT)].v[0]; }\n";

    /// A storage-buffer heap array strides by the device's descriptor size from heap byte 0.
    #[test]
    fn a_buffer_heap_array_is_laid_out_from_the_module() {
        let glsl = format!("{HEAD}{MATS}");
        let Some(m) = heap_module(&glsl) else { return };
        let ms = std::slice::from_ref(&m);
        assert!(uses_heap(ms));
        assert_eq!(
            arrays(ms).unwrap(),
            vec![Array {
                first: First::Byte(0),
                stride: Stride::Descriptor,
                held: Held::StorageBuffer,
                count: HEAP_ELEMENTS
            }]
        );
    }

    /// A `--heap-layout` file's ranges, and its twins: a bad kind, an empty or oversized range,
    /// overlapping ranges, an unknown field, each one line.
    #[test]
    fn heap_layout_files_give_ranges_or_one_line() {
        let a = layout_file(
            r#"{"resource": [{"kind": "storage_buffer", "first": 4, "count": 64},
            {"kind": "acceleration_structure", "first": 0, "count": 2}]}"#,
        )
        .unwrap();
        assert_eq!(a[0].first, First::Index(4));
        assert_eq!((a[0].held, a[0].count), (Held::StorageBuffer, 64));
        assert_eq!(a[1].held, Held::AccelerationStructure);
        for bad in [
            r#"{"resource": [{"kind": "texture", "first": 0, "count": 1}]}"#,
            r#"{"resource": [{"kind": "storage_buffer", "first": 0, "count": 0}]}"#,
            r#"{"resource": [{"kind": "storage_buffer", "first": 0, "count": 99999}]}"#,
            r#"{"resource": [{"kind": "storage_buffer", "first": 0, "count": 8},
                {"kind": "storage_buffer", "first": 7, "count": 8}]}"#,
            r#"{"resource": [{"kind": "storage_buffer", "first": 0, "count": 8, "stride": 3}]}"#,
            r#"{"resource": []}"#,
            "not json",
        ] {
            let e = layout_file(bad).unwrap_err();
            assert!(!e.contains('\n'), "{e}");
        }
    }

    /// Twin: a sampler heap (or a sampled image array) is refused in one line naming the module.
    #[test]
    fn a_sampler_heap_is_refused_naming_the_module() {
        let glsl = format!(
            "{HEAD}layout(descriptor_heap) uniform texture2D texs[];\n\
            layout(descriptor_heap) uniform sampler samps[];\n\
            void main() {{ c = textureLod(sampler2D(texs[gl_InstanceCustomIndexEXT], samps[0]), vec2(0.5), 0.0); }}\n"
        );
        let Some(m) = heap_module(&glsl) else { return };
        let e = arrays(std::slice::from_ref(&m)).unwrap_err().to_string();
        assert!(e.starts_with("h.rchit: "), "{e}");
        assert!(!e.contains('\n'), "{e}");
    }

    /// The twin of the inferred layout: a stride the module does not state (a spec constant
    /// put in place of `OpConstantSizeOfEXT`) is one line naming `--heap-layout`.
    #[test]
    fn a_stride_the_module_does_not_state_names_heap_layout() {
        use rspirv::dr::{Instruction, Operand};
        use rspirv::spirv::{Decoration, Op};
        let glsl = format!("{HEAD}{MATS}");
        let Some(m) = heap_module(&glsl) else { return };
        let mut module = crate::patches::load(&crate::tools::spirv::bytes(&m.words)).unwrap();
        let uint = module
            .types_global_values
            .iter()
            .find(|i| {
                i.class.opcode == Op::TypeInt
                    && i.operands == [Operand::LiteralBit32(32), Operand::LiteralBit32(0)]
            })
            .and_then(|i| i.result_id)
            .unwrap();
        let header = module.header.as_mut().unwrap();
        let spec = header.bound;
        header.bound += 1;
        module.types_global_values.push(Instruction::new(
            Op::SpecConstant,
            Some(uint),
            Some(spec),
            vec![Operand::LiteralBit32(16)],
        ));
        let stride = module
            .annotations
            .iter_mut()
            .find(|i| i.operands.get(1) == Some(&Operand::Decoration(Decoration::ArrayStrideIdEXT)))
            .unwrap();
        stride.operands[2] = Operand::IdRef(spec);
        let words = crate::patches::assemble(&module);
        let odd = UserModule::new("h.rchit", &words).unwrap();
        let e = arrays(std::slice::from_ref(&odd)).unwrap_err().to_string();
        assert!(e.contains("--heap-layout FILE") && e.contains("stride"), "{e}");
        assert!(!e.contains('\n'), "{e}");
        // The module as compiled is laid out.
        assert!(arrays(std::slice::from_ref(&m)).is_ok());
    }

    /// A set/binding module uses no heap.
    #[test]
    fn a_set_binding_module_uses_no_heap() {
        let words = crate::patches::assemble(&crate::patches::compiled(
            shaderc::ShaderKind::ClosestHit,
            "t",
            "#version 460\n#extension GL_EXT_ray_tracing : require\n\
            layout(set = 0, binding = 0) buffer B { vec4 v; } b;\n\
            layout(location = 0) rayPayloadInEXT vec4 c;\nvoid main() { c = b.v; }\n",
        ));
        let m = UserModule::new("t.rchit", &words).unwrap();
        assert!(!uses_heap(std::slice::from_ref(&m)));
        assert!(arrays(std::slice::from_ref(&m)).unwrap().is_empty());
    }
}
