//! What a user's modules need from the device, read from their `OpCapability` and
//! `OpExtension` instructions ([`needs`]), per the SPIR-V Environment appendix of Vulkan 1.4.360
//! (vk.xml's `<spirvcapability>` and `<spirvextension>` entries):
//! VUID-VkShaderModuleCreateInfo-pCode-08740 ("If pCode declares any of the capabilities listed
//! in the SPIR-V Environment appendix, one of the corresponding requirements must be
//! satisfied") and VUID-VkShaderModuleCreateInfo-pCode-08742 (the same for SPIR-V extensions).
//! A capability or extension outside this table is refused in one line naming it: a device
//! created without what it needs is invalid, and what it then does is no finding.
use crate::vk::{GoogleHlsl, Requirements, ShaderFeatures};
use rspirv::spirv::Capability;

/// What the modules need beyond the harness's fixed requirements.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Needs {
    pub shader: ShaderFeatures,
    /// `RayQueryKHR` / `SPV_KHR_ray_query`: VK_KHR_ray_query.
    pub ray_query: bool,
    /// `ShaderInvocationReorderNV` / `SPV_NV_shader_invocation_reorder`.
    pub invocation_reorder: bool,
    /// `UntypedPointersKHR` / `SPV_KHR_untyped_pointers`.
    pub untyped_pointers: bool,
    /// `DescriptorHeapEXT` / `SPV_EXT_descriptor_heap`.
    pub descriptor_heap: bool,
    pub google: GoogleHlsl,
}

impl Needs {
    /// `req` with these turned on (what the harness asks for stays asked for).
    pub fn apply(&self, req: &mut Requirements) {
        req.shader = self.shader;
        req.ray_query |= self.ray_query;
        req.invocation_reorder |= self.invocation_reorder;
        req.untyped_pointers |= self.untyped_pointers;
        req.descriptor_heap |= self.descriptor_heap;
        req.google = self.google;
    }
}

/// `OpCapability`'s and `OpExtension`'s opcodes.
const OP_CAPABILITY: u32 = 17;
const OP_EXTENSION: u32 = 10;

/// The operands of each instruction of opcode `op` in `words` (a header of 5 words first);
/// words past a truncated instruction are not read.
pub fn operands_of(words: &[u32], op: u32) -> Vec<&[u32]> {
    let mut out = Vec::new();
    let mut at = 5;
    while let Some(&first) = words.get(at) {
        let (count, code) = ((first >> 16) as usize, first & 0xffff);
        let Some(operands) = words.get(at + 1..at + count.max(1)) else { break };
        if code == op {
            out.push(operands);
        }
        at += count.max(1);
    }
    out
}

/// The names of the SPIR-V extensions `words` declares (`OpExtension`).
pub fn spirv_extensions(words: &[u32]) -> Vec<String> {
    operands_of(words, OP_EXTENSION)
        .into_iter()
        .map(|operands| {
            let bytes: Vec<u8> = operands.iter().flat_map(|w| w.to_le_bytes()).collect();
            let end = bytes.iter().position(|b| *b == 0).unwrap_or(bytes.len());
            String::from_utf8_lossy(&bytes[..end]).into_owned()
        })
        .collect()
}

/// What `modules` (SPIR-V words) need, or one line naming what rtprobe will not enable.
pub fn needs<'a>(modules: impl IntoIterator<Item = &'a [u32]>) -> Result<Needs, String> {
    let mut n = Needs::default();
    for words in modules {
        for e in spirv_extensions(words) {
            extension(&e, &mut n)?;
        }
        let mut subgroup = false;
        for operands in operands_of(words, OP_CAPABILITY) {
            let Some(&value) = operands.first() else { continue };
            match Capability::from_u32(value) {
                Some(c) => {
                    subgroup |= is_subgroup(c);
                    capability(c, &mut n)?
                }
                None => return Err(format!("declares capability {value}, unknown to rtprobe's SPIR-V grammar: rtprobe cannot enable what it needs")),
            }
        }
        if subgroup {
            n.shader.subgroup_stages |= stages(words);
        }
    }
    Ok(n)
}

/// `OpEntryPoint`'s opcode.
const OP_ENTRY_POINT: u32 = 15;

/// Whether `c` is a subgroup operation's capability (`GroupNonUniform*`).
fn is_subgroup(c: Capability) -> bool {
    use Capability as C;
    matches!(
        c,
        C::GroupNonUniform
            | C::GroupNonUniformVote
            | C::GroupNonUniformArithmetic
            | C::GroupNonUniformBallot
            | C::GroupNonUniformShuffle
            | C::GroupNonUniformShuffleRelative
            | C::GroupNonUniformClustered
            | C::GroupNonUniformQuad
    )
}

/// The stages of `words`' entry points (their execution models).
fn stages(words: &[u32]) -> ash::vk::ShaderStageFlags {
    use ash::vk::ShaderStageFlags as S;
    use rspirv::spirv::ExecutionModel as E;
    let stage = |model: u32| match E::from_u32(model) {
        Some(E::Vertex) => S::VERTEX,
        Some(E::Fragment) => S::FRAGMENT,
        Some(E::GLCompute) => S::COMPUTE,
        Some(E::RayGenerationKHR) => S::RAYGEN_KHR,
        Some(E::IntersectionKHR) => S::INTERSECTION_KHR,
        Some(E::AnyHitKHR) => S::ANY_HIT_KHR,
        Some(E::ClosestHitKHR) => S::CLOSEST_HIT_KHR,
        Some(E::MissKHR) => S::MISS_KHR,
        Some(E::CallableKHR) => S::CALLABLE_KHR,
        Some(E::TaskEXT) => S::TASK_EXT,
        Some(E::MeshEXT) => S::MESH_EXT,
        // Other execution models (geometry, tessellation, the NV ones) are refused by their
        // capabilities before this matters; nothing to ask of subgroupSupportedStages.
        _ => S::empty(),
    };
    operands_of(words, OP_ENTRY_POINT)
        .into_iter()
        .filter_map(|o| o.first().copied())
        .fold(S::empty(), |acc, m| acc | stage(m))
}

/// The recompile hint for DXC's old ray tracing output.
const NV_RAY_TRACING: &str = "declares SPV_NV_ray_tracing (RayTracingNV, DXC's output for an old target): recompile with `-fspv-target-env=vulkan1.2` (SPV_KHR_ray_tracing)";

/// One `OpExtension`: the device extension it needs, nothing where the harness's Vulkan 1.2
/// device has it (or 1.3, checked against the device), else refused.
fn extension(e: &str, n: &mut Needs) -> Result<(), String> {
    match e {
        "SPV_GOOGLE_hlsl_functionality1" | "SPV_GOOGLE_user_type" | "SPV_GOOGLE_decorate_string" => {
            n.google.note(e)
        }
        "SPV_KHR_ray_tracing" => {} // the harness always enables VK_KHR_ray_tracing_pipeline
        "SPV_KHR_ray_query" => n.ray_query = true,
        "SPV_KHR_ray_tracing_position_fetch" => n.shader.position_fetch = true,
        "SPV_KHR_ray_cull_mask" => n.shader.cull_mask = true,
        "SPV_NV_shader_invocation_reorder" => n.invocation_reorder = true,
        "SPV_KHR_untyped_pointers" => n.untyped_pointers = true,
        "SPV_EXT_descriptor_heap" => n.descriptor_heap = true,
        "SPV_NV_ray_tracing" => return Err(NV_RAY_TRACING.into()),
        // Enabled by VK_VERSION_1_1 / VK_VERSION_1_2 in the appendix: rtprobe needs Vulkan 1.2.
        "SPV_KHR_variable_pointers"
        | "SPV_KHR_shader_draw_parameters"
        | "SPV_KHR_8bit_storage"
        | "SPV_KHR_16bit_storage"
        | "SPV_KHR_float_controls"
        | "SPV_KHR_storage_buffer_storage_class"
        | "SPV_EXT_shader_viewport_index_layer"
        | "SPV_EXT_descriptor_indexing"
        | "SPV_KHR_vulkan_memory_model"
        | "SPV_KHR_physical_storage_buffer"
        | "SPV_KHR_multiview"
        | "SPV_KHR_device_group" => {}
        // Enabled by VK_VERSION_1_3.
        "SPV_EXT_demote_to_helper_invocation"
        | "SPV_KHR_non_semantic_info"
        | "SPV_KHR_terminate_invocation"
        | "SPV_KHR_integer_dot_product" => n.shader.vulkan13 = true,
        other => {
            return Err(format!(
                "declares SPIR-V extension {other}, which rtprobe does not enable: build the module without it"
            ))
        }
    }
    Ok(())
}

/// One `OpCapability`: the feature bit the appendix asks for, nothing for those core in Vulkan
/// 1.0–1.2 or always enabled by the harness, else refused.
fn capability(c: Capability, n: &mut Needs) -> Result<(), String> {
    let s = &mut n.shader;
    match c {
        // VK_VERSION_1_0 / 1_1 / 1_2 in the appendix, with no feature.
        Capability::Matrix
        | Capability::Shader
        | Capability::InputAttachment
        | Capability::Sampled1D
        | Capability::Image1D
        | Capability::SampledBuffer
        | Capability::ImageBuffer
        | Capability::ImageQuery
        | Capability::DerivativeControl
        | Capability::StorageImageExtendedFormats
        | Capability::DeviceGroup
        | Capability::ShaderNonUniform => {}
        // Always enabled by the harness (requirements_for): the pipeline, shaderInt64, and
        // bufferDeviceAddress.
        Capability::RayTracingKHR
        | Capability::Int64
        | Capability::PhysicalStorageBufferAddresses => {}
        Capability::RayQueryKHR => n.ray_query = true,
        Capability::RayTracingPositionFetchKHR => s.position_fetch = true,
        Capability::RayQueryPositionFetchKHR => {
            s.position_fetch = true;
            n.ray_query = true;
        }
        Capability::RayCullMaskKHR => s.cull_mask = true,
        Capability::RayTraversalPrimitiveCullingKHR => s.primitive_culling = true,
        Capability::ShaderInvocationReorderNV => n.invocation_reorder = true,
        Capability::UntypedPointersKHR => n.untyped_pointers = true,
        Capability::DescriptorHeapEXT => n.descriptor_heap = true,
        Capability::RayTracingNV => return Err(NV_RAY_TRACING.into()),
        other => return other_capability(other, n),
    }
    Ok(())
}

/// The capabilities of data types, storage, images and indexing; a capability outside the
/// table is refused (the catch-all is the refusal: a capability rtprobe has no row for must
/// never reach a device that was not asked for it).
fn other_capability(c: Capability, n: &mut Needs) -> Result<(), String> {
    use ash::vk::SubgroupFeatureFlags as F;
    let s = &mut n.shader;
    match c {
        Capability::Float16 => s.float16 = true,
        Capability::Int16 => s.int16 = true,
        Capability::Int8 => s.int8 = true,
        Capability::Float64 => s.float64 = true,
        Capability::Int64Atomics => s.int64_atomics = true,
        Capability::StorageBuffer16BitAccess => s.storage_buffer16 = true,
        Capability::UniformAndStorageBuffer16BitAccess => s.uniform_and_storage_buffer16 = true,
        Capability::StoragePushConstant16 => s.storage_push_constant16 = true,
        Capability::StorageInputOutput16 => s.storage_input_output16 = true,
        Capability::StorageBuffer8BitAccess => s.storage_buffer8 = true,
        Capability::UniformAndStorageBuffer8BitAccess => s.uniform_and_storage_buffer8 = true,
        Capability::StoragePushConstant8 => s.storage_push_constant8 = true,
        Capability::ImageGatherExtended => s.image_gather_extended = true,
        Capability::ImageCubeArray | Capability::SampledCubeArray => s.image_cube_array = true,
        Capability::MinLod => s.min_lod = true,
        Capability::StorageImageReadWithoutFormat => s.read_without_format = true,
        Capability::StorageImageWriteWithoutFormat => s.write_without_format = true,
        Capability::UniformBufferArrayDynamicIndexing => s.uniform_buffer_dynamic = true,
        Capability::SampledImageArrayDynamicIndexing => s.sampled_image_dynamic = true,
        Capability::StorageBufferArrayDynamicIndexing => s.storage_buffer_dynamic = true,
        Capability::StorageImageArrayDynamicIndexing => s.storage_image_dynamic = true,
        Capability::RuntimeDescriptorArray => s.runtime_descriptor_array = true,
        Capability::UniformBufferArrayNonUniformIndexing => s.uniform_buffer_non_uniform = true,
        Capability::SampledImageArrayNonUniformIndexing => s.sampled_image_non_uniform = true,
        Capability::StorageBufferArrayNonUniformIndexing => s.storage_buffer_non_uniform = true,
        Capability::StorageImageArrayNonUniformIndexing => s.storage_image_non_uniform = true,
        // VUID-VkPhysicalDeviceVariablePointersFeatures-variablePointers-01431 (Vulkan
        // 1.4.360): "If variablePointers is enabled then variablePointersStorageBuffer must also
        // be enabled".
        Capability::VariablePointers => {
            s.variable_pointers = true;
            s.variable_pointers_storage_buffer = true;
        }
        Capability::VariablePointersStorageBuffer => s.variable_pointers_storage_buffer = true,
        Capability::DrawParameters => s.draw_parameters = true,
        Capability::VulkanMemoryModel => s.vulkan_memory_model = true,
        Capability::VulkanMemoryModelDeviceScope => s.vulkan_memory_model_device_scope = true,
        Capability::GroupNonUniform => s.subgroup |= F::BASIC,
        Capability::GroupNonUniformVote => s.subgroup |= F::VOTE,
        Capability::GroupNonUniformArithmetic => s.subgroup |= F::ARITHMETIC,
        Capability::GroupNonUniformBallot => s.subgroup |= F::BALLOT,
        Capability::GroupNonUniformShuffle => s.subgroup |= F::SHUFFLE,
        Capability::GroupNonUniformShuffleRelative => s.subgroup |= F::SHUFFLE_RELATIVE,
        Capability::GroupNonUniformClustered => s.subgroup |= F::CLUSTERED,
        Capability::GroupNonUniformQuad => s.subgroup |= F::QUAD,
        Capability::RayTracingOpacityMicromapEXT => {
            return Err("declares RayTracingOpacityMicromapEXT: rtprobe builds no opacity micromaps and does not enable VK_EXT_opacity_micromap; build the module without it".into())
        }
        other => {
            return Err(format!(
                "declares capability {other:?}, which rtprobe does not enable (not in its table of the SPIR-V Environment appendix): build the module without it"
            ))
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A module header, then each capability, then each extension.
    fn module(caps: &[Capability], exts: &[&str]) -> Vec<u32> {
        let mut words = vec![0x0723_0203, 0x0001_0500, 0, 16, 0];
        for c in caps {
            words.extend([(2 << 16) | OP_CAPABILITY, *c as u32]);
        }
        for e in exts {
            let mut bytes = e.as_bytes().to_vec();
            bytes.resize((bytes.len() / 4 + 1) * 4, 0);
            let ops: Vec<u32> =
                bytes.chunks(4).map(|c| u32::from_le_bytes(c.try_into().unwrap())).collect();
            words.push(((ops.len() as u32 + 1) << 16) | OP_EXTENSION);
            words.extend(ops);
        }
        words
    }

    fn of(caps: &[Capability], exts: &[&str]) -> Result<Needs, String> {
        needs([module(caps, exts).as_slice()])
    }

    /// Float16, 16-bit storage and a ray query ask for their bits and VK_KHR_ray_query; 8-bit
    /// storage, Int8, Int16, Float64, Int64Atomics, the formatless image accesses and position
    /// fetch theirs; over two modules the needs add up.
    #[test]
    fn capabilities_ask_for_their_features() {
        use Capability as C;
        let n = of(
            &[C::Shader, C::RayTracingKHR, C::Float16, C::StorageBuffer16BitAccess, C::RayQueryKHR],
            &["SPV_KHR_ray_tracing", "SPV_KHR_ray_query", "SPV_KHR_16bit_storage"],
        )
        .unwrap();
        assert!(n.shader.float16 && n.shader.storage_buffer16 && n.ray_query);
        assert!(!n.shader.int16 && !n.shader.uniform_and_storage_buffer16);
        let caps = [
            C::Int8,
            C::Int16,
            C::Float64,
            C::Int64Atomics,
            C::StorageBuffer8BitAccess,
            C::UniformAndStorageBuffer8BitAccess,
            C::StoragePushConstant8,
            C::UniformAndStorageBuffer16BitAccess,
            C::StoragePushConstant16,
            C::StorageImageReadWithoutFormat,
            C::StorageImageWriteWithoutFormat,
            C::RayTracingPositionFetchKHR,
            C::GroupNonUniformBallot,
        ];
        let two =
            [module(&caps, &["SPV_KHR_ray_tracing_position_fetch"]), module(&[C::Float16], &[])];
        let n = needs(two.iter().map(Vec::as_slice)).unwrap();
        let s = n.shader;
        assert!(s.int8 && s.int16 && s.float64 && s.int64_atomics && s.float16);
        assert!(s.storage_buffer8 && s.uniform_and_storage_buffer8 && s.storage_push_constant8);
        assert!(s.uniform_and_storage_buffer16 && s.storage_push_constant16);
        assert!(s.read_without_format && s.write_without_format && s.position_fetch);
        assert_eq!(s.subgroup, ash::vk::SubgroupFeatureFlags::BALLOT);
        assert!(!n.ray_query);
        let mut req = Requirements { ray_query: false, ..Requirements::default() };
        n.apply(&mut req);
        assert_eq!(req.shader, s);
    }

    /// Subgroup operations record the stages of the modules that use them (for
    /// `subgroupSupportedStages`); the twin: a module without them adds no stage.
    #[test]
    fn subgroup_operations_record_their_stage() {
        use Capability as C;
        let mut chit = module(&[C::Shader, C::GroupNonUniformBallot], &[]);
        chit.extend([(3 << 16) | OP_ENTRY_POINT, 5316, 1]);
        let mut plain = module(&[C::Shader], &[]);
        plain.extend([(3 << 16) | OP_ENTRY_POINT, 5313, 2]);
        let n = needs([chit.as_slice(), plain.as_slice()]).unwrap();
        assert_eq!(n.shader.subgroup_stages, ash::vk::ShaderStageFlags::CLOSEST_HIT_KHR);
        assert!(needs([plain.as_slice()]).unwrap().shader.subgroup_stages.is_empty());
    }

    /// `VariablePointers` alone enables `variablePointersStorageBuffer` too (VUID-…-01431); the
    /// twin: `VariablePointersStorageBuffer` alone leaves `variablePointers` off.
    #[test]
    fn variable_pointers_bring_their_storage_buffer_bit() {
        use Capability as C;
        let s = of(&[C::VariablePointers], &["SPV_KHR_variable_pointers"]).unwrap().shader;
        assert!(s.variable_pointers && s.variable_pointers_storage_buffer);
        let s = of(&[C::VariablePointersStorageBuffer], &[]).unwrap().shader;
        assert!(s.variable_pointers_storage_buffer && !s.variable_pointers);
    }

    /// Twin: capabilities core in Vulkan 1.0–1.2 or always enabled by the harness ask for
    /// nothing more.
    #[test]
    fn core_capabilities_ask_for_nothing() {
        use Capability as C;
        let caps = [
            C::Shader,
            C::Matrix,
            C::ImageQuery,
            C::Int64,
            C::ShaderNonUniform,
            C::PhysicalStorageBufferAddresses,
            C::RayTracingKHR,
        ];
        let exts = [
            "SPV_KHR_ray_tracing",
            "SPV_EXT_descriptor_indexing",
            "SPV_KHR_physical_storage_buffer",
        ];
        assert_eq!(of(&caps, &exts).unwrap(), Needs::default());
    }

    /// SPV_NV_ray_tracing / RayTracingNV say how to recompile; opacity micromaps, a capability
    /// outside the table and an unknown extension are refused in one line naming them.
    #[test]
    fn what_rtprobe_does_not_enable_is_refused_in_one_line() {
        use Capability as C;
        let nv = of(&[C::RayTracingNV], &[]).unwrap_err();
        assert!(nv.contains("`-fspv-target-env=vulkan1.2` (SPV_KHR_ray_tracing)"), "{nv}");
        let nv_ext = of(&[C::Shader], &["SPV_NV_ray_tracing"]).unwrap_err();
        assert!(nv_ext.contains("SPV_NV_ray_tracing"), "{nv_ext}");
        let omm = of(&[C::RayTracingOpacityMicromapEXT], &[]).unwrap_err();
        assert!(omm.contains("RayTracingOpacityMicromapEXT"), "{omm}");
        let geometry = of(&[C::Geometry], &[]).unwrap_err();
        assert!(geometry.contains("capability Geometry"), "{geometry}");
        let ext = of(&[C::Shader], &["SPV_KHR_made_up"]).unwrap_err();
        assert!(ext.contains("SPV_KHR_made_up"), "{ext}");
        for e in [nv, nv_ext, omm, geometry, ext] {
            assert!(!e.contains('\n'), "{e}");
        }
    }
}
