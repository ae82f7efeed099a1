//! Whether the `scene_layout` texture cells' images and array fit the device's queried limits:
//! each image no wider or taller than `maxImageDimension2D` (VUID-VkImageCreateInfo-extent-02252),
//! the array's combined image samplers within the per-stage and per-set sampled-image and sampler
//! limits (a combined image sampler counts against both; VUID-VkPipelineLayoutCreateInfo-
//! descriptorType-06939 and 03016, Vulkan 1.4.360). An array bound update-after-bind is held to
//! the larger of each limit and its update-after-bind one (-03025, -03022). A cell over a limit
//! is `unsupported` with the image, its size and the limit: the limit is the device's, queried.
use crate::vk::DeviceInfo;

/// One queried limit, by its Vulkan name.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limit {
    pub name: &'static str,
    pub value: u32,
}

/// The limits a texture cell's images and array are held to.
#[derive(Clone, Debug, PartialEq)]
pub struct TextureLimits {
    /// `maxImageDimension2D`.
    pub dimension: Limit,
    /// The descriptor-count limits of the array.
    pub descriptors: Vec<Limit>,
}

impl TextureLimits {
    /// `info`'s limits for the texture array, bound update-after-bind (`uab`) or not.
    pub fn of(info: &DeviceInfo, uab: bool) -> TextureLimits {
        let l = &info.properties.core.limits;
        let plain = [
            ("maxPerStageDescriptorSampledImages", l.max_per_stage_descriptor_sampled_images),
            ("maxDescriptorSetSampledImages", l.max_descriptor_set_sampled_images),
            ("maxPerStageDescriptorSamplers", l.max_per_stage_descriptor_samplers),
            ("maxDescriptorSetSamplers", l.max_descriptor_set_samplers),
        ];
        let mut descriptors: Vec<Limit> =
            plain.iter().map(|&(name, value)| Limit { name, value }).collect();
        if let (true, Some(v)) = (uab, info.properties.v12) {
            let after = [
                (
                    "maxPerStageDescriptorUpdateAfterBindSampledImages",
                    v.max_per_stage_descriptor_update_after_bind_sampled_images,
                ),
                (
                    "maxDescriptorSetUpdateAfterBindSampledImages",
                    v.max_descriptor_set_update_after_bind_sampled_images,
                ),
                (
                    "maxPerStageDescriptorUpdateAfterBindSamplers",
                    v.max_per_stage_descriptor_update_after_bind_samplers,
                ),
                (
                    "maxDescriptorSetUpdateAfterBindSamplers",
                    v.max_descriptor_set_update_after_bind_samplers,
                ),
            ];
            for (d, (name, value)) in descriptors.iter_mut().zip(after) {
                if value > d.value {
                    *d = Limit { name, value };
                }
            }
        }
        let dimension = Limit { name: "maxImageDimension2D", value: l.max_image_dimension2_d };
        TextureLimits { dimension, descriptors }
    }
}

/// One image of the array: its name in messages and its size.
pub struct ImageSize<'a> {
    pub name: &'a str,
    pub width: u32,
    pub height: u32,
}

/// Why `images`, in an array of `elements` descriptors, do not fit `limits` (the first image over
/// the dimension limit, with how many more are; else the first descriptor limit exceeded), or
/// `None`.
pub fn over(images: &[ImageSize], elements: u64, limits: &TextureLimits) -> Option<String> {
    let max = limits.dimension.value;
    let big: Vec<&ImageSize> = images.iter().filter(|i| i.width > max || i.height > max).collect();
    if let Some(first) = big.first() {
        let more = match big.len() - 1 {
            0 => String::new(),
            n => format!(" (and {n} more image{})", if n == 1 { "" } else { "s" }),
        };
        return Some(format!(
            "{} is {}×{} texels, more than the device's {} ({max}){more}",
            first.name, first.width, first.height, limits.dimension.name
        ));
    }
    let l = limits.descriptors.iter().find(|l| elements > u64::from(l.value))?;
    Some(format!(
        "the texture array holds {elements} combined image samplers ({} images, repeated up to the probe's slots), more than the device's {} ({})",
        images.len(),
        l.name,
        l.value
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn limits(dimension: u32, per_stage: u32) -> TextureLimits {
        TextureLimits {
            dimension: Limit { name: "maxImageDimension2D", value: dimension },
            descriptors: vec![
                Limit { name: "maxPerStageDescriptorSampledImages", value: per_stage },
                Limit { name: "maxDescriptorSetSamplers", value: per_stage + 1 },
            ],
        }
    }

    /// An image at the limit fits, one texel more in either direction is named with its size and
    /// the limit; an array one descriptor over a limit is named with that limit.
    #[test]
    fn images_and_arrays_over_fake_limits_are_named() {
        let img = |name, width, height| ImageSize { name, width, height };
        let fits = [img("images[0] (uri \"a.png\")", 64, 64), img("images[1]", 16, 16)];
        assert_eq!(over(&fits, 8, &limits(64, 8)), None);
        let wide =
            [img("images[0] (uri \"a.png\")", 64, 64), img("images[1] (uri \"w.png\")", 65, 1)];
        let e = over(&wide, 8, &limits(64, 8)).unwrap();
        assert!(
            e.contains("images[1] (uri \"w.png\") is 65×1")
                && e.contains("maxImageDimension2D (64)"),
            "{e}"
        );
        assert!(!e.contains("more image"), "{e}");
        let tall = [img("images[0]", 1, 65), img("images[3]", 70, 2)];
        let e = over(&tall, 8, &limits(64, 8)).unwrap();
        assert!(e.starts_with("images[0] is 1×65") && e.contains("(and 1 more image)"), "{e}");
        let e = over(&fits, 9, &limits(64, 8)).unwrap();
        assert!(
            e.contains("holds 9 combined image samplers")
                && e.contains("maxPerStageDescriptorSampledImages (8)"),
            "{e}"
        );
        let e = over(&fits, 10, &limits(64, 9)).unwrap();
        assert!(e.contains("maxPerStageDescriptorSampledImages (9)"), "{e}");
    }

    /// The update-after-bind limits replace smaller plain ones only for an update-after-bind
    /// array; lavapipe's limits (its `DeviceInfo`) are read, not assumed.
    #[test]
    fn update_after_bind_limits_apply_only_to_update_after_bind_arrays() {
        let mut info = crate::vk::features::blank_device();
        info.properties.core.limits.max_per_stage_descriptor_sampled_images = 16;
        info.properties.core.limits.max_image_dimension2_d = 4096;
        info.properties.v12 = Some(ash::vk::PhysicalDeviceVulkan12Properties {
            max_per_stage_descriptor_update_after_bind_sampled_images: 500_000,
            ..Default::default()
        });
        let plain = TextureLimits::of(&info, false);
        assert_eq!(plain.dimension.value, 4096);
        assert_eq!(
            plain.descriptors[0],
            Limit { name: "maxPerStageDescriptorSampledImages", value: 16 }
        );
        let uab = TextureLimits::of(&info, true);
        assert_eq!(uab.descriptors[0].value, 500_000);
        assert_eq!(uab.descriptors[0].name, "maxPerStageDescriptorUpdateAfterBindSampledImages");
    }
}
