//! Binding the cell's descriptors under each descriptor model: `descriptor_indexing` (a descriptor
//! set with a runtime-sized, partially bound, update-after-bind array where the device allows) and
//! `descriptor_buffer` (VK_EXT_descriptor_buffer: descriptors written with vkGetDescriptorEXT into
//! a buffer) and `descriptor_heap` (VK_EXT_descriptor_heap, in [`super::heap`]). Binding 0 is the
//! records SSBO, 1 the scene TLAS, 2 the probed array.
use super::heap::HeapBinding;
use super::resources::{descriptor_type, Target};
use crate::model::{DescriptorModel, Resource};
use crate::vk::memory::{Buffer, Location};
use crate::vk::{Gpu, VkError, VkResultExt};
use ash::vk;

/// The probes' block plus the 8-byte table address the address patches append.
pub const PUSH_CONSTANT_BYTES: u32 = crate::probe::PUSH_CONSTANT_BYTES;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct LayoutKey {
    /// Stages that see the bindings and push constants (exactly the pipeline's stages).
    pub stages: vk::ShaderStageFlags,
    pub model: DescriptorModel,
    pub scene_tlas: bool,
    pub probe: Option<Resource>,
    /// Heap model, `heap_access=direct`: the probed array first in the heap.
    pub heap_direct: bool,
    /// `index=dynamic_element`: the packed resource at `probe::PACKED_SLOT`
    /// (`resources::ResourceArray::targets`).
    pub packed: bool,
}

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
    bound: Bound,
}

fn update_after_bind_supported(gpu: &Gpu, kind: Resource) -> bool {
    let v12 = gpu.info.features.v12.unwrap_or_default();
    let on = |b: vk::Bool32| b == vk::TRUE;
    match kind {
        Resource::StorageBuffer => on(v12.descriptor_binding_storage_buffer_update_after_bind),
        Resource::UniformBuffer => on(v12.descriptor_binding_uniform_buffer_update_after_bind),
        Resource::SampledImage => on(v12.descriptor_binding_sampled_image_update_after_bind),
        Resource::StorageImage => on(v12.descriptor_binding_storage_image_update_after_bind),
        Resource::AccelerationStructure => gpu
            .info
            .features
            .accel
            .is_some_and(|a| on(a.descriptor_binding_acceleration_structure_update_after_bind)),
    }
}

/// Bytes of one descriptor of `kind` in a descriptor buffer.
fn descriptor_size(
    props: &vk::PhysicalDeviceDescriptorBufferPropertiesEXT,
    kind: Resource,
) -> usize {
    match kind {
        Resource::StorageBuffer => props.storage_buffer_descriptor_size,
        Resource::UniformBuffer => props.uniform_buffer_descriptor_size,
        Resource::SampledImage => props.combined_image_sampler_descriptor_size,
        Resource::StorageImage => props.storage_image_descriptor_size,
        Resource::AccelerationStructure => props.acceleration_structure_descriptor_size,
    }
}

impl Binding {
    /// `targets[b]` are the descriptors of binding `b` (records, scene TLAS, probe array) and
    /// their kind, in the order of the layout's bindings.
    pub fn create(
        gpu: &Gpu,
        key: LayoutKey,
        targets: &[(u32, Resource, Vec<Target>)],
    ) -> Result<Binding, VkError> {
        let d = &gpu.device;
        if key.model == DescriptorModel::DescriptorHeap {
            let heap = HeapBinding::create(
                gpu,
                targets,
                &super::samplers::heap_sampler_infos(),
                key.heap_direct,
            )?;
            return Ok(Binding {
                set_layout: vk::DescriptorSetLayout::null(),
                pipeline_layout: vk::PipelineLayout::null(),
                bound: Bound::Heap(heap),
            });
        }
        let mut bindings = Vec::new();
        let mut flags = Vec::new();
        let mut uab = false;
        for (b, kind, t) in targets {
            bindings.push(
                vk::DescriptorSetLayoutBinding::default()
                    .binding(*b)
                    .descriptor_type(descriptor_type(*kind))
                    .descriptor_count(t.len() as u32)
                    .stage_flags(key.stages),
            );
            let f = if *b == 2 && key.model == DescriptorModel::DescriptorIndexing {
                let mut f = vk::DescriptorBindingFlags::PARTIALLY_BOUND;
                if update_after_bind_supported(gpu, *kind) {
                    f |= vk::DescriptorBindingFlags::UPDATE_AFTER_BIND;
                    uab = true;
                }
                f
            } else {
                vk::DescriptorBindingFlags::empty()
            };
            flags.push(f);
        }
        let mut flags_info =
            vk::DescriptorSetLayoutBindingFlagsCreateInfo::default().binding_flags(&flags);
        let mut ci = vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings);
        match key.model {
            DescriptorModel::DescriptorIndexing => {
                if uab {
                    ci = ci.flags(vk::DescriptorSetLayoutCreateFlags::UPDATE_AFTER_BIND_POOL);
                }
                ci = ci.push_next(&mut flags_info);
            }
            DescriptorModel::DescriptorBuffer => {
                ci = ci.flags(vk::DescriptorSetLayoutCreateFlags::DESCRIPTOR_BUFFER_EXT)
            }
            DescriptorModel::DescriptorHeap => unreachable!("heap bindings returned above"),
        }
        let set_layout = unsafe { d.create_descriptor_set_layout(&ci, None) }
            .at("vkCreateDescriptorSetLayout")?;
        let ranges = [vk::PushConstantRange {
            stage_flags: key.stages,
            offset: 0,
            size: PUSH_CONSTANT_BYTES,
        }];
        let layouts = [set_layout];
        let pipeline_layout = unsafe {
            d.create_pipeline_layout(
                &vk::PipelineLayoutCreateInfo::default()
                    .set_layouts(&layouts)
                    .push_constant_ranges(&ranges),
                None,
            )
        }
        .at("vkCreatePipelineLayout")?;
        let bound = match key.model {
            DescriptorModel::DescriptorIndexing => Self::write_set(gpu, set_layout, uab, targets)?,
            DescriptorModel::DescriptorBuffer => Self::write_buffer(gpu, set_layout, targets)?,
            DescriptorModel::DescriptorHeap => {
                unreachable!("the plan never runs descriptor_heap cells")
            }
        };
        Ok(Binding { set_layout, pipeline_layout, bound })
    }

    fn write_set(
        gpu: &Gpu,
        layout: vk::DescriptorSetLayout,
        uab: bool,
        targets: &[(u32, Resource, Vec<Target>)],
    ) -> Result<Bound, VkError> {
        let d = &gpu.device;
        let sizes: Vec<vk::DescriptorPoolSize> = targets
            .iter()
            .map(|(_, kind, t)| vk::DescriptorPoolSize {
                ty: descriptor_type(*kind),
                descriptor_count: t.len() as u32,
            })
            .collect();
        let mut pci = vk::DescriptorPoolCreateInfo::default().max_sets(1).pool_sizes(&sizes);
        if uab {
            pci = pci.flags(vk::DescriptorPoolCreateFlags::UPDATE_AFTER_BIND);
        }
        let pool = unsafe { d.create_descriptor_pool(&pci, None) }.at("vkCreateDescriptorPool")?;
        let layouts = [layout];
        let set = unsafe {
            d.allocate_descriptor_sets(
                &vk::DescriptorSetAllocateInfo::default()
                    .descriptor_pool(pool)
                    .set_layouts(&layouts),
            )
        }
        .at("vkAllocateDescriptorSets")?[0];
        for (b, kind, ts) in targets {
            let ty = &descriptor_type(*kind);
            let mut buffer_infos = Vec::new();
            let mut image_infos = Vec::new();
            let mut accels = Vec::new();
            for t in ts {
                match *t {
                    Target::Buffer { raw, range, .. } => buffer_infos
                        .push(vk::DescriptorBufferInfo { buffer: raw, offset: 0, range }),
                    Target::Image { view, sampler, .. } => {
                        image_infos.push(vk::DescriptorImageInfo {
                            sampler,
                            image_view: view,
                            image_layout: vk::ImageLayout::GENERAL,
                        })
                    }
                    Target::Accel { raw, .. } => accels.push(raw),
                }
            }
            let mut as_write = vk::WriteDescriptorSetAccelerationStructureKHR::default()
                .acceleration_structures(&accels);
            let mut w =
                vk::WriteDescriptorSet::default().dst_set(set).dst_binding(*b).descriptor_type(*ty);
            if !buffer_infos.is_empty() {
                w = w.buffer_info(&buffer_infos);
            } else if !image_infos.is_empty() {
                w = w.image_info(&image_infos);
            } else {
                w.descriptor_count = accels.len() as u32;
                w = w.push_next(&mut as_write);
            }
            unsafe { d.update_descriptor_sets(&[w], &[]) };
        }
        Ok(Bound::Set { pool, set })
    }

    fn write_buffer(
        gpu: &Gpu,
        layout: vk::DescriptorSetLayout,
        targets: &[(u32, Resource, Vec<Target>)],
    ) -> Result<Bound, VkError> {
        let db = gpu.descriptor_buffer.as_ref().expect("descriptor buffer enabled");
        let props = gpu.info.properties.descriptor_buffer.expect("descriptor buffer properties");
        let size = unsafe { db.get_descriptor_set_layout_size(layout) };
        let mut usage = vk::BufferUsageFlags::RESOURCE_DESCRIPTOR_BUFFER_EXT;
        if targets.iter().any(|(_, kind, _)| *kind == Resource::SampledImage) {
            usage |= vk::BufferUsageFlags::SAMPLER_DESCRIPTOR_BUFFER_EXT;
        }
        let buffer = Buffer::new(
            gpu,
            size,
            usage | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS,
            Location::Host,
            "descriptor buffer",
        )?;
        let mut bytes = vec![0u8; size as usize];
        for (b, kind, ts) in targets {
            let ty = &descriptor_type(*kind);
            let offset =
                unsafe { db.get_descriptor_set_layout_binding_offset(layout, *b) } as usize;
            let stride = descriptor_size(&props, *kind);
            for (i, t) in ts.iter().enumerate() {
                let at = offset + i * stride;
                let dst = &mut bytes[at..at + stride];
                match *t {
                    Target::Buffer { address, range, .. } => {
                        let info = vk::DescriptorAddressInfoEXT::default()
                            .address(address)
                            .range(range)
                            .format(vk::Format::UNDEFINED);
                        let data = if *ty == vk::DescriptorType::UNIFORM_BUFFER {
                            vk::DescriptorDataEXT { p_uniform_buffer: &info }
                        } else {
                            vk::DescriptorDataEXT { p_storage_buffer: &info }
                        };
                        unsafe {
                            db.get_descriptor(
                                &vk::DescriptorGetInfoEXT::default().ty(*ty).data(data),
                                dst,
                            )
                        };
                    }
                    Target::Image { view, sampler, .. } => {
                        let info = vk::DescriptorImageInfo {
                            sampler,
                            image_view: view,
                            image_layout: vk::ImageLayout::GENERAL,
                        };
                        let data = if *ty == vk::DescriptorType::COMBINED_IMAGE_SAMPLER {
                            vk::DescriptorDataEXT { p_combined_image_sampler: &info }
                        } else {
                            vk::DescriptorDataEXT { p_storage_image: &info }
                        };
                        unsafe {
                            db.get_descriptor(
                                &vk::DescriptorGetInfoEXT::default().ty(*ty).data(data),
                                dst,
                            )
                        };
                    }
                    Target::Accel { address, .. } => {
                        let data = vk::DescriptorDataEXT { acceleration_structure: address };
                        unsafe {
                            db.get_descriptor(
                                &vk::DescriptorGetInfoEXT::default().ty(*ty).data(data),
                                dst,
                            )
                        };
                    }
                }
            }
        }
        buffer.write(0, &bytes);
        Ok(Bound::Buffer { buffer, usage })
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
