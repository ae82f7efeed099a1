//! What the checks need of one module ([`ModuleInterface`]), a view of its
//! [`crate::reflect::Reflection`]: the stage, set/binding resources by descriptor kind and count,
//! the push block's byte range, and payload / callable data / hit attribute sizes.
use super::error::InterfaceError;
use super::layout::DescriptorKind;
use crate::reflect::{self, Count, Descriptor, Reflection};
use ash::vk;
use rspirv::spirv::ExecutionModel;

/// A set/binding resource variable: its kind, and its array length (`None`: not an array;
/// `Some(0)`: a runtime array).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Resource {
    pub set: u32,
    pub binding: u32,
    pub kind: DescriptorKind,
    pub array: Option<u32>,
}

/// What one module declares that a pipeline's layout and its other stages must agree with.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ModuleInterface {
    pub stage: vk::ShaderStageFlags,
    pub resources: Vec<Resource>,
    /// The push-constant block's byte range `(first member offset, end)`, if declared.
    pub push: Option<(u32, u32)>,
    /// Outgoing ray payloads and callable data, incoming ones, and the hit attribute: sizes in
    /// bytes (scalar alignment, as `maxPipelineRayPayloadSize` counts them).
    pub payloads: Vec<u32>,
    pub incoming_payload: Option<u32>,
    pub callable_data: Vec<u32>,
    pub incoming_callable_data: Option<u32>,
    pub hit_attribute: Option<u32>,
}

fn kind(d: Descriptor) -> DescriptorKind {
    match d {
        Descriptor::AccelerationStructure => DescriptorKind::AccelerationStructure,
        Descriptor::StorageImage(_) => DescriptorKind::StorageImage,
        Descriptor::SampledImage => DescriptorKind::SampledImage,
        Descriptor::CombinedImageSampler => DescriptorKind::CombinedImageSampler,
        Descriptor::Sampler => DescriptorKind::Sampler,
        Descriptor::StorageBuffer => DescriptorKind::StorageBuffer,
        Descriptor::UniformBuffer => DescriptorKind::UniformBuffer,
        Descriptor::UniformTexelBuffer => DescriptorKind::UniformTexelBuffer,
        Descriptor::StorageTexelBuffer => DescriptorKind::StorageTexelBuffer,
        Descriptor::InputAttachment => DescriptorKind::InputAttachment,
    }
}

/// The shader stage of an execution model (empty: not a Vulkan stage rtprobe checks).
fn stage(model: ExecutionModel) -> vk::ShaderStageFlags {
    match model {
        ExecutionModel::Vertex => vk::ShaderStageFlags::VERTEX,
        ExecutionModel::Fragment => vk::ShaderStageFlags::FRAGMENT,
        ExecutionModel::GLCompute => vk::ShaderStageFlags::COMPUTE,
        ExecutionModel::RayGenerationKHR => vk::ShaderStageFlags::RAYGEN_KHR,
        ExecutionModel::IntersectionKHR => vk::ShaderStageFlags::INTERSECTION_KHR,
        ExecutionModel::AnyHitKHR => vk::ShaderStageFlags::ANY_HIT_KHR,
        ExecutionModel::ClosestHitKHR => vk::ShaderStageFlags::CLOSEST_HIT_KHR,
        ExecutionModel::MissKHR => vk::ShaderStageFlags::MISS_KHR,
        ExecutionModel::CallableKHR => vk::ShaderStageFlags::CALLABLE_KHR,
        _ => vk::ShaderStageFlags::empty(),
    }
}

impl ModuleInterface {
    /// Read the interface of the module `words` (its only entry point).
    pub fn read(words: &[u32]) -> Result<ModuleInterface, InterfaceError> {
        let r = reflect::reflect_words(words, None)
            .map_err(|e| InterfaceError::NotSpirv(e.to_string()))?;
        Ok(ModuleInterface::of(&r))
    }

    /// The view of reflection `r`.
    pub fn of(r: &Reflection) -> ModuleInterface {
        let resources = r
            .bindings
            .iter()
            .map(|b| Resource {
                set: b.set,
                binding: b.binding,
                kind: kind(b.descriptor),
                array: match b.count {
                    Count::One => None,
                    Count::Fixed(n) => Some(n),
                    Count::Runtime => Some(0),
                },
            })
            .collect();
        let size = |io: &Option<reflect::Io>| io.as_ref().map(|i| i.size);
        ModuleInterface {
            stage: stage(r.model),
            resources,
            push: r.push.as_ref().map(|p| (p.start, p.end)),
            payloads: r.payloads.iter().map(|p| p.size).collect(),
            incoming_payload: size(&r.incoming_payload),
            callable_data: r.callable_data.iter().map(|p| p.size).collect(),
            incoming_callable_data: size(&r.incoming_callable_data),
            hit_attribute: size(&r.hit_attribute),
        }
    }
}
