//! `run --shader`'s descriptor buffer model (VK_EXT_descriptor_buffer): one descriptor buffer per
//! set of the pipeline's set/binding descriptors, written by `exec::bindings`'s descriptor-buffer
//! code (the matrix's: vkGetDescriptorEXT at each binding's offset in the set layout), bound
//! with vkCmdBindDescriptorBuffersEXT, each set at offset 0 of its buffer.
use super::error::HarnessError;
use super::heap::target;
use super::reflect::{Binding, BindingKind};
use super::resources::Element;
use crate::exec::bindings::write_descriptor_buffer;
use crate::exec::resources::Target;
use crate::model::Resource;
use crate::vk::memory::Buffer;
use crate::vk::Gpu;
use ash::vk;
use std::collections::BTreeMap;

/// The descriptor buffers: each set's number, buffer and usage.
pub struct DescriptorBuffers {
    sets: Vec<(u32, Buffer, vk::BufferUsageFlags)>,
}

/// The matrix's resource of a binding kind; textures and samplers are not written into
/// descriptor buffers yet (`heap::target` says so).
fn resource(kind: BindingKind) -> Option<Resource> {
    match kind {
        BindingKind::AccelerationStructure => Some(Resource::AccelerationStructure),
        BindingKind::StorageImage(_) => Some(Resource::StorageImage),
        BindingKind::StorageBuffer(_) => Some(Resource::StorageBuffer),
        BindingKind::UniformBuffer(_) => Some(Resource::UniformBuffer),
        BindingKind::SampledImage | BindingKind::Sampler | BindingKind::CombinedImageSampler => {
            None
        }
    }
}

impl DescriptorBuffers {
    /// A buffer for each set layout of `layouts` (by set number) that has bindings in `all`.
    pub fn new(
        gpu: &Gpu,
        layouts: &[vk::DescriptorSetLayout],
        all: &BTreeMap<(u32, u32), (Binding, Vec<Element>)>,
    ) -> Result<DescriptorBuffers, HarnessError> {
        let max = gpu
            .info
            .properties
            .descriptor_buffer
            .map_or(0, |p| p.max_resource_descriptor_buffer_bindings);
        let mut out = DescriptorBuffers { sets: Vec::new() };
        for (set, layout) in layouts.iter().enumerate() {
            let set = set as u32;
            let targets: Result<Vec<(u32, Resource, Vec<Target>)>, HarnessError> = all
                .iter()
                .filter(|(k, _)| k.0 == set)
                .map(|(k, (b, elems))| {
                    let ts: Result<Vec<Target>, HarnessError> =
                        elems.iter().map(|e| target(e, b.kind).map(|t| t.0)).collect();
                    let r = resource(b.kind).ok_or_else(|| HarnessError::Unsupported("textures and samplers are bound with descriptor sets only for now: run without --descriptor-model descriptor_buffer".into()))?;
                    Ok((k.1, r, ts?))
                })
                .collect();
            let targets = match targets {
                Ok(t) => t,
                Err(e) => {
                    out.destroy(gpu);
                    return Err(e);
                }
            };
            if targets.is_empty() {
                continue;
            }
            if out.sets.len() as u32 >= max {
                out.destroy(gpu);
                return Err(HarnessError::Unsupported(format!("the pipeline uses more descriptor sets than the device binds descriptor buffers (maxResourceDescriptorBufferBindings {max})")));
            }
            match write_descriptor_buffer(gpu, *layout, &targets) {
                Ok((buffer, usage)) => out.sets.push((set, buffer, usage)),
                Err(e) => {
                    out.destroy(gpu);
                    return Err(e.into());
                }
            }
        }
        Ok(out)
    }

    /// Bind every buffer, each set at offset 0 of its own.
    pub fn bind(&self, gpu: &Gpu, cmd: vk::CommandBuffer, layout: vk::PipelineLayout) {
        if self.sets.is_empty() {
            return;
        }
        let db = gpu.descriptor_buffer.as_ref().expect("descriptor buffer enabled");
        let infos: Vec<vk::DescriptorBufferBindingInfoEXT> = self
            .sets
            .iter()
            .map(|(_, b, usage)| {
                vk::DescriptorBufferBindingInfoEXT::default().address(b.address).usage(*usage)
            })
            .collect();
        let point = vk::PipelineBindPoint::RAY_TRACING_KHR;
        unsafe {
            db.cmd_bind_descriptor_buffers(cmd, &infos);
            for (i, (set, _, _)) in self.sets.iter().enumerate() {
                db.cmd_set_descriptor_buffer_offsets(cmd, point, layout, *set, &[i as u32], &[0]);
            }
        }
    }

    pub fn destroy(&self, gpu: &Gpu) {
        for (_, b, _) in &self.sets {
            b.destroy(gpu);
        }
    }
}
