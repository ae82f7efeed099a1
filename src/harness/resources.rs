//! The harness's resources, one per descriptor of the pipelines' reflected bindings, each with
//! data no other descriptor has: the acceleration structures cycle through the scene's TLASes
//! (the scene TLAS, then the AS probe's variants: other instances, other custom indices; the
//! supplied raygen's binding always the scene TLAS), every buffer holds floats that encode its
//! own descriptor (small integers in its integer words, the zero-filled sink buffer's address in
//! its 64-bit integers and pointers), storage images start at zero, textures hold texels that
//! encode their element and coordinates (`super::textures`), every sampler is the harness's one.
//! Plus the descriptor sets that bind them, and the address tables a host contract asks for.
use super::error::HarnessError;
use super::fill::Fills;
use super::ints::{Fill, IntWords};
use super::profile::set_flags;
use super::reflect::{Binding, BindingKind};
use super::scene::INDEX_BOUND;
use super::scene_textures::SceneTextures;
use super::textures;
use crate::model::contract::{AddressKind, HostContract};
use crate::model::profile::BindingFlags;
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
    /// A texture (sampled image, or combined with the sampler): its view, which
    /// `Resources::textures` owns.
    Texture(vk::ImageView),
    /// The harness's sampler.
    Sampler,
}

/// Every binding's elements, and the sets binding them.
pub struct Resources {
    pub bindings: BTreeMap<(u32, u32), (Binding, Vec<Element>)>,
    pub set_layouts: Vec<vk::DescriptorSetLayout>,
    pub pool: vk::DescriptorPool,
    pub sets: Vec<vk::DescriptorSet>,
    /// The zero-filled buffer every address word points at (`Sizes::sink` bytes).
    pub sink: Buffer,
    /// The sampler of every sampler and combined image sampler element.
    pub sampler: vk::Sampler,
    /// Every texture element's image and view.
    pub textures: textures::Textures,
    /// `--fill`'s buffer bytes, in place of [`buffer_data`] where given.
    pub fills: Fills,
}
const SINK_USAGE: vk::BufferUsageFlags = vk::BufferUsageFlags::from_raw(
    vk::BufferUsageFlags::STORAGE_BUFFER.as_raw()
        | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS.as_raw(),
);
/// What an 8-byte word holding the sink's address reads as in a read-back output: the sink's
/// address differs between processes (each variant's child makes its own), this does not.
pub const SINK_MARK: u64 = u64::from_le_bytes(*b"rtpSINK!");

/// `bytes` with every 8-byte-aligned word equal to `sink` replaced by [`SINK_MARK`].
pub fn mask_sink(mut bytes: Vec<u8>, sink: u64) -> Vec<u8> {
    for c in bytes.chunks_exact_mut(8) {
        if c == sink.to_le_bytes() {
            c.copy_from_slice(&SINK_MARK.to_le_bytes());
        }
    }
    bytes
}

/// Which of `n` TLASes binding `key` gets: the scene TLAS (0) at `scene_at` (the supplied
/// raygen's binding: it traces the scene), else the next in turn of `turn`.
fn tlas_index(key: (u32, u32), scene_at: Option<(u32, u32)>, turn: &mut usize, n: usize) -> usize {
    if scene_at == Some(key) {
        return 0;
    }
    *turn += 1;
    (*turn - 1) % n
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
/// `(5d + w + 1) mod INDEX_BOUND`, so an index read from a buffer stays inside every array the
/// harness makes, and a 64-bit integer or pointer is `sink`, the zero-filled sink buffer's
/// device address, so a shader dereferencing it reads zeros ([`super::ints`] says why).
pub fn buffer_data(d: u32, bytes: u32, ints: &IntWords, sink: u64) -> Vec<u8> {
    (0..bytes / 4).flat_map(|w| word(d, w, ints.at(4 * w), sink)).collect()
}

/// The data of element `k` of the buffer binding `b` at `key`, buffer number `d`: `fills`'
/// bytes where a fill names it, else [`buffer_data`].
fn element_data(fills: &Fills, d: u32, key: (u32, u32), k: u32, b: &Binding, sink: u64) -> Vec<u8> {
    let size = match b.kind {
        BindingKind::StorageBuffer(n) | BindingKind::UniformBuffer(n) => n,
        BindingKind::AccelerationStructure
        | BindingKind::StorageImage(_)
        | BindingKind::SampledImage
        | BindingKind::Sampler
        | BindingKind::CombinedImageSampler => 0,
    };
    match fills.buffer(key, k) {
        // Fewer bytes than the block: zeros past them, so the block the shader reads is there.
        Some(bytes) => {
            let mut v = bytes.to_vec();
            v.resize(v.len().max(size as usize), 0);
            v
        }
        None => buffer_data(d, size, &b.ints, sink),
    }
}

/// The bytes of word `w` of data set `d` holding `fill` (an address word: half of `sink`).
pub fn word(d: u32, w: u32, fill: Fill, sink: u64) -> [u8; 4] {
    match fill {
        Fill::Float => (d as f32 + 1.0 + w as f32 / 256.0).to_le_bytes(),
        Fill::SmallInt => ((5 * d + w + 1) % INDEX_BOUND).to_le_bytes(),
        Fill::AddressLow => (sink as u32).to_le_bytes(),
        Fill::AddressHigh => ((sink >> 32) as u32).to_le_bytes(),
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

pub fn descriptor_type(k: BindingKind) -> vk::DescriptorType {
    match k {
        BindingKind::AccelerationStructure => vk::DescriptorType::ACCELERATION_STRUCTURE_KHR,
        BindingKind::StorageImage(_) => vk::DescriptorType::STORAGE_IMAGE,
        BindingKind::StorageBuffer(_) => vk::DescriptorType::STORAGE_BUFFER,
        BindingKind::UniformBuffer(_) => vk::DescriptorType::UNIFORM_BUFFER,
        BindingKind::SampledImage => vk::DescriptorType::SAMPLED_IMAGE,
        BindingKind::Sampler => vk::DescriptorType::SAMPLER,
        BindingKind::CombinedImageSampler => vk::DescriptorType::COMBINED_IMAGE_SAMPLER,
    }
}

/// Resources made so far, by kind: the numbers the next ones take.
#[derive(Default)]
struct Made {
    tlases: usize,
    buffers: u32,
    textures: u32,
}

/// The storage image of binding `b`, of `extent`.
fn storage_image(
    gpu: &Gpu,
    b: &Binding,
    f: ImageFormat,
    extent: vk::Extent2D,
) -> Result<Image, HarnessError> {
    let (vf, _) = format(f).ok_or_else(|| {
        HarnessError::Unsupported(format!(
            "set {} binding {}: storage image format {f:?}",
            b.set, b.binding
        ))
    })?;
    let usage = vk::ImageUsageFlags::STORAGE
        | vk::ImageUsageFlags::TRANSFER_SRC
        | vk::ImageUsageFlags::TRANSFER_DST;
    Ok(Image::new(gpu, extent, vf, usage)?)
}

/// What [`Resources::new`] makes every element from.
struct Making<'a> {
    tlases: Vec<&'a crate::scene::gpu::AccelStruct>,
    textures: &'a textures::Textures,
    /// `scene.textures`' images, in place of the harness's textures where a fill put them.
    scene_textures: Option<&'a SceneTextures>,
    scene_at: Option<(u32, u32)>,
    extent: vk::Extent2D,
    sink: u64,
    fills: &'a Fills,
}

impl Making<'_> {
    /// Element `k` of binding `b` at `key`.
    fn element(
        &self,
        gpu: &Gpu,
        (key, k): ((u32, u32), u32),
        b: &Binding,
        made: &mut Made,
    ) -> Result<Element, HarnessError> {
        Ok(match b.kind {
            BindingKind::AccelerationStructure => {
                let t = self.tlases
                    [tlas_index(key, self.scene_at, &mut made.tlases, self.tlases.len())];
                Element::Tlas(t.raw, t.address)
            }
            BindingKind::StorageImage(f) => Element::Image(storage_image(gpu, b, f, self.extent)?),
            BindingKind::StorageBuffer(size) | BindingKind::UniformBuffer(size) => {
                let usage = vk::BufferUsageFlags::STORAGE_BUFFER
                    | vk::BufferUsageFlags::UNIFORM_BUFFER
                    | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS;
                // A filled buffer holds the fill's bytes (`--scene`'s data: sized to them), and
                // at least the reflected block, zero-padded (`element_data`).
                let filled = self.fills.buffer(key, k).map(|b| b.len().max(16) as u64);
                let size = filled.map_or(size as u64, |f| f.max(size as u64));
                let buf = Buffer::new(gpu, size, usage, Location::Host, "harness buffer")?;
                buf.write(0, &element_data(self.fills, made.buffers, key, k, b, self.sink));
                made.buffers += 1;
                Element::Buffer(buf)
            }
            BindingKind::SampledImage | BindingKind::CombinedImageSampler => {
                made.textures += 1;
                let own = self.textures.views[made.textures as usize - 1];
                let scene = self.scene_textures.and_then(|s| s.view(key, k));
                Element::Texture(scene.unwrap_or(own))
            }
            BindingKind::Sampler => Element::Sampler,
        })
    }
}

impl Resources {
    /// Resources for `bindings` (one per set and binding, aliases merged: `super::bindings`),
    /// TLASes from `scene` (the scene TLAS at `scene_at`, the supplied raygen's), images of
    /// `extent`, and the sink buffer of `sink_size` bytes; `fills`' bytes in the buffers they name
    /// and `scene_textures`' images in the texture elements they fill. The textures are not
    /// filled yet (`textures.upload`).
    pub fn new(
        gpu: &Gpu,
        bindings: &[Binding],
        scene_at: Option<(u32, u32)>,
        scene: &SceneGpu,
        extent: vk::Extent2D,
        (sink_size, buffer_model, flags): (u64, bool, BindingFlags),
        (fills, scene_textures): (&Fills, Option<&SceneTextures>),
    ) -> Result<Resources, HarnessError> {
        let unique = super::bindings::merged(bindings)?;
        let sink = Buffer::new(gpu, sink_size, SINK_USAGE, Location::Host, "harness sink")?;
        sink.write(0, &vec![0; sink_size as usize]);
        let n_textures = unique
            .values()
            .filter(|b| {
                matches!(b.kind, BindingKind::SampledImage | BindingKind::CombinedImageSampler)
            })
            .map(|b| b.count)
            .sum();
        let max_layers = gpu.info.properties.core.limits.max_image_array_layers;
        let textures = textures::Textures::new(gpu, n_textures, max_layers)?;
        let making = Making {
            tlases: std::iter::once(&scene.scene_tlas).chain(&scene.probe_tlas).collect(),
            textures: &textures,
            scene_textures,
            scene_at,
            extent,
            sink: sink.address,
            fills,
        };
        let mut all: BTreeMap<(u32, u32), (Binding, Vec<Element>)> = BTreeMap::new();
        let mut made = Made::default();
        for (key, b) in unique {
            let elems = (0..b.count)
                .map(|k| making.element(gpu, (key, k), &b, &mut made))
                .collect::<Result<Vec<_>, _>>()?;
            all.insert(key, (b, elems));
        }
        let sampler = textures::new_sampler(gpu)?;
        let (set_layouts, pool, sets) = descriptor_sets(gpu, &all, buffer_model, &flags)?;
        let fills = fills.clone();
        let r =
            Resources { bindings: all, set_layouts, pool, sets, sink, sampler, textures, fills };
        if !buffer_model {
            r.write_sets(gpu);
        }
        Ok(r)
    }

    /// Every buffer back to its own data (a shader may have written it).
    pub fn refill(&self) {
        self.sink.write(0, &vec![0; self.sink.size as usize]);
        let mut d = 0;
        for (key, (b, elems)) in &self.bindings {
            if let BindingKind::StorageBuffer(_) | BindingKind::UniformBuffer(_) = b.kind {
                for (k, e) in elems.iter().enumerate() {
                    if let Element::Buffer(buf) = e {
                        buf.write(0, &self.element_data(d, *key, k as u32, b));
                    }
                    d += 1;
                }
            }
        }
    }

    /// The data of element `k` of buffer binding `b` at `key`, buffer number `d`: its fill's
    /// bytes, else [`buffer_data`].
    pub fn element_data(&self, d: u32, key: (u32, u32), k: u32, b: &Binding) -> Vec<u8> {
        element_data(&self.fills, d, key, k, b, self.sink.address)
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
            let images: Vec<vk::DescriptorImageInfo> =
                elems.iter().filter_map(|e| self.image_info(e, b.kind)).collect();
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
                BindingKind::StorageImage(_)
                | BindingKind::SampledImage
                | BindingKind::Sampler
                | BindingKind::CombinedImageSampler => w.image_info(&images),
                BindingKind::StorageBuffer(_) | BindingKind::UniformBuffer(_) => {
                    w.buffer_info(&buffers)
                }
            };
            unsafe { gpu.device.update_descriptor_sets(&[w], &[]) };
        }
    }

    /// The image descriptor of element `e` of a binding of `kind` (`None`: not an image's).
    fn image_info(&self, e: &Element, kind: BindingKind) -> Option<vk::DescriptorImageInfo> {
        let info = vk::DescriptorImageInfo::default();
        Some(match (e, kind) {
            (Element::Image(i), _) => {
                info.image_view(i.view).image_layout(vk::ImageLayout::GENERAL)
            }
            (Element::Texture(v), BindingKind::CombinedImageSampler) => info
                .image_view(*v)
                .image_layout(vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL)
                .sampler(self.sampler),
            (Element::Texture(v), _) => {
                info.image_view(*v).image_layout(vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL)
            }
            (Element::Sampler, _) => info.sampler(self.sampler),
            (Element::Tlas(..) | Element::Buffer(_), _) => return None,
        })
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
                    Element::Image(_) | Element::Texture(..) | Element::Sampler => 0,
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
        self.sink.destroy(gpu);
        unsafe { gpu.device.destroy_sampler(self.sampler, None) };
        self.textures.destroy(gpu);
        for (_, elems) in self.bindings.values() {
            for e in elems {
                match e {
                    Element::Image(i) => i.destroy(gpu),
                    Element::Buffer(b) => b.destroy(gpu),
                    Element::Tlas(..) | Element::Texture(..) | Element::Sampler => {}
                }
            }
        }
    }
}

/// Address tables a trace reads (destroyed after it).
pub type Tables = Vec<Buffer>;

/// One set layout per set number up to the highest bound (empty ones between), a pool and the
/// sets; for descriptor buffers (`buffer_model`) layouts made for them, and no pool or sets.
type Sets = (Vec<vk::DescriptorSetLayout>, vk::DescriptorPool, Vec<vk::DescriptorSet>);

fn descriptor_sets(
    gpu: &Gpu,
    all: &BTreeMap<(u32, u32), (Binding, Vec<Element>)>,
    buffer_model: bool,
    flags: &BindingFlags,
) -> Result<Sets, VkError> {
    let d = &gpu.device;
    let n_sets = all.keys().map(|k| k.0 + 1).max().unwrap_or(0);
    if n_sets == 0 {
        return Ok((Vec::new(), vk::DescriptorPool::null(), Vec::new()));
    }
    let mut layouts = Vec::new();
    let mut sizes: BTreeMap<i32, u32> = BTreeMap::new();
    let (mut any_uab, mut variable) = (false, Vec::new());
    let counts = if buffer_model { BTreeMap::new() } else { variable_counts(gpu, all, flags) };
    for set in 0..n_sets {
        let bs: Vec<&Binding> = all.iter().filter(|(k, _)| k.0 == set).map(|(_, v)| &v.0).collect();
        let lb: Vec<vk::DescriptorSetLayoutBinding> = bs
            .iter()
            .map(|b| {
                // The pool holds the descriptors allocated (`super::variable` says why).
                *sizes.entry(descriptor_type(b.kind).as_raw()).or_default() += b.count;
                let layout = counts.get(&(b.set, b.binding)).map_or(b.count, |c| c.layout);
                vk::DescriptorSetLayoutBinding::default()
                    .binding(b.binding)
                    .descriptor_type(descriptor_type(b.kind))
                    .descriptor_count(layout)
                    .stage_flags(RT_STAGES)
            })
            .collect();
        // Binding flags only with descriptor sets (`--profile`; none without one).
        let (bf, uab) = if buffer_model { (Vec::new(), false) } else { set_flags(flags, &bs) };
        any_uab |= uab;
        let var = bs.iter().find_map(|b| counts.get(&(b.set, b.binding)));
        variable.push(var.map_or(0, |c| c.allocated));
        let mut fci = vk::DescriptorSetLayoutBindingFlagsCreateInfo::default().binding_flags(&bf);
        let mut ci = vk::DescriptorSetLayoutCreateInfo::default().bindings(&lb);
        if buffer_model {
            ci = ci.flags(vk::DescriptorSetLayoutCreateFlags::DESCRIPTOR_BUFFER_EXT);
        } else if bf.iter().any(|f| !f.is_empty()) {
            ci = ci.push_next(&mut fci);
        }
        if uab {
            ci = ci.flags(vk::DescriptorSetLayoutCreateFlags::UPDATE_AFTER_BIND_POOL);
        }
        let l = unsafe { d.create_descriptor_set_layout(&ci, None) }
            .at("vkCreateDescriptorSetLayout")?;
        layouts.push(l);
    }
    if buffer_model {
        return Ok((layouts, vk::DescriptorPool::null(), Vec::new()));
    }
    let pool = pool(gpu, &sizes, n_sets, any_uab)?;
    let mut counts = vk::DescriptorSetVariableDescriptorCountAllocateInfo::default()
        .descriptor_counts(&variable);
    let mut ai =
        vk::DescriptorSetAllocateInfo::default().descriptor_pool(pool).set_layouts(&layouts);
    if variable.iter().any(|n| *n > 0) {
        ai = ai.push_next(&mut counts);
    }
    let sets = unsafe { d.allocate_descriptor_sets(&ai) }.at("vkAllocateDescriptorSets")?;
    Ok((layouts, pool, sets))
}

/// The variable-sized bindings of `all` under `flags`, their layout bound from the device's
/// limits (`super::variable`).
fn variable_counts(
    gpu: &Gpu,
    all: &BTreeMap<(u32, u32), (Binding, Vec<Element>)>,
    flags: &BindingFlags,
) -> BTreeMap<(u32, u32), super::variable::VariableCount> {
    let bindings: BTreeMap<(u32, u32), Binding> =
        all.iter().map(|(k, (b, _))| (*k, b.clone())).collect();
    let counts = super::variable::counts(&bindings, flags, &super::variable::limits(&gpu.info));
    for line in super::variable::words(&counts) {
        tracing::info!("variable descriptor count: {line}");
    }
    counts
}

/// A pool for `n_sets` sets of the descriptors `sizes` counts by type (`uab`: for sets with
/// UPDATE_AFTER_BIND bindings).
fn pool(
    gpu: &Gpu,
    sizes: &BTreeMap<i32, u32>,
    n_sets: u32,
    uab: bool,
) -> Result<vk::DescriptorPool, VkError> {
    let pool_sizes: Vec<vk::DescriptorPoolSize> = sizes
        .iter()
        .map(|(t, n)| vk::DescriptorPoolSize {
            ty: vk::DescriptorType::from_raw(*t),
            descriptor_count: *n,
        })
        .collect();
    let mut ci =
        vk::DescriptorPoolCreateInfo::default().max_sets(n_sets.max(1)).pool_sizes(&pool_sizes);
    if uab {
        ci = ci.flags(vk::DescriptorPoolCreateFlags::UPDATE_AFTER_BIND);
    }
    unsafe { gpu.device.create_descriptor_pool(&ci, None) }.at("vkCreateDescriptorPool")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::harness::ints::Words;

    /// Issue #24: every address word of a buffer holds the sink's address, low half then high,
    /// never a small integer; the 32-bit integer and float words keep their fills.
    #[test]
    fn address_words_hold_the_sinks_address() {
        let sink = 0x0000_7f12_3456_7800_u64;
        let mut w = Words::default();
        w.addr.insert(8);
        w.low.insert(4);
        let ints = IntWords { fixed: w, tail: None };
        let data = buffer_data(3, 24, &ints, sink);
        assert_eq!(&data[8..16], &sink.to_le_bytes());
        let word_at = |o: usize| u32::from_le_bytes(data[o..o + 4].try_into().unwrap());
        assert!(word_at(4) < INDEX_BOUND);
        assert_eq!(f32::from_bits(word_at(0)), 4.0);
        // The read-back bytes carry the mark in its place, whatever the process's sink.
        let masked = mask_sink(data.clone(), sink);
        assert_eq!(&masked[8..16], &SINK_MARK.to_le_bytes());
        assert_eq!((&masked[..8], &masked[16..]), (&data[..8], &data[16..]));
    }

    /// A fill shorter than its block (36 bytes of scene positions into a `vec4 v[4]` block) is
    /// zero-padded to the block: the shader's 64 bytes are there. A longer fill is kept whole.
    #[test]
    fn a_short_fill_is_padded_to_its_block() {
        use super::super::fill::{Fill, Target};
        let b = Binding {
            set: 0,
            binding: 1,
            kind: BindingKind::UniformBuffer(64),
            count: 1,
            runtime: false,
            writable: false,
            ints: IntWords::default(),
            atomic: false,
            records: None,
        };
        let fill = |n: usize| {
            let target = Target::Binding { set: 0, binding: 1, element: None };
            Fills(vec![Fill { target, bytes: vec![7; n] }])
        };
        let short = element_data(&fill(36), 0, (0, 1), 0, &b, 0);
        assert_eq!(short.len(), 64);
        assert!(short[..36].iter().all(|x| *x == 7) && short[36..].iter().all(|x| *x == 0));
        assert_eq!(element_data(&fill(100), 0, (0, 1), 0, &b, 0), vec![7; 100]);
    }

    /// The supplied raygen's TLAS binding is the scene TLAS; other TLAS bindings take turns.
    #[test]
    fn the_supplied_raygens_tlas_is_the_scene() {
        let mut turn = 0;
        let supplied = Some((0, 2));
        let got: Vec<usize> = [(0, 0), (0, 2), (1, 0)]
            .iter()
            .map(|k| tlas_index(*k, supplied, &mut turn, 3))
            .collect();
        assert_eq!(got, [0, 0, 1]);
        // Twin: without a supplied raygen the binding after the first takes a variant.
        let mut turn = 0;
        let got: Vec<usize> =
            [(0, 0), (0, 2)].iter().map(|k| tlas_index(*k, None, &mut turn, 3)).collect();
        assert_eq!(got, [0, 1]);
    }
}
