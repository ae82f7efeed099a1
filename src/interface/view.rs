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
    /// Outgoing ray payloads and callable data, incoming ones, and the hit attribute.
    pub payloads: Vec<IoShape>,
    pub incoming_payload: Option<IoShape>,
    pub callable_data: Vec<IoShape>,
    pub incoming_callable_data: Option<IoShape>,
    pub hit_attribute: Option<IoShape>,
}

/// A payload, callable data or hit attribute as the interface check compares it: its size in
/// bytes at scalar alignment (as `maxPipelineRayPayloadSize` and `maxRayHitAttributeSize`
/// count), its structure ([`reflect::Ty::structure`], names left out), which two shapes must
/// share to be equal, and its scalars in order ([`reflect::Ty::leaves`]).
///
/// The rule (Vulkan 1.4.360, "Ray Tracing Pipeline Interface", a *must*): a payload "must be the
/// same structure for all shader stages using the payload for that ray"; callable data and an
/// intersection's hit attribute likewise: compared by structure. A triangle hit's attribute
/// "must be a vector of 2 32-bit floating-point values": compared by its scalars
/// ([`IoShape::is_barycentrics`]), because DXC declares it as
/// `BuiltInTriangleIntersectionAttributes`, a struct of one `float2`, which drivers and the
/// validation layers take as that vector — the one place rtprobe is looser than the text.
#[derive(Clone, Debug, Eq)]
pub struct IoShape {
    pub size: u32,
    pub structure: String,
    pub leaves: String,
}

impl IoShape {
    pub fn of(io: &reflect::Io) -> IoShape {
        IoShape { size: io.size, structure: io.ty.structure(), leaves: io.ty.leaves() }
    }

    /// A triangle hit's attribute: two 32-bit floats.
    pub fn barycentrics() -> IoShape {
        IoShape { size: 8, structure: "vec2<f32>".into(), leaves: "f32 f32".into() }
    }

    /// Whether this is two 32-bit floats however grouped (`vec2`, DXC's struct of a `float2`).
    pub fn is_barycentrics(&self) -> bool {
        self.size == 8 && self.leaves == "f32 f32"
    }
}

impl PartialEq for IoShape {
    fn eq(&self, other: &IoShape) -> bool {
        self.size == other.size && self.structure == other.structure
    }
}

impl std::fmt::Display for IoShape {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        write!(f, "{} ({} bytes)", self.structure, self.size)
    }
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
        let size = |io: &Option<reflect::Io>| io.as_ref().map(IoShape::of);
        ModuleInterface {
            stage: stage(r.model),
            resources,
            push: r.push.as_ref().map(|p| (p.start, p.end)),
            payloads: r.payloads.iter().map(IoShape::of).collect(),
            incoming_payload: size(&r.incoming_payload),
            callable_data: r.callable_data.iter().map(IoShape::of).collect(),
            incoming_callable_data: size(&r.incoming_callable_data),
            hit_attribute: size(&r.hit_attribute),
        }
    }
}
