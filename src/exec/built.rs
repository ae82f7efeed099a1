//! What each step of building a cell hands to the next: its shaders as SPIR-V ([`Compiled`]),
//! the cell bound and its pipeline keyed ([`Bound`], with the [`Addresses`] its push constants
//! carry), what a prebuild kept for its turn ([`Prebuilt`]), and what creating its pipeline
//! needs ([`PipelineInput`]).
use super::bindings::LayoutKey;
use super::error::CellError;
use super::heap::PipelineMapping;
use super::pipeline::{self, Pipeline};
use super::pipeline_library::Libraries;
pub(super) use super::seen::Seen;
use crate::model::{DescriptorModel, Phase, Timings};
use crate::shadergen::{CellShaders, PipelineKind};
use crate::vk::{Gpu, VkError};
use ash::vk;
use std::sync::Arc;

/// A cell's shaders as SPIR-V, workarounds applied (what phase `compile` produces).
pub(super) struct Compiled {
    pub(super) shaders: CellShaders,
    pub(super) spirv: Vec<Arc<Vec<u32>>>,
    pub(super) seen: Seen,
    /// Each module's `StableHash` of its words, where the prebuild's threads computed it (the
    /// key of the executor's interface cache: `fit`); `None`: `fit` hashes them itself.
    pub(super) keys: Option<Vec<u128>>,
}

/// The device addresses a cell's push constants carry (0 where the cell has none).
#[derive(Clone, Copy, Debug)]
pub(super) struct Addresses {
    /// The AS address table (`PushConstants::as_table`, the hand-written address variant's).
    pub(super) as_table: u64,
    /// The table the address patches read at push-constant offset `probe::PATCHED_TABLE_OFFSET`.
    pub(super) patched_table: u64,
    /// The per-instance bases (`base=buffer`).
    pub(super) base: u64,
    /// The `SceneDesc` of `scene_layout=shared_buffers`.
    pub(super) scene_desc: u64,
}

/// A cell ready to record: its descriptor binding, the key of its (created) pipeline, the
/// addresses its push constants carry, and what the driver saw of its shape.
pub(super) struct Bound {
    pub(super) key: LayoutKey,
    pub(super) pkey: u64,
    pub(super) addresses: Addresses,
    pub(super) seen: Seen,
}

/// What [`Executor::prebuild`](super::Executor::prebuild) made for one cell: its timings, the
/// phase it got to, and either the cell bound with its pipeline or the error that becomes its
/// result at its turn.
pub(super) struct Prebuilt {
    pub(super) timings: Timings,
    pub(super) phase: Phase,
    pub(super) result: Result<Bound, CellError>,
}

/// What creating one pipeline needs apart from the device, how it is made and the shaders.
pub(super) struct PipelineParts {
    pub(super) layout: vk::PipelineLayout,
    pub(super) model: DescriptorModel,
    pub(super) mapping: Option<Box<PipelineMapping>>,
    pub(super) records: pipeline::ShaderRecords,
    pub(super) specialization: pipeline::Specialization,
    /// The layout's contents hashed (`Binding::digest`), part of a group library's identity.
    pub(super) layout_digest: u128,
}

/// What creating one pipeline needs apart from the device and how it is made.
pub(super) struct PipelineInput<'a> {
    pub(super) shaders: &'a CellShaders,
    pub(super) spirv: &'a [Arc<Vec<u32>>],
    pub(super) parts: &'a PipelineParts,
}

impl PipelineInput<'_> {
    pub(super) fn desc(&self) -> pipeline::Desc<'_> {
        let p = self.parts;
        pipeline::Desc {
            shaders: self.shaders,
            spirv: self.spirv,
            layout: p.layout,
            model: p.model,
            heap: p.mapping.as_deref(),
            records: &p.records,
            specialization: &p.specialization,
        }
    }

    /// The pipeline: linked from group libraries (ray tracing pipelines, where the executor
    /// links them), else made whole, both with the cache. Descriptor-heap pipelines are always
    /// made whole: linked ones gave wrong records and crashes on lavapipe 26.2.6 where whole ones
    /// pass (134 mismatches, 62 crashes of 226 heap cells; cause not yet located), so a linked
    /// heap verdict is not trusted.
    pub(super) fn create(&self, gpu: &Gpu, how: &Creation) -> Result<Pipeline, VkError> {
        let d = self.desc();
        let p = self.parts;
        let heap = p.mapping.is_some() || p.model == crate::model::DescriptorModel::DescriptorHeap;
        match how.libraries {
            Some(l) if d.shaders.kind == PipelineKind::RayTracing && !heap => {
                l.make(gpu, how.cache, &d, p.layout_digest)
            }
            Some(_) | None => pipeline::create(gpu, how.cache, &d),
        }
    }
}

/// How an executor makes pipelines: its cache, and its group libraries where it links.
#[derive(Clone, Copy)]
pub(super) struct Creation<'a> {
    pub(super) cache: vk::PipelineCache,
    pub(super) libraries: Option<&'a Libraries>,
}
