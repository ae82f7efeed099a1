//! What a pipeline provides its shaders ([`PipelineDesc`]): each binding's descriptor kind and
//! count and the stages that see it, the push-constant range, the device's hit-attribute limit,
//! and which modules share a hit group.
use ash::vk;

/// A descriptor's kind, as a layout binding declares it (`VkDescriptorType`) and as a shader's
/// resource variable needs it (Vulkan 1.4.360, "Shader Resource and Descriptor Type
/// Correspondence").
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum DescriptorKind {
    StorageBuffer,
    UniformBuffer,
    SampledImage,
    StorageImage,
    CombinedImageSampler,
    Sampler,
    UniformTexelBuffer,
    StorageTexelBuffer,
    InputAttachment,
    AccelerationStructure,
}

impl DescriptorKind {
    /// The kind of an `OpTypeImage` with `Dim` `dim` and `Sampled` `sampled`.
    pub fn of_image(dim: u32, sampled: u32) -> DescriptorKind {
        const DIM_BUFFER: u32 = 5;
        const DIM_SUBPASS_DATA: u32 = 6;
        match (dim, sampled) {
            (DIM_SUBPASS_DATA, _) => DescriptorKind::InputAttachment,
            (DIM_BUFFER, 1) => DescriptorKind::UniformTexelBuffer,
            (DIM_BUFFER, _) => DescriptorKind::StorageTexelBuffer,
            (_, 1) => DescriptorKind::SampledImage,
            (_, _) => DescriptorKind::StorageImage,
        }
    }

    /// Whether a layout binding of this kind can back a shader variable of kind `shader`: the
    /// same kind, or a combined image sampler behind a sampled image or a sampler.
    pub fn backs(self, shader: DescriptorKind) -> bool {
        self == shader
            || (self == DescriptorKind::CombinedImageSampler
                && matches!(shader, DescriptorKind::SampledImage | DescriptorKind::Sampler))
    }

    /// The Vulkan name (`VK_DESCRIPTOR_TYPE_…` without the prefix, lower case).
    pub fn as_str(self) -> &'static str {
        match self {
            DescriptorKind::StorageBuffer => "storage buffer",
            DescriptorKind::UniformBuffer => "uniform buffer",
            DescriptorKind::SampledImage => "sampled image",
            DescriptorKind::StorageImage => "storage image",
            DescriptorKind::CombinedImageSampler => "combined image sampler",
            DescriptorKind::Sampler => "sampler",
            DescriptorKind::UniformTexelBuffer => "uniform texel buffer",
            DescriptorKind::StorageTexelBuffer => "storage texel buffer",
            DescriptorKind::InputAttachment => "input attachment",
            DescriptorKind::AccelerationStructure => "acceleration structure",
        }
    }

    /// The kind of a `VkDescriptorType` (`None`: one rtprobe's layouts never hold).
    pub fn of_vk(t: vk::DescriptorType) -> Option<DescriptorKind> {
        Some(match t {
            vk::DescriptorType::STORAGE_BUFFER => DescriptorKind::StorageBuffer,
            vk::DescriptorType::UNIFORM_BUFFER => DescriptorKind::UniformBuffer,
            vk::DescriptorType::SAMPLED_IMAGE => DescriptorKind::SampledImage,
            vk::DescriptorType::STORAGE_IMAGE => DescriptorKind::StorageImage,
            vk::DescriptorType::COMBINED_IMAGE_SAMPLER => DescriptorKind::CombinedImageSampler,
            vk::DescriptorType::SAMPLER => DescriptorKind::Sampler,
            vk::DescriptorType::UNIFORM_TEXEL_BUFFER => DescriptorKind::UniformTexelBuffer,
            vk::DescriptorType::STORAGE_TEXEL_BUFFER => DescriptorKind::StorageTexelBuffer,
            vk::DescriptorType::INPUT_ATTACHMENT => DescriptorKind::InputAttachment,
            vk::DescriptorType::ACCELERATION_STRUCTURE_KHR => DescriptorKind::AccelerationStructure,
            _ => return None,
        })
    }
}

/// One layout binding (or, under descriptor heaps, one set/binding mapping and what the heap
/// holds there).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BindingDesc {
    pub set: u32,
    pub binding: u32,
    pub kind: DescriptorKind,
    /// `descriptorCount`.
    pub count: u32,
    pub stages: vk::ShaderStageFlags,
}

/// The push-constant range (push data under descriptor heaps).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PushRange {
    pub offset: u32,
    pub size: u32,
    pub stages: vk::ShaderStageFlags,
}

/// A ray tracing hit group: indices into the pipeline's modules.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct HitGroup {
    pub closest_hit: Option<usize>,
    pub any_hit: Option<usize>,
    pub intersection: Option<usize>,
}

/// What a pipeline provides its shaders.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct PipelineDesc {
    pub bindings: Vec<BindingDesc>,
    pub push: Option<PushRange>,
    /// `maxRayHitAttributeSize` of the device (0: not a ray tracing pipeline).
    pub max_hit_attribute: u32,
    pub hit_groups: Vec<HitGroup>,
}
