//! The matrix axes' value types. The snake_case names here are the user's contract: cell ids,
//! `--filter`, reports and baselines all use them. Each axis lists its values in one `ALL` array,
//! in the order cells are planned; the axes themselves are declared in `model::registry`.
use serde::{Deserialize, Serialize};
use std::fmt;

macro_rules! axis {
    ($(#[$m:meta])* $name:ident { $($(#[$vm:meta])* $v:ident = $s:literal),* $(,)? }) => {
        $(#[$m])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
        #[serde(rename_all = "snake_case")]
        pub enum $name { $($(#[$vm])* $v),* }
        impl $name {
            pub const ALL: &'static [$name] = &[$($name::$v),*];
            /// The values' names, in the order of `ALL`.
            pub const NAMES: &'static [&'static str] = &[$($s),*];
            pub fn as_str(self) -> &'static str { match self { $($name::$v => $s),* } }
            pub fn parse(s: &str) -> Option<Self> { match s { $($s => Some($name::$v),)* _ => None } }
        }
        impl fmt::Display for $name {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result { f.write_str(self.as_str()) }
        }
    };
}

axis!(
    /// The shader stage that performs the probed read.
    Stage {
        Raygen = "raygen", ClosestHit = "closest_hit", AnyHit = "any_hit", Miss = "miss",
        Intersection = "intersection", Callable = "callable", Fragment = "fragment", Compute = "compute",
    }
);

axis!(
    /// The kind of descriptor the probed stage reads.
    Resource {
        StorageBuffer = "storage_buffer", UniformBuffer = "uniform_buffer", SampledImage = "sampled_image",
        StorageImage = "storage_image", AccelerationStructure = "acceleration_structure",
    }
);

axis!(
    /// How the array element / descriptor slot is chosen. `dynamic_element` is the pattern engines
    /// are told to use instead of a dynamic descriptor index: one descriptor at the spec-constant
    /// slot (`probe::PACKED_SLOT`) holding every slot's elements, and the dynamic value
    /// (as `dynamic` computes it) selecting the element inside it — an SSBO read at
    /// `v[packedElement(dyn, e)]` (geometry), a `texture2DArray` sampled at layer `dyn`
    /// (materials). Only for those two resources (`Cell::dynamic_element_applies`).
    IndexSource {
        Literal = "literal", SpecConstant = "spec_constant", PushConstant = "push_constant", Dynamic = "dynamic",
        DynamicElement = "dynamic_element",
    }
);

axis!(
    /// How an acceleration structure is reached (only for `resource=acceleration_structure`).
    AsAccess {
        Descriptor = "descriptor", Address = "address", AddressPatched = "address_patched",
    }
);

axis!(
    /// How descriptors are bound.
    DescriptorModel {
        DescriptorIndexing = "descriptor_indexing", DescriptorBuffer = "descriptor_buffer", DescriptorHeap = "descriptor_heap",
    }
);

axis!(
    /// Shader execution reordering (GL_NV_shader_invocation_reorder) in raygen before the probed
    /// closest-hit read: the primary ray is traced into a hit object, the invocations are
    /// reordered, then the hit object's shader runs. Only on cells that have it (`Cell::reorder`).
    Reorder {
        /// `reorderThreadNV(hitObject)`.
        Reorder = "reorder",
        /// `reorderThreadNV(hitObject, hint, 16)` with the hit instance's custom index as the
        /// coherence hint.
        ReorderHint = "reorder_hint",
    }
);

axis!(
    /// How a `descriptor_heap` cell's shaders reach the heap (only for that model). `mapped_*`:
    /// the unchanged set/binding shaders through VkShaderDescriptorSetAndBindingMappingInfoEXT,
    /// the probed array's heap position from a constant offset, an index in push data, an index
    /// loaded from a buffer whose address is in push data, or an index in the SBT shader record;
    /// `direct`: `layout(descriptor_heap)` GLSL.
    HeapAccess {
        MappedConstantOffset = "mapped_constant_offset", MappedPushIndex = "mapped_push_index",
        MappedIndirectIndex = "mapped_indirect_index", MappedShaderRecordIndex = "mapped_shader_record_index",
        Direct = "direct",
    }
);

axis!(
    /// Where a closest-hit probe's runtime `base` (the `base` of `base + gl_InstanceCustomIndexEXT`)
    /// comes from when it is not push data (the default, no axis value in the id): the SBT shader
    /// record of the hit group (`probe::ShaderRecordData::dyn_base`, different per hit group), or
    /// a buffer of per-instance bases (different for neighbouring instances) read through a device
    /// address at `gl_InstanceID` (`probe::spec::Base::value`). Only on cells that have it
    /// (`Cell::base_applies`).
    BaseSource {
        ShaderRecord = "shader_record", Buffer = "buffer",
    }
);

axis!(
    /// How a `heap_access=direct` sampled-image probe picks its sampler from the sampler heap
    /// (`sampler probeSampler[]`, separate from the texture heap as in the original engine): a
    /// constant index (`probe::SAMPLER_LITERAL`) or a dynamic one (the stage's runtime
    /// value modulo the heap's samplers). The samplers differ in address mode and the probe samples
    /// outside [0, 1], so the sampler chosen shows in the texel read (`probe::sampled_element`).
    SamplerIndex {
        Constant = "constant", Dynamic = "dynamic",
    }
);

axis!(
    /// How a scene-layout cell's closest-hit fetches the hit triangle's data (its three vertex
    /// indices, one coordinate of each vertex and its material index), the two layouts engines
    /// switch between: `shared_buffers`, the glTF ray tracing tutorial's — one position and one
    /// index buffer for the whole scene, a `PrimMeshInfo {indexOffset, vertexOffset,
    /// materialIndex}` table and a `SceneDesc` of device addresses, no descriptor indexed — and
    /// `per_mesh`, one storage buffer per mesh in a descriptor array selected by the custom index.
    /// Only on the cells that have it (`Cell::scene_layout_applies`).
    SceneLayout {
        SharedBuffers = "shared_buffers", PerMesh = "per_mesh",
    }
);

impl Stage {
    /// Stages of a ray tracing pipeline (the rest are graphics / compute).
    pub fn is_ray_tracing(self) -> bool {
        !matches!(self, Stage::Fragment | Stage::Compute)
    }

    /// Stages where `traceRayEXT` is allowed by the Vulkan spec (raygen, closest-hit, miss);
    /// elsewhere tracing needs ray queries.
    pub fn can_trace_ray(self) -> bool {
        matches!(self, Stage::Raygen | Stage::ClosestHit | Stage::Miss)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip() {
        for s in Stage::ALL {
            assert_eq!(Stage::parse(s.as_str()), Some(*s));
            assert_eq!(
                serde_json::to_value(s).unwrap(),
                serde_json::Value::String(s.as_str().into())
            );
        }
        assert_eq!(
            DescriptorModel::parse("descriptor_heap"),
            Some(DescriptorModel::DescriptorHeap)
        );
        assert_eq!(IndexSource::parse("nope"), None);
    }
}
