//! Building a batch of cells ahead of their turns, streamed: the batch's GLSL generated, then
//! compiled or read from the disk cache, on a pool of threads into the compiler's per-source
//! cache; each cell's modules taken from that cache in order, then, on the threads again, what
//! needs nothing of the executor ([`super::analysed`]: workarounds patched in, what the driver
//! sees of the modules, their interfaces read); then descriptor bindings in
//! cell order on the calling thread (the staging), each distinct pipeline's input handed to a
//! pool of threads ([`super::pipeline_pool`]) as soon as its first cell is staged; then the
//! cells take their turns on the calling thread as their pipelines arrive ([`Prebuild::turn`]),
//! while later pipelines are still being made. `vkCreateRayTracingPipelinesKHR`,
//! `vkCreateGraphicsPipelines` and `vkCreateComputePipelines` may be called from several threads
//! at once (Vulkan spec, "Threading Behavior": only the pipeline cache, when created with
//! `EXTERNALLY_SYNCHRONIZED`, needs external synchronization; ours is not). Every error is kept
//! for its cell, with its phase, and becomes the cell's result at its turn, exactly as if the
//! cell had been built then, except one whose outcome ends the worker (a lost device, a fence
//! past its deadline): that aborts the prebuild, since the device is unusable and no cell of the
//! batch can be blamed. Each unit of work (the threaded GLSL, each cell's compile and bindings,
//! each pipeline) is reported as a [`Step`], so the supervisor's deadline measures silence, not
//! the batch's size. Traces still run one cell at a time, on the calling thread.
use super::analysed::Analysed;
use super::built::{Bound, Compiled, Prebuilt};
use super::error::CellError;
use super::executor::Executor;
use super::pipeline::Pipeline;
use super::pipeline_pool::{Job, Made, Maker, Pool};
use crate::model::Cell;
use crate::model::Phase;
use crate::model::Timings;
use std::collections::{HashSet, VecDeque};
use std::sync::Arc;
use std::time::Instant;

/// A unit of prebuild progress, reported as it happens (the worker sends it as the step of phase
/// `prebuild`; each restarts the supervisor's deadline).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Step {
    /// GLSL sources compiled on the threads (k of n).
    Glsl(usize, usize),
    /// Cells compiled and bound, in order on the calling thread (k of n).
    Compiled(usize, usize),
    /// Pipelines created on the threads (k of the n handed to them so far: n grows while cells
    /// are still being staged).
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

/// Told each [`Step`], from the calling thread and the pool's threads.
pub type Progress = Arc<dyn Fn(Step) + Send + Sync>;

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

/// A staged cell waiting for its turn: `maker` is the index of the pipeline it makes (the first
/// cell of each pipeline not created yet; its timings get the time), `None` when another cell
/// makes it.
struct Waiting {
    id: String,
    timings: Timings,
    bound: Bound,
    maker: Option<usize>,
}

/// A batch's prebuild under way: its staged cells waiting for their turns, and the pipelines the
/// pool's threads make for them.
pub struct Prebuild {
    pool: Option<Pool>,
    waiting: VecDeque<Waiting>,
    /// Pipelines received from the threads (or their errors, kept for their maker's turn), with
    /// each one's milliseconds on its thread, by maker index, until their maker's turn.
    made: Vec<Option<(Result<Pipeline, CellError>, f64)>>,
    received: usize,
    /// Keys of the pipelines that failed: their other cells build at their turn.
    failed: HashSet<u64>,
    /// Time the calling thread waited for pipelines and no cell has been charged with yet.
    unclaimed_wait_ms: f64,
    pub stats: PrebuildStats,
}

impl Prebuild {
    /// Every pipeline of the batch made (and received).
    pub fn done(&self) -> bool {
        self.received == self.made.len()
    }

    /// Let the pool's threads go on where the worker's test hook held them (the first cell ran).
    pub fn release(&self) {
        if let Some(p) = &self.pool {
            p.open();
        }
    }
}

impl Executor {
    /// Start building `cells`: compile and bind them in order, each new pipeline handed to
    /// `threads` threads as soon as its cell is staged (`held`: the test hook's, the threads
    /// make only the first pipeline until [`Prebuild::release`]). `progress` is told every unit
    /// of work ([`Step`]). An error whose outcome ends the worker is returned ([`keep`]): no cell
    /// of the batch can be blamed.
    pub fn prebuild(
        &mut self,
        cells: &[Cell],
        threads: usize,
        held: bool,
        progress: Progress,
    ) -> Result<Prebuild, CellError> {
        let generated = self.precompile(cells, threads, &*progress);
        let maker =
            Maker { gpu: self.gpu.clone(), cache: self.cache, libraries: self.libraries.clone() };
        let p = progress.clone();
        let pool =
            Pool::start(maker, threads, held, Arc::new(move |k, n| p(Step::Pipelines(k, n))));
        let mut pb = Prebuild {
            pool: Some(pool),
            waiting: VecDeque::new(),
            made: Vec::new(),
            received: 0,
            failed: HashSet::new(),
            unclaimed_wait_ms: 0.0,
            stats: PrebuildStats::default(),
        };
        let mut seen = HashSet::new();
        // Each cell staged as soon as the threads have analysed it, in order.
        self.analysed_in_order(cells, generated, threads, |exec, k, a| {
            if let Some((compiled, w)) = exec.stage(&cells[k], a)? {
                pb.push(exec, &cells[k], compiled, w, &mut seen);
            }
            progress(Step::Compiled(k + 1, cells.len()));
            Ok::<(), CellError>(())
        })?;
        if let Some(p) = &mut pb.pool {
            p.close();
        }
        pb.stats = PrebuildStats {
            pipelines: pb.made.len(),
            threads: threads.clamp(1, pb.made.len().max(1)),
        };
        Ok(pb)
    }

    /// Each cell's GLSL, generated once on the threads (what [`Executor::cell_shaders`] makes:
    /// the injected fault and lane evidence decided here first); compiled or read from the disk
    /// cache on the threads (into the compiler's per-source cache), then taken by each cell's
    /// compile in order.
    fn precompile(
        &mut self,
        cells: &[Cell],
        threads: usize,
        progress: &(dyn Fn(Step) + Send + Sync),
    ) -> Vec<crate::shadergen::CellShaders> {
        let how: Vec<_> = cells
            .iter()
            .map(|c| {
                let roll = crate::model::inject::roll(&self.opts.inject, c, self.opts.inject_seed);
                self.generation(c, roll.as_ref())
            })
            .collect();
        let generated: Vec<_> = crate::pool::map(
            cells.len(),
            threads,
            || Some(()),
            |_, k| crate::shadergen::generate_with(&cells[k], how[k].0, how[k].1),
            &|_, _| {},
        )
        .into_iter()
        .zip(cells.iter().zip(&how))
        // Every item is taken (each thread's state is `Some`); made here should one not be.
        .map(|(g, (c, &(fault, lanes)))| {
            g.unwrap_or_else(|| crate::shadergen::generate_with(c, fault, lanes))
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

    /// Bind one cell on the calling thread, compiled on the threads (the interfaces they read
    /// kept, its `--dump` written here) or here: `Some` when it is ready for its pipeline; `None`
    /// when its error is kept for its turn; `Err` when the error ends the worker.
    fn stage(
        &mut self,
        cell: &Cell,
        a: Analysed,
    ) -> Result<Option<(Compiled, Waiting)>, CellError> {
        let (mut timings, compiled) = match a {
            Analysed::Compiled(c, t, interfaces) => {
                self.interfaces.extend(interfaces);
                (t, self.dump(cell, &c.shaders, &c.spirv).map(|()| c))
            }
            Analysed::Whole(shaders) => {
                let mut t = Timings::default();
                let c = self.compile_cell(cell, shaders, &mut t);
                (t, c)
            }
            Analysed::Failed(e, t) => (t, Err(e)),
        };
        let (phase, e) = match compiled {
            Err(e) => (Phase::Compile, e),
            Ok(compiled) => match self.bind_cell(cell, &compiled, &mut timings) {
                Ok(bound) => {
                    let w = Waiting { id: cell.id(), timings, bound, maker: None };
                    return Ok(Some((compiled, w)));
                }
                Err(e) => (Phase::Pipeline, e),
            },
        };
        let e = keep(e)?;
        self.prebuilt.insert(cell.id(), Prebuilt { timings, phase, result: Err(e) });
        Ok(None)
    }

    /// Before `cell`'s turn: if it was staged, its pipeline waited for (the wait in its timings)
    /// and what it needs kept for [`Executor::run`]. An error that ends the worker (from any
    /// pipeline received meanwhile) is returned.
    pub fn turn(&mut self, pb: &mut Prebuild, cell: &Cell) -> Result<(), CellError> {
        if pb.waiting.front().is_none_or(|w| w.id != cell.id()) {
            return Ok(()); // not staged: its error is kept already, or it builds at its turn
        }
        let Some(mut w) = pb.waiting.pop_front() else { return Ok(()) };
        let t = Instant::now();
        if let Some(j) = w.maker {
            while pb.made[j].is_none() {
                let m = pb.pool.as_ref().and_then(Pool::recv);
                pb.receive(m.ok_or(CellError::PoolEnded)?)?;
            }
        }
        w.timings.pipeline_wait_ms =
            t.elapsed().as_secs_f64() * 1e3 + std::mem::take(&mut pb.unclaimed_wait_ms);
        let result = match w.maker.and_then(|j| pb.made[j].take()) {
            Some((result, ms)) => {
                w.timings.pipeline_ms = ms;
                match result {
                    Ok(p) => {
                        self.keep_pipeline(w.bound.pkey, p);
                        Ok(w.bound)
                    }
                    Err(e) => {
                        pb.failed.insert(w.bound.pkey);
                        Err(e)
                    }
                }
            }
            // A failed pipeline's maker keeps its error; the other cells of that pipeline try
            // again at their turn, as they would have without the prebuild.
            None if pb.failed.contains(&w.bound.pkey) => return Ok(()),
            None => Ok(w.bound),
        };
        let entry = Prebuilt { timings: w.timings, phase: Phase::Pipeline, result };
        self.prebuilt.insert(w.id, entry);
        Ok(())
    }

    /// Take the pipelines made so far without waiting: whether all are made. An error that ends
    /// the worker is returned.
    pub fn poll(&mut self, pb: &mut Prebuild) -> Result<bool, CellError> {
        while let Some(m) = pb.pool.as_ref().and_then(Pool::try_recv) {
            pb.receive(m)?;
        }
        Ok(pb.done())
    }

    /// Wait for every pipeline of the batch (the wait is charged to the next cell's turn).
    pub fn wait_all(&mut self, pb: &mut Prebuild) -> Result<(), CellError> {
        let t = Instant::now();
        pb.release();
        while !pb.done() {
            let m = pb.pool.as_ref().and_then(Pool::recv);
            pb.receive(m.ok_or(CellError::PoolEnded)?)?;
        }
        pb.unclaimed_wait_ms += t.elapsed().as_secs_f64() * 1e3;
        Ok(())
    }

    /// The batch is over: the threads joined, and any pipeline no cell took (none, when every
    /// cell had its turn) destroyed: no cell used it.
    pub fn end(&mut self, mut pb: Prebuild) {
        if let Some(p) = pb.pool.take() {
            p.join();
        }
        for (r, _) in pb.made.iter_mut().filter_map(Option::take) {
            if let Ok(p) = r {
                p.destroy(&self.gpu);
            }
        }
    }

    /// Keep a made pipeline; one whose key a cell made meanwhile at its turn is destroyed.
    fn keep_pipeline(&mut self, pkey: u64, p: Pipeline) {
        match self.pipelines.entry(pkey) {
            std::collections::hash_map::Entry::Vacant(e) => {
                e.insert(p);
            }
            std::collections::hash_map::Entry::Occupied(_) => p.destroy(&self.gpu),
        }
    }
}

impl Prebuild {
    /// A staged cell queued for its turn; a new pipeline's input handed to the threads.
    fn push(
        &mut self,
        exec: &Executor,
        cell: &Cell,
        compiled: Compiled,
        mut w: Waiting,
        seen: &mut HashSet<u64>,
    ) {
        let pkey = w.bound.pkey;
        if !exec.pipelines.contains_key(&pkey) && seen.insert(pkey) {
            let index = self.made.len();
            self.made.push(None);
            w.maker = Some(index);
            let parts = exec.pipeline_parts(cell, &w.bound);
            if let Some(p) = &mut self.pool {
                p.send(Job { index, compiled, parts });
            }
        }
        self.waiting.push_back(w);
    }

    /// A pipeline from the threads, kept until its maker's turn; an error that ends the worker
    /// is returned at once.
    fn receive(&mut self, m: Made) -> Result<(), CellError> {
        self.received += 1;
        let Made { index, result, ms } = m;
        let result = match result {
            Ok(p) => Ok(p),
            Err(e) => Err(keep(e.into())?),
        };
        self.made[index] = Some((result, ms));
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::gpu::BuildError;
    use crate::vk::VkError;
    use ash::vk;
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
