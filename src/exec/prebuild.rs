//! Building a batch of cells ahead of their turn: the batch's GLSL compiled on a pool of threads
//! into the compiler's per-source cache, then workarounds and descriptor bindings in cell order
//! on the calling thread (cheap), then every distinct pipeline the batch needs on the pool.
//! `vkCreateRayTracingPipelinesKHR`, `vkCreateGraphicsPipelines` and `vkCreateComputePipelines`
//! may be called from several threads at once (Vulkan spec, "Threading Behavior": only the
//! pipeline cache, when created with `EXTERNALLY_SYNCHRONIZED`, needs external synchronization;
//! ours is not). Every error is kept for its cell, with its phase, and becomes the cell's result
//! at its turn, exactly as if the cell had been built then, except one whose outcome ends the
//! worker (a lost device, a fence past its deadline): that aborts the prebuild, since the device
//! is unusable and no cell of the batch can be blamed. Each unit of work (the threaded GLSL, each
//! cell's compile and bindings, each pipeline) is reported as a [`Step`], so the supervisor's
//! deadline measures silence, not the batch's size. Traces still run one cell at a time.
use super::built::{Bound, Compiled, PipelineInput, Prebuilt};
use super::compile::cell_shaders;
use super::error::CellError;
use super::executor::Executor;
use super::pipeline::Pipeline;
use crate::model::Cell;
use crate::model::Phase;
use crate::model::Timings;
use crate::shadergen::CellShaders;
use crate::vk::{Gpu, VkError};
use ash::vk;
use std::collections::HashSet;
use std::time::Instant;

/// A unit of prebuild progress, reported as it happens (the worker sends it as the step of phase
/// `prebuild`; each restarts the supervisor's deadline).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Step {
    /// GLSL sources compiled on the threads (k of n).
    Glsl(usize, usize),
    /// Cells compiled and bound, in order on the calling thread (k of n).
    Compiled(usize, usize),
    /// Pipelines created on the threads (k of n).
    Pipelines(usize, usize),
}

impl std::fmt::Display for Step {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        match self {
            Step::Glsl(k, n) => write!(f, "glsl {k}/{n}"),
            Step::Compiled(k, n) => write!(f, "compiled {k}/{n}"),
            Step::Pipelines(k, n) => write!(f, "pipelines {k}/{n}"),
        }
    }
}

/// An error met while prebuilding: kept for its cell's turn (`Ok`), or returned to abort the
/// prebuild (`Err`) when its outcome ends the worker: after a device loss or a hung fence no
/// later work on the device means anything, and the batch must be re-run cell by cell.
fn keep(e: CellError) -> Result<CellError, CellError> {
    if e.outcome().ends_worker() {
        Err(e)
    } else {
        Ok(e)
    }
}

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

/// A cell compiled and bound on the calling thread, waiting for its pipeline.
struct Staged {
    cell: Cell,
    timings: Timings,
    compiled: Compiled,
    bound: Bound,
}

impl Executor {
    /// Build `cells` (compile, bind, create pipelines on `threads` threads), keeping each cell's
    /// result for [`Executor::run`]. `progress` is called after every unit of work ([`Step`]).
    /// An error whose outcome ends the worker is returned ([`keep`]): no cell of the batch can be
    /// blamed.
    pub fn prebuild(
        &mut self,
        cells: &[Cell],
        threads: usize,
        progress: &(dyn Fn(Step) + Sync),
    ) -> Result<PrebuildStats, CellError> {
        let generated = self.precompile(cells, threads, progress);
        let mut staged = Vec::new();
        for (k, (cell, shaders)) in cells.iter().zip(generated).enumerate() {
            if let Some(s) = self.stage(cell, shaders)? {
                staged.push(s);
            }
            progress(Step::Compiled(k + 1, cells.len()));
        }
        let makers = self.makers(&staged);
        let made = self.make_pipelines(&staged, &makers, threads, progress);
        let failed = self.keep_pipelines(&mut staged, &makers, made)?;
        // A failed pipeline's maker keeps its error (above); the other cells of that pipeline try
        // again at their turn, as they would have without the prebuild.
        for Staged { cell, timings, bound, .. } in staged {
            if !failed.contains(&bound.pkey) {
                self.prebuilt.insert(
                    cell.id(),
                    Prebuilt { timings, phase: Phase::Pipeline, result: Ok(bound) },
                );
            }
        }
        Ok(PrebuildStats {
            pipelines: makers.len(),
            threads: threads.clamp(1, makers.len().max(1)),
        })
    }

    /// Each cell's GLSL, generated once; compiled on the threads first (into the compiler's
    /// per-source cache), then taken by each cell's compile in order.
    fn precompile(
        &mut self,
        cells: &[Cell],
        threads: usize,
        progress: &(dyn Fn(Step) + Sync),
    ) -> Vec<CellShaders> {
        let generated: Vec<_> = cells
            .iter()
            .map(|c| {
                cell_shaders(
                    c,
                    crate::model::inject::roll(&self.opts.inject, c, self.opts.inject_seed)
                        .as_ref(),
                )
            })
            .collect();
        if self.opts.spirv_dir.is_none() {
            let sources: Vec<_> = generated
                .iter()
                .flat_map(|g| g.shaders.iter().map(|s| (s.role, s.glsl.as_str())))
                .collect();
            self.compiler.precompile(&sources, threads, &|k, n| progress(Step::Glsl(k, n)));
        }
        generated
    }

    /// Compile and bind one cell on the calling thread: `Some` when it is ready for its pipeline;
    /// `None` when its error is kept for its turn; `Err` when the error ends the worker.
    fn stage(&mut self, cell: &Cell, shaders: CellShaders) -> Result<Option<Staged>, CellError> {
        let mut timings = Timings::default();
        let (phase, e) = match self.compile_cell(cell, shaders, &mut timings) {
            Err(e) => (Phase::Compile, e),
            Ok(compiled) => match self.bind_cell(cell, &compiled, &mut timings) {
                Ok(bound) => return Ok(Some(Staged { cell: *cell, timings, compiled, bound })),
                Err(e) => (Phase::Pipeline, e),
            },
        };
        let e = keep(e)?;
        self.prebuilt.insert(cell.id(), Prebuilt { timings, phase, result: Err(e) });
        Ok(None)
    }

    /// Which staged cells make a pipeline: the first cell of each pipeline not created yet (its
    /// timings get the time).
    fn makers(&self, staged: &[Staged]) -> Vec<usize> {
        let mut seen = HashSet::new();
        (0..staged.len())
            .filter(|&i| {
                let pkey = staged[i].bound.pkey;
                !self.pipelines.contains_key(&pkey) && seen.insert(pkey)
            })
            .collect()
    }

    /// The makers' pipelines, created on `threads` threads, in the makers' order.
    fn make_pipelines(
        &self,
        staged: &[Staged],
        makers: &[usize],
        threads: usize,
        progress: &(dyn Fn(Step) + Sync),
    ) -> Vec<Made> {
        let shared = Shared {
            gpu: &self.gpu,
            cache: self.cache,
            inputs: makers
                .iter()
                .map(|&i| {
                    let s = &staged[i];
                    self.pipeline_input(&s.cell, &s.compiled, &s.bound)
                })
                .collect(),
        };
        create_all(&shared, threads, &|k, n| progress(Step::Pipelines(k, n)))
    }

    /// Keep each made pipeline, or its error for its maker's turn (with the time in its timings);
    /// the keys of the pipelines that failed. An error that ends the worker is returned.
    fn keep_pipelines(
        &mut self,
        staged: &mut [Staged],
        makers: &[usize],
        made: Vec<Made>,
    ) -> Result<HashSet<u64>, CellError> {
        let mut failed: HashSet<u64> = HashSet::new();
        for (&i, Made(result, ms)) in makers.iter().zip(made) {
            let s = &mut staged[i];
            s.timings.pipeline_ms = ms;
            match result {
                Ok(p) => {
                    self.pipelines.insert(s.bound.pkey, p);
                }
                Err(e) => {
                    let e = keep(e.into())?;
                    failed.insert(s.bound.pkey);
                    let timings = s.timings.clone();
                    self.prebuilt.insert(
                        s.cell.id(),
                        Prebuilt { timings, phase: Phase::Pipeline, result: Err(e) },
                    );
                }
            }
        }
        Ok(failed)
    }
}

/// Create every input's pipeline on `threads` threads, in the inputs' order.
fn create_all(
    shared: &Shared,
    threads: usize,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Vec<Made> {
    let made = crate::pool::map(
        shared.inputs.len(),
        threads,
        || Some(()),
        |(), i| {
            let t = Instant::now();
            let r = shared.inputs[i].create(shared.gpu, shared.cache);
            Made(r, t.elapsed().as_secs_f64() * 1e3)
        },
        progress,
    );
    made.into_iter().map(|m| m.expect("every thread takes items (its init cannot fail)")).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::gpu::BuildError;
    use std::time::Duration;

    #[test]
    fn an_error_that_ends_the_worker_aborts_the_prebuild_and_others_are_kept() {
        let lost = || VkError::DeviceLost { call: "vkCreateDescriptorPool" };
        let aborts = [
            CellError::Vk(lost()),
            CellError::Build(BuildError::Vk(lost())),
            CellError::Build(BuildError::TimedOut(Duration::from_secs(1))),
            CellError::Timeout("upload"),
            CellError::Vk(VkError::Call { call: "vkWaitForFences", result: vk::Result::TIMEOUT }),
        ];
        for e in aborts {
            let what = e.to_string();
            assert!(keep(e).is_err(), "{what} must abort the prebuild");
        }
        let kept = [
            CellError::Vk(VkError::Call {
                call: "vkCreateRayTracingPipelinesKHR",
                result: vk::Result::ERROR_OUT_OF_HOST_MEMORY,
            }),
            CellError::Io(crate::exec::files::FileError::NotSpirv("x".into())),
            CellError::NotImplemented("x".into()),
            CellError::Unsupported("x".into()),
        ];
        for e in kept {
            let what = e.to_string();
            assert!(keep(e).is_ok(), "{what} is the cell's own result");
        }
    }

    #[test]
    fn steps_name_the_work_and_count_it() {
        assert_eq!(Step::Compiled(3, 512).to_string(), "compiled 3/512");
        assert_eq!(Step::Pipelines(1, 2).to_string(), "pipelines 1/2");
        assert_eq!(Step::Glsl(4, 9).to_string(), "glsl 4/9");
    }
}
