//! Snapshot of the plan on lavapipe (`rtprobe run --list --patches all --canaries`): cell ids are
//! the report's contract, so any change to them (or to what lavapipe is said to support) must show
//! up in review. Update with `RTPROBE_UPDATE_SNAPSHOTS=1 cargo test --release --test snapshot`.
mod common;
use common::*;

#[test]
fn plan_on_lavapipe_matches_the_snapshot() {
    let o = run(&["run", "--list", "--patches", "all", "--canaries"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let got = stdout(&o);
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/snapshots/plan-lavapipe.txt");
    if std::env::var("RTPROBE_UPDATE_SNAPSHOTS").is_ok_and(|v| v == "1") {
        std::fs::write(&path, &got).unwrap();
        return;
    }
    let want = std::fs::read_to_string(&path)
        .expect("snapshot exists (RTPROBE_UPDATE_SNAPSHOTS=1 writes it)");
    if got != want {
        let diff: Vec<String> = want
            .lines()
            .zip(got.lines())
            .enumerate()
            .filter(|(_, (a, b))| a != b)
            .take(10)
            .map(|(i, (a, b))| format!("line {}:\n  want {a}\n  got  {b}", i + 1))
            .collect();
        panic!(
            "plan differs from tests/snapshots/plan-lavapipe.txt ({} vs {} lines):\n{}",
            want.lines().count(),
            got.lines().count(),
            diff.join("\n")
        );
    }
}
