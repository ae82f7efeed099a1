//! The first half of phase `pipeline`: a cell's resources (built by `prepare`), its layout key
//! (stages, model, which bindings, heap direct or mapped, packed), whether its modules fit that
//! layout (`fit`), its descriptor binding (cached per key), the addresses its push constants
//! carry and the key of its pipeline.
use super::bindings::{Binding, LayoutKey};
use super::built::{Addresses, Bound, Compiled};
use super::error::CellError;
use super::executor::Executor;
use super::pipeline_key;
use crate::model::{Cell, SceneLayout, Timings};
use crate::probe::spec::{ArrayAt, ProbeSpec};
use crate::shadergen::{CellShaders, PipelineKind};
use ash::vk;
use std::time::Instant;

/// The stages of a pipeline of `kind`: all of them see the bindings and push constants.
fn stages(kind: PipelineKind) -> vk::ShaderStageFlags {
    match kind {
        PipelineKind::RayTracing => {
            vk::ShaderStageFlags::RAYGEN_KHR
                | vk::ShaderStageFlags::MISS_KHR
                | vk::ShaderStageFlags::CLOSEST_HIT_KHR
                | vk::ShaderStageFlags::ANY_HIT_KHR
                | vk::ShaderStageFlags::INTERSECTION_KHR
                | vk::ShaderStageFlags::CALLABLE_KHR
        }
        PipelineKind::Graphics => vk::ShaderStageFlags::VERTEX | vk::ShaderStageFlags::FRAGMENT,
        PipelineKind::Compute => vk::ShaderStageFlags::COMPUTE,
    }
}

/// The layout key of a cell with `spec` and `shaders`; `all_stages`: RTPROBE_BINDING_STAGES=all
/// declares bindings and push constants for VK_SHADER_STAGE_ALL instead of the pipeline's stages
/// (reproduces reports/lavapipe/FINDINGS.md).
pub(super) fn layout_key(spec: &ProbeSpec, shaders: &CellShaders, all_stages: bool) -> LayoutKey {
    let stages = if all_stages { vk::ShaderStageFlags::ALL } else { stages(shaders.kind) };
    LayoutKey {
        stages,
        model: spec.model,
        scene_tlas: shaders.uses_scene_tlas,
        probe: shaders.uses_probe_binding.then_some(spec.resource),
        heap_direct: spec.array == ArrayAt::Heap,
        packed: spec.packed(),
        per_mesh: spec.layout == Some(SceneLayout::PerMesh),
        textures: spec.layout_textures(),
    }
}

impl Executor {
    /// Resources (built by `prepare`), descriptor bindings (cached per layout) and the key of the
    /// cell's pipeline: the first half of phase `pipeline`.
    pub(super) fn bind_cell(
        &mut self,
        cell: &Cell,
        c: &Compiled,
        timings: &mut Timings,
    ) -> Result<Bound, CellError> {
        let t = Instant::now();
        let spec = ProbeSpec::of(cell);
        self.ensure_resources(cell, &c.shaders, self.opts.timeout)?;
        let key = layout_key(&spec, &c.shaders, self.opts.all_stages);
        self.fit(key, &c.shaders, (&c.spirv, c.keys.as_deref()))?;
        self.ensure_binding(key)?;
        let addresses = self.addresses(&spec);
        timings.setup_ms = t.elapsed().as_secs_f64() * 1e3;
        // pipeline (reused for identical SPIR-V and model)
        let pkey = pipeline_key::of(c, &spec, key);
        Ok(Bound { key, pkey, addresses, seen: c.seen })
    }

    /// The binding of `key`, created (with its targets) unless it exists.
    fn ensure_binding(&mut self, key: LayoutKey) -> Result<(), CellError> {
        if !self.bindings.contains_key(&key) {
            let targets = self.targets(key)?;
            let b = Binding::create(&self.gpu, key, &targets)?;
            self.bindings.insert(key, b);
        }
        Ok(())
    }

    /// The addresses a cell with `spec` pushes: its address tables and per-instance bases (built
    /// by `ensure_resources`).
    fn addresses(&self, spec: &ProbeSpec) -> Addresses {
        // The table the address patches read at push-constant offset probe::PATCHED_TABLE_OFFSET
        // (PushConstants::as_table is the hand-written address variant's).
        let mut patched_table = 0;
        if spec.addresses.ssbo_table {
            patched_table = self.ssbo_table.as_ref().map(|b| b.address).unwrap_or(0);
        }
        let mut as_table = 0;
        if spec.addresses.as_table {
            as_table = self.as_table.as_ref().map(|b| b.address).unwrap_or(0);
            patched_table = as_table;
        }
        let base = if spec.instance_bases() {
            self.bases.as_ref().map(|b| b.address).unwrap_or(0)
        } else {
            0
        };
        let scene_desc = match (&self.shared_layout, spec.scene_desc()) {
            (Some(s), true) => s.desc.address,
            (None, _) | (Some(_), false) => 0,
        };
        Addresses { as_table, patched_table, base, scene_desc }
    }
}
