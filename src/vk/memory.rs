//! Buffers and images with their memory: one allocation each (the probes' scenes are small), host
//! visible where the CPU writes or reads them, device local for acceleration structures.
use super::error::{VkError, VkResultExt};
use super::Gpu;
use ash::vk;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Location {
    /// HOST_VISIBLE | HOST_COHERENT, persistently mapped.
    Host,
    /// What the device writes and the host reads back: HOST_VISIBLE | HOST_COHERENT, and
    /// HOST_CACHED where a type has it (host reads of uncached memory, write-combined or over
    /// the bus, are many times slower), persistently mapped.
    Readback,
    /// DEVICE_LOCAL.
    Device,
}

pub struct Buffer {
    pub raw: vk::Buffer,
    pub memory: vk::DeviceMemory,
    pub size: u64,
    /// Device address (0 unless created with SHADER_DEVICE_ADDRESS usage).
    pub address: u64,
    mapped: *mut u8,
}

fn allocate(
    gpu: &Gpu,
    req: vk::MemoryRequirements,
    loc: Location,
    device_address: bool,
    what: &'static str,
) -> Result<vk::DeviceMemory, VkError> {
    let find = |f| gpu.info.memory_type_index(req.memory_type_bits, f);
    let type_index = pick(loc, find).ok_or(VkError::NoMemoryType {
        what,
        type_bits: req.memory_type_bits,
        flags: preferred(loc)[0],
    })?;
    let mut flags_info =
        vk::MemoryAllocateFlagsInfo::default().flags(vk::MemoryAllocateFlags::DEVICE_ADDRESS);
    let mut info =
        vk::MemoryAllocateInfo::default().allocation_size(req.size).memory_type_index(type_index);
    if device_address {
        info = info.push_next(&mut flags_info);
    }
    unsafe { gpu.device.allocate_memory(&info, None) }.at("vkAllocateMemory")
}

/// The memory property flags a location takes, best first: the first that some allowed type
/// has is used (`DeviceInfo::memory_type_index`: the lowest such type).
fn preferred(loc: Location) -> Vec<vk::MemoryPropertyFlags> {
    use vk::MemoryPropertyFlags as F;
    match loc {
        Location::Host => vec![F::HOST_VISIBLE | F::HOST_COHERENT],
        Location::Readback => {
            vec![
                F::HOST_VISIBLE | F::HOST_COHERENT | F::HOST_CACHED,
                F::HOST_VISIBLE | F::HOST_COHERENT,
            ]
        }
        Location::Device => vec![F::DEVICE_LOCAL, F::empty()],
    }
}

/// The memory type for `loc`: the first of its [`preferred`] flags that `find` (the lowest
/// allowed type having them) finds.
fn pick(loc: Location, find: impl Fn(vk::MemoryPropertyFlags) -> Option<u32>) -> Option<u32> {
    preferred(loc).into_iter().find_map(find)
}

impl Buffer {
    pub fn new(
        gpu: &Gpu,
        size: u64,
        usage: vk::BufferUsageFlags,
        loc: Location,
        what: &'static str,
    ) -> Result<Buffer, VkError> {
        let d = &gpu.device;
        let size = size.max(16);
        let raw = unsafe {
            d.create_buffer(&vk::BufferCreateInfo::default().size(size).usage(usage), None)
        }
        .at("vkCreateBuffer")?;
        let req = unsafe { d.get_buffer_memory_requirements(raw) };
        let bda = usage.contains(vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS);
        let memory = match allocate(gpu, req, loc, bda, what) {
            Ok(m) => m,
            Err(e) => {
                unsafe { d.destroy_buffer(raw, None) };
                return Err(e);
            }
        };
        unsafe { d.bind_buffer_memory(raw, memory, 0) }.at("vkBindBufferMemory")?;
        let mapped = match loc {
            Location::Host | Location::Readback => {
                unsafe { d.map_memory(memory, 0, vk::WHOLE_SIZE, vk::MemoryMapFlags::empty()) }
                    .at("vkMapMemory")? as *mut u8
            }
            Location::Device => std::ptr::null_mut(),
        };
        let address = if bda {
            unsafe {
                d.get_buffer_device_address(&vk::BufferDeviceAddressInfo::default().buffer(raw))
            }
        } else {
            0
        };
        Ok(Buffer { raw, memory, size, address, mapped })
    }

    /// A host-visible buffer holding `bytes`.
    pub fn with_data(
        gpu: &Gpu,
        bytes: &[u8],
        usage: vk::BufferUsageFlags,
        what: &'static str,
    ) -> Result<Buffer, VkError> {
        let b = Buffer::new(gpu, bytes.len() as u64, usage, Location::Host, what)?;
        b.write(0, bytes);
        Ok(b)
    }

    pub fn write(&self, offset: usize, bytes: &[u8]) {
        assert!(!self.mapped.is_null(), "write to a device-local buffer");
        assert!(offset + bytes.len() <= self.size as usize, "write past the end of a buffer");
        // SAFETY: mapped for the buffer's whole size; bounds checked above.
        unsafe {
            std::ptr::copy_nonoverlapping(bytes.as_ptr(), self.mapped.add(offset), bytes.len())
        };
    }

    pub fn read(&self, len: usize) -> Vec<u8> {
        assert!(!self.mapped.is_null(), "read from a device-local buffer");
        let len = len.min(self.size as usize);
        let mut v = vec![0u8; len];
        // SAFETY: mapped for the buffer's whole size; len clamped.
        unsafe { std::ptr::copy_nonoverlapping(self.mapped, v.as_mut_ptr(), len) };
        v
    }

    /// The first `len` bytes of the mapping (clamped to the buffer), read in place: what the
    /// device wrote, once the work that wrote it is known complete (a fence waited on).
    pub fn mapped(&self, len: usize) -> &[u8] {
        assert!(!self.mapped.is_null(), "read from a device-local buffer");
        let len = len.min(self.size as usize);
        // SAFETY: mapped for the buffer's whole size (host coherent) for as long as `self`
        // lives; len clamped; the caller reads it only after the device's writes completed.
        unsafe { std::slice::from_raw_parts(self.mapped, len) }
    }

    /// Set `len` bytes from `offset` to `byte` (no staging vector).
    pub fn fill(&self, offset: usize, len: usize, byte: u8) {
        assert!(!self.mapped.is_null(), "write to a device-local buffer");
        assert!(offset + len <= self.size as usize, "write past the end of a buffer");
        // SAFETY: mapped for the buffer's whole size; bounds checked above.
        unsafe { std::ptr::write_bytes(self.mapped.add(offset), byte, len) };
    }

    pub fn destroy(&self, gpu: &Gpu) {
        unsafe {
            gpu.device.destroy_buffer(self.raw, None);
            gpu.device.free_memory(self.memory, None);
        }
    }
}

/// A small 2D image with one view, left in `GENERAL` layout (valid for sampling and storage).
pub struct Image {
    pub raw: vk::Image,
    pub view: vk::ImageView,
    pub memory: vk::DeviceMemory,
    pub extent: vk::Extent2D,
}

impl Image {
    pub fn new(
        gpu: &Gpu,
        extent: vk::Extent2D,
        format: vk::Format,
        usage: vk::ImageUsageFlags,
    ) -> Result<Image, VkError> {
        Self::with_layers(gpu, extent, format, usage, None)
    }

    /// `layers`: `None` a 2D image with a 2D view; `Some(n)` an array image of `n` layers with a
    /// 2D-array view of all of them.
    pub fn with_layers(
        gpu: &Gpu,
        extent: vk::Extent2D,
        format: vk::Format,
        usage: vk::ImageUsageFlags,
        layers: Option<u32>,
    ) -> Result<Image, VkError> {
        let d = &gpu.device;
        let ci = vk::ImageCreateInfo::default()
            .image_type(vk::ImageType::TYPE_2D)
            .format(format)
            .extent(vk::Extent3D { width: extent.width, height: extent.height, depth: 1 })
            .mip_levels(1)
            .array_layers(layers.unwrap_or(1))
            .samples(vk::SampleCountFlags::TYPE_1)
            .tiling(vk::ImageTiling::OPTIMAL)
            .usage(usage)
            .initial_layout(vk::ImageLayout::UNDEFINED);
        let raw = unsafe { d.create_image(&ci, None) }.at("vkCreateImage")?;
        let req = unsafe { d.get_image_memory_requirements(raw) };
        let memory = allocate(gpu, req, Location::Device, false, "image")?;
        unsafe { d.bind_image_memory(raw, memory, 0) }.at("vkBindImageMemory")?;
        let view = create_view(gpu, raw, format, layers)?;
        Ok(Image { raw, view, memory, extent })
    }

    pub fn destroy(&self, gpu: &Gpu) {
        unsafe {
            gpu.device.destroy_image_view(self.view, None);
            gpu.device.destroy_image(self.raw, None);
            gpu.device.free_memory(self.memory, None);
        }
    }
}

/// A view of `image`: 2D (`layers` `None`), or 2D array over its first `n` layers.
pub fn create_view(
    gpu: &Gpu,
    image: vk::Image,
    format: vk::Format,
    layers: Option<u32>,
) -> Result<vk::ImageView, VkError> {
    let vci = vk::ImageViewCreateInfo::default()
        .image(image)
        .view_type(view_type(layers))
        .format(format)
        .subresource_range(layer_range(layers));
    unsafe { gpu.device.create_image_view(&vci, None) }.at("vkCreateImageView")
}

/// The view type of a view over `layers` (see [`create_view`]).
pub fn view_type(layers: Option<u32>) -> vk::ImageViewType {
    if layers.is_some() {
        vk::ImageViewType::TYPE_2D_ARRAY
    } else {
        vk::ImageViewType::TYPE_2D
    }
}

/// The colour subresource range over `layers` (one layer for `None`).
pub fn layer_range(layers: Option<u32>) -> vk::ImageSubresourceRange {
    vk::ImageSubresourceRange { layer_count: layers.unwrap_or(1), ..color_range() }
}

pub fn color_range() -> vk::ImageSubresourceRange {
    vk::ImageSubresourceRange {
        aspect_mask: vk::ImageAspectFlags::COLOR,
        base_mip_level: 0,
        level_count: 1,
        base_array_layer: 0,
        layer_count: 1,
    }
}

/// A full memory barrier between everything before and after (probes are small; precision of
/// synchronization is not what they test).
pub fn full_barrier(gpu: &Gpu, cmd: vk::CommandBuffer) {
    let mb = [vk::MemoryBarrier::default()
        .src_access_mask(vk::AccessFlags::MEMORY_WRITE)
        .dst_access_mask(vk::AccessFlags::MEMORY_READ | vk::AccessFlags::MEMORY_WRITE)];
    unsafe {
        gpu.device.cmd_pipeline_barrier(
            cmd,
            vk::PipelineStageFlags::ALL_COMMANDS,
            vk::PipelineStageFlags::ALL_COMMANDS,
            vk::DependencyFlags::empty(),
            &mb,
            &[],
            &[],
        )
    };
}

/// One image layout transition (whole color image).
pub struct Transition {
    pub from: (vk::ImageLayout, vk::AccessFlags, vk::PipelineStageFlags),
    pub to: (vk::ImageLayout, vk::AccessFlags, vk::PipelineStageFlags),
}

pub fn transition(gpu: &Gpu, cmd: vk::CommandBuffer, image: vk::Image, t: Transition) {
    let b = vk::ImageMemoryBarrier::default()
        .image(image)
        .subresource_range(vk::ImageSubresourceRange {
            layer_count: vk::REMAINING_ARRAY_LAYERS,
            ..color_range()
        })
        .old_layout(t.from.0)
        .new_layout(t.to.0)
        .src_access_mask(t.from.1)
        .dst_access_mask(t.to.1);
    unsafe {
        gpu.device.cmd_pipeline_barrier(
            cmd,
            t.from.2,
            t.to.2,
            vk::DependencyFlags::empty(),
            &[],
            &[],
            &[b],
        )
    };
}

/// An uploaded image's use after its copy: the layout, the access and the stage that read it.
pub type ImageUse = (vk::ImageLayout, vk::AccessFlags, vk::PipelineStageFlags);

/// Record the copy of `staging` from `offset` into the first `layers` layers of `img` (its
/// whole extent): UNDEFINED → TRANSFER_DST, the copy, then `then` for the shaders' reads.
pub fn record_image_upload(
    gpu: &Gpu,
    cmd: vk::CommandBuffer,
    img: &Image,
    staging: &Buffer,
    (offset, layers): (u64, u32),
    then: ImageUse,
) {
    let top =
        (vk::ImageLayout::UNDEFINED, vk::AccessFlags::empty(), vk::PipelineStageFlags::TOP_OF_PIPE);
    let dst = (
        vk::ImageLayout::TRANSFER_DST_OPTIMAL,
        vk::AccessFlags::TRANSFER_WRITE,
        vk::PipelineStageFlags::TRANSFER,
    );
    transition(gpu, cmd, img.raw, Transition { from: top, to: dst });
    let region = vk::BufferImageCopy::default()
        .buffer_offset(offset)
        .image_subresource(vk::ImageSubresourceLayers {
            aspect_mask: vk::ImageAspectFlags::COLOR,
            mip_level: 0,
            base_array_layer: 0,
            layer_count: layers,
        })
        .image_extent(vk::Extent3D {
            width: img.extent.width,
            height: img.extent.height,
            depth: 1,
        });
    // SAFETY: `cmd` is recording; the caller keeps `img` and `staging` alive until the
    // submission's fence has signalled.
    unsafe {
        gpu.device.cmd_copy_buffer_to_image(
            cmd,
            staging.raw,
            img.raw,
            vk::ImageLayout::TRANSFER_DST_OPTIMAL,
            &[region],
        )
    };
    transition(gpu, cmd, img.raw, Transition { from: dst, to: then });
}

#[cfg(test)]
mod tests {
    use super::*;
    use vk::MemoryPropertyFlags as F;

    /// The lowest of `types` having `flags` (as `DeviceInfo::memory_type_index` finds).
    fn lowest(types: &[F], flags: F) -> Option<u32> {
        types.iter().position(|t| t.contains(flags)).map(|i| i as u32)
    }

    /// A discrete GPU's order (the spec sorts a type before its supersets): device local, then
    /// host visible and coherent (uncached: write-combined), then the same cached. Readback
    /// takes the cached type, other host buffers the first; without a cached type, readback
    /// falls back to the coherent one (the twin).
    #[test]
    fn readback_prefers_cached_host_memory() {
        let hv = F::HOST_VISIBLE | F::HOST_COHERENT;
        let discrete = [F::empty(), F::DEVICE_LOCAL, hv, hv | F::HOST_CACHED];
        assert_eq!(pick(Location::Readback, |f| lowest(&discrete, f)), Some(3));
        assert_eq!(pick(Location::Host, |f| lowest(&discrete, f)), Some(2));
        assert_eq!(pick(Location::Device, |f| lowest(&discrete, f)), Some(1));
        let uncached = [F::DEVICE_LOCAL, hv];
        assert_eq!(pick(Location::Readback, |f| lowest(&uncached, f)), Some(1));
        assert_eq!(pick(Location::Device, |f| lowest(&[hv], f)), Some(0));
        assert_eq!(pick(Location::Host, |f| lowest(&[F::DEVICE_LOCAL], f)), None);
    }
}
