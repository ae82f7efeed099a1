//! Pipelines created on a pool of threads as their inputs arrive ([`Pool`]): the prebuild hands
//! each maker's input over as soon as the cell is staged, and takes the made pipelines back, in
//! any order, on the thread that runs the cells. The threads own what they use (the device and
//! the group libraries behind `Arc`s, the inputs moved to them), so the cell thread keeps the
//! executor to itself meanwhile. `vkCreate*Pipelines` may be called from several threads at once
//! (`exec::prebuild`'s module doc quotes the spec).
use super::built::{Compiled, Creation, PipelineInput, PipelineParts};
use super::pipeline::Pipeline;
use super::pipeline_library::Libraries;
use crate::vk::{Gpu, VkError};
use ash::vk;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc::{channel, Receiver, Sender};
use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;
use std::time::Instant;

/// One pipeline to make: the `index`-th maker's compiled shaders and the rest of its input.
pub(super) struct Job {
    pub(super) index: usize,
    pub(super) compiled: Compiled,
    pub(super) parts: PipelineParts,
}

// SAFETY: a job is SPIR-V, GLSL text, Vulkan handles and create-info data; the heap mapping's
// pNext pointers point into its own box, which moves with it. Only the thread that takes it
// reads it.
unsafe impl Send for Job {}

/// A pipeline made on a thread (or its error), with the milliseconds it took there.
pub(super) struct Made {
    pub(super) index: usize,
    pub(super) result: Result<Pipeline, VkError>,
    pub(super) ms: f64,
}

// SAFETY: a pipeline is Vulkan handles and its SBT buffer's mapping; the thread that made it no
// longer touches it once it is handed over.
unsafe impl Send for Made {}

/// How the threads make pipelines: the device, its cache and group libraries.
pub(super) struct Maker {
    pub(super) gpu: Arc<Gpu>,
    pub(super) cache: vk::PipelineCache,
    pub(super) libraries: Option<Arc<Libraries>>,
}

// SAFETY: `Gpu` is handles and function tables, only read; the pipeline cache is not created
// `EXTERNALLY_SYNCHRONIZED`, so several threads may use it; `Libraries` keeps its slots behind a
// mutex.
unsafe impl Send for Maker {}
unsafe impl Sync for Maker {}

/// A gate the threads wait at before any job but the first: open unless the worker's test hook
/// holds the pool (`misbehave`'s `overlap:` actions), so that the first cell runs while the
/// other pipelines are still to be made.
type Gate = Arc<(Mutex<bool>, Condvar)>;

/// Threads making pipelines from the jobs sent to them.
pub(super) struct Pool {
    jobs: Option<Sender<Job>>,
    made: Receiver<Made>,
    threads: Vec<JoinHandle<()>>,
    gate: Gate,
    /// Pipelines made and jobs sent so far (the threads read both for their progress).
    counts: Arc<(AtomicUsize, AtomicUsize)>,
    /// Jobs sent so far.
    pub(super) sent: usize,
}

impl Pool {
    /// `threads` threads; `progress(done, sent)` after each pipeline, on its thread.
    pub(super) fn start(
        maker: Maker,
        threads: usize,
        held: bool,
        progress: Arc<dyn Fn(usize, usize) + Send + Sync>,
    ) -> Pool {
        let (jobs, rx) = channel::<Job>();
        let (tx, made) = channel::<Made>();
        let rx = Arc::new(Mutex::new(rx));
        let maker = Arc::new(maker);
        let gate: Gate = Arc::new((Mutex::new(!held), Condvar::new()));
        let counts = Arc::new((AtomicUsize::new(0), AtomicUsize::new(0)));
        let threads = (0..threads.max(1))
            .map(|_| {
                let (rx, tx, maker, gate) = (rx.clone(), tx.clone(), maker.clone(), gate.clone());
                let (counts, progress) = (counts.clone(), progress.clone());
                std::thread::spawn(move || loop {
                    let job = match rx.lock().unwrap_or_else(|p| p.into_inner()).recv() {
                        Ok(j) => j,
                        Err(_) => return,
                    };
                    if job.index > 0 {
                        wait_open(&gate);
                    }
                    let made = make(&maker, job);
                    let done = counts.0.fetch_add(1, Ordering::Relaxed) + 1;
                    // Told before it is handed over: no progress line can follow the cell
                    // thread's `prebuilt`, which it sends once it has every pipeline.
                    progress(done, counts.1.load(Ordering::Relaxed));
                    let _ = tx.send(made);
                })
            })
            .collect();
        Pool { jobs: Some(jobs), made, threads, gate, counts, sent: 0 }
    }

    pub(super) fn send(&mut self, job: Job) {
        self.sent += 1;
        self.counts.1.store(self.sent, Ordering::Relaxed);
        if let Some(j) = &self.jobs {
            // The threads hold the receiver until the sender closes: this cannot fail.
            let _ = j.send(job);
        }
    }

    /// No more jobs: the threads end once the queue is empty.
    pub(super) fn close(&mut self) {
        self.jobs = None;
    }

    /// Let the held threads go on (the test hook's hold; a no-op otherwise).
    pub(super) fn open(&self) {
        let (m, c) = &*self.gate;
        *m.lock().unwrap_or_else(|p| p.into_inner()) = true;
        c.notify_all();
    }

    /// The next pipeline made, waiting for it (`None`: every thread has ended).
    pub(super) fn recv(&self) -> Option<Made> {
        self.made.recv().ok()
    }

    /// A pipeline made already, without waiting.
    pub(super) fn try_recv(&self) -> Option<Made> {
        self.made.try_recv().ok()
    }

    /// Wait for the threads to end (after [`Pool::close`] and every job received).
    pub(super) fn join(mut self) {
        self.close();
        self.open();
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

fn wait_open(gate: &Gate) {
    let (m, c) = &**gate;
    let mut open = m.lock().unwrap_or_else(|p| p.into_inner());
    while !*open {
        open = c.wait(open).unwrap_or_else(|p| p.into_inner());
    }
}

fn make(maker: &Maker, job: Job) -> Made {
    let how = Creation { cache: maker.cache, libraries: maker.libraries.as_deref() };
    let input = PipelineInput {
        shaders: &job.compiled.shaders,
        spirv: &job.compiled.spirv,
        parts: &job.parts,
    };
    let t = Instant::now();
    let result = input.create(&maker.gpu, &how);
    Made { index: job.index, result, ms: t.elapsed().as_secs_f64() * 1e3 }
}
