//! The executor of one device ([`Executor`]): what it holds (the scene and its CPU reference,
//! the shader compiler, the submitter, the records buffer, the sampler, the pipeline cache, and
//! what cells made: scene acceleration structures, resource arrays, address tables, the color
//! target, bindings, pipelines, prebuilt cells), its options, its creation and teardown, and the
//! pipeline cache saved back.
use super::bindings::{Binding, LayoutKey};
use super::built::Creation;
use super::built::Prebuilt;
use super::error::CellError;
use super::pipeline::Pipeline;
use super::pipeline_cache;
use super::pipeline_library::Libraries;
use super::resources::ResourceArray;
use super::samplers;
use crate::model::{Phase, Resource, SceneParams};
use crate::probe::RECORD_SIZE;
use crate::reference::SceneReference;
use crate::scene::gpu::SceneGpu;
use crate::scene::Scene;
use crate::shadergen::compile::Compiler;
use crate::vk::memory::{Buffer, Image, Location};
use crate::vk::submit::Submitter;
use crate::vk::{Gpu, VkError};
use ash::vk;
use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};

#[derive(Clone, Debug)]
pub struct ExecOptions {
    /// Fence deadline per submission of a cell (and of what a cell builds at its turn).
    pub timeout: Duration,
    /// Fence deadline of the setup's submissions ([`Executor::prepare`]: the scene's AS build,
    /// image uploads), inside the supervisor's setup deadline, not a cell's: a worker that
    /// compiles afresh builds the AS with the driver's build shaders uncompiled (lavapipe 26:
    /// 1.7 s alone, past 16 s on a loaded machine), and that is no cell's timeout.
    pub setup_timeout: Duration,
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
    /// Folder whose `glsl/` keeps GLSL compiles between runs (`shadergen::disk_cache`; `None`:
    /// compile afresh, as bisect's, repro's, GPU-AV's and mutant workers do).
    pub glsl_cache: Option<PathBuf>,
    /// `RTPROBE_BINDING_STAGES=all` of the run (the job file's `binding_stages`).
    pub all_stages: bool,
    /// `--lane-evidence` of the run: where the probe measures its lane evidence.
    pub lanes: crate::model::LaneMode,
}

/// Told each phase a cell (or the setup) enters; an error ends the cell there (the worker's
/// fault injection uses it to stand in for a device loss).
pub type PhaseHook<'a> = &'a mut dyn FnMut(Phase) -> Result<(), VkError>;

pub struct Executor {
    /// Shared with the prebuild's pipeline threads (`pipeline_pool`).
    pub gpu: Arc<Gpu>,
    /// Shared with a checker thread (`checker`), as is the reference.
    pub(super) scene: Arc<Scene>,
    pub(super) sref: Arc<SceneReference>,
    pub(super) opts: ExecOptions,
    pub(super) compiler: Compiler,
    pub(super) submitter: Submitter,
    pub(super) records: Buffer,
    pub(super) sampler: vk::Sampler,
    pub(super) cache: vk::PipelineCache,
    pub(super) scene_gpu: Option<SceneGpu>,
    pub(super) arrays: HashMap<Resource, ResourceArray>,
    pub(super) as_table: Option<Buffer>,
    pub(super) ssbo_table: Option<Buffer>,
    /// `base=buffer`: one base per scene instance (`probe::base_buffer`).
    pub(super) bases: Option<Buffer>,
    /// `scene_layout=shared_buffers`' buffers and `SceneDesc`.
    pub(super) shared_layout: Option<super::layout_buffers::SharedBuffers>,
    /// `scene_layout=per_mesh`'s mesh buffers.
    pub(super) mesh_layout: Option<super::layout_buffers::MeshBuffers>,
    /// The `scene_layout` texture cells' textures and material table.
    pub(super) layout_textures: Option<super::layout_textures::LayoutTextures>,
    pub(super) color: Option<Image>,
    pub(super) bindings: HashMap<LayoutKey, Binding>,
    pub(super) pipelines: HashMap<u64, Pipeline>,
    /// Cells compiled and bound ahead of their turn, with their pipelines, by cell id.
    pub(super) prebuilt: HashMap<String, Prebuilt>,
    /// Where the pipeline cache came from and what was loaded.
    pub cache_status: Option<pipeline_cache::Loaded>,
    /// Group libraries of ray tracing pipelines (a device created with VK_KHR_pipeline_library:
    /// its RT pipelines are linked from them).
    pub(super) libraries: Option<Arc<Libraries>>,
    /// The stages where the device lists subgroup ballot (`DeviceInfo::subgroup_ballot`).
    pub(super) ballot: Vec<crate::model::Stage>,
    /// Milliseconds the CPU reference took.
    pub reference_ms: f64,
    /// What a cell's readback and check fill, kept from cell to cell.
    pub(super) scratch: Scratch,
    /// Each distinct module's interface, read once (`fit`), by a hash of its words.
    pub(super) interfaces: std::collections::HashMap<u128, crate::interface::ModuleInterface>,
}

/// Buffers every cell's readback and check fill, reused from cell to cell so that their pages
/// stay mapped and warm: the records, and the reference's expected records (the last cell's,
/// reused by a next cell with the same key).
#[derive(Default)]
pub(super) struct Scratch {
    pub(super) records: Vec<crate::probe::Record>,
    pub(super) expected: crate::reference::ExpectedMemo,
}

impl Executor {
    /// The shader compiler failing to start is `CellError::Compile(CompileError::Init)`, not a
    /// Vulkan error: the worker's setup reports it as such.
    pub fn new(gpu: Gpu, params: &SceneParams, opts: ExecOptions) -> Result<Self, CellError> {
        let scene = Scene::of(params)?;
        let t = Instant::now();
        let sref = SceneReference::compute(&scene);
        let reference_ms = t.elapsed().as_secs_f64() * 1e3;
        let mut compiler = Compiler::new()?;
        compiler.use_disk_cache(opts.glsl_cache.as_deref());
        let submitter = Submitter::new(&gpu)?;
        let records = Buffer::new(
            &gpu,
            (params.pixels() * RECORD_SIZE) as u64,
            vk::BufferUsageFlags::STORAGE_BUFFER
                | vk::BufferUsageFlags::TRANSFER_DST
                | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS,
            Location::Readback,
            "records",
        )?;
        let sampler = samplers::create_sampler(&gpu)?;
        let (cache, cache_status) = pipeline_cache::open(&gpu, opts.pipeline_cache.as_deref())?;
        let libraries = gpu.enabled.pipeline_library.then(Arc::default);
        // `Gpu` holds raw create-info pointers, so it is not `Send`/`Sync` by itself; the only
        // other thread that sees it is a prebuild's pipeline thread, through
        // `pipeline_pool::Maker`, whose `unsafe impl` says why that is sound.
        #[allow(clippy::arc_with_non_send_sync)]
        let gpu = Arc::new(gpu);
        let stages = crate::model::Stage::ALL.iter().copied();
        let ballot = stages.filter(|&s| gpu.info.subgroup_ballot(s)).collect();
        Ok(Executor {
            gpu,
            ballot,
            scene: Arc::new(scene),
            sref: Arc::new(sref),
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
            shared_layout: None,
            mesh_layout: None,
            layout_textures: None,
            color: None,
            bindings: HashMap::new(),
            pipelines: HashMap::new(),
            prebuilt: HashMap::new(),
            cache_status,
            libraries,
            reference_ms,
            scratch: Scratch::default(),
            interfaces: Default::default(),
        })
    }

    /// Destroy every pipeline and group library made so far (each cell's submission has been
    /// waited for): what a later cell needs is made again, from the pipeline cache. Keeps the
    /// driver's live pipelines to a chunk's (a driver's creation time can grow with them).
    pub fn release_pipelines(&mut self) {
        for p in self.pipelines.values() {
            p.destroy(&self.gpu);
        }
        self.pipelines.clear();
        if let Some(l) = self.libraries.take() {
            l.destroy(&self.gpu);
            self.libraries = Some(Arc::default());
        }
    }

    /// How this executor makes pipelines.
    pub(super) fn creation(&self) -> Creation<'_> {
        Creation { cache: self.cache, libraries: self.libraries.as_deref() }
    }

    /// Write the pipeline cache back to its file (merged with what is there): the bytes written;
    /// `None` without a cache folder. The error is text: the worker sends it as it is
    /// (`WorkerMsg::CacheSaved`).
    pub fn save_pipeline_cache(&self) -> Option<Result<u64, String>> {
        let path = &self.cache_status.as_ref()?.path;
        Some(pipeline_cache::save(&self.gpu, self.cache, path).map_err(|e| e.to_string()))
    }
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
        if let Some(l) = &self.libraries {
            l.destroy(gpu);
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
        if let Some(s) = &self.shared_layout {
            s.destroy(gpu);
        }
        if let Some(m) = &self.mesh_layout {
            m.destroy(gpu);
        }
        if let Some(t) = &self.layout_textures {
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
