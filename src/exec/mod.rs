//! Runs cells on one device: [`Executor::prepare`] builds the scene's acceleration structures,
//! the probed resources and address tables that a worker's cells need before the first cell runs
//! (so a fault there is the worker's setup, not a cell's); per cell it creates descriptor bindings
//! and pipelines (reused after), records and submits the trace / draw / dispatch with a deadline,
//! reads the records back and compares them with the CPU reference, telling its caller each
//! [`Phase`] it enters. Everything that can go wrong becomes an [`Outcome`].
pub mod bindings;
pub mod error;
mod files;
pub mod heap;
pub mod pictures;
pub mod pipeline;
pub mod pipeline_cache;
pub mod prebuild;
pub mod resources;

pub use error::CellError;

use crate::model::InjectedFault;
use crate::model::Phase;
use crate::model::SceneParams;
use crate::model::{Canary, Cell, Resource};
use crate::model::{CellResult, Outcome, Timings};
use crate::probe::spec::{ArrayAt, ProbeSpec, ReadIndex};
use crate::probe::{self, Record, RECORD_SIZE};
use crate::reference::{self, SceneReference};
use crate::scene::gpu::SceneGpu;
use crate::scene::Scene;
use crate::shadergen::{self, compile::Compiler, PipelineKind};
use crate::vk::memory::{transition, Buffer, Image, Location, Transition};
use crate::vk::submit::{Submitter, Waited};
use crate::vk::{fault, Gpu, VkError};
use ash::vk;
use bindings::{Binding, LayoutKey};
use pipeline::Pipeline;
use resources::{ResourceArray, Target};
use std::collections::HashMap;
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// An address no driver maps: the invalid-address canary reads there.
pub const CANARY_BAD_ADDRESS: u64 = 0xdead_0000_0000;

#[derive(Clone, Debug)]
pub struct ExecOptions {
    /// Fence deadline per submission.
    pub timeout: Duration,
    /// `--inject-fault`: cells matching one of these misbehave at the probed read.
    pub inject: Vec<crate::model::Injection>,
    /// Seed of this worker's flaky-injection dice (recorded in each injected result).
    pub inject_seed: u64,
    /// Write each cell's GLSL and SPIR-V under this folder, and pictures of each mismatch.
    pub dump: Option<PathBuf>,
    /// A repro bundle's `shaders/`: each module is read from `<role file>.spv` there (already
    /// patched as the cell says) instead of compiled.
    pub spirv_dir: Option<PathBuf>,
    /// Folder of the persisted pipeline caches (`None`: an empty cache, nothing saved).
    pub pipeline_cache: Option<PathBuf>,
    /// `RTPROBE_BINDING_STAGES=all` of the run (the job file's `binding_stages`).
    pub all_stages: bool,
}

/// A cell's shaders as SPIR-V, workarounds applied (what phase `compile` produces).
struct Compiled {
    shaders: shadergen::CellShaders,
    spirv: Vec<std::sync::Arc<Vec<u32>>>,
    /// The `nonuniformEXT` the compiler dropped (direct heap cells).
    dropped: Option<heap::DroppedNonUniform>,
}

/// A cell ready to record: its descriptor binding, the key of its (created) pipeline, the
/// addresses its push constants carry, and the note on what the compiler did to its shape.
struct Bound {
    key: LayoutKey,
    pkey: u64,
    as_table_address: u64,
    patched_table_address: u64,
    /// The per-instance bases' address (`base=buffer`; 0 otherwise).
    base_address: u64,
    dropped: Option<heap::DroppedNonUniform>,
}

/// What [`Executor::prebuild`] made for one cell: its timings, the phase it got to, and either the
/// cell bound with its pipeline or the error that becomes its result at its turn.
struct Prebuilt {
    timings: Timings,
    phase: Phase,
    result: Result<Bound, CellError>,
}

/// What creating one pipeline needs apart from the device and the cache.
struct PipelineInput<'a> {
    shaders: &'a shadergen::CellShaders,
    spirv: &'a [std::sync::Arc<Vec<u32>>],
    layout: vk::PipelineLayout,
    model: crate::model::DescriptorModel,
    mapping: Option<Box<heap::PipelineMapping>>,
    records: pipeline::ShaderRecords,
}

impl PipelineInput<'_> {
    fn create(&self, gpu: &Gpu, cache: vk::PipelineCache) -> Result<Pipeline, VkError> {
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

/// Told each phase a cell (or the setup) enters; an error ends the cell there (the worker's
/// fault injection uses it to stand in for a device loss).
pub type PhaseHook<'a> = &'a mut dyn FnMut(Phase) -> Result<(), VkError>;

pub struct Executor {
    pub gpu: Gpu,
    scene: Scene,
    sref: SceneReference,
    opts: ExecOptions,
    compiler: Compiler,
    submitter: Submitter,
    records: Buffer,
    sampler: vk::Sampler,
    cache: vk::PipelineCache,
    scene_gpu: Option<SceneGpu>,
    arrays: HashMap<Resource, ResourceArray>,
    as_table: Option<Buffer>,
    ssbo_table: Option<Buffer>,
    /// `base=buffer`: one base per scene instance (`probe::base_buffer`).
    bases: Option<Buffer>,
    color: Option<Image>,
    bindings: HashMap<LayoutKey, Binding>,
    pipelines: HashMap<u64, Pipeline>,
    /// Cells compiled and bound ahead of their turn, with their pipelines, by cell id.
    prebuilt: HashMap<String, Prebuilt>,
    /// Where the pipeline cache came from and what was loaded.
    pub cache_status: Option<pipeline_cache::Loaded>,
    /// Milliseconds the CPU reference took.
    pub reference_ms: f64,
}

impl Executor {
    /// The shader compiler failing to start is `CellError::Compile(CompileError::Init)`, not a
    /// Vulkan error: the worker's setup reports it as such.
    pub fn new(gpu: Gpu, params: &SceneParams, opts: ExecOptions) -> Result<Self, CellError> {
        let scene = Scene::build(params);
        let t = Instant::now();
        let sref = SceneReference::compute(&scene);
        let reference_ms = t.elapsed().as_secs_f64() * 1e3;
        let compiler = Compiler::new()?;
        let submitter = Submitter::new(&gpu)?;
        let records = Buffer::new(
            &gpu,
            (params.pixels() * RECORD_SIZE) as u64,
            vk::BufferUsageFlags::STORAGE_BUFFER
                | vk::BufferUsageFlags::TRANSFER_DST
                | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS,
            Location::Host,
            "records",
        )?;
        let sampler = resources::create_sampler(&gpu)?;
        let (cache, cache_status) = pipeline_cache::open(&gpu, opts.pipeline_cache.as_deref())?;
        Ok(Executor {
            gpu,
            scene,
            sref,
            opts,
            compiler,
            submitter,
            records,
            sampler,
            cache,
            scene_gpu: None,
            arrays: HashMap::new(),
            as_table: None,
            ssbo_table: None,
            bases: None,
            color: None,
            bindings: HashMap::new(),
            pipelines: HashMap::new(),
            prebuilt: HashMap::new(),
            cache_status,
            reference_ms,
        })
    }

    /// Build everything `cells` need before any of them runs: the scene's acceleration
    /// structures, resource arrays, address tables, the color target. A device loss or a fence
    /// timeout here is the worker's setup fault (no cell ran on this device). A plain creation
    /// error (say, a format the driver refuses) is left to the cells that need that resource:
    /// they retry it and report it as their own `error`.
    pub fn prepare(&mut self, cells: &[Cell]) -> Result<(), CellError> {
        for cell in cells {
            let shaders = shadergen::generate(cell);
            if let Err(e) = self.ensure_resources(cell, &shaders) {
                if e.outcome() != Outcome::Error {
                    return Err(e);
                }
                tracing::warn!("setup for {}: {e}; left to the cell", cell.id());
            }
        }
        Ok(())
    }

    /// Write the pipeline cache back to its file (merged with what is there): the bytes written;
    /// `None` without a cache folder. The error is text: the worker sends it as it is
    /// (`WorkerMsg::CacheSaved`).
    pub fn save_pipeline_cache(&self) -> Option<Result<u64, String>> {
        let path = &self.cache_status.as_ref()?.path;
        Some(pipeline_cache::save(&self.gpu, self.cache, path).map_err(|e| e.to_string()))
    }

    /// Run one cell. Never panics on driver misbehaviour; every failure is an outcome.
    pub fn run(&mut self, cell: &Cell, on_phase: PhaseHook) -> CellResult {
        let start = Instant::now();
        let validation_before = crate::vk::instance::validation_error_count();
        let mut timings = Timings::default();
        let injected = crate::model::inject::roll(&self.opts.inject, cell, self.opts.inject_seed);
        let result = self
            .try_run(cell, injected.as_ref(), &mut timings, on_phase)
            .and_then(|done| on_phase(Phase::Check).map(|()| done).map_err(CellError::from));
        let mut out = match result {
            Ok((records, dropped)) => {
                let t = Instant::now();
                let r = self.check(cell, &records, dropped);
                let note = dropped.map(|d| d.note());
                timings.check_ms += t.elapsed().as_secs_f64() * 1e3;
                let detail = match (r.detail.clone(), note) {
                    (Some(d), Some(n)) => Some(format!("{d}; {n}")),
                    (d, n) => d.or(n),
                };
                CellResult { timings: timings.clone(), detail, ..r }
            }
            Err(e) => {
                let outcome = e.outcome();
                let detail = if outcome == Outcome::Timeout {
                    format!("{e} (fence wait limit {:?})", self.opts.timeout)
                } else {
                    e.to_string()
                };
                let fault =
                    if outcome == Outcome::DeviceLost { fault::query(&self.gpu) } else { None };
                CellResult {
                    outcome,
                    detail: Some(detail),
                    timings: timings.clone(),
                    comparison: None,
                    fault,
                    validation_errors: 0,
                }
            }
        };
        out.timings.total_ms = start.elapsed().as_secs_f64() * 1e3;
        out.validation_errors = crate::vk::instance::validation_error_count() - validation_before;
        out
    }

    /// Compare `records` with the reference; `dropped`: the driver saw the cell's non-uniform
    /// descriptor or sampler index without `NonUniform` (the compiler dropped it), so that part of
    /// the read is judged as undefined.
    fn check(
        &self,
        cell: &Cell,
        records: &[Record],
        dropped: Option<heap::DroppedNonUniform>,
    ) -> CellResult {
        let none = |outcome, detail: &str| CellResult {
            outcome,
            detail: Some(detail.into()),
            timings: Timings::default(),
            comparison: None,
            fault: None,
            validation_errors: 0,
        };
        if let Some(c) = cell.canary {
            return none(
                Outcome::Pass,
                &format!(
                    "canary {} ran to completion: this driver did not fault on it",
                    c.as_str()
                ),
            );
        }
        let undefined = reference::Undefined {
            descriptor: ProbeSpec::of(cell).read == ReadIndex::Undefined
                || dropped.is_some_and(|d| d.resource),
            sampler: dropped.is_some_and(|d| d.sampler),
        };
        let expected = reference::expected_with(cell, &self.scene, &self.sref, undefined);
        let (w, h) = (self.scene.params.width, self.scene.params.height);
        let mut cmp = reference::compare(&expected, records, w);
        let outcome = if cmp.passed() { Outcome::Pass } else { Outcome::Mismatch };
        let mut detail = (!cmp.passed()).then(|| {
            format!(
                "{} of {} compared pixels differ ({:?})",
                cmp.mismatched_pixels, cmp.compared, cmp.by_field
            )
        });
        if let (Some(dir), Some(d)) =
            (self.opts.dump.as_ref().filter(|_| !cmp.passed()), detail.as_mut())
        {
            match crate::exec::pictures::write(&dir.join(cell.id()), &expected, records, w, h) {
                Ok(paths) => cmp.pictures = paths,
                Err(e) => d.push_str(&format!("; pictures not written: {e}")),
            }
        }
        CellResult {
            outcome,
            detail,
            timings: Timings::default(),
            comparison: Some(cmp),
            fault: None,
            validation_errors: 0,
        }
    }

    fn ensure_scene(&mut self) -> Result<&SceneGpu, CellError> {
        if self.scene_gpu.is_none() {
            self.scene_gpu =
                Some(SceneGpu::build(&self.gpu, &self.scene, &self.submitter, self.opts.timeout)?);
        }
        Ok(self.scene_gpu.as_ref().expect("built above"))
    }

    fn slots(&self, r: Resource) -> u32 {
        probe::slot_count(r, self.scene.params.instances)
    }

    /// Targets of bindings 0..=2 for `key`, creating what is missing.
    fn targets(&mut self, key: LayoutKey) -> Result<Vec<(u32, Resource, Vec<Target>)>, CellError> {
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
            let s = self.ensure_scene()?;
            t.push((
                1,
                Resource::AccelerationStructure,
                vec![Target::Accel { raw: s.scene_tlas.raw, address: s.scene_tlas.address }],
            ));
        }
        if let Some(r) = key.probe {
            let slots = self.slots(r);
            let targets = if r == Resource::AccelerationStructure {
                let s = self.ensure_scene()?;
                (0..slots)
                    .map(|k| {
                        let a = &s.probe_tlas[probe::as_slot_tlas(k)];
                        Target::Accel { raw: a.raw, address: a.address }
                    })
                    .collect()
            } else {
                self.ensure_array(r)?;
                self.arrays[&r].targets(self.sampler, r, key.packed).map_err(|e| match e {
                    resources::PackedError::TooManyLayers { .. } => {
                        CellError::Unsupported(e.to_string())
                    }
                    resources::PackedError::NoPacked(_) => CellError::NotImplemented(e.to_string()),
                })?
            };
            t.push((2, r, targets));
        }
        Ok(t)
    }

    /// The scene, resource arrays, address tables and color target `cell` needs (built once,
    /// normally by [`Executor::prepare`]).
    fn ensure_resources(
        &mut self,
        cell: &Cell,
        shaders: &shadergen::CellShaders,
    ) -> Result<(), CellError> {
        let spec = ProbeSpec::of(cell);
        if shaders.kind == PipelineKind::RayTracing
            || shaders.uses_scene_tlas
            || spec.resource == Resource::AccelerationStructure
        {
            self.ensure_scene()?;
        }
        if shaders.uses_probe_binding && spec.resource != Resource::AccelerationStructure {
            self.ensure_array(spec.resource)?;
        }
        if spec.addresses.ssbo_table && self.ssbo_table.is_none() {
            self.ensure_array(Resource::StorageBuffer)?;
            let addrs: Vec<u64> =
                self.arrays[&Resource::StorageBuffer].buffers.iter().map(|b| b.address).collect();
            self.ssbo_table =
                Some(resources::address_table(&self.gpu, &addrs, "SSBO address table")?);
        }
        if spec.addresses.as_table && self.as_table.is_none() {
            let s = self.ensure_scene()?;
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

    fn ensure_array(&mut self, r: Resource) -> Result<(), CellError> {
        if !self.arrays.contains_key(&r) {
            let a = ResourceArray::create(
                &self.gpu,
                r,
                self.slots(r),
                &self.submitter,
                self.opts.timeout,
            )?;
            self.arrays.insert(r, a);
        }
        Ok(())
    }

    /// GLSL → SPIR-V (cached per source), the cell's workarounds, `--dump`: phase `compile`.
    fn compile_cell(
        &mut self,
        cell: &Cell,
        shaders: shadergen::CellShaders,
        timings: &mut Timings,
    ) -> Result<Compiled, CellError> {
        let spec = ProbeSpec::of(cell);
        if spec.array == ArrayAt::Heap && shadergen::glslang::find().is_none() {
            return Err(CellError::NotImplemented(shadergen::glslang::missing_reason()));
        }
        // SPIR-V
        let mut spirv = Vec::new();
        for s in &shaders.shaders {
            let words = match &self.opts.spirv_dir {
                Some(dir) => {
                    std::sync::Arc::new(files::bundle_spirv(dir, s.role).map_err(CellError::Io)?)
                }
                None => {
                    let (words, ms) = self.compiler.compile(s.role, &s.glsl)?;
                    timings.compile_ms += ms;
                    words
                }
            };
            spirv.push(words);
        }
        // The spec's workarounds: as-to-address for address_patched cells, then the cell's own
        // patch. A bundle's SPIR-V is patched already.
        let workarounds = spec.workarounds().filter(|_| self.opts.spirv_dir.is_none());
        for w in workarounds {
            let t = Instant::now();
            let mut patched_any = false;
            for words in spirv.iter_mut() {
                match crate::patches::workaround::patch_module(words, w) {
                    Ok(Some(p)) => {
                        *words = std::sync::Arc::new(p);
                        patched_any = true;
                    }
                    Ok(None) => {}
                    Err(e) => return Err(e.into()),
                }
            }
            timings.compile_ms += t.elapsed().as_secs_f64() * 1e3;
            if !patched_any {
                return Err(crate::patches::PatchError::NothingToPatch {
                    patch: w.as_str(),
                    what: "no module of the cell has the access this workaround rewrites".into(),
                }
                .into());
            }
        }
        if let Some(dir) = &self.opts.dump {
            files::dump(dir, cell, &shaders, &spirv).map_err(CellError::Io)?;
        }
        let dropped = heap::dropped_nonuniform(&spec, &spirv);
        Ok(Compiled { shaders, spirv, dropped })
    }

    /// Resources (built by `prepare`), descriptor bindings (cached per layout) and the key of the
    /// cell's pipeline: the first half of phase `pipeline`.
    fn bind_cell(
        &mut self,
        cell: &Cell,
        c: &Compiled,
        timings: &mut Timings,
    ) -> Result<Bound, CellError> {
        let t = Instant::now();
        let spec = ProbeSpec::of(cell);
        self.ensure_resources(cell, &c.shaders)?;
        let stages = match c.shaders.kind {
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
        };
        // RTPROBE_BINDING_STAGES=all: declare bindings and push constants for VK_SHADER_STAGE_ALL
        // instead of the pipeline's stages (reproduces reports/lavapipe/FINDINGS.md).
        let stages = if self.opts.all_stages { vk::ShaderStageFlags::ALL } else { stages };
        let key = LayoutKey {
            stages,
            model: spec.model,
            scene_tlas: c.shaders.uses_scene_tlas,
            probe: c.shaders.uses_probe_binding.then_some(spec.resource),
            heap_direct: spec.array == ArrayAt::Heap,
            packed: spec.packed(),
        };
        if !self.bindings.contains_key(&key) {
            let targets = self.targets(key)?;
            let b = Binding::create(&self.gpu, key, &targets)?;
            self.bindings.insert(key, b);
        }
        // The table the address patches read at push-constant offset probe::PATCHED_TABLE_OFFSET
        // (PushConstants::as_table is the hand-written address variant's).
        let mut patched_table_address = 0;
        if spec.addresses.ssbo_table {
            patched_table_address = self.ssbo_table.as_ref().map(|b| b.address).unwrap_or(0);
        }
        let mut as_table_address = 0;
        if spec.addresses.as_table {
            as_table_address = self.as_table.as_ref().map(|b| b.address).unwrap_or(0);
            patched_table_address = as_table_address;
        }
        let base_address = if spec.instance_bases() {
            self.bases.as_ref().map(|b| b.address).unwrap_or(0)
        } else {
            0
        };
        timings.setup_ms = t.elapsed().as_secs_f64() * 1e3;
        // pipeline (reused for identical SPIR-V and model)
        let pkey = {
            use std::hash::{Hash, Hasher};
            let mut hs = std::collections::hash_map::DefaultHasher::new();
            for s in &c.spirv {
                s.hash(&mut hs);
            }
            spec.model.hash(&mut hs);
            spec.heap.hash(&mut hs);
            key.hash(&mut hs);
            c.shaders.recursion_depth.hash(&mut hs);
            hs.finish()
        };
        Ok(Bound {
            key,
            pkey,
            as_table_address,
            patched_table_address,
            base_address,
            dropped: c.dropped,
        })
    }

    /// What creating the cell's pipeline needs, apart from the device and cache.
    fn pipeline_input<'a>(&self, cell: &Cell, c: &'a Compiled, b: &Bound) -> PipelineInput<'a> {
        let spec = ProbeSpec::of(cell);
        let binding = &self.bindings[&b.key];
        let layout = binding.heap_layout();
        let mapping =
            spec.heap.zip(layout.as_ref()).map(|(access, l)| heap::PipelineMapping::new(access, l));
        let records = pipeline::shader_records(&spec, layout.as_ref());
        PipelineInput {
            shaders: &c.shaders,
            spirv: &c.spirv,
            layout: binding.pipeline_layout,
            model: spec.model,
            mapping,
            records,
        }
    }

    /// The cell's pipeline, created unless an identical one exists: the second half of `pipeline`.
    fn ensure_pipeline(
        &mut self,
        cell: &Cell,
        c: &Compiled,
        b: &Bound,
        timings: &mut Timings,
    ) -> Result<(), CellError> {
        if !self.pipelines.contains_key(&b.pkey) {
            let input = self.pipeline_input(cell, c, b);
            let t = Instant::now();
            let p = input.create(&self.gpu, self.cache)?;
            timings.pipeline_ms = t.elapsed().as_secs_f64() * 1e3;
            self.pipelines.insert(b.pkey, p);
        }
        Ok(())
    }

    /// Compile, bind and create the pipeline of `cell` (sequentially, phase by phase), or take
    /// what [`Executor::prebuild`] made for it.
    fn build(
        &mut self,
        cell: &Cell,
        injected: Option<&InjectedFault>,
        timings: &mut Timings,
        on_phase: PhaseHook,
    ) -> Result<Bound, CellError> {
        on_phase(Phase::Compile)?;
        match self.prebuilt.remove(&cell.id()) {
            Some(p) => {
                *timings = p.timings;
                if p.phase == Phase::Pipeline {
                    on_phase(Phase::Pipeline)?;
                }
                p.result
            }
            None => {
                let c = self.compile_cell(cell, cell_shaders(cell, injected), timings)?;
                on_phase(Phase::Pipeline)?;
                let b = self.bind_cell(cell, &c, timings)?;
                self.ensure_pipeline(cell, &c, &b, timings)?;
                Ok(b)
            }
        }
    }

    /// The cell's push constants (layout: probe::PushConstants, then the patches' table address).
    fn push_constants(&self, cell: &Cell, injected: Option<&InjectedFault>, b: &Bound) -> Vec<u8> {
        let (w, h) = (self.scene.params.width, self.scene.params.height);
        let spec = ProbeSpec::of(cell);
        let fault = injected.map(|i| i.fault);
        let injected_bad =
            injected.is_some_and(|i| i.fault.reads_bad_address() && i.armed != Some(false));
        probe::PushConstants {
            loop_forever: u32::from(
                spec.canary == Some(Canary::InfiniteLoop)
                    || fault == Some(crate::model::inject::FaultKind::Hang),
            ),
            as_table: b.as_table_address,
            base_address: b.base_address,
            bad_address: if spec.canary == Some(Canary::InvalidAddress) || injected_bad {
                CANARY_BAD_ADDRESS
            } else {
                0
            },
            inject_salt: fault
                .map(|f| crate::model::inject::value_salt(f, &cell.id()))
                .unwrap_or(0),
            ..probe::push_constants(w, h, self.scene.params.instances, spec.resource)
        }
        .to_bytes(b.patched_table_address)
    }

    /// The cell's records, and the `nonuniformEXT` the compiler dropped from the cell's shape (if any).
    fn try_run(
        &mut self,
        cell: &Cell,
        injected: Option<&InjectedFault>,
        timings: &mut Timings,
        on_phase: PhaseHook,
    ) -> Result<(Vec<Record>, Option<heap::DroppedNonUniform>), CellError> {
        let bound = self.build(cell, injected, timings, on_phase)?;
        on_phase(Phase::Record)?;
        let pc = self.push_constants(cell, injected, &bound);
        let gpu = &self.gpu;
        let work = Work {
            pipe: &self.pipelines[&bound.pkey],
            binding: &self.bindings[&bound.key],
            stages: bound.key.stages,
            pc: &pc,
            color: self.color.as_ref(),
            size: (self.scene.params.width, self.scene.params.height),
        };
        // Sentinel: a record no probe wrote reads as flags 0xffffffff. Written from the host
        // (the buffer is mapped): a vkCmdFillBuffer is an internal compute dispatch on some
        // drivers and must not disturb the state this cell binds.
        self.records.write(0, &vec![0xffu8; self.scene.params.pixels() * RECORD_SIZE]);
        let mut entered_trace = Ok(());
        let waited = self.submitter.run(gpu, self.opts.timeout, |cmd| unsafe {
            work.record(gpu, cmd);
            let to_host = [vk::MemoryBarrier::default()
                .src_access_mask(vk::AccessFlags::MEMORY_WRITE)
                .dst_access_mask(vk::AccessFlags::HOST_READ)];
            gpu.device.cmd_pipeline_barrier(
                cmd,
                vk::PipelineStageFlags::ALL_COMMANDS,
                vk::PipelineStageFlags::HOST,
                vk::DependencyFlags::empty(),
                &to_host,
                &[],
                &[],
            );
            // Recorded: what follows is the submission and the fence wait.
            entered_trace = on_phase(Phase::Trace);
        })?;
        entered_trace?;
        match waited {
            Waited::TimedOut => return Err(CellError::Timeout("the cell's submission")),
            Waited::Done(d) => timings.trace_ms = d.as_secs_f64() * 1e3,
        }
        on_phase(Phase::Readback)?;
        let t = Instant::now();
        let bytes = self.records.read(self.scene.params.pixels() * RECORD_SIZE);
        let recs = bytes.chunks_exact(RECORD_SIZE).map(Record::from_bytes).collect();
        timings.check_ms = t.elapsed().as_secs_f64() * 1e3;
        Ok((recs, bound.dropped))
    }
}

/// One cell's GPU work: its pipeline, bindings and push constants over a `size` (w, h) launch.
struct Work<'a> {
    pipe: &'a Pipeline,
    binding: &'a Binding,
    stages: vk::ShaderStageFlags,
    pc: &'a [u8],
    color: Option<&'a Image>,
    size: (u32, u32),
}

impl Work<'_> {
    /// Record the trace, dispatch or draw into `cmd` (in the recording state).
    unsafe fn record(&self, gpu: &Gpu, cmd: vk::CommandBuffer) {
        let (d, (w, h), pipe, binding) = (&gpu.device, self.size, self.pipe, self.binding);
        let point = match pipe.kind {
            PipelineKind::RayTracing => vk::PipelineBindPoint::RAY_TRACING_KHR,
            PipelineKind::Compute => vk::PipelineBindPoint::COMPUTE,
            PipelineKind::Graphics => vk::PipelineBindPoint::GRAPHICS,
        };
        match pipe.kind {
            PipelineKind::RayTracing => {
                binding.bind(gpu, cmd, point);
                d.cmd_bind_pipeline(cmd, point, pipe.raw);
                binding.push(gpu, cmd, self.stages, self.pc);
                let sbt = pipe.sbt.as_ref().expect("RT pipelines have an SBT");
                gpu.rt.as_ref().expect("RT enabled").cmd_trace_rays(
                    cmd,
                    &sbt.raygen,
                    &sbt.miss,
                    &sbt.hit,
                    &sbt.callable,
                    w,
                    h,
                    1,
                );
            }
            PipelineKind::Compute => {
                binding.bind(gpu, cmd, point);
                d.cmd_bind_pipeline(cmd, point, pipe.raw);
                binding.push(gpu, cmd, self.stages, self.pc);
                d.cmd_dispatch(cmd, w.div_ceil(8), h.div_ceil(8), 1);
            }
            PipelineKind::Graphics => {
                let img = self.color.expect("color target created");
                let top = (
                    vk::ImageLayout::UNDEFINED,
                    vk::AccessFlags::empty(),
                    vk::PipelineStageFlags::TOP_OF_PIPE,
                );
                let att = (
                    vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL,
                    vk::AccessFlags::COLOR_ATTACHMENT_WRITE,
                    vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT,
                );
                transition(gpu, cmd, img.raw, Transition { from: top, to: att });
                let att = [vk::RenderingAttachmentInfo::default()
                    .image_view(img.view)
                    .image_layout(vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL)
                    .load_op(vk::AttachmentLoadOp::CLEAR)
                    .store_op(vk::AttachmentStoreOp::STORE)];
                let area = vk::Rect2D {
                    offset: vk::Offset2D::default(),
                    extent: vk::Extent2D { width: w, height: h },
                };
                d.cmd_begin_rendering(
                    cmd,
                    &vk::RenderingInfo::default()
                        .render_area(area)
                        .layer_count(1)
                        .color_attachments(&att),
                );
                binding.bind(gpu, cmd, point);
                d.cmd_bind_pipeline(cmd, point, pipe.raw);
                binding.push(gpu, cmd, self.stages, self.pc);
                d.cmd_set_viewport(
                    cmd,
                    0,
                    &[vk::Viewport {
                        x: 0.0,
                        y: 0.0,
                        width: w as f32,
                        height: h as f32,
                        min_depth: 0.0,
                        max_depth: 1.0,
                    }],
                );
                d.cmd_set_scissor(cmd, 0, &[area]);
                d.cmd_draw(cmd, 6, (w / probe::TILE) * (h / probe::TILE), 0, 0);
                d.cmd_end_rendering(cmd);
            }
        }
    }
}

/// The GLSL of every shader `cell` needs, with its injected fault (if any) appended.
fn cell_shaders(cell: &Cell, injected: Option<&InjectedFault>) -> shadergen::CellShaders {
    shadergen::generate_with(cell, injected.map(|i| i.fault))
}

impl Drop for Executor {
    fn drop(&mut self) {
        let gpu = &self.gpu;
        unsafe {
            let _ = gpu.device.device_wait_idle();
        }
        for p in self.pipelines.values() {
            p.destroy(gpu);
        }
        for b in self.bindings.values() {
            b.destroy(gpu);
        }
        for a in self.arrays.values() {
            a.destroy(gpu);
        }
        for t in self.as_table.iter().chain(self.ssbo_table.iter()).chain(self.bases.iter()) {
            t.destroy(gpu);
        }
        if let Some(c) = &self.color {
            c.destroy(gpu);
        }
        if let Some(s) = &self.scene_gpu {
            s.destroy(gpu);
        }
        self.records.destroy(gpu);
        self.submitter.destroy(gpu);
        unsafe {
            gpu.device.destroy_sampler(self.sampler, None);
            gpu.device.destroy_pipeline_cache(self.cache, None);
        }
    }
}
