//! Judging traced cells on a thread of their own ([`Checker`]), so that the cell thread goes on to
//! the next cell's device work while the last cell's records are compared with the reference.
//!
//! Only an overlapped cell's check goes there (`runner::overlap`): its `start` and `result` lines
//! are held back until `prebuilt` anyway, so a result that comes later changes nothing the
//! supervisor sees, and a death before `prebuilt` is the batch's, re-run serially, where every
//! check is on the cell thread again. Results come back in the order the cells were handed
//! over. The thread reads a copy of the executor's [`World`] (the scene and its reference are
//! shared; the reference's AS probe rays, filled once behind a `OnceLock`, are traced in the
//! setup where a cell needs them) and keeps its own expected-records memo. A panic there is caught
//! and handed back as that cell's [`Judged`]: the caller names the cell to the supervisor, then
//! resumes it (`runner::held`), so the worker's death is pinned on that cell as it would be with
//! the check inline.
use super::check::World;
use super::executor::{ExecOptions, Executor};
use super::run::Traced;
use crate::model::CellResult;
use crate::model::Stage;
use crate::probe::Record;
use crate::reference::{ExpectedMemo, SceneReference};
use crate::scene::Scene;
use std::sync::{mpsc, Arc};
use std::thread::JoinHandle;

/// Cells handed over and not yet taken at most: a caller waits for the oldest before handing over
/// more (`runner::held`), so the records kept stay a few cells' and a check that hangs is found
/// within a few cells of its own.
pub const QUEUE: usize = 4;

/// What the thread judges with: the executor's world, owned.
struct Owned {
    scene: Arc<Scene>,
    sref: Arc<SceneReference>,
    opts: ExecOptions,
    ballot: Vec<Stage>,
}

impl Owned {
    fn world(&self) -> World<'_> {
        World { scene: &self.scene, sref: &self.sref, opts: &self.opts, ballot: &self.ballot }
    }
}

/// A cell's result and its records' vector, or the payload of the check's panic.
pub type Judged = std::thread::Result<(CellResult, Vec<Record>)>;

/// A checker thread and the cells handed to it.
pub struct Checker {
    jobs: Option<mpsc::SyncSender<Traced>>,
    results: mpsc::Receiver<Judged>,
    thread: Option<JoinHandle<()>>,
    /// Handed over and not yet taken.
    pending: usize,
}

impl Checker {
    /// A checker thread judging as `exec` would.
    pub fn start(exec: &Executor) -> std::io::Result<Checker> {
        Checker::of(Owned {
            scene: Arc::clone(&exec.scene),
            sref: Arc::clone(&exec.sref),
            opts: exec.opts.clone(),
            ballot: exec.ballot.clone(),
        })
    }

    /// A checker thread judging in `owned`'s world.
    fn of(owned: Owned) -> std::io::Result<Checker> {
        let mut memo = ExpectedMemo::default();
        Checker::with(move |t| owned.world().finish(t, &mut memo))
    }

    /// A checker thread judging each cell with `judge`.
    pub(crate) fn with(
        judge: impl FnMut(Traced) -> (CellResult, Vec<Record>) + Send + 'static,
    ) -> std::io::Result<Checker> {
        let (jobs, rx) = mpsc::sync_channel::<Traced>(QUEUE);
        let (tx, results) = mpsc::channel::<Judged>();
        let thread = std::thread::Builder::new()
            .name("checker".into())
            .spawn(move || judge_all(judge, &rx, &tx))?;
        Ok(Checker { jobs: Some(jobs), results, thread: Some(thread), pending: 0 })
    }

    /// Hand `t` over; its result comes from [`Checker::take`] after those handed before it.
    pub fn submit(&mut self, t: Traced) {
        // The thread stops only after a panic, whose payload waits in `results`: `take` resumes
        // it before this cell's turn comes.
        if self.jobs.as_ref().is_some_and(|j| j.send(t).is_err()) {
            self.jobs = None;
        }
        self.pending += 1;
    }

    /// Cells handed over and not yet taken.
    pub fn pending(&self) -> usize {
        self.pending
    }

    /// The oldest pending cell's result and its records' vector, waiting for it, or its check's
    /// panic (for the caller to resume once it has said which cell it was).
    pub fn take(&mut self) -> Judged {
        assert!(self.pending > 0, "no cell handed to the checker");
        self.pending -= 1;
        match self.results.recv() {
            Ok(judged) => judged,
            Err(mpsc::RecvError) => panic!("the checker thread ended with cells pending"),
        }
    }

    /// The oldest pending cell's result where it is judged already ([`Checker::take`] without
    /// the wait).
    pub fn try_take(&mut self) -> Option<Judged> {
        if self.pending == 0 {
            return None;
        }
        match self.results.try_recv() {
            Ok(judged) => {
                self.pending -= 1;
                Some(judged)
            }
            Err(mpsc::TryRecvError::Empty) => None,
            Err(mpsc::TryRecvError::Disconnected) => Some(self.take()),
        }
    }
}

impl Drop for Checker {
    fn drop(&mut self) {
        self.jobs = None;
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// The thread: each traced cell judged in turn, until the sender goes or a check panics.
fn judge_all(
    mut judge: impl FnMut(Traced) -> (CellResult, Vec<Record>),
    jobs: &mpsc::Receiver<Traced>,
    results: &mpsc::Sender<Judged>,
) {
    for t in jobs {
        let judged = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| judge(t)));
        let stop = judged.is_err();
        if results.send(judged).is_err() || stop {
            return;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{Cell, DescriptorModel, IndexSource, Outcome, Resource};
    use crate::model::{SceneParams, Timings};
    use std::time::Duration;

    fn owned() -> Owned {
        let params = SceneParams { width: 16, height: 8, ..SceneParams::default() };
        let scene = Scene::build(&params);
        let sref = SceneReference::compute(&scene);
        let opts = ExecOptions {
            timeout: Duration::from_secs(1),
            setup_timeout: Duration::from_secs(1),
            inject: vec![],
            inject_seed: 0,
            dump: None,
            spirv_dir: None,
            pipeline_cache: None,
            glsl_cache: None,
            all_stages: false,
            lanes: Default::default(),
        };
        Owned { scene: Arc::new(scene), sref: Arc::new(sref), opts, ballot: vec![] }
    }

    fn cell(stage: Stage) -> Cell {
        let model = DescriptorModel::DescriptorIndexing;
        Cell::new(stage, Resource::StorageBuffer, IndexSource::PushConstant, model)
    }

    /// `cell` traced with `records`.
    fn traced(cell: Cell, records: Vec<Record>) -> Traced {
        Traced { records, device_part_ms: 1.0, ..Traced::for_tests(cell) }
    }

    /// What a correct driver writes for `cell`: the reference's records.
    fn correct(o: &Owned, cell: &Cell) -> Vec<Record> {
        let expected = crate::reference::expected(cell, &o.scene, &o.sref);
        expected.iter().map(|e| e.record).collect()
    }

    #[test]
    fn the_checker_judges_as_the_cell_thread_does_and_in_the_order_handed_over() {
        let o = owned();
        let cells = [cell(Stage::ClosestHit), cell(Stage::Raygen), cell(Stage::Miss)];
        let mut jobs: Vec<Vec<Record>> = cells.iter().map(|c| correct(&o, c)).collect();
        // The middle cell read another element: garbage bits in every probed value.
        let probed = jobs[1].iter_mut().filter(|r| r.flags & crate::probe::FLAG_PROBE != 0);
        let mut corrupted = 0;
        for r in probed {
            r.value = [f32::from_bits(0x7fc0_dead); 4];
            corrupted += 1;
        }
        assert!(corrupted > 0, "the raygen cell probes some pixel");
        let world = o.world();
        let mut memo = ExpectedMemo::default();
        let inline: Vec<CellResult> = cells
            .iter()
            .zip(&jobs)
            .map(|(c, r)| world.finish(traced(*c, r.clone()), &mut memo).0)
            .collect();
        let outcomes: Vec<Outcome> = inline.iter().map(|r| r.outcome).collect();
        assert_eq!(outcomes, [Outcome::Pass, Outcome::Mismatch, Outcome::Pass]);
        let mut checker = Checker::of(owned()).unwrap();
        for (c, r) in cells.iter().zip(jobs) {
            checker.submit(traced(*c, r));
        }
        assert_eq!(checker.pending(), 3);
        for want in &inline {
            let (got, records) = checker.take().unwrap();
            assert_eq!(got.outcome, want.outcome);
            // (Debug: the garbage's worst value is NaN, which `==` never equals)
            assert_eq!(format!("{:?}", got.comparison), format!("{:?}", want.comparison));
            assert_eq!(got.detail, want.detail);
            assert_eq!(records.len(), 16 * 8, "the records' vector comes back");
        }
        assert_eq!(checker.pending(), 0);
        assert!(checker.try_take().is_none());
    }

    /// A checker judges with the ballot stages it holds (`Owned::ballot`, what `Checker::start`
    /// copies from the executor): an index-broadcast mutant has its prediction only where its own
    /// stage is among them (`World::mutation`). Twins: none listed, or another stage only, and
    /// it has none.
    #[test]
    fn a_broadcast_mutants_prediction_needs_the_ballot_stages_the_checker_holds() {
        let model = DescriptorModel::DescriptorIndexing;
        let mut c = Cell::new(Stage::Raygen, Resource::StorageBuffer, IndexSource::Dynamic, model);
        c.nonuniform = true;
        c.mutant = Some(crate::model::Mutant::IndexBroadcast);
        let records = correct(&owned(), &c);
        let cases =
            [(vec![], false), (vec![Stage::Miss], false), (vec![Stage::Miss, Stage::Raygen], true)];
        for (ballot, want) in cases {
            let mut checker = Checker::of(Owned { ballot: ballot.clone(), ..owned() }).unwrap();
            checker.submit(traced(c, records.clone()));
            let (r, _) = checker.take().unwrap();
            let predicted = r.comparison.as_ref().is_some_and(|cmp| cmp.mutant.is_some());
            assert_eq!(predicted, want, "ballot in {ballot:?}: {:?}", r.detail);
        }
    }

    #[test]
    fn a_result_not_judged_yet_is_not_taken_without_waiting() {
        let (go, wait) = mpsc::channel::<()>();
        let mut checker = Checker::with(move |t| {
            wait.recv().unwrap();
            let r = CellResult {
                outcome: Outcome::Pass,
                detail: Some("judged".into()),
                timings: Timings::default(),
                comparison: None,
                fault: None,
                validation_errors: 0,
            };
            (r, t.records)
        });
        let c = checker.as_mut().unwrap();
        c.submit(traced(cell(Stage::Raygen), vec![]));
        assert!(c.try_take().is_none());
        assert_eq!(c.pending(), 1);
        go.send(()).unwrap();
        let (r, _) = c.take().unwrap();
        assert_eq!(r.detail.as_deref(), Some("judged"));
    }

    #[test]
    fn a_check_that_panics_hands_its_panic_back_as_that_cells_result() {
        let mut checker = Checker::with(|_| panic!("the check's own bug")).unwrap();
        checker.submit(traced(cell(Stage::Raygen), vec![]));
        // A cell handed over after the thread stopped is still counted, never lost silently.
        std::thread::sleep(Duration::from_millis(50));
        checker.submit(traced(cell(Stage::Miss), vec![]));
        assert_eq!(checker.pending(), 2);
        let Err(payload) = checker.take() else { panic!("the panic was not handed back") };
        assert_eq!(payload.downcast_ref::<&str>(), Some(&"the check's own bug"));
    }
}
