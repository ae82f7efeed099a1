//! Building a batch of cells ahead of their turn: the batch's GLSL compiled on a pool of threads
//! into the compiler's per-source cache, then workarounds and descriptor bindings in cell order
//! on the calling thread (cheap), then every distinct pipeline the batch needs on the pool.
//! `vkCreateRayTracingPipelinesKHR`, `vkCreateGraphicsPipelines` and `vkCreateComputePipelines`
//! may be called from several threads at once (Vulkan spec, "Threading Behavior": only the
//! pipeline cache, when created with `EXTERNALLY_SYNCHRONIZED`, needs external synchronization;
//! ours is not). Every error is kept for its cell, with its phase, and becomes the cell's result
//! at its turn, exactly as if the cell had been built then. Traces still run one cell at a time.
use super::{Bound, CellError, Compiled, Executor, Pipeline, PipelineInput, Prebuilt};
use crate::matrix::Cell;
use crate::outcome::Timings;
use crate::runner::phase::Phase;
use crate::vk::{Gpu, VkError};
use ash::vk;
use std::collections::{HashMap, HashSet};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::Instant;

/// What a prebuild did.
#[derive(Clone, Copy, Debug, Default)]
pub struct PrebuildStats {
    /// Pipelines created (on the threads).
    pub pipelines: usize,
    pub threads: usize,
}

/// The pipelines' inputs shared by the threads.
struct Shared<'a> {
    gpu: &'a Gpu,
    cache: vk::PipelineCache,
    inputs: Vec<PipelineInput<'a>>,
}

// SAFETY: the inputs are plain Vulkan handles and create-info data (the heap mapping's pNext
// pointers point into its own box) that live for the thread scope and are only read; the device
// functions are thread-safe for pipeline creation (module doc) and `Gpu` is only read.
unsafe impl Sync for Shared<'_> {}

/// A created pipeline handed back from a thread.
struct Made(Result<Pipeline, VkError>, f64);
// SAFETY: a pipeline is Vulkan handles and its SBT buffer's mapping; the thread that made it
// no longer touches it once it is handed over.
unsafe impl Send for Made {}

impl Executor {
    /// Build `cells` (compile, bind, create pipelines on `threads` threads), keeping each cell's
    /// result for [`Executor::run`]. `progress(done, total)` is called as pipelines finish. A
    /// device loss during pipeline creation is returned: no cell of the batch can be blamed.
    pub fn prebuild(&mut self, cells: &[Cell], threads: usize, progress: &(dyn Fn(usize, usize) + Sync)) -> Result<PrebuildStats, VkError> {
        // The batch's GLSL compiled on the threads first (into the compiler's per-source cache).
        if self.opts.spirv_dir.is_none() {
            let generated: Vec<_> = cells
                .iter()
                .map(|c| {
                    let injected = crate::matrix::inject::roll(&self.opts.inject, c, self.opts.inject_seed);
                    crate::shadergen::generate_with(&crate::shadergen::source_cell(c), injected.map(|i| i.fault))
                })
                .collect();
            let sources: Vec<_> = generated.iter().flat_map(|g| g.shaders.iter().map(|s| (s.role, s.glsl.as_str()))).collect();
            self.compiler.precompile(&sources, threads);
        }
        let mut staged: Vec<(Cell, Timings, Compiled, Bound)> = Vec::new();
        for cell in cells {
            let mut timings = Timings::default();
            let injected = crate::matrix::inject::roll(&self.opts.inject, cell, self.opts.inject_seed);
            let compiled = match self.compile_cell(cell, injected.as_ref(), &mut timings) {
                Ok(c) => c,
                Err(e) => {
                    self.prebuilt.insert(cell.id(), Prebuilt { timings, phase: Phase::Compile, result: Err(e) });
                    continue;
                }
            };
            match self.bind_cell(cell, &compiled, &mut timings) {
                Ok(b) => staged.push((*cell, timings, compiled, b)),
                Err(e) => {
                    if let CellError::Vk(VkError::DeviceLost { .. }) = e {
                        return Err(VkError::DeviceLost { call: "descriptor setup during prebuild" });
                    }
                    self.prebuilt.insert(cell.id(), Prebuilt { timings, phase: Phase::Pipeline, result: Err(e) });
                }
            }
        }
        // The first cell of each pipeline not created yet makes it (its timings get the time).
        let mut seen = HashSet::new();
        let makers: Vec<usize> = (0..staged.len()).filter(|&i| !self.pipelines.contains_key(&staged[i].3.pkey) && seen.insert(staged[i].3.pkey)).collect();
        let made = {
            let shared = Shared {
                gpu: &self.gpu,
                cache: self.cache,
                inputs: makers.iter().map(|&i| self.pipeline_input(&staged[i].0, &staged[i].2, &staged[i].3)).collect(),
            };
            create_all(&shared, threads, progress)
        };
        let mut failed: HashMap<u64, usize> = HashMap::new();
        for (&i, Made(result, ms)) in makers.iter().zip(made) {
            staged[i].1.pipeline_ms = ms;
            match result {
                Ok(p) => {
                    self.pipelines.insert(staged[i].3.pkey, p);
                }
                Err(e) if e.is_device_lost() => return Err(e),
                Err(e) => {
                    failed.insert(staged[i].3.pkey, i);
                    let (cell, timings) = (staged[i].0, staged[i].1.clone());
                    self.prebuilt.insert(cell.id(), Prebuilt { timings, phase: Phase::Pipeline, result: Err(e.into()) });
                }
            }
        }
        for (i, (cell, timings, _, bound)) in staged.into_iter().enumerate() {
            match failed.get(&bound.pkey) {
                Some(&maker) if maker == i => {} // its error is kept above
                // Another cell's creation of this pipeline failed: this one tries again at its
                // turn, as it would have without the prebuild.
                Some(_) => {}
                None => {
                    self.prebuilt.insert(cell.id(), Prebuilt { timings, phase: Phase::Pipeline, result: Ok(bound) });
                }
            }
        }
        Ok(PrebuildStats { pipelines: makers.len(), threads: threads.clamp(1, makers.len().max(1)) })
    }
}

/// Create every input's pipeline on `threads` threads, in the inputs' order.
fn create_all(shared: &Shared, threads: usize, progress: &(dyn Fn(usize, usize) + Sync)) -> Vec<Made> {
    let n = shared.inputs.len();
    let next = AtomicUsize::new(0);
    let done = AtomicUsize::new(0);
    let out: Vec<Mutex<Option<Made>>> = (0..n).map(|_| Mutex::new(None)).collect();
    std::thread::scope(|s| {
        for _ in 0..threads.clamp(1, n.max(1)) {
            s.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                if i >= n {
                    break;
                }
                let t = Instant::now();
                let r = shared.inputs[i].create(shared.gpu, shared.cache);
                let made = Made(r, t.elapsed().as_secs_f64() * 1e3);
                *out[i].lock().unwrap_or_else(|p| p.into_inner()) = Some(made);
                progress(done.fetch_add(1, Ordering::Relaxed) + 1, n);
            });
        }
    });
    out.into_iter().map(|m| m.into_inner().unwrap_or_else(|p| p.into_inner()).expect("every index was taken by a thread")).collect()
}
