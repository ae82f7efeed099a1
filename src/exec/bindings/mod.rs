//! Binding the cell's descriptors under each descriptor model: `descriptor_indexing` (a descriptor
//! set with a runtime-sized, partially bound, update-after-bind array where the device allows) and
//! `descriptor_buffer` (VK_EXT_descriptor_buffer: descriptors written with vkGetDescriptorEXT into
//! a buffer) and `descriptor_heap` (VK_EXT_descriptor_heap, in [`super::heap`]). Binding 0 is the
//! records SSBO, 1 the scene TLAS, 2 the probed array.
//!
//! Files: the layout key bindings are cached by (`key`), the set and pipeline layouts (`layout`),
//! the descriptor set of `descriptor_indexing` (`set`) and the descriptor buffer of
//! `descriptor_buffer` (`buffer`); here the binding of each model, bound and pushed to.
mod buffer;
mod key;
mod layout;
mod set;

pub use buffer::write as write_descriptor_buffer;
pub use key::LayoutKey;
pub use layout::PUSH_CONSTANT_BYTES;

use super::heap::HeapBinding;
use super::resources::Target;
use crate::model::{DescriptorModel, Resource};
use crate::vk::memory::Buffer;
use crate::vk::{Gpu, VkError};
use ash::vk;
use layout::{binding_flags, digest, pipeline_layout, set_layout};

/// What holds a binding's descriptors under its model.
enum Bound {
    Set {
        pool: vk::DescriptorPool,
        set: vk::DescriptorSet,
    },
    /// `usage`: the descriptor-buffer usage the layout needs (SAMPLER only with samplers).
    Buffer {
        buffer: Buffer,
        usage: vk::BufferUsageFlags,
    },
    /// Resource and sampler heaps; no set layout, no pipeline layout (both null).
    Heap(HeapBinding),
}

pub struct Binding {
    pub set_layout: vk::DescriptorSetLayout,
    pub pipeline_layout: vk::PipelineLayout,
    /// The layouts' contents hashed (`layout::digest`; 0 for the heap model, which has none).
    pub digest: u128,
    bound: Bound,
}

impl Binding {
    /// `targets[b]` are the descriptors of binding `b` (records, scene TLAS, probe array) and
    /// their kind, in the order of the layout's bindings.
    pub fn create(
        gpu: &Gpu,
        key: LayoutKey,
        targets: &[(u32, Resource, Vec<Target>)],
    ) -> Result<Binding, VkError> {
        if key.model == DescriptorModel::DescriptorHeap {
            return Self::create_heap(gpu, key, targets);
        }
        let flags = binding_flags(gpu, key, targets);
        let uab = flags.iter().any(|f| f.contains(vk::DescriptorBindingFlags::UPDATE_AFTER_BIND));
        let digest = digest(key, targets, &flags, uab);
        let set_layout = set_layout(gpu, key, targets, &flags, uab)?;
        let pipeline_layout = pipeline_layout(gpu, key.stages, set_layout)?;
        let bound = match key.model {
            DescriptorModel::DescriptorIndexing => {
                let (pool, set) = set::write(gpu, set_layout, uab, targets)?;
                Bound::Set { pool, set }
            }
            DescriptorModel::DescriptorBuffer => {
                let (buffer, usage) = buffer::write(gpu, set_layout, targets)?;
                Bound::Buffer { buffer, usage }
            }
            DescriptorModel::DescriptorHeap => {
                unreachable!("the plan never runs descriptor_heap cells")
            }
        };
        Ok(Binding { set_layout, pipeline_layout, digest, bound })
    }

    /// The heap model's binding: resource and sampler heaps, no set or pipeline layout.
    fn create_heap(
        gpu: &Gpu,
        key: LayoutKey,
        targets: &[(u32, Resource, Vec<Target>)],
    ) -> Result<Binding, VkError> {
        let heap = HeapBinding::create(
            gpu,
            targets,
            &super::samplers::heap_sampler_infos(),
            key.heap_direct,
        )?;
        Ok(Binding {
            set_layout: vk::DescriptorSetLayout::null(),
            pipeline_layout: vk::PipelineLayout::null(),
            digest: 0,
            bound: Bound::Heap(heap),
        })
    }

    pub fn bind(&self, gpu: &Gpu, cmd: vk::CommandBuffer, point: vk::PipelineBindPoint) {
        match &self.bound {
            Bound::Set { set, .. } => unsafe {
                gpu.device.cmd_bind_descriptor_sets(
                    cmd,
                    point,
                    self.pipeline_layout,
                    0,
                    &[*set],
                    &[],
                )
            },
            Bound::Buffer { buffer, usage } => {
                let db = gpu.descriptor_buffer.as_ref().expect("descriptor buffer enabled");
                let info = [vk::DescriptorBufferBindingInfoEXT::default()
                    .address(buffer.address)
                    .usage(*usage)];
                unsafe {
                    db.cmd_bind_descriptor_buffers(cmd, &info);
                    db.cmd_set_descriptor_buffer_offsets(
                        cmd,
                        point,
                        self.pipeline_layout,
                        0,
                        &[0],
                        &[0],
                    );
                }
            }
            Bound::Heap(h) => h.bind(gpu, cmd),
        }
    }

    /// The probes' push block: push constants, or push data under the heap model.
    pub fn push(&self, gpu: &Gpu, cmd: vk::CommandBuffer, stages: vk::ShaderStageFlags, pc: &[u8]) {
        match &self.bound {
            Bound::Set { .. } | Bound::Buffer { .. } => unsafe {
                gpu.device.cmd_push_constants(cmd, self.pipeline_layout, stages, 0, pc)
            },
            Bound::Heap(h) => h.push(gpu, cmd, pc),
        }
    }

    /// Where the descriptors sit in the resource heap (heap model only).
    pub fn heap_layout(&self) -> Option<super::heap::HeapLayout> {
        match &self.bound {
            Bound::Heap(h) => Some(h.layout),
            Bound::Set { .. } | Bound::Buffer { .. } => None,
        }
    }

    pub fn destroy(&self, gpu: &Gpu) {
        unsafe {
            match &self.bound {
                Bound::Set { pool, .. } => gpu.device.destroy_descriptor_pool(*pool, None),
                Bound::Buffer { buffer, .. } => buffer.destroy(gpu),
                Bound::Heap(h) => h.destroy(gpu),
            }
            gpu.device.destroy_pipeline_layout(self.pipeline_layout, None);
            gpu.device.destroy_descriptor_set_layout(self.set_layout, None);
        }
    }
}
