//! The `descriptor_heap` binding path (VK_EXT_descriptor_heap). The cell's set/binding shaders
//! reach a resource heap and a sampler heap through VkShaderDescriptorSetAndBindingMappingInfoEXT
//! chained to every shader stage ("mapped"); `direct` cells read the probed array straight from
//! the heap (`layout(descriptor_heap)`), with only the records and scene TLAS mapped.
//!
//! The resource heap is a buffer with the descriptor-heap usage ([`HeapLayout`]): the records SSBO
//! (binding 0) and the scene TLAS (binding 1) in `slot`-byte slots (the largest buffer / image
//! descriptor, aligned), and the probed array (binding 2) with the stride of its own descriptor
//! type — the stride `layout(descriptor_heap)` arrays index with (OpConstantSizeOfEXT) — then the
//! driver's reserved range. Mapped cells: records at 0, TLAS at `slot`, the array at
//! an index of its stride past them. Direct cells: the array at 0 (so the shader's own index is the
//! heap index, as in the original engine's `heap[base + gl_InstanceCustomIndexEXT]`), records and
//! TLAS after it. The sampler heap holds the probes' samplers (`probe::SAMPLER_MODES`; sampler 0
//! at offset 0 is the one mapped combined image samplers use, direct probes index them with the
//! sampler class's descriptor size as stride), then its reserved range.
//! Descriptors are written with vkWriteResourceDescriptorsEXT / vkWriteSamplerDescriptorsEXT, both
//! heaps bound with vkCmdBind{Resource,Sampler}HeapEXT, and push constants are push data
//! (vkCmdPushDataEXT): the probes' block (`probe::PushConstants`) at offset 0, the probed array's heap index at
//! [`PUSH_INDEX_OFFSET`], and at [`PUSH_INDEX_ADDRESS_OFFSET`] the address of a buffer holding the
//! same index.
//!
//! Bindings 0 and 1 are always HEAP_WITH_CONSTANT_OFFSET. Binding 2 follows the cell's
//! `heap_access`: a constant offset, HEAP_WITH_PUSH_INDEX (the index read from push data),
//! HEAP_WITH_INDIRECT_INDEX (read from the buffer whose address is in push data) or
//! HEAP_WITH_SHADER_RECORD_INDEX (read from the first 4 bytes of every SBT record's shader record
//! data). All ways must read the same descriptors.
use super::resources::{descriptor_type, Target};
use crate::model::{HeapAccess, Resource};
use crate::probe::spec::{Access, ArrayAt, ProbeSpec, Sampler};
use crate::probe::PUSH_CONSTANT_BYTES;
use crate::vk::features::PROBE_IMAGE_FORMAT;
use crate::vk::heap::{self as h, MappingSource};
use crate::vk::memory::{Buffer, Location};
use crate::vk::{Gpu, VkError, VkResultExt};
use ash::vk;
use std::ffi::c_void;

/// Push-data offset of the probed array's heap index (right after the probes' push block).
pub const PUSH_INDEX_OFFSET: u32 = PUSH_CONSTANT_BYTES;
/// Push-data offset of the address of the buffer holding that index (`mapped_indirect_index`).
pub const PUSH_INDEX_ADDRESS_OFFSET: u32 = PUSH_CONSTANT_BYTES + 8;

fn align(x: u64, a: u64) -> u64 {
    x.div_ceil(a.max(1)) * a.max(1)
}

/// One bound heap: its buffer and what vkCmdBind*HeapEXT takes.
struct Heap {
    buffer: Buffer,
    bind: h::BindHeapInfo,
}

impl Heap {
    /// A heap buffer of `used` bytes plus the driver's reserved range, its address aligned to
    /// `alignment`; `bytes` (the descriptors) are written at the start.
    fn create(
        gpu: &Gpu,
        bytes: &[u8],
        alignment: u64,
        reserved: u64,
        what: &'static str,
    ) -> Result<Heap, VkError> {
        let reserved_offset = align(bytes.len() as u64, alignment.max(1));
        let size = reserved_offset + reserved;
        let usage = h::BUFFER_USAGE_DESCRIPTOR_HEAP | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS;
        let buffer = Buffer::new(gpu, size + alignment, usage, Location::Host, what)?;
        let base = align(buffer.address, alignment);
        buffer.write((base - buffer.address) as usize, bytes);
        let bind = h::BindHeapInfo {
            s_type: h::STRUCTURE_TYPE_BIND_HEAP_INFO_EXT,
            p_next: std::ptr::null(),
            heap_range: h::DeviceAddressRange { address: base, size },
            reserved_range_offset: reserved_offset,
            reserved_range_size: reserved,
        };
        Ok(Heap { buffer, bind })
    }
}

/// Where the descriptors sit in the resource heap (bytes).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HeapLayout {
    pub records: u32,
    pub tlas: u32,
    /// The probed array's element 0, and its stride (the descriptor size of its type).
    pub probe: u32,
    pub probe_stride: u32,
}

impl HeapLayout {
    /// `slot`: bytes per records / TLAS slot; `probe_stride`: the probed type's descriptor size;
    /// `probe_count`: elements of the probed array; `direct`: the array first (see the module doc).
    pub fn new(slot: u32, probe_stride: u32, probe_count: u32, direct: bool) -> HeapLayout {
        if direct {
            let records = align((probe_count * probe_stride) as u64, slot as u64) as u32;
            HeapLayout { records, tlas: records + slot, probe: 0, probe_stride }
        } else {
            // After records and TLAS, one unused descriptor, so an index off by one reads zeros.
            let index = (2 * slot).div_ceil(probe_stride.max(1)) + 1;
            HeapLayout { records: 0, tlas: slot, probe: index * probe_stride, probe_stride }
        }
    }

    /// The heap index of the probed array's element 0 in units of its stride (what push data or
    /// the shader record holds for the index-sourced mappings).
    pub fn probe_index(&self) -> u32 {
        self.probe / self.probe_stride.max(1)
    }

    fn offset(&self, binding: u32, element: usize) -> usize {
        match binding {
            0 => self.records as usize,
            1 => self.tlas as usize,
            _ => self.probe as usize + element * self.probe_stride as usize,
        }
    }
}

pub struct HeapBinding {
    resources: Heap,
    samplers: Heap,
    /// Holds the probed array's heap index (`mapped_indirect_index` reads it through its address).
    index: Buffer,
    pub layout: HeapLayout,
}

fn props(gpu: &Gpu) -> h::PhysicalDeviceDescriptorHeapPropertiesEXT {
    gpu.info.properties.descriptor_heap.unwrap_or_default()
}

fn fns(gpu: &Gpu) -> &h::HeapFns {
    gpu.heap.as_ref().expect("descriptor heap enabled for heap cells (worker::requirements)")
}

/// A descriptor type as the heaps hold it: heaps have no combined descriptors, a sampled image's
/// image goes to the resource heap, its sampler to the sampler heap.
fn heap_type(ty: vk::DescriptorType) -> vk::DescriptorType {
    if ty == vk::DescriptorType::COMBINED_IMAGE_SAMPLER {
        vk::DescriptorType::SAMPLED_IMAGE
    } else {
        ty
    }
}

/// The device's descriptor sizes, and the commands that write descriptors.
struct Sizes<'a> {
    gpu: &'a Gpu,
    p: h::PhysicalDeviceDescriptorHeapPropertiesEXT,
    f: &'a h::HeapFns,
}

impl Sizes<'_> {
    /// How many bytes a descriptor write fills: vkGetPhysicalDeviceDescriptorSizeEXT ("for
    /// tools"; only those bytes are written and read).
    fn written(&self, ty: vk::DescriptorType) -> u32 {
        unsafe { (self.f.get_descriptor_size)(self.gpu.info.raw, heap_type(ty)) as u32 }
    }

    /// The stride of a descriptor array in the heap is its class's descriptor size: buffers and
    /// acceleration structures (address ranges) `bufferDescriptorSize`, images
    /// `imageDescriptorSize`. A shader reading the heap directly strides by
    /// `OpConstantSizeOfEXT` of the type, which is that class size, not the exact size above
    /// (on lavapipe 26 an AS descriptor is 8 bytes, the buffer class 16).
    fn class(&self, ty: vk::DescriptorType) -> u32 {
        let p = &self.p;
        (match heap_type(ty) {
            vk::DescriptorType::SAMPLED_IMAGE | vk::DescriptorType::STORAGE_IMAGE => {
                p.image_descriptor_size
            }
            vk::DescriptorType::SAMPLER => p.sampler_descriptor_size,
            _ => p.buffer_descriptor_size,
        }) as u32
    }
}

/// The resource descriptors to write: what each describes (`kinds`: type, image or not, index
/// into `views` or `ranges`) and where it goes (`at`: offset and size). The write infos point
/// into these, so they live until the write call.
#[derive(Default)]
struct ResourceWrites {
    ranges: Vec<h::DeviceAddressRange>,
    views: Vec<vk::ImageViewCreateInfo<'static>>,
    kinds: Vec<(vk::DescriptorType, bool, usize)>,
    at: Vec<(usize, usize)>,
}

impl ResourceWrites {
    fn of(
        sizes: &Sizes,
        targets: &[(u32, Resource, Vec<Target>)],
        layout: &HeapLayout,
    ) -> ResourceWrites {
        let mut w = ResourceWrites::default();
        for (b, kind, ts) in targets {
            let ty = &descriptor_type(*kind);
            for (i, t) in ts.iter().enumerate() {
                w.at.push((layout.offset(*b, i), sizes.written(*ty) as usize));
                match *t {
                    Target::Buffer { address, range, .. } => {
                        w.ranges.push(h::DeviceAddressRange { address, size: range });
                        w.kinds.push((heap_type(*ty), false, w.ranges.len() - 1));
                    }
                    // The range of an AS descriptor is unused and may be 0 (VkResourceDescriptorInfoEXT).
                    Target::Accel { address, .. } => {
                        w.ranges.push(h::DeviceAddressRange { address, size: 0 });
                        w.kinds.push((heap_type(*ty), false, w.ranges.len() - 1));
                    }
                    Target::Image { image, layers, .. } => {
                        w.views.push(
                            vk::ImageViewCreateInfo::default()
                                .image(image)
                                .view_type(crate::vk::memory::view_type(layers))
                                .format(PROBE_IMAGE_FORMAT)
                                .subresource_range(crate::vk::memory::layer_range(layers)),
                        );
                        w.kinds.push((heap_type(*ty), true, w.views.len() - 1));
                    }
                }
            }
        }
        w
    }

    /// The resource heap's bytes: every descriptor written at its place.
    fn write(&self, sizes: &Sizes) -> Result<Vec<u8>, VkError> {
        let end = self.at.iter().map(|(o, n)| o + n).max().unwrap_or(0);
        let mut bytes = vec![0u8; end];
        let images: Vec<h::ImageDescriptorInfo> = self
            .views
            .iter()
            .map(|v| h::ImageDescriptorInfo {
                s_type: h::STRUCTURE_TYPE_IMAGE_DESCRIPTOR_INFO_EXT,
                p_next: std::ptr::null(),
                p_view: v as *const _ as *const _,
                layout: vk::ImageLayout::GENERAL,
            })
            .collect();
        let infos: Vec<h::ResourceDescriptorInfo> = self
            .kinds
            .iter()
            .map(|&(ty, image, i)| h::ResourceDescriptorInfo {
                s_type: h::STRUCTURE_TYPE_RESOURCE_DESCRIPTOR_INFO_EXT,
                p_next: std::ptr::null(),
                ty,
                data: if image {
                    h::ResourceDescriptorData { p_image: &images[i] }
                } else {
                    h::ResourceDescriptorData { p_address_range: &self.ranges[i] }
                },
            })
            .collect();
        let base = bytes.as_mut_ptr();
        // SAFETY: every range lies inside `bytes` (its length is the largest end).
        let dst: Vec<h::HostAddressRange> = self
            .at
            .iter()
            .map(|&(o, n)| h::HostAddressRange {
                address: unsafe { base.add(o) } as *mut c_void,
                size: n,
            })
            .collect();
        // SAFETY: infos, their pointees and dst are alive and sized as declared.
        unsafe {
            (sizes.f.write_resource_descriptors)(
                sizes.gpu.device.handle(),
                infos.len() as u32,
                infos.as_ptr(),
                dst.as_ptr(),
            )
        }
        .result()
        .at("vkWriteResourceDescriptorsEXT")?;
        Ok(bytes)
    }
}

/// The sampler heap's bytes: `samplers` in order. A `sampler probeSampler[]` heap array strides
/// by OpConstantSizeOfEXT of the sampler type, its class's descriptor size
/// (`samplerDescriptorSize`), like the resource arrays; never less than what a write fills.
fn write_samplers(sizes: &Sizes, samplers: &[vk::SamplerCreateInfo]) -> Result<Vec<u8>, VkError> {
    let sampler_size = sizes.written(vk::DescriptorType::SAMPLER).max(1) as usize;
    let sampler_stride = sizes.class(vk::DescriptorType::SAMPLER).max(sampler_size as u32) as usize;
    let mut sbytes = vec![0u8; sampler_stride * (samplers.len().max(1) - 1) + sampler_size];
    let sbase = sbytes.as_mut_ptr();
    // SAFETY: sampler k's range [k * stride, k * stride + size) lies inside `sbytes`.
    let sdst: Vec<h::HostAddressRange> = (0..samplers.len())
        .map(|k| h::HostAddressRange {
            address: unsafe { sbase.add(k * sampler_stride) } as *mut c_void,
            size: sampler_size,
        })
        .collect();
    // SAFETY: one destination range per sampler info, all alive for the call.
    unsafe {
        (sizes.f.write_sampler_descriptors)(
            sizes.gpu.device.handle(),
            samplers.len() as u32,
            samplers.as_ptr(),
            sdst.as_ptr(),
        )
    }
    .result()
    .at("vkWriteSamplerDescriptorsEXT")?;
    Ok(sbytes)
}

impl HeapBinding {
    /// Write `targets[b]` (binding b's descriptors) into a new resource heap laid out for a
    /// `direct` or mapped cell, and `samplers` into a new sampler heap (in order, at the sampler
    /// stride).
    pub fn create(
        gpu: &Gpu,
        targets: &[(u32, Resource, Vec<Target>)],
        samplers: &[vk::SamplerCreateInfo],
        direct: bool,
    ) -> Result<HeapBinding, VkError> {
        let sizes = Sizes { gpu, p: props(gpu), f: fns(gpu) };
        let p = &sizes.p;
        let slot = align(
            p.buffer_descriptor_size.max(p.image_descriptor_size),
            p.buffer_descriptor_alignment.max(p.image_descriptor_alignment),
        ) as u32;
        let (probe_ty, probe_count) = targets
            .iter()
            .find(|(b, _, _)| *b == 2)
            .map(|(_, kind, t)| (descriptor_type(*kind), t.len() as u32))
            .unwrap_or((vk::DescriptorType::STORAGE_BUFFER, 0));
        let layout = HeapLayout::new(
            slot,
            sizes.class(probe_ty).max(sizes.written(probe_ty)).max(1),
            probe_count,
            direct,
        );

        let bytes = ResourceWrites::of(&sizes, targets, &layout).write(&sizes)?;
        let resources = Heap::create(
            gpu,
            &bytes,
            p.resource_heap_alignment,
            p.min_resource_heap_reserved_range,
            "resource heap",
        )?;
        let samplers = write_samplers(&sizes, samplers).and_then(|sbytes| {
            Heap::create(
                gpu,
                &sbytes,
                p.sampler_heap_alignment.max(p.sampler_descriptor_alignment),
                p.min_sampler_heap_reserved_range,
                "sampler heap",
            )
        });
        let index_usage =
            vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS;
        let index = samplers.and_then(|s| {
            match Buffer::with_data(
                gpu,
                &layout.probe_index().to_le_bytes(),
                index_usage,
                "heap index",
            ) {
                Ok(b) => Ok((s, b)),
                Err(e) => {
                    s.buffer.destroy(gpu);
                    Err(e)
                }
            }
        });
        let (samplers, index) = match index {
            Ok(x) => x,
            Err(e) => {
                resources.buffer.destroy(gpu);
                return Err(e);
            }
        };
        tracing::debug!(?layout, "descriptor heaps written");
        Ok(HeapBinding { resources, samplers, index, layout })
    }

    pub fn bind(&self, gpu: &Gpu, cmd: vk::CommandBuffer) {
        let f = fns(gpu);
        // SAFETY: valid command buffer in the recording state; the infos are plain values.
        unsafe {
            (f.cmd_bind_resource_heap)(cmd, &self.resources.bind);
            (f.cmd_bind_sampler_heap)(cmd, &self.samplers.bind);
        }
    }

    /// The probes' push block, the probed array's heap index and the address of the buffer
    /// holding it, as push data.
    pub fn push(&self, gpu: &Gpu, cmd: vk::CommandBuffer, pc: &[u8]) {
        let mut data = pc.to_vec();
        data.resize(PUSH_INDEX_OFFSET as usize, 0);
        data.extend_from_slice(&self.layout.probe_index().to_le_bytes());
        data.resize(PUSH_INDEX_ADDRESS_OFFSET as usize, 0);
        data.extend_from_slice(&self.index.address.to_le_bytes());
        let info = h::PushDataInfo {
            s_type: h::STRUCTURE_TYPE_PUSH_DATA_INFO_EXT,
            p_next: std::ptr::null(),
            offset: 0,
            data: h::HostAddressRangeConst {
                address: data.as_ptr() as *const c_void,
                size: data.len(),
            },
        };
        // SAFETY: `data` outlives the call, which copies it into the command buffer.
        unsafe { (fns(gpu).cmd_push_data)(cmd, &info) };
    }

    pub fn destroy(&self, gpu: &Gpu) {
        self.resources.buffer.destroy(gpu);
        self.samplers.buffer.destroy(gpu);
        self.index.destroy(gpu);
    }
}

/// A constant-offset mapping source: `heap_offset`, arrays at `stride`.
fn constant(heap_offset: u32, stride: u32) -> h::MappingSourceData {
    h::MappingSourceData {
        constant_offset: h::MappingConstantOffset {
            heap_offset,
            heap_array_stride: stride,
            p_embedded_sampler: std::ptr::null(),
            sampler_heap_offset: 0,
            sampler_heap_array_stride: 0,
        },
    }
}

/// Where binding 2 (the probed array) comes from for a cell reaching the heap `access`-wise, for
/// a heap laid out as `l`; `None` for direct cells (the probe reads the heap itself).
fn probe_source(
    access: HeapAccess,
    l: &HeapLayout,
) -> Option<(MappingSource, h::MappingSourceData)> {
    let stride = l.probe_stride;
    match access {
        HeapAccess::MappedConstantOffset => {
            Some((MappingSource::HeapWithConstantOffset, constant(l.probe, stride)))
        }
        HeapAccess::MappedPushIndex => Some((
            MappingSource::HeapWithPushIndex,
            h::MappingSourceData {
                push_index: h::MappingPushIndex {
                    heap_offset: 0,
                    push_offset: PUSH_INDEX_OFFSET,
                    heap_index_stride: stride,
                    heap_array_stride: stride,
                    p_embedded_sampler: std::ptr::null(),
                    use_combined_image_sampler_index: vk::FALSE,
                    sampler_heap_offset: 0,
                    sampler_push_offset: PUSH_INDEX_OFFSET,
                    sampler_heap_index_stride: 0,
                    sampler_heap_array_stride: 0,
                },
            },
        )),
        HeapAccess::MappedIndirectIndex => Some((
            MappingSource::HeapWithIndirectIndex,
            h::MappingSourceData {
                indirect_index: h::MappingIndirectIndex {
                    heap_offset: 0,
                    push_offset: PUSH_INDEX_ADDRESS_OFFSET,
                    address_offset: 0,
                    heap_index_stride: stride,
                    heap_array_stride: stride,
                    p_embedded_sampler: std::ptr::null(),
                    use_combined_image_sampler_index: vk::FALSE,
                    sampler_heap_offset: 0,
                    sampler_push_offset: PUSH_INDEX_ADDRESS_OFFSET,
                    sampler_address_offset: 0,
                    sampler_heap_index_stride: 0,
                    sampler_heap_array_stride: 0,
                },
            },
        )),
        HeapAccess::MappedShaderRecordIndex => Some((
            MappingSource::HeapWithShaderRecordIndex,
            h::MappingSourceData {
                shader_record_index: h::MappingShaderRecordIndex {
                    heap_offset: 0,
                    shader_record_offset: 0,
                    heap_index_stride: stride,
                    heap_array_stride: stride,
                    p_embedded_sampler: std::ptr::null(),
                    use_combined_image_sampler_index: vk::FALSE,
                    sampler_heap_offset: 0,
                    sampler_shader_record_offset: 0,
                    sampler_heap_index_stride: 0,
                    sampler_heap_array_stride: 0,
                },
            },
        )),
        HeapAccess::Direct => None,
    }
}

/// The set/binding → heap mapping every stage of a heap pipeline gets (boxed: the info points at
/// the mappings).
pub struct PipelineMapping {
    mappings: Vec<h::SetAndBindingMapping>,
    info: h::ShaderSetAndBindingMappingInfo,
}

impl PipelineMapping {
    /// The mapping of a cell reaching the heap `access`-wise, for a heap laid out as `l`. Direct
    /// cells map only the records and TLAS (the probe reads the heap itself).
    pub fn new(access: HeapAccess, l: &HeapLayout) -> Box<PipelineMapping> {
        let probe = probe_source(access, l);
        let mapping =
            |binding: u32, (source, source_data): (MappingSource, h::MappingSourceData)| {
                h::SetAndBindingMapping {
                    s_type: h::STRUCTURE_TYPE_DESCRIPTOR_SET_AND_BINDING_MAPPING_EXT,
                    p_next: std::ptr::null(),
                    descriptor_set: 0,
                    first_binding: binding,
                    binding_count: 1,
                    resource_mask: h::SPIRV_RESOURCE_TYPE_ALL,
                    source,
                    source_data,
                }
            };
        let mut mappings = vec![
            mapping(0, (MappingSource::HeapWithConstantOffset, constant(l.records, 0))),
            mapping(1, (MappingSource::HeapWithConstantOffset, constant(l.tlas, 0))),
        ];
        mappings.extend(probe.map(|p| mapping(2, p)));
        let mut b = Box::new(PipelineMapping {
            info: h::ShaderSetAndBindingMappingInfo {
                s_type: h::STRUCTURE_TYPE_SHADER_DESCRIPTOR_SET_AND_BINDING_MAPPING_INFO_EXT,
                p_next: std::ptr::null(),
                mapping_count: mappings.len() as u32,
                p_mappings: std::ptr::null(),
            },
            mappings,
        });
        b.info.p_mappings = b.mappings.as_ptr();
        b
    }

    /// What to chain to each VkPipelineShaderStageCreateInfo.
    pub fn stage_next(&self) -> *const c_void {
        &self.info as *const _ as *const c_void
    }
}

/// SPIR-V opcodes and enumerants the NonUniform check reads (SPIR-V 1.6 unified spec;
/// SPV_KHR_untyped_pointers; SPV_EXT_descriptor_heap).
const OP_LOAD: u32 = 61;
const OP_DECORATE: u32 = 71;
const OP_SAMPLED_IMAGE: u32 = 86;
const OP_UNTYPED_ACCESS_CHAIN: u32 = 4419;
const OP_UNTYPED_IN_BOUNDS_ACCESS_CHAIN: u32 = 4420;
const DECORATION_BUILTIN: u32 = 11;
const DECORATION_NON_UNIFORM: u32 = 5300;
const BUILTIN_SAMPLER_HEAP: u32 = 5122;
const BUILTIN_RESOURCE_HEAP: u32 = 5123;

/// The module's instructions as (opcode, operands), stopping at a malformed word count (0, or
/// past the end).
fn instructions(words: &[u32]) -> impl Iterator<Item = (u32, &[u32])> {
    let mut i = 5; // after the header
    std::iter::from_fn(move || {
        let first = *words.get(i)?;
        let (count, op) = ((first >> 16) as usize, first & 0xffff);
        if count == 0 {
            return None;
        }
        let operands = words.get(i + 1..i + count)?;
        i += count;
        Some((op, operands))
    })
}

/// How a module's accesses into one descriptor heap (`layout(descriptor_heap)` arrays:
/// `OpUntypedAccessChainKHR` / `OpUntypedInBoundsAccessChainKHR` on the variable decorated
/// `BuiltIn ResourceHeapEXT` / `SamplerHeapEXT`) are decorated: `None` without such an access,
/// `Some(true)` when every one has `NonUniform` on its index, on itself, on the descriptor loaded
/// through it or on the sampled image made from that (where SPIR-V 2.16.2 and
/// VUID-RuntimeSpirv-NonUniform-06274 accept it), `Some(false)` when one has none of these.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct HeapNonUniform {
    pub resource: Option<bool>,
    pub sampler: Option<bool>,
}

pub fn heap_nonuniform(words: &[u32]) -> HeapNonUniform {
    let mut nonuniform = std::collections::HashSet::new();
    let (mut resource_heap, mut sampler_heap) = (None, None);
    for (op, o) in instructions(words) {
        match (op, o) {
            (OP_DECORATE, [id, d, ..]) if *d == DECORATION_NON_UNIFORM => {
                nonuniform.insert(*id);
            }
            (OP_DECORATE, [id, d, b, ..])
                if *d == DECORATION_BUILTIN && *b == BUILTIN_RESOURCE_HEAP =>
            {
                resource_heap = Some(*id)
            }
            (OP_DECORATE, [id, d, b, ..])
                if *d == DECORATION_BUILTIN && *b == BUILTIN_SAMPLER_HEAP =>
            {
                sampler_heap = Some(*id)
            }
            _ => {}
        }
    }
    // What is made from an id: loads through a pointer, sampled images from an image or sampler.
    let mut made_from: std::collections::HashMap<u32, Vec<u32>> = std::collections::HashMap::new();
    for (op, o) in instructions(words) {
        match (op, o) {
            (OP_LOAD, [_, result, pointer, ..]) => {
                made_from.entry(*pointer).or_default().push(*result)
            }
            (OP_SAMPLED_IMAGE, [_, result, image, sampler]) => {
                made_from.entry(*image).or_default().push(*result);
                made_from.entry(*sampler).or_default().push(*result);
            }
            _ => {}
        }
    }
    let uses = |id: &u32| made_from.get(id).into_iter().flatten().copied().collect::<Vec<u32>>();
    let mut out = HeapNonUniform::default();
    for (op, o) in instructions(words) {
        // OpUntyped(InBounds)AccessChainKHR: result type, result, base type, base, indexes...
        if let (
            OP_UNTYPED_ACCESS_CHAIN | OP_UNTYPED_IN_BOUNDS_ACCESS_CHAIN,
            [_, result, _, base, first, ..],
        ) = (op, o)
        {
            let loads = uses(result);
            let sampled: Vec<u32> = loads.iter().flat_map(&uses).collect();
            let decorated = [*result, *first]
                .iter()
                .chain(&loads)
                .chain(&sampled)
                .any(|id| nonuniform.contains(id));
            let slot = if Some(*base) == resource_heap {
                &mut out.resource
            } else if Some(*base) == sampler_heap {
                &mut out.sampler
            } else {
                continue;
            };
            *slot = Some(slot.unwrap_or(true) && decorated);
        }
    }
    out
}

/// The heaps of a `direct` cell whose non-uniform index reached the driver without `NonUniform`
/// although the GLSL asked for it: the compiler dropped `nonuniformEXT` (glslang 16.6 does on
/// `layout(descriptor_heap)` arrays; reports/lavapipe-26/FINDINGS.md #3). The driver then saw an
/// undecorated non-uniform index, which the spec leaves undefined, so that part of the read is
/// judged as undefined (`reference::Undefined`: a descriptor index any element of the array, a
/// sampler index any of the heap's samplers).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DroppedNonUniform {
    pub resource: bool,
    pub sampler: bool,
}

impl DroppedNonUniform {
    pub fn note(&self) -> String {
        let which = match (self.resource, self.sampler) {
            (true, true) => "the resource and the sampler heap index",
            (true, false) => "the resource heap index",
            (false, _) => "the sampler heap index",
        };
        format!(
            "the GLSL compiler dropped nonuniformEXT on {which}: no NonUniform decoration reached the driver, so that index is judged as undefined ({}; {})",
            if self.resource { "any element of the array" } else { "any of the heap's samplers, slot and element exact" },
            crate::model::NO_NONUNIFORM_VUID
        )
    }
}

/// For a `direct` heap cell: which heap accesses lost the `nonuniformEXT` the GLSL gave them
/// (where the spec qualifies them: the descriptor index, the dynamic sampler index).
pub fn dropped_nonuniform(
    spec: &ProbeSpec,
    spirv: &[std::sync::Arc<Vec<u32>>],
) -> Option<DroppedNonUniform> {
    if spec.array != ArrayAt::Heap {
        return None;
    }
    let wants_resource = spec.access == (Access::Slot { nonuniform: true });
    let wants_sampler = spec.sampler == (Sampler::Dynamic { nonuniform: true });
    let scans: Vec<HeapNonUniform> = spirv.iter().map(|w| heap_nonuniform(w)).collect();
    let lost =
        |get: fn(&HeapNonUniform) -> Option<bool>| scans.iter().any(|h| get(h) == Some(false));
    let d = DroppedNonUniform {
        resource: wants_resource && lost(|h| h.resource),
        sampler: wants_sampler && lost(|h| h.sampler),
    };
    (d.resource || d.sampler).then_some(d)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nonuniform_decorations_are_found_and_their_absence_too() {
        // OpCapability Shader; %10 the resource heap; %30 = an access chain into it at index %20.
        let header = [0x0723_0203, 0x0001_0600, 0, 40, 0];
        let module = |decoration: &[u32]| -> Vec<u32> {
            let base = [
                (2 << 16) | 17,
                1,
                (4 << 16) | OP_DECORATE,
                10,
                DECORATION_BUILTIN,
                BUILTIN_RESOURCE_HEAP,
            ];
            header
                .iter()
                .chain(&base)
                .chain(decoration)
                .chain(&[(6 << 16) | OP_UNTYPED_ACCESS_CHAIN, 1, 30, 2, 10, 20])
                .copied()
                .collect()
        };
        // OpDecorate %20 NonUniform
        assert_eq!(
            heap_nonuniform(&module(&[(3 << 16) | OP_DECORATE, 20, DECORATION_NON_UNIFORM]))
                .resource,
            Some(true)
        );
        // OpDecorate %20 Binding 2... with a NonUniform-valued operand: must not count
        assert_eq!(
            heap_nonuniform(&module(&[(4 << 16) | OP_DECORATE, 20, 33, DECORATION_NON_UNIFORM]))
                .resource,
            Some(false)
        );
        assert_eq!(heap_nonuniform(&module(&[])).resource, Some(false));
        assert_eq!(heap_nonuniform(&header), HeapNonUniform::default());
        // a zero word count ends nowhere near an infinite loop
        assert_eq!(heap_nonuniform(&[0, 0, 0, 0, 0, 0, 0]), HeapNonUniform::default());
    }

    /// Per heap: an untyped access chain into the sampler heap whose index is decorated, one into
    /// the resource heap whose index is not (what glslang 16.6 emits when it keeps one qualifier
    /// and drops the other), and a module with no heap access at all.
    #[test]
    fn heap_accesses_are_judged_per_heap_by_their_own_decoration() {
        let header = [0x0723_0203, 0x0001_0600, 0, 40, 0];
        let decorate = |id: u32, d: u32, extra: &[u32]| -> Vec<u32> {
            [vec![((3 + extra.len() as u32) << 16) | OP_DECORATE, id, d], extra.to_vec()].concat()
        };
        let chain = |result: u32, base: u32, index: u32| {
            vec![(6 << 16) | OP_UNTYPED_ACCESS_CHAIN, 1, result, 2, base, index]
        };
        let module = |parts: Vec<Vec<u32>>| -> Vec<u32> {
            header.iter().copied().chain(parts.into_iter().flatten()).collect()
        };
        // %10 resource heap, %11 sampler heap; %20 / %21 indices; %30 / %31 chains.
        let builtins = vec![
            decorate(10, DECORATION_BUILTIN, &[BUILTIN_RESOURCE_HEAP]),
            decorate(11, DECORATION_BUILTIN, &[BUILTIN_SAMPLER_HEAP]),
        ];
        let m = module(
            [
                builtins.clone(),
                vec![decorate(21, DECORATION_NON_UNIFORM, &[])],
                vec![chain(30, 10, 20), chain(31, 11, 21)],
            ]
            .concat(),
        );
        assert_eq!(
            heap_nonuniform(&m),
            HeapNonUniform { resource: Some(false), sampler: Some(true) }
        );
        // decorated on the chain's result instead of the index counts too
        let m = module(
            [
                builtins.clone(),
                vec![decorate(30, DECORATION_NON_UNIFORM, &[])],
                vec![chain(30, 10, 20)],
            ]
            .concat(),
        );
        assert_eq!(heap_nonuniform(&m), HeapNonUniform { resource: Some(true), sampler: None });
        // a NonUniform elsewhere does not vouch for an undecorated heap access
        let m = module(
            [builtins, vec![decorate(99, DECORATION_NON_UNIFORM, &[])], vec![chain(31, 11, 21)]]
                .concat(),
        );
        assert!(instructions(&m).any(|(op, o)| op == OP_DECORATE && o[1] == DECORATION_NON_UNIFORM));
        assert_eq!(heap_nonuniform(&m), HeapNonUniform { resource: None, sampler: Some(false) });
        assert_eq!(heap_nonuniform(&header), HeapNonUniform::default());
        // decorated on the sampled image made from the loaded sampler (where the VUID wants it)
        let m = module(vec![
            decorate(11, DECORATION_BUILTIN, &[BUILTIN_SAMPLER_HEAP]),
            decorate(41, DECORATION_NON_UNIFORM, &[]),
            chain(31, 11, 21),
            vec![(4 << 16) | OP_LOAD, 3, 40, 31],
            vec![(5 << 16) | OP_SAMPLED_IMAGE, 4, 41, 39, 40],
        ]);
        assert_eq!(heap_nonuniform(&m), HeapNonUniform { resource: None, sampler: Some(true) });
        // truncated or zero word counts: no panic, no loop
        assert_eq!(
            heap_nonuniform(&[0x0723_0203, 0, 0, 0, 0, (9 << 16) | OP_UNTYPED_ACCESS_CHAIN, 1]),
            HeapNonUniform::default()
        );
        assert_eq!(heap_nonuniform(&[0x0723_0203, 0, 0, 0, 0, 0, 0, 0]), HeapNonUniform::default());
    }

    #[test]
    fn layouts_keep_descriptors_apart_and_index_sources_agree() {
        for direct in [false, true] {
            for (slot, stride) in [(64, 16), (64, 64), (64, 32), (256, 48)] {
                let l = HeapLayout::new(slot, stride, 17, direct);
                let probe_end = l.probe + 17 * stride;
                // records, TLAS and the probed array do not overlap
                assert!(l.records + slot <= l.tlas || l.tlas + slot <= l.records);
                for start in [l.records, l.tlas] {
                    assert!(start + slot <= l.probe || probe_end <= start, "{l:?}");
                }
                // an index-sourced mapping (index × stride) lands exactly on the array
                assert_eq!(l.probe_index() * stride, l.probe, "{l:?}");
                assert_eq!(direct, l.probe == 0);
            }
        }
    }
}
