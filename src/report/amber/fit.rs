//! Which cells an Amber script can reproduce, judged on the cell's probe spec
//! (`probe::spec::ProbeSpec`): what the spec needs that AmberScript lacks is refused with that
//! reason, and what rtprobe does not write yet says so.
use crate::model::{Cell, DescriptorModel, Injection, Resource, Stage};
use crate::probe::spec::{Access, Base, ElementMap, ProbeSpec, Sampler};

/// Why a cell gets no Amber script (a sentence for the bundle's README and the issue).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum Unfit {
    #[error("canaries are not probe cells (they hang or fault on purpose)")]
    Canary,
    #[error("the run traced a glTF scene (run --scene): rtprobe writes Amber scripts of its procedural scene only (not implemented); `rtprobe run --cell-spec` re-runs the cell on the scene file")]
    SceneFile,
    /// The injection's spec.
    #[error("the cell has an injected fault ({0}): Amber cannot reproduce rtprobe's injection (a load through a device address in push constants, per-attempt dice)")]
    Injected(String),
    #[error("the cell runs a mutant (an emulated driver bug rtprobe writes into the SPIR-V), not a driver's behaviour")]
    Mutant,
    #[error("scene-layout cells (scene_layout=per_mesh): rtprobe does not write the per-mesh scene buffers in AmberScript (not implemented)")]
    SceneLayout,
    #[error("Amber has no VK_EXT_descriptor_buffer")]
    DescriptorBuffer,
    #[error("Amber has no VK_EXT_descriptor_heap")]
    DescriptorHeap,
    #[error("AmberScript cannot specialize ray tracing shaders (SPECIALIZE belongs to ATTACH; ray tracing pipelines take SHADER_GROUPs), and the probe's slot is specialization constant 0")]
    RtSpecialization,
    #[error("AmberScript's SHADER_BINDING_TABLE holds group handles only: no shader record data for the probe's base (base=shader_record)")]
    ShaderRecordBase,
    #[error("shader execution reordering needs VkPhysicalDeviceRayTracingInvocationReorderFeaturesNV, which AmberScript's DEVICE_FEATURE cannot enable")]
    Reorder,
    #[error(
        "graphics cell: rtprobe writes Amber scripts for compute and ray tracing cells only (not implemented)"
    )]
    Graphics,
    #[error("image arrays: rtprobe does not write its probe images in AmberScript yet (not implemented)")]
    ImageArrays,
    #[error("acceleration-structure arrays: AmberScript binds one TLAS per BIND ACCELERATION_STRUCTURE, and the AS probe reads an array of them (as_access=address: device addresses)")]
    AccelerationStructure,
    /// The push-constant addresses the probe reads.
    #[error("the probe reads device addresses from push constants ({0}), which AmberScript cannot provide")]
    PushAddresses(String),
    #[error("separate samplers from a sampler heap: Amber has no VK_EXT_descriptor_heap")]
    SamplerHeap,
    #[error("rtprobe has no packed {0} buffer to bind at the spec-constant slot (index=dynamic_element)")]
    NoPackedBuffer(Resource),
    #[error("the probe reads an address table, not a descriptor: AmberScript cannot provide device addresses")]
    AddressTable,
    /// The number of shaders of a cell taken for a compute cell.
    #[error("the cell has {0} shaders; a compute cell has one")]
    ShaderCount(usize),
}

/// Whether AmberScript can run `cell` (with `inject`) as rtprobe does, or why not.
pub fn fits(cell: &Cell, inject: Option<&Injection>) -> Result<(), Unfit> {
    let spec = ProbeSpec::of(cell);
    if spec.canary.is_some() {
        return Err(Unfit::Canary);
    }
    if let Some(i) = inject {
        return Err(Unfit::Injected(i.spec.clone()));
    }
    if spec.mutant.is_some() {
        return Err(Unfit::Mutant);
    }
    // shared_buffers is refused below for its push-constant address (sceneDesc)
    if spec.layout == Some(crate::model::SceneLayout::PerMesh) {
        return Err(Unfit::SceneLayout);
    }
    match spec.model {
        DescriptorModel::DescriptorIndexing => {}
        DescriptorModel::DescriptorBuffer => return Err(Unfit::DescriptorBuffer),
        DescriptorModel::DescriptorHeap => return Err(Unfit::DescriptorHeap),
    }
    match spec.resource {
        Resource::StorageBuffer | Resource::UniformBuffer => {}
        Resource::SampledImage | Resource::StorageImage => return Err(Unfit::ImageArrays),
        Resource::AccelerationStructure => return Err(Unfit::AccelerationStructure),
    }
    stage_fits(&spec)?;
    let addresses = spec.push_addresses();
    if !addresses.is_empty() {
        return Err(Unfit::PushAddresses(addresses.join(", ")));
    }
    match spec.sampler {
        Sampler::None => {}
        Sampler::Constant | Sampler::Dynamic { .. } => return Err(Unfit::SamplerHeap),
    }
    access_fits(&spec)
}

/// What the probed stage's pipeline needs: compute as it is; ray tracing without a specialized
/// slot, shader record data or reordering.
fn stage_fits(spec: &ProbeSpec) -> Result<(), Unfit> {
    match spec.stage {
        Stage::Compute => Ok(()),
        Stage::Raygen
        | Stage::ClosestHit
        | Stage::AnyHit
        | Stage::Miss
        | Stage::Intersection
        | Stage::Callable => {
            if spec.spec_constant() {
                return Err(Unfit::RtSpecialization);
            }
            if spec.reorder.is_some() {
                return Err(Unfit::Reorder);
            }
            match spec.base {
                // The bases buffer's address is refused with the push addresses.
                Base::None | Base::PushData | Base::InstanceBuffer => Ok(()),
                Base::ShaderRecord => Err(Unfit::ShaderRecordBase),
            }
        }
        Stage::Fragment => Err(Unfit::Graphics),
    }
}

fn access_fits(spec: &ProbeSpec) -> Result<(), Unfit> {
    match (spec.access, spec.element) {
        (
            Access::Slot { .. },
            ElementMap::None | ElementMap::Own | ElementMap::Packed | ElementMap::Layer,
        )
        | (Access::Packed, ElementMap::Packed) => Ok(()),
        (Access::Packed, ElementMap::None | ElementMap::Own | ElementMap::Layer) => {
            Err(Unfit::NoPackedBuffer(spec.resource))
        }
        (
            Access::AddressTable,
            ElementMap::None | ElementMap::Own | ElementMap::Packed | ElementMap::Layer,
        ) => Err(Unfit::AddressTable),
    }
}
