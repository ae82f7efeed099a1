//! What each step of building a cell hands to the next: its shaders as SPIR-V ([`Compiled`]),
//! the cell bound and its pipeline keyed ([`Bound`], with the [`Addresses`] its push constants
//! carry), what a prebuild kept for its turn ([`Prebuilt`]), and what creating its pipeline
//! needs ([`PipelineInput`]).
use super::bindings::LayoutKey;
use super::error::CellError;
use super::heap::{DroppedNonUniform, PipelineMapping};
use super::pipeline::{self, Pipeline};
use crate::model::{DescriptorModel, Phase, Timings};
use crate::shadergen::CellShaders;
use crate::vk::{Gpu, VkError};
use ash::vk;
use std::sync::Arc;

/// A cell's shaders as SPIR-V, workarounds applied (what phase `compile` produces).
pub(super) struct Compiled {
    pub(super) shaders: CellShaders,
    pub(super) spirv: Vec<Arc<Vec<u32>>>,
    /// The `nonuniformEXT` the compiler dropped (direct heap cells).
    pub(super) dropped: Option<DroppedNonUniform>,
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
}

/// A cell ready to record: its descriptor binding, the key of its (created) pipeline, the
/// addresses its push constants carry, and the note on what the compiler did to its shape.
pub(super) struct Bound {
    pub(super) key: LayoutKey,
    pub(super) pkey: u64,
    pub(super) addresses: Addresses,
    pub(super) dropped: Option<DroppedNonUniform>,
}

/// What [`Executor::prebuild`](super::Executor::prebuild) made for one cell: its timings, the
/// phase it got to, and either the cell bound with its pipeline or the error that becomes its
/// result at its turn.
pub(super) struct Prebuilt {
    pub(super) timings: Timings,
    pub(super) phase: Phase,
    pub(super) result: Result<Bound, CellError>,
}

/// What creating one pipeline needs apart from the device and the cache.
pub(super) struct PipelineInput<'a> {
    pub(super) shaders: &'a CellShaders,
    pub(super) spirv: &'a [Arc<Vec<u32>>],
    pub(super) layout: vk::PipelineLayout,
    pub(super) model: DescriptorModel,
    pub(super) mapping: Option<Box<PipelineMapping>>,
    pub(super) records: pipeline::ShaderRecords,
}

impl PipelineInput<'_> {
    pub(super) fn create(&self, gpu: &Gpu, cache: vk::PipelineCache) -> Result<Pipeline, VkError> {
        pipeline::create(
            gpu,
            cache,
            self.shaders,
            self.spirv,
            self.layout,
            self.model,
            self.mapping.as_deref(),
            &self.records,
        )
    }
}
