//! The part of a prebuild's compile that needs nothing of the executor, on threads of its own
//! running ahead of the staging ([`Executor::analysed_in_order`]): each cell's modules are taken
//! from the compiler's cache in order on the calling thread, a few cells ahead of the one it
//! stages; then, on the threads, they are
//! patched with the spec's workarounds, read for what the driver sees of them (`seen`: a SPIR-V
//! parse of each probed module) and hashed, and each module's interface not read yet, which the
//! staging checks against its layout (`fit`), is read by the one thread that claims it first.
//! The calling thread stages each cell as soon as it is analysed, in cell order, so the first
//! pipeline goes to the pool at once. These were most of the staging's CPU time (perf on
//! lavapipe 25: `Seen::of`, the workarounds, the interface reads) and ran serially on the cell
//! thread before (0.24 s for 512 cells on the H200, s32's trace); the staging keeps `--dump`,
//! the bindings and the pipeline key. A mutant cell's modules are mutated with the executor's
//! reference, so it is compiled whole at its staging, as before. Every error is its cell's, in
//! phase `compile`, as if it had been compiled at its staging; a module whose interface another
//! cell's thread claimed and has not handed over yet is read again by `fit`.
use super::built::{Compiled, Seen};
use super::compile::patch_workarounds;
use super::error::CellError;
use super::executor::Executor;
use super::fit::module_key;
use crate::interface::ModuleInterface;
use crate::model::{Cell, LaneEvidence, Timings};
use crate::probe::spec::ProbeSpec;
use crate::shadergen::CellShaders;
use std::collections::HashSet;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc::channel;
use std::sync::{Arc, Condvar, Mutex};

/// A cell of a prebuild, analysed.
pub(super) enum Analysed {
    /// Compiled, its workarounds patched in and its modules hashed, with the interfaces its
    /// thread read: `--dump` and the bindings are left.
    Compiled(Compiled, Timings, Vec<(u128, ModuleInterface)>),
    /// A mutant cell's GLSL: compiled whole at its staging (`Executor::compile_cell`).
    Whole(CellShaders),
    /// Its compile failed (phase `compile`).
    Failed(CellError, Timings),
}

/// A cell's modules as the compiler's cache gave them, for the threads.
enum Looked {
    Modules { shaders: CellShaders, spirv: Vec<Arc<Vec<u32>>>, lanes: LaneEvidence, t: Timings },
    Done(Analysed),
}

/// What the threads share: the cells' modules (each taken once), whether to patch (false for a
/// bundle's SPIR-V, patched already), the module keys whose interface is read or claimed, and how
/// many cells the calling thread has looked up (the threads wait for them) and whether it stopped.
struct Shared<'a> {
    cells: &'a [Cell],
    looked: Vec<Mutex<Option<Looked>>>,
    patch: bool,
    claimed: Mutex<HashSet<u128>>,
    state: Mutex<(usize, bool)>,
    more: Condvar,
}

/// Stops the threads when dropped: at the end, after an error, or while unwinding, so that no
/// thread is left waiting for a cell that will not be looked up.
struct Stop<'a, 'b>(&'a Shared<'b>);

impl Drop for Stop<'_, '_> {
    fn drop(&mut self) {
        self.0.state.lock().unwrap_or_else(|p| p.into_inner()).1 = true;
        self.0.more.notify_all();
    }
}

impl Shared<'_> {
    /// Wait until cell `k` is looked up: false when the calling thread stopped first.
    fn wait_for(&self, k: usize) -> bool {
        let mut state = self.state.lock().unwrap_or_else(|p| p.into_inner());
        while state.0 <= k && !state.1 {
            state = self.more.wait(state).unwrap_or_else(|p| p.into_inner());
        }
        state.0 > k
    }

    /// Cell `k` looked up (`None`: none to analyse), for the threads.
    fn publish(&self, k: usize, looked: Option<Looked>) {
        *self.looked[k].lock().unwrap_or_else(|p| p.into_inner()) = looked;
        self.state.lock().unwrap_or_else(|p| p.into_inner()).0 = k + 1;
        self.more.notify_all();
    }

    /// Cell `k` analysed (`None`: taken already).
    fn analyse(&self, k: usize) -> Option<Analysed> {
        let looked = self.looked[k].lock().unwrap_or_else(|p| p.into_inner()).take()?;
        let (shaders, mut spirv, lanes, mut t) = match looked {
            Looked::Done(a) => return Some(a),
            Looked::Modules { shaders, spirv, lanes, t } => (shaders, spirv, lanes, t),
        };
        let cell = &self.cells[k];
        if let Err(e) = patch_workarounds(cell, &mut spirv, self.patch, &mut t) {
            return Some(Analysed::Failed(e, t));
        }
        let seen = Seen::of(cell, &shaders, &spirv, lanes);
        let keys: Vec<u128> = spirv.iter().map(|w| module_key(w)).collect();
        let mut interfaces = Vec::new();
        for (i, (w, key)) in spirv.iter().zip(&keys).enumerate() {
            if self.claimed.lock().unwrap_or_else(|p| p.into_inner()).insert(*key) {
                // One that cannot be read is left to `fit`, which makes it the cell's error.
                if let Ok(m) = crate::interface::read(i, w) {
                    interfaces.push((*key, m));
                }
            }
        }
        let compiled = Compiled { shaders, spirv, seen, keys: Some(keys) };
        Some(Analysed::Compiled(compiled, t, interfaces))
    }
}

/// Cell `k` analysed on a thread, its panic caught to be handed to the calling thread: a thread
/// that died instead would leave the calling thread waiting for cell `k` for ever (the other
/// threads wait for cells it has not looked up yet), a hang the supervisor could only time out.
type Caught = std::thread::Result<Option<Analysed>>;

fn caught(shared: &Shared<'_>, k: usize) -> Caught {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| shared.analyse(k)))
}

impl Executor {
    /// `stage(executor, k, cell k analysed)` for each of `cells` (with its `generated` GLSL), in
    /// order, each as soon as one of `threads` threads has analysed it; the calling thread looks
    /// cells up (`look`) a few ahead of the one it stages, so the threads start at once. An
    /// error of `stage` stops the threads and is returned.
    pub(super) fn analysed_in_order<E>(
        &mut self,
        cells: &[Cell],
        generated: Vec<CellShaders>,
        threads: usize,
        mut stage: impl FnMut(&mut Executor, usize, Analysed) -> Result<(), E>,
    ) -> Result<(), E> {
        let shared = Shared {
            cells,
            looked: cells.iter().map(|_| Mutex::new(None)).collect(),
            patch: self.opts.spirv_dir.is_none(),
            claimed: Mutex::new(self.interfaces.keys().copied().collect()),
            state: Mutex::new((0, false)),
            more: Condvar::new(),
        };
        let (n, ahead, next) = (cells.len(), 2 * threads.max(1), AtomicUsize::new(0));
        let mut generated = generated.into_iter();
        std::thread::scope(|s| {
            let (tx, rx) = channel();
            // Made before the first thread: should a later one fail to start (a panic in
            // `spawn`), the started ones are let go instead of waiting for cell 0 for ever.
            let _stop = Stop(&shared);
            for _ in 0..threads.clamp(1, n.max(1)) {
                let (tx, shared, next) = (tx.clone(), &shared, &next);
                s.spawn(move || loop {
                    let k = next.fetch_add(1, Ordering::Relaxed);
                    if k >= n || !shared.wait_for(k) || tx.send((k, caught(shared, k))).is_err() {
                        return;
                    }
                });
            }
            drop(tx);
            let (mut ready, mut looked_up) = (cells.iter().map(|_| None).collect::<Vec<_>>(), 0);
            for k in 0..n {
                while looked_up < n && looked_up <= k + ahead {
                    let l = generated.next().map(|g| self.look(&cells[looked_up], g));
                    shared.publish(looked_up, l);
                    looked_up += 1;
                }
                while ready[k].is_none() {
                    match rx.recv() {
                        Ok((j, Ok(a))) => ready[j] = Some(a),
                        // A panic in a thread's analysis is the cell thread's, as when the
                        // analysis ran here: the worker dies on it, in cell `j`'s staging.
                        Ok((_, Err(panic))) => std::panic::resume_unwind(panic),
                        Err(_) => break, // every thread ended: what is left is taken here
                    }
                }
                // `Some(None)`: its thread found nothing to analyse (taken already).
                let Some(a) = ready[k].take().flatten().or_else(|| shared.analyse(k)) else {
                    continue;
                };
                stage(self, k, a)?;
            }
            Ok(())
        })
    }

    /// The executor's part of a cell, on the calling thread: its modules from the compiler's
    /// cache and the lane evidence its records carry (read before the workarounds: only a
    /// bundle's SPIR-V is inspected for it, and a bundle is never patched).
    fn look(&mut self, cell: &Cell, shaders: CellShaders) -> Looked {
        if ProbeSpec::of(cell).mutant.is_some() {
            return Looked::Done(Analysed::Whole(shaders));
        }
        let mut t = Timings::default();
        match self.look_up(cell, shaders, &mut t) {
            Ok((shaders, spirv)) => {
                let lanes = self.recorded_lanes(cell, &shaders, &spirv);
                Looked::Modules { shaders, spirv, lanes, t }
            }
            Err(e) => Looked::Done(Analysed::Failed(e, t)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{DescriptorModel, IndexSource, Resource, Stage, Workaround};
    use crate::shadergen::compile::Compiler;

    fn buffer_cell(stage: Stage, index: IndexSource) -> Cell {
        Cell::new(stage, Resource::StorageBuffer, index, DescriptorModel::DescriptorIndexing)
    }

    /// Threads' shared state over `cells`, `looked` up to `published`.
    fn shared_of<'a>(
        cells: &'a [Cell],
        looked: Vec<Option<Looked>>,
        published: usize,
    ) -> Shared<'a> {
        Shared {
            cells,
            looked: looked.into_iter().map(Mutex::new).collect(),
            patch: true,
            claimed: Mutex::new(HashSet::new()),
            state: Mutex::new((published, false)),
            more: Condvar::new(),
        }
    }

    fn looked(c: &mut Compiler, cell: &Cell) -> Looked {
        let shaders = crate::shadergen::generate(cell);
        let spirv = shaders.shaders.iter().map(|s| c.compile(s.role, &s.glsl).unwrap().0).collect();
        let (lanes, t) = (LaneEvidence::Absent, Timings::default());
        Looked::Modules { shaders, spirv, lanes, t }
    }

    /// On a thread, a cell's workarounds are patched in and what the driver sees read from the
    /// patched modules, exactly as its compile at its turn does; a module two cells share has
    /// its interface read once. Twin: a module that is not SPIR-V fails its cell's compile
    /// (never a panic), and its interface is left to `fit`.
    #[test]
    fn a_cell_analysed_on_a_thread_is_compiled_as_at_its_turn_and_garbage_fails_it() {
        let mut c = Compiler::new().unwrap();
        let plain = buffer_cell(Stage::ClosestHit, IndexSource::Dynamic);
        let patched = Cell { patch: Some(Workaround::Nonuniform), ..plain };
        let mut garbage = looked(&mut c, &plain);
        if let Looked::Modules { spirv, .. } = &mut garbage {
            spirv.iter_mut().for_each(|w| *w = Arc::new(vec![0xdead_beef; 12]));
        }
        let cells = [plain, patched, patched];
        let all = vec![Some(looked(&mut c, &plain)), Some(looked(&mut c, &patched)), Some(garbage)];
        let shared = shared_of(&cells, all, 3);
        let Some(Analysed::Compiled(p, _, first)) = shared.analyse(0) else { panic!("plain") };
        let Some(Analysed::Compiled(n, _, second)) = shared.analyse(1) else { panic!("patched") };
        assert!(shared.analyse(1).is_none(), "a cell is taken once");
        // The patch reached the probed module, and `seen` was read after it.
        let (mut want, mut t) = (looked(&mut c, &patched), Timings::default());
        let Looked::Modules { shaders, spirv, lanes, .. } = &mut want else { unreachable!() };
        patch_workarounds(&patched, spirv, true, &mut t).unwrap();
        assert_eq!(n.spirv, *spirv);
        assert_ne!(n.spirv, p.spirv, "the workaround was not applied");
        assert_eq!(n.seen, Seen::of(&patched, shaders, spirv, *lanes));
        assert_eq!(n.keys, Some(spirv.iter().map(|w| module_key(w)).collect()));
        // Shared modules (raygen, misses) are read by the first cell only.
        let distinct: HashSet<_> = p.keys.iter().flatten().collect();
        assert_eq!(first.len(), distinct.len());
        assert!(second.len() < n.spirv.len() && !second.is_empty(), "{}", second.len());
        // The twin: garbage words fail the cell, and no interface of them is kept.
        match shared.analyse(2) {
            Some(Analysed::Failed(CellError::Patch(_), _)) => {}
            Some(Analysed::Failed(e, _)) => panic!("another error: {e}"),
            _ => panic!("garbage SPIR-V compiled"),
        }
    }

    /// A panic in a thread's analysis comes back as that cell's, to be resumed on the calling
    /// thread, never a thread that ends silently (which would leave the calling thread waiting
    /// for the cell for ever). Twin: an analysis that does not panic comes back as itself.
    #[test]
    fn a_panicking_analysis_is_handed_to_the_calling_thread() {
        let mut c = Compiler::new().unwrap();
        let cell = buffer_cell(Stage::Raygen, IndexSource::Literal);
        // A cell index past `cells` makes `analyse` panic (its `cells[k]`).
        let shared = shared_of(&[], vec![Some(looked(&mut c, &cell))], 1);
        let hook = std::panic::take_hook();
        std::panic::set_hook(Box::new(|_| {}));
        let got = caught(&shared, 0);
        std::panic::set_hook(hook);
        assert!(got.is_err(), "the panic was lost");
        let cells = [cell];
        let fine = Shared {
            cells: &cells,
            looked: vec![Mutex::new(Some(looked(&mut c, &cell)))],
            ..shared
        };
        assert!(matches!(caught(&fine, 0), Ok(Some(Analysed::Compiled(..)))));
    }

    /// A thread waits for a cell until the calling thread looks it up, and is let go, told so,
    /// when the calling thread stops first (an error, the end, or unwinding): none is left
    /// waiting for a cell that will never come.
    #[test]
    fn threads_wait_for_looked_up_cells_and_a_stop_lets_them_go() {
        let cells = [buffer_cell(Stage::Raygen, IndexSource::Literal); 2];
        let shared = shared_of(&cells, vec![None, None], 0);
        std::thread::scope(|s| {
            let first = s.spawn(|| shared.wait_for(0));
            let second = s.spawn(|| shared.wait_for(1));
            shared.publish(0, None);
            assert!(first.join().unwrap(), "cell 0 was looked up");
            drop(Stop(&shared));
            assert!(!second.join().unwrap(), "cell 1 never was: the stop says so");
        });
        assert!(shared.analyse(0).is_none(), "nothing to analyse in a cell published empty");
    }
}
