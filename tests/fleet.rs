//! End-to-end tests of rtprobe in CI on lavapipe: shards merged equal the unsharded run, a
//! baseline turns known faults into passes and new ones into named regressions, improvements and
//! flakes are handled, performance bounds fail a slow run, and `diff` shows exactly what changed.
mod common;
use common::*;
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

const FILTER: &str =
    "stage=raygen|miss,resource=storage_buffer|uniform_buffer,descriptor_model=descriptor_indexing";
const KNOWN: &str = "stage=miss,index=literal@value";

fn report(path: &Path) -> Value {
    serde_json::from_slice(&std::fs::read(path).expect("report written")).expect("report is JSON")
}

fn verdicts(r: &Value) -> BTreeMap<String, String> {
    r["cells"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| {
            (c["id"].as_str().unwrap().to_string(), c["outcome"].as_str().unwrap().to_string())
        })
        .collect()
}

fn run_to(dir: &Path, name: &str, extra: &[&str]) -> (PathBuf, std::process::Output) {
    let out = dir.join(name);
    let mut args =
        vec!["run", "--patches", "none", "--filter", FILTER, "-o", out.to_str().unwrap()];
    args.extend_from_slice(extra);
    let o = run(&args);
    (out, o)
}

#[test]
fn shards_merged_equal_the_unsharded_run() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let (all, o) = run_to(dir.path(), "all.json", &["--inject-fault", KNOWN]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let mut parts = vec![];
    let mut sizes = vec![];
    for i in 1..=3 {
        let (p, o) = run_to(
            dir.path(),
            &format!("s{i}.json"),
            &["--inject-fault", KNOWN, "--shard", &format!("{i}/3")],
        );
        assert!(matches!(o.status.code(), Some(0 | 1)), "{}", stderr(&o));
        sizes.push(report(&p)["cells"].as_array().unwrap().len());
        parts.push(p);
    }
    assert_eq!(
        sizes.iter().sum::<usize>(),
        22,
        "20 cells, and the 2 storage-buffer dynamic_element ones"
    );
    assert!(sizes.iter().max().unwrap() - sizes.iter().min().unwrap() <= 1, "balanced: {sizes:?}");
    let merged = dir.path().join("merged.json");
    let mut args = vec!["merge", "-o", merged.to_str().unwrap()];
    args.extend(parts.iter().map(|p| p.to_str().unwrap()));
    let o = run(&args);
    // The merged report's verdict is the run's: the injected fault is a finding (exit 1).
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let last = stdout(&o).trim_end().lines().last().unwrap_or_default().to_string();
    assert!(last.starts_with("verdict: FAIL — 2 findings"), "{}", stdout(&o));
    let (a, m) = (report(&all), report(&merged));
    assert_eq!(verdicts(&a), verdicts(&m), "same cells, same verdicts");
    assert_eq!(a["plan"]["planned"], m["plan"]["planned"]);
    assert_eq!(a["summary"], m["summary"]);
    assert_eq!(m["options"]["merged_from"].as_array().unwrap().len(), 3);
    // The merged report is a run report like any other: diff against the unsharded run is empty.
    let o = run(&["diff", all.to_str().unwrap(), merged.to_str().unwrap(), "--noise", "1000"]);
    assert_eq!(o.status.code(), Some(0), "{}", stdout(&o));
    assert!(stdout(&o).contains("no outcome changes"));
    // Reports of another scene do not merge.
    let (other, _) = run_to(dir.path(), "seed2.json", &["--seed", "2", "--shard", "1/3"]);
    let o = run(&[
        "merge",
        "-o",
        dir.path().join("x.json").to_str().unwrap(),
        parts[0].to_str().unwrap(),
        other.to_str().unwrap(),
    ]);
    assert_one_line_error(&o, 9, "does not belong");
    assert!(!dir.path().join("x.json").exists(), "no half-written output");
    // The same shard twice would double its attempts: refused.
    let o = run(&[
        "merge",
        "-o",
        dir.path().join("x.json").to_str().unwrap(),
        parts[0].to_str().unwrap(),
        parts[0].to_str().unwrap(),
    ]);
    assert_one_line_error(&o, 9, "already merged");
}

#[test]
fn a_baseline_expects_known_faults_and_names_new_ones() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let (first, _) = run_to(dir.path(), "first.json", &["--inject-fault", KNOWN]);
    let base = dir.path().join("base.json");
    let o = run(&[
        "baseline",
        first.to_str().unwrap(),
        "-o",
        base.to_str().unwrap(),
        "--bug",
        "https://example.invalid/1",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let b: Value = serde_json::from_slice(&std::fs::read(&base).unwrap()).unwrap();
    assert_eq!(b["schema"], "rtprobe.baseline/1");
    assert_eq!(b["expected"].as_array().unwrap().len(), 2, "miss x 2 resources, literal: {b}");
    // The same faults again: the run passes.
    let (_, o) = run_to(
        dir.path(),
        "again.json",
        &["--inject-fault", KNOWN, "--baseline", base.to_str().unwrap()],
    );
    assert_eq!(o.status.code(), Some(0), "{}", stdout(&o));
    assert!(stdout(&o).contains("0 regressions, 0 missing, 0 unexpected passes"), "{}", stdout(&o));
    // A new fault fails it, naming the cell.
    let (r, o) = run_to(
        dir.path(),
        "new.json",
        &[
            "--inject-fault",
            KNOWN,
            "--inject-fault",
            "stage=raygen,index=spec_constant,resource=uniform_buffer@value",
            "--baseline",
            base.to_str().unwrap(),
        ],
    );
    assert_eq!(o.status.code(), Some(1), "{}", stdout(&o));
    assert!(stdout(&o).contains("REGRESSION: raygen.uniform_buffer.spec_constant.descriptor_indexing expected pass got mismatch"), "{}", stdout(&o));
    assert_eq!(report(&r)["baseline"]["cells"].as_array().unwrap().len(), 1);
    // The known faults gone: an improvement, failing unless allowed.
    let (_, o) = run_to(dir.path(), "fixed.json", &["--baseline", base.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1), "{}", stdout(&o));
    assert!(stdout(&o).contains("UnexpectedPass: miss.storage_buffer.literal.descriptor_indexing expected mismatch got pass (update the baseline"), "{}", stdout(&o));
    let (_, o) = run_to(
        dir.path(),
        "fixed2.json",
        &["--baseline", base.to_str().unwrap(), "--allow-improvements"],
    );
    assert_eq!(o.status.code(), Some(0), "{}", stdout(&o));
    // In deqp-runner's form the same expectations hold.
    let csv = dir.path().join("fails.csv");
    let o = run(&[
        "baseline",
        first.to_str().unwrap(),
        "-o",
        csv.to_str().unwrap(),
        "--format",
        "deqp",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&csv).unwrap();
    assert!(text.contains("miss.storage_buffer.literal.descriptor_indexing,Fail"), "{text}");
    let (_, o) = run_to(
        dir.path(),
        "csv.json",
        &["--inject-fault", KNOWN, "--baseline", csv.to_str().unwrap()],
    );
    assert_eq!(o.status.code(), Some(0), "{}", stdout(&o));
    // A known flake tolerates its flake, whichever way the die falls.
    let flakes = dir.path().join("flakes.csv");
    std::fs::write(&flakes, "# flake: bug https://example.invalid/2, 1 of 2 attempts\nraygen.storage_buffer.literal.descriptor_indexing,Flake\n").unwrap();
    let (_, o) = run_to(
        dir.path(),
        "flaky.json",
        &[
            "--inject-fault",
            "stage=raygen,index=literal,resource=storage_buffer@flaky:0.5",
            "--baseline",
            flakes.to_str().unwrap(),
        ],
    );
    assert_eq!(o.status.code(), Some(0), "{}", stdout(&o));
    // A bad baseline is one error line.
    std::fs::write(&flakes, "a.b,Exploded\n").unwrap();
    let (_, o) = run_to(dir.path(), "bad.json", &["--baseline", flakes.to_str().unwrap()]);
    assert_one_line_error(&o, 9, "unknown status");
}

#[test]
fn a_phase_slower_than_its_bound_fails_the_run() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let (first, _) = run_to(dir.path(), "first.json", &[]);
    let base = dir.path().join("base.json");
    let o = run(&[
        "baseline",
        first.to_str().unwrap(),
        "-o",
        base.to_str().unwrap(),
        "--perf",
        "pipeline,check",
        "--perf-factor",
        "1000",
        "--perf-slack-ms",
        "100",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (_, o) = run_to(dir.path(), "ok.json", &["--baseline", base.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "generous bounds hold: {}", stdout(&o));
    // The same run against a bound it cannot meet (as if the driver got 1000x slower).
    let mut b: Value = serde_json::from_slice(&std::fs::read(&base).unwrap()).unwrap();
    b["performance"]["pipeline"] =
        serde_json::json!({ "mean_ms": 0.0, "factor": 1.0, "slack_ms": 0.0 });
    std::fs::write(&base, serde_json::to_vec(&b).unwrap()).unwrap();
    let (_, o) = run_to(dir.path(), "slow.json", &["--baseline", base.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1), "{}", stdout(&o));
    assert!(stdout(&o).contains("PERFORMANCE REGRESSION: pipeline"), "{}", stdout(&o));
    assert_one_line_error(
        &run(&[
            "baseline",
            first.to_str().unwrap(),
            "-o",
            base.to_str().unwrap(),
            "--perf",
            "warp",
        ]),
        2,
        "not a phase",
    );
}

#[test]
fn diff_of_a_report_with_itself_is_empty_and_with_an_edit_shows_the_edit() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let (r, _) = run_to(dir.path(), "r.json", &[]);
    let o = run(&["diff", r.to_str().unwrap(), r.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", stdout(&o));
    assert!(stdout(&o).contains("no outcome changes (22 unchanged)"), "{}", stdout(&o));
    assert!(stdout(&o).contains("no phase changed"), "{}", stdout(&o));
    let mut edited = report(&r);
    let cells = edited["cells"].as_array_mut().unwrap();
    cells[3]["outcome"] = Value::String("device_lost".into());
    let id = cells[3]["id"].as_str().unwrap().to_string();
    let gone = cells.remove(7)["id"].as_str().unwrap().to_string();
    let e = dir.path().join("e.json");
    std::fs::write(&e, serde_json::to_vec(&edited).unwrap()).unwrap();
    let md = dir.path().join("d.md");
    let o = run(&[
        "diff",
        r.to_str().unwrap(),
        e.to_str().unwrap(),
        "--format",
        "md",
        "-o",
        md.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stdout(&o));
    let text = std::fs::read_to_string(&md).unwrap();
    assert!(text.contains("1 regressed, 1 gone"), "{text}");
    assert!(text.contains(&format!("| ❌ regressed | `{id}` | pass | device_lost |")), "{text}");
    assert!(text.contains(&format!("| ➖ gone | `{gone}` | pass | — |")), "{text}");
    assert_eq!(
        text.lines().filter(|l| l.contains("` |")).count(),
        2,
        "exactly the two edited cells: {text}"
    );
}

/// Issue 22's CI transcript: a sharded run held to a baseline, whose shards each pass (the
/// baseline's entries for other shards' cells are theirs), is refused at the merge when a shard
/// is missing or the shard counts differ — never merged into a `complete` report of some cells.
#[test]
fn a_sharded_run_with_a_baseline_and_a_missing_shard_is_refused_at_the_merge() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let (first, _) = run_to(dir.path(), "first.json", &["--inject-fault", KNOWN]);
    let base = dir.path().join("base.json");
    let o = run(&["baseline", first.to_str().unwrap(), "-o", base.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let shard = |label: &str| {
        let name = format!("s{}.json", label.replace('/', "-"));
        let args =
            ["--inject-fault", KNOWN, "--shard", label, "--baseline", base.to_str().unwrap()];
        let (p, o) = run_to(dir.path(), &name, &args);
        assert_eq!(o.status.code(), Some(0), "shard {label}: {}", stdout(&o));
        assert!(!stdout(&o).contains("MISSING"), "{}", stdout(&o));
        p
    };
    let (s1, s2, s3) = (shard("1/3"), shard("2/3"), shard("3/3"));
    let merged = dir.path().join("merged.json");
    let merge = |parts: &[&PathBuf]| {
        let mut args = vec!["merge", "-o", merged.to_str().unwrap()];
        args.extend(parts.iter().map(|p| p.to_str().unwrap()));
        run(&args)
    };
    assert_one_line_error(&merge(&[&s1, &s2]), 9, "shard 3/3 missing (given: 1/3, 2/3)");
    assert!(!merged.exists(), "no report of 15 of 22 cells");
    let half = shard("2/2");
    assert_one_line_error(&merge(&[&s1, &half, &s3]), 9, "the shards of one run share their count");
    assert!(!merged.exists());
    let o = merge(&[&s1, &s2, &s3]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(report(&merged)["cells"].as_array().unwrap().len(), 22);
}

fn write_baseline(dir: &Path, name: &str, expected: Value) -> PathBuf {
    let p = dir.join(name);
    let b = serde_json::json!({ "schema": "rtprobe.baseline/1", "expected": expected });
    std::fs::write(&p, serde_json::to_vec_pretty(&b).unwrap()).unwrap();
    p
}

/// Issue 22's T1, T2 and T4, reproduced with injected faults: each fails the run.
#[test]
fn a_baseline_does_not_let_another_fault_a_risen_flake_or_a_vanished_cell_through() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    // T1: `error` expected, a mismatch got.
    let known = "miss.storage_buffer.literal.descriptor_indexing";
    let b = write_baseline(
        dir.path(),
        "t1.json",
        serde_json::json!([
            { "cell": known, "outcome": "error" },
            { "cell": "miss.uniform_buffer.literal.descriptor_indexing", "outcome": "mismatch" }
        ]),
    );
    let (_, o) = run_to(
        dir.path(),
        "t1r.json",
        &["--inject-fault", KNOWN, "--baseline", b.to_str().unwrap()],
    );
    assert_eq!(o.status.code(), Some(1), "{}", stdout(&o));
    assert!(
        stdout(&o).contains(&format!("REGRESSION: {known} expected error got mismatch")),
        "{}",
        stdout(&o)
    );
    // T2: a flake recorded at 1 of 8 that crashes 6 of 6 times.
    let flaky = "raygen.storage_buffer.literal.descriptor_indexing";
    let b = write_baseline(
        dir.path(),
        "t2.json",
        serde_json::json!([{ "cell": flaky, "outcome": "crash", "flake": true, "also": ["pass"], "rate": "1 of 8 attempts" }]),
    );
    let args = [
        "--filter",
        "stage=raygen,index=literal,resource=storage_buffer,descriptor_model=descriptor_indexing",
        "--inject-fault",
        "stage=raygen,index=literal,resource=storage_buffer@device",
        "--repeat",
        "6",
        "--baseline",
        b.to_str().unwrap(),
    ];
    let out = dir.path().join("t2r.json");
    let mut all = vec!["run", "--patches", "none", "-o", out.to_str().unwrap()];
    all.extend_from_slice(&args);
    let o = run(&all);
    assert_eq!(o.status.code(), Some(1), "{}", stdout(&o));
    assert!(
        stdout(&o).contains("its fault rate rose: 6 of 6 attempts against 1 of 8"),
        "{}",
        stdout(&o)
    );
    // T4: an expected crash whose cell is unsupported here (lavapipe 25 has no descriptor heap).
    let heap = "raygen.storage_buffer.literal.descriptor_heap.direct";
    let b = write_baseline(
        dir.path(),
        "t4.json",
        serde_json::json!([{ "cell": heap, "outcome": "crash" }]),
    );
    // The heap cell among cells that run (a plan the device can run none of is refused before
    // any baseline check, issue 29: below).
    let out = dir.path().join("t4r.json");
    let o = run(&[
        "run",
        "-o",
        out.to_str().unwrap(),
        "--filter",
        "stage=raygen,resource=storage_buffer,index=literal",
        "--baseline",
        b.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stdout(&o));
    assert!(
        stdout(&o).contains(&format!(
            "MISSING: {heap}: expected crash, but the cell is unsupported here"
        )),
        "{}",
        stdout(&o)
    );
    assert_eq!(report(&out)["baseline"]["cells"][0]["status"], "missing");
    // The heap cell alone: nothing the device can run, refused (exit 5), never a pass.
    let o = run(&[
        "run",
        "-o",
        dir.path().join("t4only.json").to_str().unwrap(),
        "--filter",
        "stage=raygen,resource=storage_buffer,index=literal,descriptor_model=descriptor_heap,heap_access=direct",
        "--baseline",
        b.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(5), "{}", String::from_utf8_lossy(&o.stderr));
}
