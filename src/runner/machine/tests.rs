//! The worker state machine without processes: each test feeds lines, ends of output, deadlines
//! and exits at chosen instants and checks the state and the effects. Twins guard the
//! attributions that matter: a death mid-cell is never a pass, a fault outside a cell is never
//! a cell's.
use super::*;
use crate::model::{CellResult, DescriptorModel, IndexSource, Resource, Stage, Timings};

const LIMITS: Limits =
    Limits { timeout: Duration::from_secs(10), setup_timeout: Duration::from_secs(60) };

fn cells() -> Vec<Cell> {
    [Stage::Raygen, Stage::ClosestHit, Stage::Miss]
        .iter()
        .map(|&s| {
            Cell::new(
                s,
                Resource::StorageBuffer,
                IndexSource::Dynamic,
                DescriptorModel::DescriptorIndexing,
            )
        })
        .collect()
}

fn at(t0: Instant, ms: u64) -> Instant {
    t0 + Duration::from_millis(ms)
}

fn feed(w: Worker, input: Input, now: Instant) -> (Worker, Vec<Effect>) {
    step(w, input, now, &LIMITS)
}

fn msg(m: WorkerMsg) -> Input {
    Input::Msg(m)
}

fn ready() -> Input {
    msg(WorkerMsg::Ready {
        device_ms: 1.0,
        create_ms: 0.7,
        reference_ms: 2.0,
        as_build_ms: Some(0.5),
        setup_wait_ms: 0.4,
        device_features: vec!["VK_KHR_ray_tracing_pipeline".into()],
        pipeline_cache: None,
        driver_cache: None,
    })
}

fn start(c: &Cell) -> Input {
    msg(WorkerMsg::Start { cell: c.id() })
}

fn phase(p: Phase, step: Option<&str>) -> Input {
    msg(WorkerMsg::Phase { phase: p, step: step.map(String::from) })
}

fn result(c: &Cell, outcome: Outcome) -> Input {
    let result = CellResult {
        outcome,
        detail: Some(format!("{} here", outcome.as_str())),
        timings: Timings::default(),
        comparison: None,
        fault: None,
        validation_errors: 0,
    };
    msg(WorkerMsg::Result { cell: c.id(), result })
}

fn exit(code: Option<i32>, signal: Option<i32>) -> WorkerExit {
    WorkerExit { code, signal, ..Default::default() }
}

/// Worker 7 with three cells, ready at t0 + 100 ms.
fn ready_worker(t0: Instant) -> Worker {
    let (w, _) = feed(Worker::new(7, cells(), false, t0), ready(), at(t0, 100));
    w
}

/// `ready_worker`, running its first cell since t0 + 200 ms, now in `p`.
fn in_cell(t0: Instant, p: Phase) -> Worker {
    let (w, _) = feed(ready_worker(t0), start(&cells()[0]), at(t0, 200));
    let (w, _) = feed(w, phase(p, None), at(t0, 250));
    w
}

/// `ready_worker` after its first cell's result at t0 + 300 ms.
fn one_done(t0: Instant) -> Worker {
    let (w, _) = feed(in_cell(t0, Phase::Check), result(&cells()[0], Outcome::Pass), at(t0, 300));
    w
}

/// Kills (or reaps) the dying worker: the effect asked for, then what `exit` records.
fn dies(w: Worker, cause: Input, ended: WorkerExit, now: Instant) -> (Effect, Vec<Effect>) {
    let (w, mut fx) = feed(w, cause, now);
    assert_eq!(fx.len(), 1, "{fx:?}");
    assert!(matches!(w.state, State::Dying { .. }));
    assert_eq!(w.deadline(&LIMITS), None, "the supervisor waits for no deadline while it kills");
    let (w, recorded) = feed(w, Input::Exited(ended), now);
    assert!(w.ended());
    (fx.remove(0), recorded)
}

fn attempts(fx: &[Effect]) -> Vec<(Cell, &Attempt)> {
    fx.iter()
        .filter_map(|e| {
            if let Effect::Report(Event::Attempt { cell, attempt }) = e {
                Some((*cell, attempt))
            } else {
                None
            }
        })
        .collect()
}

fn events(fx: &[Effect]) -> Vec<&WorkerEvent> {
    fx.iter()
        .filter_map(|e| if let Effect::Report(Event::Worker(ev)) = e { Some(ev) } else { None })
        .collect()
}

fn fruitless(fx: &[Effect]) -> Option<(usize, &Attempt)> {
    fx.iter().find_map(|e| {
        if let Effect::Fruitless { batch, not_run } = e {
            Some((*batch, not_run))
        } else {
            None
        }
    })
}

#[test]
fn ready_records_the_setup_and_starts_the_gap_before_the_first_cell() {
    let t0 = Instant::now();
    let (w, fx) = feed(Worker::new(7, cells(), false, t0), ready(), at(t0, 100));
    assert_eq!(w.deadline(&LIMITS), Some(at(t0, 100) + LIMITS.timeout));
    assert!(
        matches!(fx[0], Effect::Report(Event::WorkerReady { device_ms, .. }) if device_ms == 1.0)
    );
    let ev = events(&fx)[0];
    assert_eq!(
        (ev.worker, ev.phase, ev.outcome, ev.cells, ev.wall_ms),
        (7, Phase::Setup, Outcome::Pass, 3, 100.0)
    );
    assert_eq!(ev.device_features, ["VK_KHR_ray_tracing_pipeline"]);
    assert_eq!(w.phase, Phase::BetweenCells);
}

#[test]
fn setup_has_its_own_deadline_and_the_others_share_the_timeout() {
    let t0 = Instant::now();
    assert_eq!(
        Worker::new(1, cells(), false, t0).deadline(&LIMITS),
        Some(t0 + LIMITS.setup_timeout)
    );
    assert_eq!(in_cell(t0, Phase::Trace).deadline(&LIMITS), Some(at(t0, 200) + LIMITS.timeout));
    assert_eq!(one_done(t0).deadline(&LIMITS), Some(at(t0, 300) + LIMITS.timeout));
}

#[test]
fn a_result_line_is_the_cells_attempt_with_its_phase_and_time() {
    let t0 = Instant::now();
    let (w, fx) =
        feed(in_cell(t0, Phase::Check), result(&cells()[0], Outcome::Mismatch), at(t0, 450));
    let [(cell, a)] = attempts(&fx)[..] else { panic!("{fx:?}") };
    assert_eq!(cell, cells()[0]);
    assert_eq!(
        (a.outcome, a.phase, a.worker, a.wall_ms, a.isolated),
        (Outcome::Mismatch, Some(Phase::Check), 7, 250.0, false)
    );
    assert_eq!(a.detail.as_deref(), Some("mismatch here"));
    assert!(a.result.is_some() && a.worker_exit.is_none());
    assert_eq!(a.device_features, ["VK_KHR_ray_tracing_pipeline"]);
    // A mismatch does not end the worker: the next cell's gap starts.
    assert_eq!(w.state, State::Between { since: at(t0, 450) });
    assert_eq!((w.phase, w.pending.len(), w.progressed), (Phase::BetweenCells, 2, true));
}

#[test]
fn the_last_result_moves_to_teardown_and_a_clean_exit_records_nothing() {
    let t0 = Instant::now();
    let mut w = ready_worker(t0);
    for (k, c) in cells().iter().enumerate() {
        let t = 1000 * (k as u64 + 1);
        (w, _) = feed(w, start(c), at(t0, t));
        (w, _) = feed(w, result(c, Outcome::Pass), at(t0, t + 10));
    }
    assert_eq!((&w.state, w.phase), (&State::Teardown { since: at(t0, 3010) }, Phase::Teardown));
    let (asked, recorded) = dies(w, Input::Eof, exit(Some(0), None), at(t0, 3020));
    assert_eq!(asked, Effect::Reap, "its output ended: reaped, not killed");
    assert!(recorded.is_empty(), "{recorded:?}");
}

#[test]
fn a_crash_in_teardown_is_the_workers_not_a_cells() {
    let t0 = Instant::now();
    let mut w = ready_worker(t0);
    for c in cells() {
        (w, _) = feed(w, start(&c), at(t0, 200));
        (w, _) = feed(w, result(&c, Outcome::Pass), at(t0, 300));
    }
    let (_, fx) = dies(w, Input::Eof, exit(None, Some(libc::SIGSEGV)), at(t0, 400));
    assert!(attempts(&fx).is_empty());
    let ev = events(&fx)[0];
    assert_eq!((ev.phase, ev.outcome), (Phase::Teardown, Outcome::Crash));
    assert_eq!(fruitless(&fx), None, "it ran its cells");
}

#[test]
fn a_device_lost_result_ends_the_worker() {
    let t0 = Instant::now();
    let (w, fx) =
        feed(in_cell(t0, Phase::Trace), result(&cells()[0], Outcome::DeviceLost), at(t0, 300));
    assert_eq!(attempts(&fx)[0].1.outcome, Outcome::DeviceLost);
    assert_eq!(w.state, State::Teardown { since: at(t0, 300) }, "two cells left, yet it must exit");
    assert_eq!(w.pending.len(), 2);
    // It `_exit(0)`s by itself: nothing more to record; its cells stay queued for the next worker.
    let (_, fx) = dies(w, Input::Eof, exit(Some(0), None), at(t0, 310));
    assert!(fx.is_empty(), "{fx:?}");
}

#[test]
fn eof_mid_cell_is_a_crash_in_the_cells_phase() {
    let t0 = Instant::now();
    let (asked, fx) = dies(
        in_cell(t0, Phase::Pipeline),
        Input::Eof,
        exit(None, Some(libc::SIGSEGV)),
        at(t0, 700),
    );
    assert_eq!(asked, Effect::Reap);
    let [(cell, a)] = attempts(&fx)[..] else { panic!("{fx:?}") };
    assert_eq!(cell, cells()[0]);
    assert_eq!((a.outcome, a.phase, a.wall_ms), (Outcome::Crash, Some(Phase::Pipeline), 500.0));
    assert_eq!(
        a.detail.as_deref(),
        Some("worker killed by signal 11 (SIGSEGV) mid-cell, in pipeline")
    );
    assert_eq!(a.worker_exit.as_ref().and_then(|e| e.signal), Some(libc::SIGSEGV));
    assert!(events(&fx).is_empty(), "a cell's fault, not the worker's");
}

#[test]
fn eof_mid_cell_is_never_a_pass() {
    // The twin of the crash: however the process ended, a cell without a result did not pass.
    let t0 = Instant::now();
    for ended in [
        exit(Some(0), None),
        exit(Some(1), None),
        exit(None, None),
        exit(None, Some(libc::SIGKILL)),
    ] {
        let (_, fx) = dies(in_cell(t0, Phase::Trace), Input::Eof, ended.clone(), at(t0, 300));
        let [(_, a)] = attempts(&fx)[..] else { panic!("{fx:?}") };
        assert_ne!(a.outcome, Outcome::Pass, "{ended:?}");
        assert!(a.result.is_none());
        assert_eq!(a.phase, Some(Phase::Trace));
    }
}

#[test]
fn a_deadline_mid_cell_is_the_cells_timeout() {
    let t0 = Instant::now();
    let (asked, fx) = dies(
        in_cell(t0, Phase::Trace),
        Input::Deadline,
        exit(None, Some(libc::SIGTERM)),
        at(t0, 10_200),
    );
    assert_eq!(asked, Effect::Kill);
    let [(cell, a)] = attempts(&fx)[..] else { panic!("{fx:?}") };
    assert_eq!((cell, a.outcome, a.phase), (cells()[0], Outcome::Timeout, Some(Phase::Trace)));
    assert_eq!(
        a.detail.as_deref(),
        Some("no result within 10s, in trace; worker process group killed")
    );
    assert!(events(&fx).is_empty());
}

#[test]
fn a_deadline_between_cells_is_never_blamed_on_a_cell() {
    let t0 = Instant::now();
    let (asked, fx) =
        dies(one_done(t0), Input::Deadline, exit(None, Some(libc::SIGTERM)), at(t0, 10_300));
    assert_eq!(asked, Effect::Kill);
    assert!(attempts(&fx).is_empty(), "{fx:?}");
    let ev = events(&fx)[0];
    assert_eq!((ev.phase, ev.outcome), (Phase::BetweenCells, Outcome::Timeout));
    assert_eq!(ev.detail.as_deref(), Some("no next cell within 10s after the last result; killed"));
    assert_eq!(fruitless(&fx), None, "it ran a cell");
}

#[test]
fn a_deadline_in_setup_is_a_failed_setup() {
    let t0 = Instant::now();
    let (w, _) = feed(
        Worker::new(3, cells(), true, t0),
        phase(Phase::Setup, Some("vkCreateDevice")),
        at(t0, 5),
    );
    let (asked, fx) = dies(w, Input::Deadline, exit(None, Some(libc::SIGKILL)), at(t0, 60_000));
    assert_eq!(asked, Effect::Kill);
    let ev = events(&fx)[0];
    assert_eq!(
        (ev.phase, ev.outcome, ev.cells, ev.wall_ms),
        (Phase::Setup, Outcome::Timeout, 3, 60_000.0)
    );
    assert_eq!(
        ev.detail.as_deref(),
        Some("worker setup took longer than 60s, in setup (vkCreateDevice); killed")
    );
    let (batch, not_run) = fruitless(&fx).expect("no attempt: fruitless");
    assert_eq!(
        (batch, not_run.outcome, not_run.isolated, not_run.not_run()),
        (3, Outcome::Timeout, true, true)
    );
    assert!(not_run.detail.as_deref().unwrap().starts_with(
        "not run: two workers in a row failed before running a cell; the last: timeout in setup"
    ));
    assert!(attempts(&fx).is_empty(), "the scheduler decides whether its cells are given up");
}

#[test]
fn a_deadline_in_teardown_is_the_workers() {
    let t0 = Instant::now();
    let (w, _) = feed(in_cell(t0, Phase::Trace), result(&cells()[0], Outcome::Crash), at(t0, 300));
    let (_, fx) = dies(w, Input::Deadline, exit(None, Some(libc::SIGTERM)), at(t0, 10_300));
    assert!(attempts(&fx).is_empty());
    let ev = events(&fx)[0];
    assert_eq!((ev.phase, ev.outcome), (Phase::Teardown, Outcome::Timeout));
    assert!(ev
        .detail
        .as_deref()
        .unwrap()
        .starts_with("did not exit within 10s after its last cell"));
}

#[test]
fn a_failed_setup_is_a_worker_event_and_fruitless() {
    let t0 = Instant::now();
    let (w, _) = feed(
        Worker::new(2, cells(), false, t0),
        phase(Phase::Setup, Some("acceleration structures and resources")),
        at(t0, 5),
    );
    let fatal = msg(WorkerMsg::Fatal {
        message: "injected device loss".into(),
        outcome: Outcome::DeviceLost,
        halt: None,
    });
    let (asked, fx) = dies(w, fatal, exit(Some(3), None), at(t0, 50));
    assert_eq!(asked, Effect::Kill, "its group is killed: nothing of it may linger");
    let ev = events(&fx)[0];
    assert_eq!((ev.phase, ev.outcome), (Phase::Setup, Outcome::DeviceLost));
    assert_eq!(ev.detail.as_deref(), Some("worker setup failed in setup (acceleration structures and resources): injected device loss"));
    let (_, not_run) = fruitless(&fx).expect("fruitless");
    assert_eq!(
        (not_run.outcome, not_run.phase, not_run.worker),
        (Outcome::DeviceLost, Some(Phase::Setup), 2)
    );
}

/// A fatal message that halts the run: the shader compiler could not start.
fn no_compiler() -> Input {
    msg(WorkerMsg::Fatal {
        message: "the shader compiler (shaderc) could not be started".into(),
        outcome: Outcome::Error,
        halt: Some(Halt::NoShaderCompiler),
    })
}

fn halts(fx: &[Effect]) -> Vec<Halt> {
    fx.iter()
        .filter_map(|e| if let Effect::Report(Event::Halt(h)) = e { Some(*h) } else { None })
        .collect()
}

#[test]
fn a_setup_without_a_shader_compiler_is_recorded_then_halts_the_run() {
    let t0 = Instant::now();
    let (w, _) = feed(
        Worker::new(4, cells(), false, t0),
        phase(Phase::Setup, Some("vkCreateDevice")),
        at(t0, 5),
    );
    let (asked, fx) = dies(w, no_compiler(), exit(Some(3), None), at(t0, 50));
    assert_eq!(asked, Effect::Kill);
    let ev = events(&fx)[0];
    assert_eq!((ev.worker, ev.phase, ev.outcome), (4, Phase::Setup, Outcome::Error));
    assert_eq!(
        ev.detail.as_deref(),
        Some("worker setup failed in setup (vkCreateDevice): the shader compiler (shaderc) could not be started")
    );
    assert_eq!(halts(&fx), [Halt::NoShaderCompiler]);
    assert!(
        matches!(fx.last(), Some(Effect::Report(Event::Halt(_)))),
        "the worker's record comes first: {fx:?}"
    );
    // The run stops: its cells are neither given up as not run nor blamed.
    assert_eq!(fruitless(&fx), None, "{fx:?}");
    assert!(attempts(&fx).is_empty());
}

#[test]
fn only_a_halting_fatal_halts_and_a_halt_is_never_lost() {
    // The twin: the same failed setup without `halt` is this worker's alone (fruitless, retried).
    let t0 = Instant::now();
    let plain = msg(WorkerMsg::Fatal {
        message: "the shader compiler (shaderc) could not be started".into(),
        outcome: Outcome::Error,
        halt: None,
    });
    let (_, fx) = dies(Worker::new(4, cells(), false, t0), plain, exit(Some(3), None), at(t0, 50));
    assert!(halts(&fx).is_empty() && fruitless(&fx).is_some(), "{fx:?}");
    // A halt in any state reaches the supervisor: mid-cell, while prebuilding.
    let ids: Vec<String> = cells().iter().map(Cell::id).collect();
    let (prebuilding, _) =
        feed(ready_worker(t0), msg(WorkerMsg::Prebuild { cells: ids, threads: 4 }), at(t0, 200));
    for w in [in_cell(t0, Phase::Compile), prebuilding] {
        let (_, fx) = dies(w, no_compiler(), exit(Some(0), None), at(t0, 300));
        assert_eq!(halts(&fx), [Halt::NoShaderCompiler], "{fx:?}");
        assert!(attempts(&fx).is_empty() && fruitless(&fx).is_none(), "{fx:?}");
    }
}

#[test]
fn a_fatal_mid_cell_is_the_workers_and_the_cell_runs_again() {
    let t0 = Instant::now();
    let fatal =
        msg(WorkerMsg::Fatal { message: "gone".into(), outcome: Outcome::Error, halt: None });
    let (_, fx) = dies(in_cell(t0, Phase::Record), fatal, exit(Some(2), None), at(t0, 300));
    assert!(attempts(&fx).is_empty(), "{fx:?}");
    assert_eq!(events(&fx)[0].phase, Phase::Record);
}

#[test]
fn a_prebuild_step_restarts_the_deadline() {
    let t0 = Instant::now();
    let ids: Vec<String> = cells().iter().map(Cell::id).collect();
    let (w, _) =
        feed(ready_worker(t0), msg(WorkerMsg::Prebuild { cells: ids, threads: 4 }), at(t0, 200));
    assert_eq!(
        (w.phase, w.deadline(&LIMITS)),
        (Phase::Prebuild, Some(at(t0, 200) + LIMITS.timeout))
    );
    let (w, _) = feed(w, phase(Phase::Prebuild, Some("pipelines 1/3")), at(t0, 9_000));
    assert_eq!(w.deadline(&LIMITS), Some(at(t0, 9_000) + LIMITS.timeout));
    assert_eq!(w.where_(), "prebuild (pipelines 1/3)");
    let (w, fx) = feed(
        w,
        msg(WorkerMsg::Prebuilt {
            wall_ms: 5.0,
            pipelines: 3,
            threads: 4,
            overlapped: 1,
            checked_apart: 1,
        }),
        at(t0, 9_500),
    );
    assert_eq!(
        fx,
        [Effect::Report(Event::Prebuilt {
            wall_ms: 5.0,
            pipelines: 3,
            threads: 4,
            overlapped: 1,
            checked_apart: 1
        })]
    );
    assert_eq!(w.state, State::Between { since: at(t0, 9_500) });
}

#[test]
fn a_phase_or_a_repeated_start_mid_cell_does_not_restart_the_deadline() {
    // The twin: only a prebuild's progress moves a deadline; a cell's clock runs from its start.
    let t0 = Instant::now();
    let (w, _) = feed(in_cell(t0, Phase::Pipeline), phase(Phase::Trace, None), at(t0, 9_000));
    let (w, fx) = feed(w, start(&cells()[0]), at(t0, 9_500));
    assert!(matches!(&fx[..], [Effect::Log(l)] if l.contains("ignored")));
    assert_eq!((w.phase, w.deadline(&LIMITS)), (Phase::Trace, Some(at(t0, 200) + LIMITS.timeout)));
}

/// A ready worker that began prebuilding every cell of [`cells`] at 200 ms, and their ids.
fn prebuilding(t0: Instant) -> (Worker, Vec<String>) {
    let ids: Vec<String> = cells().iter().map(Cell::id).collect();
    let msg = msg(WorkerMsg::Prebuild { cells: ids.clone(), threads: 4 });
    (feed(ready_worker(t0), msg, at(t0, 200)).0, ids)
}

#[test]
fn a_death_while_prebuilding_sends_its_batch_cell_by_cell() {
    let t0 = Instant::now();
    let (w, ids) = prebuilding(t0);
    for (cause, ended, outcome) in [
        (Input::Deadline, exit(None, Some(libc::SIGTERM)), Outcome::Timeout),
        (Input::Eof, exit(None, Some(libc::SIGSEGV)), Outcome::Crash),
        (
            msg(WorkerMsg::Fatal {
                message: "lost".into(),
                outcome: Outcome::DeviceLost,
                halt: None,
            }),
            exit(Some(0), None),
            Outcome::DeviceLost,
        ),
    ] {
        let (_, fx) = dies(w.clone(), cause, ended, at(t0, 300));
        assert_eq!(fx[0], Effect::Serial(ids.clone()));
        let ev = events(&fx)[0];
        assert_eq!((ev.phase, ev.outcome), (Phase::Prebuild, outcome));
        assert!(ev
            .detail
            .as_deref()
            .unwrap()
            .ends_with("; its batch runs again, each cell building at its turn"));
        assert!(
            attempts(&fx).is_empty() && fruitless(&fx).is_none(),
            "blamed on no cell, and no give-up: {fx:?}"
        );
    }
}

/// An overlapped cell that loses the device ends the worker with its `fatal`: the
/// VK_EXT_device_fault data it sent just before stays in the prebuild's death record.
#[test]
fn an_overlapped_device_loss_keeps_its_fault_data() {
    let t0 = Instant::now();
    let (w, ids) = prebuilding(t0);
    let step = crate::runner::protocol::overlapped_step(&ids[0], Phase::Trace);
    let (w, _) = feed(w, phase(Phase::Prebuild, Some(&step)), at(t0, 5_000));
    let fault = crate::model::FaultInfo {
        description: "page fault at 0xdead0000".into(),
        vendor_binary_bytes: 64,
        ..Default::default()
    };
    let sent = WorkerMsg::DeviceFault { cell: ids[0].clone(), fault: fault.clone() };
    let (with, fx) = feed(w.clone(), msg(sent.clone()), at(t0, 5_001));
    assert!(fx.is_empty(), "{fx:?}");
    let lost = || {
        msg(WorkerMsg::Fatal { message: "lost".into(), outcome: Outcome::DeviceLost, halt: None })
    };
    let (_, fx) = dies(with, lost(), exit(Some(0), None), at(t0, 5_002));
    let ev = events(&fx)[0];
    assert_eq!((ev.phase, ev.outcome), (Phase::Prebuild, Outcome::DeviceLost));
    assert_eq!(ev.overlapped_cell.as_deref(), Some(ids[0].as_str()));
    assert_eq!(ev.fault.as_ref(), Some(&fault));
    // The twin: a death without the message has no fault data.
    let (_, fx) = dies(w, lost(), exit(Some(0), None), at(t0, 5_002));
    assert_eq!(events(&fx)[0].fault, None);
    // Outside a prebuild it is no one's: logged and ignored.
    let (between, fx) = feed(ready_worker(t0), msg(sent), at(t0, 300));
    assert!(matches!(&fx[..], [Effect::Log(l)] if l.contains("ignored")), "{fx:?}");
    assert!(matches!(between.state, State::Between { .. }));
}

/// Cells that ran while the prebuild's pipelines were still being made (`runner::overlap`):
/// their phases come as prebuild steps and their lines after `prebuilt`. A death before it is
/// the prebuild's, blamed on no cell, whichever cell's phase was named last; after it, the held
/// lines are ordinary attempts, timed by the worker (they arrive together).
#[test]
fn overlapped_cells_are_blamed_on_no_cell_until_prebuilt() {
    let t0 = Instant::now();
    let (w, ids) = prebuilding(t0);
    let step = crate::runner::protocol::overlapped_step(&ids[0], Phase::Trace);
    let (w, _) = feed(w, phase(Phase::Prebuild, Some(&step)), at(t0, 5_000));
    assert_eq!(
        w.deadline(&LIMITS),
        Some(at(t0, 5_000) + LIMITS.timeout),
        "a cell's phase is progress"
    );
    assert_eq!(w.where_(), format!("prebuild ({step})"));
    for (cause, ended, outcome) in [
        (Input::Eof, exit(None, Some(libc::SIGSEGV)), Outcome::Crash),
        (Input::Deadline, exit(None, Some(libc::SIGTERM)), Outcome::Timeout),
    ] {
        let (_, fx) = dies(w.clone(), cause, ended, at(t0, 6_000));
        assert_eq!(fx[0], Effect::Serial(ids.clone()), "every unfinished cell goes serial");
        assert_eq!((events(&fx)[0].phase, events(&fx)[0].outcome), (Phase::Prebuild, outcome));
        assert!(attempts(&fx).is_empty(), "no cell blamed: {fx:?}");
        // The entry names the overlapped cell, for a baseline to hold it to that cell's verdict.
        assert_eq!(events(&fx)[0].overlapped_cell.as_deref(), Some(ids[0].as_str()));
    }
    // A pool step after it keeps the cell named; a death before any overlapped step names none.
    let (w2, _) = feed(w.clone(), phase(Phase::Prebuild, Some("pipelines 2/3")), at(t0, 5_500));
    let (_, fx) = dies(w2, Input::Eof, exit(None, Some(libc::SIGSEGV)), at(t0, 6_000));
    assert_eq!(events(&fx)[0].overlapped_cell.as_deref(), Some(ids[0].as_str()));
    let (fresh, _) = prebuilding(t0);
    let (_, fx) = dies(fresh, Input::Eof, exit(None, Some(libc::SIGSEGV)), at(t0, 6_000));
    assert_eq!(events(&fx)[0].overlapped_cell, None);
    let done = WorkerMsg::Prebuilt {
        wall_ms: 9.0,
        pipelines: 3,
        threads: 4,
        overlapped: 1,
        checked_apart: 1,
    };
    let (w, _) = feed(w, msg(done), at(t0, 7_000));
    let (w, _) = feed(w, start(&cells()[0]), at(t0, 7_000));
    let Input::Msg(WorkerMsg::Result { cell, mut result }) = result(&cells()[0], Outcome::Pass)
    else {
        unreachable!()
    };
    result.timings.total_ms = 40.0;
    let (w, fx) = feed(w, msg(WorkerMsg::Result { cell, result }), at(t0, 7_001));
    let a = attempts(&fx);
    assert_eq!((a.len(), a[0].1.outcome), (1, Outcome::Pass));
    assert_eq!(a[0].1.wall_ms, 40.0, "the worker's time, not the 1 ms between the lines");
    assert_eq!(w.state, State::Between { since: at(t0, 7_001) });
}

#[test]
fn garbage_lines_are_counted_and_logged_up_to_a_limit() {
    let t0 = Instant::now();
    let mut w = in_cell(t0, Phase::Trace);
    let mut logged = vec![];
    for k in 0..50 {
        let (next, fx) = feed(w, Input::Garbage(format!("noise {k}")), at(t0, 300 + k));
        w = next;
        logged.extend(fx);
    }
    assert_eq!(w.garbage, 50);
    assert_eq!(logged.len() as u64, GARBAGE_LOGGED + 1);
    assert_eq!(logged[0], Effect::Log("worker 7 said: noise 0".into()));
    assert_eq!(
        logged[GARBAGE_LOGGED as usize],
        Effect::Log("worker 7 keeps printing; further lines not logged".into())
    );
    assert_eq!(
        w.deadline(&LIMITS),
        Some(at(t0, 200) + LIMITS.timeout),
        "noise holds no deadline off"
    );
}

#[test]
fn lines_out_of_place_are_ignored() {
    let t0 = Instant::now();
    let w = one_done(t0);
    let (w2, fx) = feed(w.clone(), ready(), at(t0, 400));
    assert!(matches!(&fx[..], [Effect::Log(l)] if l.contains("ready again")));
    assert_eq!(w2.state, w.state);
    let stranger = Cell { nonuniform: true, ..cells()[1] };
    let (w2, fx) = feed(w.clone(), start(&stranger), at(t0, 400));
    assert!(fx.is_empty() && w2.state == w.state, "a cell outside its job does not start");
    let (w2, fx) = feed(w.clone(), result(&stranger, Outcome::Pass), at(t0, 400));
    assert!(fx.is_empty() && w2.state == w.state, "nor is it recorded");
    let (w2, fx) = feed(
        w.clone(),
        msg(WorkerMsg::Prebuilt {
            wall_ms: 1.0,
            pipelines: 1,
            threads: 2,
            overlapped: 0,
            checked_apart: 0,
        }),
        at(t0, 400),
    );
    assert!(fx.is_empty() && w2.state == w.state, "prebuilt without a prebuild");
    let (_, fx) = feed(
        in_cell(t0, Phase::Trace),
        msg(WorkerMsg::Prebuild { cells: vec![], threads: 2 }),
        at(t0, 400),
    );
    assert!(matches!(&fx[..], [Effect::Log(l)] if l.contains("not between cells")));
}

#[test]
fn a_dying_worker_takes_no_more_lines() {
    let t0 = Instant::now();
    let (w, _) = feed(in_cell(t0, Phase::Trace), Input::Eof, at(t0, 300));
    let (w, fx) = feed(w, result(&cells()[0], Outcome::Pass), at(t0, 301));
    assert!(fx.is_empty());
    let (w, fx) = feed(w, Input::Deadline, at(t0, 302));
    assert!(fx.is_empty(), "one kill per death");
    assert!(matches!(w.state, State::Dying { cause: Cause::Eof, .. }));
}

#[test]
fn cache_saved_is_passed_on_with_its_reason() {
    let t0 = Instant::now();
    let (_, fx) =
        feed(one_done(t0), msg(WorkerMsg::CacheSaved { bytes: None, error: None }), at(t0, 400));
    assert_eq!(fx, [Effect::Report(Event::CacheSaved(Err("not saved".into())))]);
}

#[test]
fn a_death_is_a_crash_unless_the_exit_was_clean() {
    assert_eq!(died(&exit(None, Some(libc::SIGSEGV))).0, Outcome::Crash);
    assert!(died(&exit(None, Some(libc::SIGSEGV))).1.contains("SIGSEGV"));
    assert_eq!(died(&exit(Some(3), None)).0, Outcome::Crash);
    assert_eq!(died(&exit(Some(0), None)).0, Outcome::Error);
    assert_eq!(died(&exit(None, None)).0, Outcome::Error);
}

/// `exiting` after the last result: the worker ends at once, its process released (reaped in the
/// background, not waited for), nothing recorded. Its twins: `exiting` with cells left (after a
/// device loss, or mid-run) changes nothing, and the crash that follows is still recorded.
#[test]
fn exiting_after_the_last_result_ends_the_worker_without_waiting_for_its_exit() {
    let t0 = Instant::now();
    let mut w = ready_worker(t0);
    for c in cells() {
        (w, _) = feed(w, start(&c), at(t0, 200));
        (w, _) = feed(w, result(&c, Outcome::Pass), at(t0, 300));
    }
    let (done, fx) = feed(w, msg(WorkerMsg::Exiting), at(t0, 310));
    assert_eq!(fx, [Effect::Release]);
    assert!(done.ended() && done.deadline(&LIMITS).is_none(), "{:?}", done.state);
    // Mid-run: ignored; the cell's clock keeps running, and a death is still the cell's.
    let (w, fx) = feed(in_cell(t0, Phase::Trace), msg(WorkerMsg::Exiting), at(t0, 320));
    assert!(matches!(fx[..], [Effect::Log(_)]) && matches!(w.state, State::Cell { .. }));
    let (_, fx) = dies(w, Input::Eof, exit(None, Some(libc::SIGSEGV)), at(t0, 330));
    assert_eq!(attempts(&fx)[0].1.outcome, Outcome::Crash);
    // After a device loss (cells left): the worker must still be reaped and its exit read.
    let (w, _) =
        feed(in_cell(t0, Phase::Trace), result(&cells()[0], Outcome::DeviceLost), at(t0, 300));
    let (w, fx) = feed(w, msg(WorkerMsg::Exiting), at(t0, 301));
    assert!(!fx.contains(&Effect::Release) && matches!(w.state, State::Teardown { .. }));
}
