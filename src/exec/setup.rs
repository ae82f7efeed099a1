//! What cells need built on the device before they bind: the scene's acceleration structures,
//! the probed resource arrays, the scene-layout cells' buffers, the SSBO and AS address tables, the per-instance bases and the color
//! target (all built once, normally by [`Executor::prepare`] before the first cell), and the
//! targets of a layout's bindings 0..=2 taken from them.
use super::bindings::LayoutKey;
use super::error::CellError;
use super::executor::Executor;
use super::layout_buffers::{MeshBuffers, SharedBuffers};
use super::layout_textures::LayoutTextures;
use super::pipeline;
use super::resources::{self, ResourceArray, Target};
use crate::model::{Cell, Outcome, Resource, SceneLayout};
use crate::probe;
use crate::probe::spec::ProbeSpec;
use crate::scene::gpu::SceneGpu;
use crate::shadergen::{self, PipelineKind};
use crate::vk::memory::{Buffer, Image};
use ash::vk;
use std::time::Duration;

impl Executor {
    /// Build everything `cells` need before any of them runs: the scene's acceleration
    /// structures, resource arrays, address tables, the color target. A device loss or a fence
    /// timeout here is the worker's setup fault (no cell ran on this device). A plain creation
    /// error (say, a format the driver refuses) is left to the cells that need that resource:
    /// they retry it and report it as their own `error`; so is a scene rtprobe cannot probe (a
    /// scene-layout cell's slot clash, a texture cell on a scene without textures): those cells
    /// are `not_implemented` with the reason, the worker's other cells run.
    pub fn prepare(&mut self, cells: &[Cell]) -> Result<(), CellError> {
        for cell in cells {
            let shaders = shadergen::generate(cell);
            if let Err(e) = self.ensure_resources(cell, &shaders, self.opts.setup_timeout) {
                match e.outcome() {
                    Outcome::Error | Outcome::NotImplemented | Outcome::Unsupported => {
                        tracing::warn!("setup for {}: {e}; left to the cell", cell.id());
                    }
                    Outcome::Pass
                    | Outcome::Mismatch
                    | Outcome::DeviceLost
                    | Outcome::Crash
                    | Outcome::Timeout => return Err(e),
                }
            }
        }
        // The CPU reference's AS probe rays, when a cell reads them, here in the setup (under
        // `--setup-timeout`): traced lazily at the first AS cell's check they ran under that
        // cell's `--timeout`, and on a large scene every AS cell timed out in its check in turn
        // (2M triangles, `--timeout 0.4`: 6 false `timeout` findings; the review of 2026-12-04).
        if cells.iter().any(|c| c.resource == Resource::AccelerationStructure) {
            self.sref.as_probe(&self.scene);
        }
        Ok(())
    }

    /// The host-side wall time of the scene's acceleration structures' build (geometry upload,
    /// BLAS and TLAS builds, the fence wait), when this executor built them.
    pub fn as_build_ms(&self) -> Option<f64> {
        self.scene_gpu.as_ref().map(|s| s.build_ms)
    }

    /// Milliseconds this executor's thread has spent waiting on the queue so far (every fence
    /// wait of its submitter: the scene's AS build, uploads, traces). Read after
    /// [`Executor::prepare`] it is the setup's queue waits (`timing.setup_wait_ms`).
    pub fn fence_wait_ms(&self) -> f64 {
        self.submitter.waited().as_secs_f64() * 1e3
    }

    /// The scene's acceleration structures, built if missing with a fence wait of at most `wait`.
    fn ensure_scene(&mut self, wait: Duration) -> Result<&SceneGpu, CellError> {
        if self.scene_gpu.is_none() {
            self.scene_gpu = Some(SceneGpu::build(&self.gpu, &self.scene, &self.submitter, wait)?);
        }
        Ok(self.scene_gpu.as_ref().expect("built above"))
    }

    /// Descriptors of the probed array of `r`.
    pub(super) fn slots(&self, r: Resource) -> u32 {
        probe::slot_count(r, self.scene.params.instances)
    }

    /// Targets of bindings 0..=2 for `key`, creating what is missing.
    pub(super) fn targets(
        &mut self,
        key: LayoutKey,
    ) -> Result<Vec<(u32, Resource, Vec<Target>)>, CellError> {
        let mut t = vec![(
            0,
            Resource::StorageBuffer,
            vec![Target::Buffer {
                raw: self.records.raw,
                address: self.records.address,
                range: self.records.size,
            }],
        )];
        if key.scene_tlas {
            let s = self.ensure_scene(self.opts.timeout)?;
            t.push((
                1,
                Resource::AccelerationStructure,
                vec![Target::Accel { raw: s.scene_tlas.raw, address: s.scene_tlas.address }],
            ));
        }
        if let Some(r) = key.probe {
            let slots = self.slots(r);
            let targets = if key.textures {
                self.ensure_textures(self.opts.timeout)?;
                self.layout_textures.as_ref().expect("made above").targets(self.sampler)
            } else if key.per_mesh {
                self.ensure_layout(SceneLayout::PerMesh)?;
                self.mesh_layout.as_ref().expect("made above").targets()
            } else if r == Resource::AccelerationStructure {
                let s = self.ensure_scene(self.opts.timeout)?;
                (0..slots)
                    .map(|k| {
                        let a = &s.probe_tlas[probe::as_slot_tlas(k)];
                        Target::Accel { raw: a.raw, address: a.address }
                    })
                    .collect()
            } else {
                self.ensure_array(r, self.opts.timeout)?;
                self.arrays[&r].targets(self.sampler, r, key.packed).map_err(|e| match e {
                    resources::PackedError::TooManyLayers { .. } => {
                        CellError::Unsupported(e.to_string())
                    }
                    resources::PackedError::NoPacked(_) => CellError::NotImplemented(e.to_string()),
                })?
            };
            t.push((2, r, targets));
            if key.textures && key.per_mesh {
                // a per_mesh texture cell: its mesh buffers after the textures
                self.ensure_layout(SceneLayout::PerMesh)?;
                let meshes = self.mesh_layout.as_ref().expect("made above").targets();
                let binding = crate::scene::layout::TEXTURE_CELL_MESH_BINDING;
                t.push((binding, Resource::StorageBuffer, meshes));
            }
        }
        Ok(t)
    }

    /// The scene, resource arrays, address tables and color target `cell` needs (built once,
    /// normally by [`Executor::prepare`]); `wait` bounds each build's fence wait (the setup's
    /// deadline in `prepare`, the cell's at its turn).
    pub(super) fn ensure_resources(
        &mut self,
        cell: &Cell,
        shaders: &shadergen::CellShaders,
        wait: Duration,
    ) -> Result<(), CellError> {
        let spec = ProbeSpec::of(cell);
        if shaders.kind == PipelineKind::RayTracing
            || shaders.uses_scene_tlas
            || spec.resource == Resource::AccelerationStructure
        {
            self.ensure_scene(wait)?;
        }
        if let Some(l) = spec.layout {
            self.ensure_layout(l)?;
            if spec.layout_textures() {
                self.ensure_textures(wait)?;
            }
        } else if shaders.uses_probe_binding && spec.resource != Resource::AccelerationStructure {
            self.ensure_array(spec.resource, wait)?;
        }
        if spec.addresses.ssbo_table && self.ssbo_table.is_none() {
            self.ensure_array(Resource::StorageBuffer, wait)?;
            let addrs: Vec<u64> =
                self.arrays[&Resource::StorageBuffer].buffers.iter().map(|b| b.address).collect();
            self.ssbo_table =
                Some(resources::address_table(&self.gpu, &addrs, "SSBO address table")?);
        }
        if spec.addresses.as_table && self.as_table.is_none() {
            let s = self.ensure_scene(wait)?;
            let addrs: Vec<u64> = s.probe_tlas.iter().map(|t| t.address).collect();
            let slots = self.slots(Resource::AccelerationStructure);
            self.as_table = Some(resources::as_table(&self.gpu, &addrs, slots)?);
        }
        if spec.instance_bases() && self.bases.is_none() {
            let bytes = probe::base_buffer(self.scene.params.instances);
            let usage =
                vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS;
            self.bases = Some(Buffer::with_data(&self.gpu, &bytes, usage, "per-instance bases")?);
        }
        if shaders.kind == PipelineKind::Graphics && self.color.is_none() {
            let (w, h) = (self.scene.params.width, self.scene.params.height);
            self.color = Some(Image::new(
                &self.gpu,
                vk::Extent2D { width: w, height: h },
                pipeline::COLOR_FORMAT,
                vk::ImageUsageFlags::COLOR_ATTACHMENT,
            )?);
        }
        Ok(())
    }

    /// The buffers of scene layout `l`, made once (only the layout a cell reads).
    fn ensure_layout(&mut self, l: SceneLayout) -> Result<(), CellError> {
        match l {
            SceneLayout::SharedBuffers if self.shared_layout.is_none() => {
                self.shared_layout = Some(SharedBuffers::create(&self.gpu, &self.scene)?);
            }
            SceneLayout::PerMesh if self.mesh_layout.is_none() => {
                self.mesh_layout = Some(MeshBuffers::create(&self.gpu, &self.scene)?);
            }
            SceneLayout::SharedBuffers | SceneLayout::PerMesh => {}
        }
        Ok(())
    }

    /// The texture cells' textures and material table, made once (after `shared_buffers`' own
    /// buffers, whose `SceneDesc` gets the table's address).
    fn ensure_textures(&mut self, wait: Duration) -> Result<(), CellError> {
        self.ensure_layout(SceneLayout::SharedBuffers)?;
        if self.layout_textures.is_none() {
            let shared = self.shared_layout.as_ref().expect("made above");
            let how = (&self.submitter, wait);
            let what = (&*self.scene, self.slots(Resource::SampledImage));
            self.layout_textures = Some(LayoutTextures::create(&self.gpu, what, shared, how)?);
        }
        Ok(())
    }

    fn ensure_array(&mut self, r: Resource, wait: Duration) -> Result<(), CellError> {
        if !self.arrays.contains_key(&r) {
            let a = ResourceArray::create(&self.gpu, r, self.slots(r), &self.submitter, wait)?;
            self.arrays.insert(r, a);
        }
        Ok(())
    }
}
