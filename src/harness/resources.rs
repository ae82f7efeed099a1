//! The harness's resources, one per descriptor of the pipelines' reflected bindings, each with
//! data no other descriptor has: the acceleration structures cycle through the scene's TLASes
//! (the scene TLAS, then the AS probe's variants: other instances, other custom indices), every
//! buffer holds floats that encode its own descriptor (small integers in its integer words), storage images start at zero. Plus the
//! descriptor sets that bind them, and the address tables a host contract asks for.
use super::error::HarnessError;
use super::ints::{Fill, IntWords};
use super::reflect::{Binding, BindingKind};
use super::scene::INDEX_BOUND;
use crate::model::contract::{AddressKind, HostContract};
use crate::scene::gpu::SceneGpu;
use crate::vk::memory::{Buffer, Image, Location};
use crate::vk::{Gpu, VkError, VkResultExt};
use ash::vk;
use rspirv::spirv::ImageFormat;
use std::collections::BTreeMap;

/// What one descriptor element is bound to.
pub enum Element {
    /// A TLAS: its handle and device address.
    Tlas(vk::AccelerationStructureKHR, u64),
    Image(Image),
    Buffer(Buffer),
}

/// Every binding's elements, and the sets binding them.
pub struct Resources {
    pub bindings: BTreeMap<(u32, u32), (Binding, Vec<Element>)>,
    pub set_layouts: Vec<vk::DescriptorSetLayout>,
    pub pool: vk::DescriptorPool,
    pub sets: Vec<vk::DescriptorSet>,
}

/// The Vulkan format and texel size of a storage image format.
pub fn format(f: ImageFormat) -> Option<(vk::Format, u32)> {
    Some(match f {
        ImageFormat::Rgba32f => (vk::Format::R32G32B32A32_SFLOAT, 16),
        ImageFormat::Rgba32ui => (vk::Format::R32G32B32A32_UINT, 16),
        ImageFormat::Rgba16f => (vk::Format::R16G16B16A16_SFLOAT, 8),
        ImageFormat::Rg32f => (vk::Format::R32G32_SFLOAT, 8),
        ImageFormat::Rgba8 => (vk::Format::R8G8B8A8_UNORM, 4),
        ImageFormat::R32f => (vk::Format::R32_SFLOAT, 4),
        ImageFormat::R32ui => (vk::Format::R32_UINT, 4),
        ImageFormat::R32i => (vk::Format::R32_SINT, 4),
        _ => return None,
    })
}

/// The data of buffer number `d` (counted over every buffer descriptor) with integer words
/// `ints`: a float word `w` is `d + 1 + w / 256`, so no two descriptors hold the same values and
/// every word is a plain number a shader can mix into a colour; an integer word is
/// `(5d + w + 1) mod INDEX_BOUND` (the high half of a 64-bit one 0), so an index read from a
/// buffer stays inside every array the harness makes ([`super::ints`] says why).
pub fn buffer_data(d: u32, bytes: u32, ints: &IntWords) -> Vec<u8> {
    (0..bytes / 4).flat_map(|w| word(d, w, ints.at(4 * w))).collect()
}

/// The bytes of word `w` of data set `d` holding `fill`.
pub fn word(d: u32, w: u32, fill: Fill) -> [u8; 4] {
    match fill {
        Fill::Float => (d as f32 + 1.0 + w as f32 / 256.0).to_le_bytes(),
        Fill::SmallInt => ((5 * d + w + 1) % INDEX_BOUND).to_le_bytes(),
        Fill::Zero => [0; 4],
    }
}

const RT_STAGES: vk::ShaderStageFlags = vk::ShaderStageFlags::from_raw(
    vk::ShaderStageFlags::RAYGEN_KHR.as_raw()
        | vk::ShaderStageFlags::MISS_KHR.as_raw()
        | vk::ShaderStageFlags::CLOSEST_HIT_KHR.as_raw()
        | vk::ShaderStageFlags::ANY_HIT_KHR.as_raw()
        | vk::ShaderStageFlags::INTERSECTION_KHR.as_raw()
        | vk::ShaderStageFlags::CALLABLE_KHR.as_raw(),
);

/// The shader stages the harness's layouts name.
pub fn rt_stages() -> vk::ShaderStageFlags {
    RT_STAGES
}

fn descriptor_type(k: BindingKind) -> vk::DescriptorType {
    match k {
        BindingKind::AccelerationStructure => vk::DescriptorType::ACCELERATION_STRUCTURE_KHR,
        BindingKind::StorageImage(_) => vk::DescriptorType::STORAGE_IMAGE,
        BindingKind::StorageBuffer(_) => vk::DescriptorType::STORAGE_BUFFER,
        BindingKind::UniformBuffer(_) => vk::DescriptorType::UNIFORM_BUFFER,
    }
}

impl Resources {
    /// Resources for `bindings` (one per set and binding; the same binding in several modules must
    /// agree on its type), TLASes from `scene`, images of `extent`.
    pub fn new(
        gpu: &Gpu,
        bindings: &[Binding],
        scene: &SceneGpu,
        extent: vk::Extent2D,
    ) -> Result<Resources, HarnessError> {
        let tlases: Vec<&crate::scene::gpu::AccelStruct> =
            std::iter::once(&scene.scene_tlas).chain(&scene.probe_tlas).collect();
        let mut unique: BTreeMap<(u32, u32), Binding> = BTreeMap::new();
        for b in bindings {
            match unique.get_mut(&(b.set, b.binding)) {
                Some(old) if old.kind != b.kind || old.count != b.count => {
                    return Err(HarnessError::Interface(format!(
                        "set {} binding {} is {:?} x{} in one module and {:?} x{} in another",
                        b.set, b.binding, old.kind, old.count, b.kind, b.count
                    )));
                }
                // Written by any module: compared after the trace.
                Some(old) => {
                    old.writable |= b.writable;
                    old.atomic |= b.atomic;
                    old.records = old.records.or(b.records);
                }
                None => {
                    unique.insert((b.set, b.binding), b.clone());
                }
            }
        }
        let mut all: BTreeMap<(u32, u32), (Binding, Vec<Element>)> = BTreeMap::new();
        let (mut n_as, mut n_buf) = (0usize, 0u32);
        for (key, b) in unique {
            let mut elems = Vec::new();
            for _ in 0..b.count {
                elems.push(match b.kind {
                    BindingKind::AccelerationStructure => {
                        let t = tlases[n_as % tlases.len()];
                        n_as += 1;
                        Element::Tlas(t.raw, t.address)
                    }
                    BindingKind::StorageImage(f) => {
                        let (vf, _) = format(f).ok_or_else(|| {
                            HarnessError::Unsupported(format!(
                                "set {} binding {}: storage image format {f:?}",
                                b.set, b.binding
                            ))
                        })?;
                        let usage = vk::ImageUsageFlags::STORAGE
                            | vk::ImageUsageFlags::TRANSFER_SRC
                            | vk::ImageUsageFlags::TRANSFER_DST;
                        Element::Image(Image::new(gpu, extent, vf, usage)?)
                    }
                    BindingKind::StorageBuffer(size) | BindingKind::UniformBuffer(size) => {
                        let usage = vk::BufferUsageFlags::STORAGE_BUFFER
                            | vk::BufferUsageFlags::UNIFORM_BUFFER
                            | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS;
                        let buf =
                            Buffer::new(gpu, size as u64, usage, Location::Host, "harness buffer")?;
                        buf.write(0, &buffer_data(n_buf, size, &b.ints));
                        n_buf += 1;
                        Element::Buffer(buf)
                    }
                });
            }
            all.insert(key, (b, elems));
        }
        let (set_layouts, pool, sets) = descriptor_sets(gpu, &all)?;
        let r = Resources { bindings: all, set_layouts, pool, sets };
        r.write_sets(gpu);
        Ok(r)
    }

    /// Every buffer back to its own data (a shader may have written it).
    pub fn refill(&self) {
        let mut d = 0;
        for (b, elems) in self.bindings.values() {
            if let BindingKind::StorageBuffer(size) | BindingKind::UniformBuffer(size) = b.kind {
                for e in elems {
                    if let Element::Buffer(buf) = e {
                        buf.write(0, &buffer_data(d, size, &b.ints));
                    }
                    d += 1;
                }
            }
        }
    }

    fn write_sets(&self, gpu: &Gpu) {
        for ((set, binding), (b, elems)) in &self.bindings {
            let dst = self.sets[*set as usize];
            let handles: Vec<vk::AccelerationStructureKHR> = elems
                .iter()
                .filter_map(|e| match e {
                    Element::Tlas(h, _) => Some(*h),
                    _ => None,
                })
                .collect();
            let images: Vec<vk::DescriptorImageInfo> = elems
                .iter()
                .filter_map(|e| match e {
                    Element::Image(i) => Some(
                        vk::DescriptorImageInfo::default()
                            .image_view(i.view)
                            .image_layout(vk::ImageLayout::GENERAL),
                    ),
                    _ => None,
                })
                .collect();
            let buffers: Vec<vk::DescriptorBufferInfo> = elems
                .iter()
                .filter_map(|e| match e {
                    Element::Buffer(x) => Some(
                        vk::DescriptorBufferInfo::default().buffer(x.raw).range(vk::WHOLE_SIZE),
                    ),
                    _ => None,
                })
                .collect();
            let mut as_info = vk::WriteDescriptorSetAccelerationStructureKHR::default()
                .acceleration_structures(&handles);
            let mut w = vk::WriteDescriptorSet::default()
                .dst_set(dst)
                .dst_binding(*binding)
                .descriptor_type(descriptor_type(b.kind))
                .descriptor_count(b.count);
            w = match b.kind {
                BindingKind::AccelerationStructure => w.push_next(&mut as_info),
                BindingKind::StorageImage(_) => w.image_info(&images),
                _ => w.buffer_info(&buffers),
            };
            unsafe { gpu.device.update_descriptor_sets(&[w], &[]) };
        }
    }

    /// The 8-byte addresses a host contract asks for, each at its push-constant offset, and the
    /// table buffers they point at (to destroy after the trace).
    pub fn contract_addresses(
        &self,
        gpu: &Gpu,
        c: &HostContract,
    ) -> Result<(Vec<(u32, u64)>, Tables), HarnessError> {
        let mut out = Vec::new();
        let mut tables = Vec::new();
        for a in &c.addresses {
            let (_, elems) = self.bindings.get(&(a.set, a.binding)).ok_or_else(|| {
                HarnessError::Interface(format!(
                    "the contract addresses set {} binding {}, which no unpatched module binds",
                    a.set, a.binding
                ))
            })?;
            let addresses: Vec<u64> = elems
                .iter()
                .map(|e| match e {
                    Element::Tlas(_, addr) => *addr,
                    Element::Buffer(b) => b.address,
                    Element::Image(_) => 0,
                })
                .collect();
            match a.kind {
                AddressKind::AccelerationStructure => out.push((a.offset, addresses[0])),
                AddressKind::AccelerationStructureTable | AddressKind::BufferTable => {
                    let bytes: Vec<u8> = addresses.iter().flat_map(|x| x.to_le_bytes()).collect();
                    let usage = vk::BufferUsageFlags::STORAGE_BUFFER
                        | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS;
                    let t = Buffer::with_data(gpu, &bytes, usage, "address table")?;
                    out.push((a.offset, t.address));
                    tables.push(t);
                }
            }
        }
        Ok((out, tables))
    }

    pub fn destroy(&self, gpu: &Gpu) {
        unsafe {
            gpu.device.destroy_descriptor_pool(self.pool, None);
            for l in &self.set_layouts {
                gpu.device.destroy_descriptor_set_layout(*l, None);
            }
        }
        for (_, elems) in self.bindings.values() {
            for e in elems {
                match e {
                    Element::Image(i) => i.destroy(gpu),
                    Element::Buffer(b) => b.destroy(gpu),
                    Element::Tlas(..) => {}
                }
            }
        }
    }
}

/// Address tables a trace reads (destroyed after it).
pub type Tables = Vec<Buffer>;

/// One set layout per set number up to the highest bound (empty ones between), a pool and the
/// sets.
type Sets = (Vec<vk::DescriptorSetLayout>, vk::DescriptorPool, Vec<vk::DescriptorSet>);

fn descriptor_sets(
    gpu: &Gpu,
    all: &BTreeMap<(u32, u32), (Binding, Vec<Element>)>,
) -> Result<Sets, VkError> {
    let d = &gpu.device;
    let n_sets = all.keys().map(|k| k.0 + 1).max().unwrap_or(0);
    if n_sets == 0 {
        return Ok((Vec::new(), vk::DescriptorPool::null(), Vec::new()));
    }
    let mut layouts = Vec::new();
    let mut sizes: BTreeMap<i32, u32> = BTreeMap::new();
    for set in 0..n_sets {
        let lb: Vec<vk::DescriptorSetLayoutBinding> = all
            .iter()
            .filter(|(k, _)| k.0 == set)
            .map(|(k, (b, _))| {
                *sizes.entry(descriptor_type(b.kind).as_raw()).or_default() += b.count;
                vk::DescriptorSetLayoutBinding::default()
                    .binding(k.1)
                    .descriptor_type(descriptor_type(b.kind))
                    .descriptor_count(b.count)
                    .stage_flags(RT_STAGES)
            })
            .collect();
        let l = unsafe {
            d.create_descriptor_set_layout(
                &vk::DescriptorSetLayoutCreateInfo::default().bindings(&lb),
                None,
            )
        }
        .at("vkCreateDescriptorSetLayout")?;
        layouts.push(l);
    }
    let pool_sizes: Vec<vk::DescriptorPoolSize> = sizes
        .iter()
        .map(|(t, n)| vk::DescriptorPoolSize {
            ty: vk::DescriptorType::from_raw(*t),
            descriptor_count: *n,
        })
        .collect();
    let pool = unsafe {
        d.create_descriptor_pool(
            &vk::DescriptorPoolCreateInfo::default()
                .max_sets(n_sets.max(1))
                .pool_sizes(&pool_sizes),
            None,
        )
    }
    .at("vkCreateDescriptorPool")?;
    let sets = if layouts.is_empty() {
        Vec::new()
    } else {
        unsafe {
            d.allocate_descriptor_sets(
                &vk::DescriptorSetAllocateInfo::default()
                    .descriptor_pool(pool)
                    .set_layouts(&layouts),
            )
        }
        .at("vkAllocateDescriptorSets")?
    };
    Ok((layouts, pool, sets))
}
