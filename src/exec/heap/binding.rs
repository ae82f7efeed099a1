//! A cell's two descriptor heaps: the resource heap and the sampler heap created, written and
//! bound (vkCmdBind{Resource,Sampler}HeapEXT), with the buffer holding the probed array's heap
//! index that `mapped_indirect_index` reads, and the push data recorded; and heaps of descriptors
//! at given places ([`PlacedHeaps`], `run --shader`'s heap model) made and bound the same way.
use super::layout::{align, HeapLayout};
use super::push;
use super::sizes::{fns, props, Sizes};
use super::write::{write_samplers, Placed, ResourceWrites};
use crate::exec::resources::{descriptor_type, Target};
use crate::model::Resource;
use crate::vk::heap as h;
use crate::vk::memory::{Buffer, Location};
use crate::vk::{Gpu, VkError};
use ash::vk;

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

/// The resource heap of `bytes` and the sampler heap of `samplers`, both created (neither left
/// behind on an error).
fn heaps(
    gpu: &Gpu,
    sizes: &Sizes,
    bytes: &[u8],
    samplers: &[vk::SamplerCreateInfo],
) -> Result<(Heap, Heap), VkError> {
    let p = &sizes.p;
    let resources = Heap::create(
        gpu,
        bytes,
        p.resource_heap_alignment,
        p.min_resource_heap_reserved_range,
        "resource heap",
    )?;
    let samplers = write_samplers(sizes, samplers).and_then(|sbytes| {
        Heap::create(
            gpu,
            &sbytes,
            p.sampler_heap_alignment.max(p.sampler_descriptor_alignment),
            p.min_sampler_heap_reserved_range,
            "sampler heap",
        )
    });
    match samplers {
        Ok(s) => Ok((resources, s)),
        Err(e) => {
            resources.buffer.destroy(gpu);
            Err(e)
        }
    }
}

/// vkCmdBindResourceHeapEXT and vkCmdBindSamplerHeapEXT of `resources` and `samplers`.
fn bind_heaps(gpu: &Gpu, cmd: vk::CommandBuffer, resources: &Heap, samplers: &Heap) {
    let f = fns(gpu);
    // SAFETY: valid command buffer in the recording state; the infos are plain values.
    unsafe {
        (f.cmd_bind_resource_heap)(cmd, &resources.bind);
        (f.cmd_bind_sampler_heap)(cmd, &samplers.bind);
    }
}

/// The stride of an array of `ty` descriptors in a heap on this device: its class's descriptor
/// size (what `OpConstantSizeOfEXT` of the type is), never less than what a write fills.
pub fn descriptor_stride(gpu: &Gpu, ty: vk::DescriptorType) -> u32 {
    let sizes = Sizes { gpu, p: props(gpu), f: fns(gpu) };
    sizes.class(ty).max(sizes.written(ty)).max(1)
}

/// Heaps of descriptors at given places, for a pipeline not made from a cell (`run --shader`):
/// the same heap creation, descriptor writes and binding as a cell's [`HeapBinding`], the
/// sampler heap empty.
pub struct PlacedHeaps {
    resources: Heap,
    samplers: Heap,
}

impl PlacedHeaps {
    pub fn create(gpu: &Gpu, placed: &[Placed]) -> Result<PlacedHeaps, VkError> {
        let sizes = Sizes { gpu, p: props(gpu), f: fns(gpu) };
        let bytes = ResourceWrites::placed(&sizes, placed).write(&sizes)?;
        let (resources, samplers) = heaps(gpu, &sizes, &bytes, &[])?;
        tracing::debug!(descriptors = placed.len(), bytes = bytes.len(), "placed heaps written");
        Ok(PlacedHeaps { resources, samplers })
    }

    pub fn bind(&self, gpu: &Gpu, cmd: vk::CommandBuffer) {
        bind_heaps(gpu, cmd, &self.resources, &self.samplers);
    }

    /// `data` as push data at offset 0 (what push-constant blocks read in a heap pipeline).
    pub fn push(&self, gpu: &Gpu, cmd: vk::CommandBuffer, data: &[u8]) {
        push::push(gpu, cmd, data);
    }

    pub fn destroy(&self, gpu: &Gpu) {
        self.resources.buffer.destroy(gpu);
        self.samplers.buffer.destroy(gpu);
    }
}

pub struct HeapBinding {
    resources: Heap,
    samplers: Heap,
    /// Holds the probed array's heap index (`mapped_indirect_index` reads it through its address).
    index: Buffer,
    pub layout: HeapLayout,
}

/// The resource heap's layout for `targets` on this device: records and TLAS slots of the largest
/// buffer / image descriptor (aligned), the probed array (binding 2) at its class's stride.
fn heap_layout(
    sizes: &Sizes,
    targets: &[(u32, Resource, Vec<Target>)],
    direct: bool,
) -> HeapLayout {
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
    let stride = sizes.class(probe_ty).max(sizes.written(probe_ty)).max(1);
    HeapLayout::new(slot, stride, probe_count, direct)
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
        let layout = heap_layout(&sizes, targets, direct);
        let bytes = ResourceWrites::of(&sizes, targets, &layout).write(&sizes)?;
        let (resources, samplers) = heaps(gpu, &sizes, &bytes, samplers)?;
        let index_usage =
            vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS;
        let index = match Buffer::with_data(
            gpu,
            &layout.probe_index().to_le_bytes(),
            index_usage,
            "heap index",
        ) {
            Ok(b) => b,
            Err(e) => {
                resources.buffer.destroy(gpu);
                samplers.buffer.destroy(gpu);
                return Err(e);
            }
        };
        tracing::debug!(?layout, "descriptor heaps written");
        Ok(HeapBinding { resources, samplers, index, layout })
    }

    pub fn bind(&self, gpu: &Gpu, cmd: vk::CommandBuffer) {
        bind_heaps(gpu, cmd, &self.resources, &self.samplers);
    }

    /// The probes' push block, the probed array's heap index and the address of the buffer
    /// holding it, as push data.
    pub fn push(&self, gpu: &Gpu, cmd: vk::CommandBuffer, pc: &[u8]) {
        push::push(gpu, cmd, &push::bytes(pc, self.layout.probe_index(), self.index.address));
    }

    pub fn destroy(&self, gpu: &Gpu) {
        self.resources.buffer.destroy(gpu);
        self.samplers.buffer.destroy(gpu);
        self.index.destroy(gpu);
    }
}
