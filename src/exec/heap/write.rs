//! Writing descriptors into heap bytes: the resource heap's (vkWriteResourceDescriptorsEXT, each
//! at its [`HeapLayout`] place) and the sampler heap's (vkWriteSamplerDescriptorsEXT, at the
//! sampler stride).
use super::layout::HeapLayout;
use super::sizes::{heap_type, Sizes};
use crate::exec::resources::{descriptor_type, Target};
use crate::model::Resource;
use crate::vk::features::PROBE_IMAGE_FORMAT;
use crate::vk::heap as h;
use crate::vk::{VkError, VkResultExt};
use ash::vk;
use std::ffi::c_void;

/// One descriptor placed at a byte offset of the resource heap (`run --shader`'s heap model):
/// what it describes, its type, and an image's view format.
pub struct Placed {
    pub offset: usize,
    pub ty: vk::DescriptorType,
    pub target: Target,
    pub format: vk::Format,
}

/// The resource descriptors to write: what each describes (`kinds`: type, image or not, index
/// into `views` or `ranges`) and where it goes (`at`: offset and size). The write infos point
/// into these, so they live until the write call.
#[derive(Default)]
pub(super) struct ResourceWrites {
    ranges: Vec<h::DeviceAddressRange>,
    views: Vec<vk::ImageViewCreateInfo<'static>>,
    kinds: Vec<(vk::DescriptorType, bool, usize)>,
    at: Vec<(usize, usize)>,
}

impl ResourceWrites {
    pub(super) fn of(
        sizes: &Sizes,
        targets: &[(u32, Resource, Vec<Target>)],
        layout: &HeapLayout,
    ) -> ResourceWrites {
        let mut w = ResourceWrites::default();
        for (b, kind, ts) in targets {
            let ty = &descriptor_type(*kind);
            for (i, t) in ts.iter().enumerate() {
                w.at.push((layout.offset(*b, i), sizes.written(*ty) as usize));
                w.add(*ty, t, PROBE_IMAGE_FORMAT);
            }
        }
        w
    }

    /// The writes of descriptors at given places (`run --shader`'s heap model).
    pub(super) fn placed(sizes: &Sizes, placed: &[Placed]) -> ResourceWrites {
        let mut w = ResourceWrites::default();
        for p in placed {
            w.at.push((p.offset, sizes.written(p.ty) as usize));
            w.add(p.ty, &p.target, p.format);
        }
        w
    }

    /// One descriptor of type `ty` for `t` (an image viewed as `format`).
    fn add(&mut self, ty: vk::DescriptorType, t: &Target, format: vk::Format) {
        match *t {
            Target::Buffer { address, range, .. } => {
                self.ranges.push(h::DeviceAddressRange { address, size: range });
                self.kinds.push((heap_type(ty), false, self.ranges.len() - 1));
            }
            // The range of an AS descriptor is unused and may be 0 (VkResourceDescriptorInfoEXT).
            Target::Accel { address, .. } => {
                self.ranges.push(h::DeviceAddressRange { address, size: 0 });
                self.kinds.push((heap_type(ty), false, self.ranges.len() - 1));
            }
            Target::Image { image, layers, .. } => {
                self.views.push(
                    vk::ImageViewCreateInfo::default()
                        .image(image)
                        .view_type(crate::vk::memory::view_type(layers))
                        .format(format)
                        .subresource_range(crate::vk::memory::layer_range(layers)),
                );
                self.kinds.push((heap_type(ty), true, self.views.len() - 1));
            }
        }
    }

    /// The resource heap's bytes: every descriptor written at its place.
    pub(super) fn write(&self, sizes: &Sizes) -> Result<Vec<u8>, VkError> {
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
pub(super) fn write_samplers(
    sizes: &Sizes,
    samplers: &[vk::SamplerCreateInfo],
) -> Result<Vec<u8>, VkError> {
    let sampler_size = sizes.written(vk::DescriptorType::SAMPLER).max(1) as usize;
    let sampler_stride = sizes.class(vk::DescriptorType::SAMPLER).max(sampler_size as u32) as usize;
    let mut sbytes = vec![0u8; sampler_stride * (samplers.len().max(1) - 1) + sampler_size];
    if samplers.is_empty() {
        // An empty sampler heap (`run --shader`): nothing to write (samplerCount must be > 0).
        return Ok(sbytes);
    }
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
