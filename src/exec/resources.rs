//! The probed resources, one array per kind, created the first time a cell needs that kind: one
//! buffer or image per slot (as an engine keeps one SSBO per mesh and one texture per material),
//! each holding `probe::ELEMENTS` elements `probe::resource_value(kind, slot, element)` (a
//! buffer's `vec4 v[ELEMENTS]`, an image's 2×2 texels, element e at texel (e & 1, e >> 1)); plus the
//! TLAS and SSBO address tables. Storage buffers and sampled images also get the packed resource of
//! `index=dynamic_element` (`probe::PACKED_SLOT`): one buffer with every slot's elements
//! (`probe::packed_bytes`), or one array image whose layer d holds slot d's texels, and (images)
//! a one-layer 2D-array view of every slot's own image, so that the whole probed array has the
//! shader's `sampler2DArray` type.
use crate::model::Resource;
use crate::probe;
use crate::vk::features::PROBE_IMAGE_FORMAT;
use crate::vk::memory::{record_image_upload, Buffer, Image};
use crate::vk::submit::{Submitter, Waited};
use crate::vk::{Gpu, VkError};
use ash::vk;
use std::time::Duration;

/// What one descriptor points at.
#[derive(Clone, Copy, Debug)]
pub enum Target {
    Buffer {
        raw: vk::Buffer,
        address: u64,
        range: u64,
    },
    /// `image`: for heap descriptors, which are made from a view description, not a view;
    /// `layers`: the view's (`None` 2D, `Some(n)` 2D array of n layers, `vk::memory::create_view`).
    Image {
        image: vk::Image,
        view: vk::ImageView,
        sampler: vk::Sampler,
        layers: Option<u32>,
    },
    Accel {
        raw: vk::AccelerationStructureKHR,
        address: u64,
    },
}

pub struct ResourceArray {
    pub buffers: Vec<Buffer>,
    pub images: Vec<Image>,
    /// The packed buffer or array image of `index=dynamic_element` (storage buffers and sampled
    /// images; `None` for images where the device's maxImageArrayLayers is below the slot count).
    packed: Option<Packed>,
    /// One-layer 2D-array views of `images` (sampled images).
    array_views: Vec<vk::ImageView>,
    /// The device's maxImageArrayLayers (why an image array has no packed image).
    max_layers: u32,
}

enum Packed {
    Buffer(Buffer),
    Image(Image, u32),
}

/// Why a cell cannot have its packed resource.
#[derive(Debug, thiserror::Error)]
pub enum PackedError {
    #[error("index=dynamic_element packs {slots} slots into one array texture; the device's maxImageArrayLayers is {max}")]
    TooManyLayers { slots: u32, max: u32 },
    #[error("rtprobe has no packed resource for {0} (index=dynamic_element)")]
    NoPacked(Resource),
}

impl ResourceArray {
    pub fn create(
        gpu: &Gpu,
        kind: Resource,
        slots: u32,
        submitter: &Submitter,
        timeout: Duration,
    ) -> Result<Self, VkError> {
        let mut array = ResourceArray {
            buffers: Vec::new(),
            images: Vec::new(),
            packed: None,
            array_views: Vec::new(),
            max_layers: gpu.info.properties.core.limits.max_image_array_layers,
        };
        match kind {
            Resource::StorageBuffer | Resource::UniformBuffer => {
                array.add_buffers(gpu, kind, slots)?
            }
            Resource::SampledImage | Resource::StorageImage => {
                let staging = array.add_images(gpu, kind, slots)?;
                array.upload(gpu, staging, submitter, timeout)?;
            }
            Resource::AccelerationStructure => {}
        }
        Ok(array)
    }

    /// One buffer per slot holding its elements and, for storage buffers, the packed buffer.
    fn add_buffers(&mut self, gpu: &Gpu, kind: Resource, slots: u32) -> Result<(), VkError> {
        let usage = if kind == Resource::StorageBuffer {
            vk::BufferUsageFlags::STORAGE_BUFFER
        } else {
            vk::BufferUsageFlags::UNIFORM_BUFFER
        };
        for s in 0..slots {
            self.buffers.push(Buffer::with_data(
                gpu,
                &value_bytes(kind, s),
                usage | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS,
                "probe buffer",
            )?);
        }
        if kind == Resource::StorageBuffer {
            self.packed = Some(Packed::Buffer(Buffer::with_data(
                gpu,
                &probe::packed_bytes(kind, slots),
                usage | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS,
                "packed probe buffer",
            )?));
        }
        Ok(())
    }

    /// One 2×2 image per slot and, for sampled images, a one-layer 2D-array view of each and the
    /// packed array image (where maxImageArrayLayers allows it); not yet filled. Returns the
    /// staging buffers holding their texels, in the order [`ResourceArray::upload`] copies them.
    fn add_images(
        &mut self,
        gpu: &Gpu,
        kind: Resource,
        slots: u32,
    ) -> Result<Vec<Buffer>, VkError> {
        let usage = vk::ImageUsageFlags::TRANSFER_DST
            | if kind == Resource::SampledImage {
                vk::ImageUsageFlags::SAMPLED
            } else {
                vk::ImageUsageFlags::STORAGE
            };
        let mut staging = Vec::new();
        for s in 0..slots {
            self.images.push(Image::new(gpu, IMAGE_EXTENT, PROBE_IMAGE_FORMAT, usage)?);
            staging.push(staging_buffer(gpu, &value_bytes(kind, s))?);
        }
        if kind == Resource::SampledImage {
            for i in &self.images {
                self.array_views.push(crate::vk::memory::create_view(
                    gpu,
                    i.raw,
                    PROBE_IMAGE_FORMAT,
                    Some(1),
                )?);
            }
            if slots <= self.max_layers {
                let img =
                    Image::with_layers(gpu, IMAGE_EXTENT, PROBE_IMAGE_FORMAT, usage, Some(slots))?;
                staging.push(staging_buffer(gpu, &probe::packed_bytes(kind, slots))?);
                self.packed = Some(Packed::Image(img, slots));
            }
        }
        Ok(staging)
    }

    /// Copy `staging` into the images (each slot's, then the packed image), leaving them in the
    /// GENERAL layout, and destroy it; a fence wait past `timeout` is an error.
    fn upload(
        &self,
        gpu: &Gpu,
        staging: Vec<Buffer>,
        submitter: &Submitter,
        timeout: Duration,
    ) -> Result<(), VkError> {
        let packed_image = match &self.packed {
            Some(Packed::Image(img, n)) => Some((img, *n)),
            Some(Packed::Buffer(_)) | None => None,
        };
        let uploads: Vec<(&Image, u32)> =
            self.images.iter().map(|i| (i, 1)).chain(packed_image).collect();
        let general = (
            vk::ImageLayout::GENERAL,
            vk::AccessFlags::SHADER_READ,
            vk::PipelineStageFlags::ALL_COMMANDS,
        );
        let waited = submitter.run(gpu, timeout, |cmd| {
            for ((img, layers), st) in uploads.iter().zip(&staging) {
                record_image_upload(gpu, cmd, img, st, (0, *layers), general);
            }
        });
        if waited? == Waited::TimedOut {
            // The copies may still be running: the staging buffers are left alive (leaked), as
            // VUID-vkDestroyBuffer-buffer-00922 asks (see `SceneGpu::build_with`).
            return Err(VkError::Call {
                call: "image upload (fence wait)",
                result: vk::Result::TIMEOUT,
            });
        }
        for st in &staging {
            st.destroy(gpu);
        }
        Ok(())
    }

    /// The descriptors of the probed array; `packed` (`index=dynamic_element`): the packed
    /// resource at `probe::PACKED_SLOT` and, for images, every slot's 2D-array view.
    pub fn targets(
        &self,
        sampler: vk::Sampler,
        kind: Resource,
        packed: bool,
    ) -> Result<Vec<Target>, PackedError> {
        let mut t: Vec<Target> = if !self.buffers.is_empty() {
            self.buffers
                .iter()
                .map(|b| Target::Buffer {
                    raw: b.raw,
                    address: b.address,
                    range: 16 * probe::ELEMENTS as u64,
                })
                .collect()
        } else if packed {
            self.images
                .iter()
                .zip(&self.array_views)
                .map(|(i, v)| Target::Image { image: i.raw, view: *v, sampler, layers: Some(1) })
                .collect()
        } else {
            self.images
                .iter()
                .map(|i| Target::Image { image: i.raw, view: i.view, sampler, layers: None })
                .collect()
        };
        if packed {
            let slot = probe::PACKED_SLOT as usize;
            t[slot] = match &self.packed {
                Some(Packed::Buffer(b)) => {
                    Target::Buffer { raw: b.raw, address: b.address, range: b.size }
                }
                Some(Packed::Image(i, n)) => {
                    Target::Image { image: i.raw, view: i.view, sampler, layers: Some(*n) }
                }
                None if kind == Resource::SampledImage => {
                    return Err(PackedError::TooManyLayers {
                        slots: t.len() as u32,
                        max: self.max_layers,
                    })
                }
                None => return Err(PackedError::NoPacked(kind)),
            };
        }
        Ok(t)
    }

    pub fn destroy(&self, gpu: &Gpu) {
        for b in &self.buffers {
            b.destroy(gpu);
        }
        for i in &self.images {
            i.destroy(gpu);
        }
        for v in &self.array_views {
            unsafe { gpu.device.destroy_image_view(*v, None) };
        }
        match &self.packed {
            Some(Packed::Buffer(b)) => b.destroy(gpu),
            Some(Packed::Image(i, _)) => i.destroy(gpu),
            None => {}
        }
    }
}

/// The probe images' size: 2×2 texels, element e at texel (e & 1, e >> 1).
const IMAGE_EXTENT: vk::Extent2D = vk::Extent2D { width: 2, height: 2 };

/// Every element of `kind`'s `slot`, in element order (texels row by row for a 2×2 image).
fn value_bytes(kind: Resource, slot: u32) -> Vec<u8> {
    (0..probe::ELEMENTS)
        .flat_map(|e| probe::resource_value(kind, slot, e))
        .flat_map(|f| f.to_le_bytes())
        .collect()
}

/// A host buffer holding `bytes` to copy into an image.
fn staging_buffer(gpu: &Gpu, bytes: &[u8]) -> Result<Buffer, VkError> {
    Buffer::with_data(gpu, bytes, vk::BufferUsageFlags::TRANSFER_SRC, "staging")
}

pub fn descriptor_type(kind: Resource) -> vk::DescriptorType {
    match kind {
        Resource::StorageBuffer => vk::DescriptorType::STORAGE_BUFFER,
        Resource::UniformBuffer => vk::DescriptorType::UNIFORM_BUFFER,
        Resource::SampledImage => vk::DescriptorType::COMBINED_IMAGE_SAMPLER,
        Resource::StorageImage => vk::DescriptorType::STORAGE_IMAGE,
        Resource::AccelerationStructure => vk::DescriptorType::ACCELERATION_STRUCTURE_KHR,
    }
}

/// A buffer of `slots` device addresses: slot k → probe TLAS variant `probe::as_slot_tlas(k)`.
pub fn as_table(gpu: &Gpu, variant_addresses: &[u64], slots: u32) -> Result<Buffer, VkError> {
    let addrs: Vec<u64> = (0..slots).map(|k| variant_addresses[probe::as_slot_tlas(k)]).collect();
    address_table(gpu, &addrs, "AS address table")
}

/// A host-visible buffer holding `addresses` as 64-bit values, itself reachable by address.
pub fn address_table(gpu: &Gpu, addresses: &[u64], what: &'static str) -> Result<Buffer, VkError> {
    let bytes: Vec<u8> = addresses.iter().flat_map(|a| a.to_le_bytes()).collect();
    Buffer::with_data(
        gpu,
        &bytes,
        vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS,
        what,
    )
}
