//! The held lines with a checker thread whose judge is the test's: each result names the cell it
//! was judged for, so a result put in another cell's place shows.
use super::*;
use crate::model::Timings;
use crate::model::{Cell, CellResult, DescriptorModel, IndexSource, Outcome, Resource, Stage};
use std::sync::{Arc, Mutex};
use std::time::Duration;

fn cell(stage: Stage) -> Cell {
    let model = DescriptorModel::DescriptorIndexing;
    Cell::new(stage, Resource::StorageBuffer, IndexSource::Literal, model)
}

/// A result whose detail is the judged cell's id.
fn named(traced: &Traced) -> CellResult {
    CellResult {
        outcome: Outcome::Pass,
        detail: Some(traced.cell().id()),
        timings: Timings::default(),
        comparison: None,
        fault: None,
        validation_errors: 0,
    }
}

/// Held lines judged by `judge`, and the cells they named to the supervisor.
fn held(
    judge: impl FnMut(Traced) -> (CellResult, Vec<Record>) + Send + 'static,
) -> (Held, Arc<Mutex<Vec<String>>>) {
    let told = Arc::new(Mutex::new(vec![]));
    let t = told.clone();
    let mut h = Held::new(Box::new(move |c| t.lock().unwrap().push(c.to_string())));
    h.checker = Some(Checker::with(judge).unwrap());
    (h, told)
}

fn start(c: &Cell) -> WorkerMsg {
    WorkerMsg::Start { cell: c.id() }
}

#[test]
fn each_result_goes_in_its_own_cells_place_between_the_other_lines() {
    // The first check is the slowest: later ones are back before it, and must wait their turn.
    let (mut h, told) = held(|t| {
        if t.cell().stage == Stage::Raygen {
            std::thread::sleep(Duration::from_millis(50));
        }
        (named(&t), vec![])
    });
    let [a, b, c] = [cell(Stage::Raygen), cell(Stage::Miss), cell(Stage::ClosestHit)];
    let mut none = |_: Vec<Record>| {};
    h.push(start(&a));
    h.hand_over(a.id(), Traced::for_tests(a), &mut none);
    h.push(start(&b));
    h.push(WorkerMsg::Result { cell: b.id(), result: named(&Traced::for_tests(b)) });
    h.push(start(&c));
    h.hand_over(c.id(), Traced::for_tests(c), &mut none);
    h.collect(&mut none, false);
    let (lines, apart) = h.drain(&mut none);
    assert_eq!(apart, 2);
    let got: Vec<String> = lines
        .iter()
        .map(|m| match m {
            WorkerMsg::Start { cell } => format!("start {cell}"),
            WorkerMsg::Result { cell, result } => {
                assert_eq!(result.detail.as_deref(), Some(cell.as_str()), "judged for its cell");
                format!("result {cell}")
            }
            other => panic!("{other:?}"),
        })
        .collect();
    let want = [("start", &a), ("result", &a), ("start", &b), ("result", &b), ("start", &c)];
    let mut want: Vec<String> = want.iter().map(|(k, c)| format!("{k} {}", c.id())).collect();
    want.push(format!("result {}", c.id()));
    assert_eq!(got, want);
    // Waiting at the end named the cells waited for, oldest first.
    assert!(told.lock().unwrap().iter().all(|t| *t == a.id() || *t == c.id()));
}

#[test]
fn a_full_queue_waits_for_its_oldest_cell_and_names_it_first() {
    let (mut h, told) = held(|t| {
        std::thread::sleep(Duration::from_millis(20));
        (named(&t), vec![])
    });
    let cells: Vec<Cell> = Stage::ALL.iter().map(|&s| cell(s)).take(QUEUE + 1).collect();
    assert_eq!(cells.len(), QUEUE + 1, "enough stages for a full queue");
    let mut none = |_: Vec<Record>| {};
    for c in &cells {
        h.hand_over(c.id(), Traced::for_tests(*c), &mut none);
        assert!(h.checking.len() <= QUEUE);
    }
    assert_eq!(told.lock().unwrap().first(), Some(&cells[0].id()), "the oldest waited for");
    let (lines, apart) = h.drain(&mut none);
    assert_eq!((lines.len(), apart), (QUEUE + 1, QUEUE + 1));
}

#[test]
fn a_check_that_panics_names_its_own_cell_before_the_panic_goes_on() {
    let (mut h, told) = held(|t| {
        if t.cell().stage == Stage::Miss {
            panic!("the check's own bug");
        }
        (named(&t), vec![])
    });
    let [a, b, c] = [cell(Stage::Raygen), cell(Stage::Miss), cell(Stage::ClosestHit)];
    let mut none = |_: Vec<Record>| {};
    for x in [a, b, c] {
        h.hand_over(x.id(), Traced::for_tests(x), &mut none);
    }
    // The cell thread went on to c; b's panic must still be named as b's, when a collect that
    // does not wait meets it.
    let deadline = std::time::Instant::now() + Duration::from_secs(20);
    let payload = loop {
        let collect = std::panic::AssertUnwindSafe(|| h.collect(&mut none, false));
        match std::panic::catch_unwind(collect) {
            Err(payload) => break payload,
            Ok(()) => assert!(std::time::Instant::now() < deadline, "the panic never came back"),
        }
        std::thread::sleep(Duration::from_millis(10));
    };
    assert_eq!(payload.downcast_ref::<&str>(), Some(&"the check's own bug"));
    assert_eq!(*told.lock().unwrap(), [b.id()], "only the panicking cell named");
}
