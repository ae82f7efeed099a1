//! `rtprobe bench --quick` on lavapipe: the bench.json contract, detection that follows the
//! injection (f = 1 catches every cell; a tiny f at 8×8 misses some: the twin), flaky attempts
//! caught exactly when armed, sweep entries with unknown flags skipped, well-formed SVGs, and bad
//! input as one error line with nothing written. Nothing here depends on wall-clock speed.
mod common;
use common::*;
use serde_json::Value;

use rtprobe::report::chart::check_well_formed as well_formed;

fn points<'a>(v: &'a Value, section: &str) -> &'a Vec<Value> {
    v[section]["points"].as_array().unwrap_or_else(|| panic!("{section}.points missing"))
}

#[test]
fn quick_bench_writes_its_contract_and_detection_follows_the_injection() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let out = dir.path().join("b");
    let o = run(&[
        "bench",
        "--quick",
        "--sizes",
        "8,16",
        "--fractions",
        "0.001,1",
        "--seeds",
        "1",
        "-o",
        out.to_str().unwrap(),
        "--sweep-args",
        "-j 1",
        "-j 1 --no-such-flag 3",
    ]);
    assert!(o.status.success(), "bench failed: {}", stderr(&o));
    let b: Value = serde_json::from_slice(&std::fs::read(out.join("bench.json")).unwrap()).unwrap();
    assert_eq!(b["schema"], "rtprobe.bench/1");
    assert_eq!(b["tool"]["version"], env!("CARGO_PKG_VERSION"));
    assert!(b["device"]["name"].as_str().unwrap().contains("llvmpipe"));
    assert!(
        b["driver"]["version"].is_string() && b["options"]["sizes"] == serde_json::json!([8, 16])
    );

    // Time against size: every size, every phase, the exact command.
    let st = points(&b, "size_time");
    assert_eq!(st.len(), 2);
    for p in st {
        let cmd = p["command"].as_str().unwrap();
        assert!(
            cmd.starts_with("rtprobe run --no-confirm --patches none")
                && (cmd.contains("--size 8x8") || cmd.contains("--size 16x16")),
            "{cmd}"
        );
        assert!(p["cells_run"].as_u64().unwrap() > 0 && p["findings"] == 0, "{p}");
        for ph in [
            "spawn_reference",
            "device",
            "compile",
            "pipeline",
            "setup",
            "trace",
            "check",
            "overhead",
        ] {
            assert!(p["phases_ms"][ph].as_f64().unwrap() >= 0.0, "{ph}");
        }
    }

    // Detection: f = 1 corrupts every checked record, so every injected cell is caught.
    let det = points(&b, "detection");
    assert_eq!(det.len(), 4, "2 sizes × 2 fractions × 1 seed");
    for p in det {
        let d = &p["detection"];
        assert!(p["command"].as_str().unwrap().contains("@value:"), "{}", p["command"]);
        assert!(
            d["trials"].as_u64().unwrap() >= 4 && p["not_compared"].as_array().unwrap().is_empty(),
            "{p}"
        );
        assert!(d["n_min"].as_u64().unwrap() > 0);
        for t in p["trials"].as_array().unwrap() {
            assert!(
                t["n"].as_u64().unwrap() <= (p["size"].as_u64().unwrap().pow(2)),
                "n is at most the pixels: {t}"
            );
        }
        if p["fraction"] == 1.0 {
            assert_eq!(d["measured"], 1.0, "f=1 must catch every cell: {p}");
            assert_eq!(d["predicted"], 1.0);
            assert_eq!(d["corrupted_share"], 1.0, "every checked record is wrong at f=1");
        }
    }
    // The twin: a wrong value on 0.1% of 64 rays is mostly missed (deterministic for seed 1).
    let tiny = det.iter().find(|p| p["size"] == 8 && p["fraction"] == 0.001).unwrap();
    assert!(tiny["detection"]["measured"].as_f64().unwrap() < 1.0, "{tiny}");
    assert!(tiny["detection"]["predicted"].as_f64().unwrap() < 0.1);

    // Flaky: an attempt faults exactly when its die armed the fault (lavapipe: a crash).
    let fl = points(&b, "flaky");
    assert_eq!(fl.len(), 1);
    let p = &fl[0];
    assert_eq!(p["armed_detected"], p["armed"], "{p}");
    assert_eq!(p["faulted_unarmed"], 0, "{p}");
    let rounds = p["rounds"].as_u64().unwrap() as usize;
    assert_eq!(p["measured"].as_array().unwrap().len(), rounds);
    assert_eq!(p["predicted"][0], 0.5);
    assert_eq!(p["repeats_needed"]["0.95"]["predicted"], 5);

    // Sweep: the unknown flag is skipped with its reason, the other entry ran.
    let sw = b["sweep"]["entries"].as_array().unwrap();
    assert_eq!(sw.len(), 2);
    assert!(sw[0]["skipped"].is_null() && sw[0]["wall_ratio"] == 1.0);
    assert_eq!(sw[0]["phase_ratio"]["trace"], 1.0);
    assert!(sw[1]["skipped"].as_str().unwrap().contains("--no-such-flag"), "{}", sw[1]);

    // Mutants (`--quick`: 16×16, the quick cells): every applicable mutant that must be caught is
    // killed; the rate leaves out only survivors the cell's own rule allows.
    let mu = points(&b, "mutants");
    assert_eq!(mu.len(), 1);
    let t = &mu[0]["counts"]["total"];
    assert!(mu[0]["command"].as_str().unwrap().contains("--mutants --filter"), "{}", mu[0]);
    assert!(t["applicable"].as_u64().unwrap() > 0 && t["killed"].as_u64().unwrap() > 0, "{t}");
    assert_eq!((t["probe_defects"].as_u64(), t["faults"].as_u64()), (Some(0), Some(0)), "{t}");
    assert_eq!(mu[0]["counts"]["kill_rate"], 1.0);
    assert!(mu[0]["ms_per_mutant_attempt"].as_f64().unwrap() > 0.0);

    for (name, needles) in [
        ("mutants-kills.svg", &["killed", "value-bits", "16×16"][..]),
        (
            "detection-vs-size.svg",
            &["measured f=0.001", "1-(1-f)^n, f=1", "share of injected cells caught"][..],
        ),
        ("time-vs-size.svg", &["wall", "trace", "time (s"][..]),
        ("flaky-repeats.svg", &["measured P=0.5", "1-(1-P)^r, P=0.5", "attempts r"][..]),
        ("sweep-phases.svg", &["-j 1", "trace", "device"][..]),
    ] {
        let svg = std::fs::read_to_string(out.join(name)).unwrap();
        well_formed(&svg).unwrap_or_else(|e| panic!("{name}: {e}"));
        for n in needles {
            assert!(svg.contains(n), "{name} lacks {n:?}");
        }
    }
    assert!(!std::fs::read_to_string(out.join("sweep-phases.svg"))
        .unwrap()
        .contains("no-such-flag"));
}

#[test]
fn bench_bad_input_is_one_line_and_writes_nothing() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let out = dir.path().join("b");
    let o_arg = out.to_str().unwrap();
    for (args, needle) in [
        (vec!["--sizes", "63"], "--sizes: unknown size"),
        (vec!["--flaky-size", "12"], "--flaky-size: unknown size"),
        (vec!["--sizes", "64x32"], "not square"),
        (vec!["--fractions", "0"], "outside (0, 1]"),
        (vec!["--fractions", "1.5"], "outside (0, 1]"),
        (vec!["--flaky", "1"], "outside (0, 1)"),
        (vec!["--inject-filter", "stage=nope"], "--inject-filter"),
        (vec!["--sweep-args", "-j 1 -o x"], "--sweep-args"),
    ] {
        let mut a = vec!["bench", "--quick", "-o", o_arg];
        a.extend(args);
        assert_one_line_error(&run(&a), 2, needle);
        assert!(!out.exists(), "nothing is created for bad arguments");
    }
    // An output directory that cannot be made (below a file).
    let file = dir.path().join("file");
    std::fs::write(&file, b"x").unwrap();
    assert_one_line_error(
        &run(&["bench", "--quick", "-o", file.join("sub").to_str().unwrap()]),
        9,
        "cannot create",
    );
    // A run that fails (no such device) stops the bench: its exit code, one line, no files.
    assert_one_line_error(
        &run(&["bench", "--quick", "--device", "no-such-gpu", "-o", o_arg]),
        6,
        "rtprobe run",
    );
    assert_eq!(std::fs::read_dir(&out).unwrap().count(), 0, "no half-written output");
    // Filters that parse but select no cell: the run bench starts says why (its exit code, 2),
    // nothing written.
    assert_one_line_error(
        &run(&[
            "bench",
            "--quick",
            "-o",
            o_arg,
            "--matrix-filter",
            "stage=raygen",
            "--matrix-filter",
            "stage=miss",
        ]),
        2,
        "have no cell in common",
    );
    assert_eq!(std::fs::read_dir(&out).unwrap().count(), 0, "no half-written output");
}

/// SIGTERM to `bench` mid-run (a `timeout` wrapper, a cancelled CI job) kills its `rtprobe run`
/// child with that child's workers, removes its work folder with what they wrote there (the
/// child's job folder lies inside it), says nothing was written, and writes nothing in `-o`
/// (made beforehand to know it takes files). Twin:
/// the children once ran in bench's process group, unhardened, and outlived a SIGTERM to bench.
#[test]
fn sigterm_during_bench_kills_its_runs_and_leaves_nothing() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let out = dir.path().join("b");
    let mut c = bin();
    c.args(["bench", "--quick", "-o"]).arg(&out).env("TMPDIR", dir.path());
    let (status, err) =
        interrupt_once_children_run(c, (dir.path(), " run "), libc::SIGTERM, |_| {});
    assert_eq!(status.code(), Some(143), "{status:?} {err}");
    assert!(err.contains("terminated (SIGTERM)") && err.contains("nothing was written"), "{err}");
    assert!(!err.contains("--resume"), "{err}");
    assert_eq!(entries(&out), Vec::<String>::new(), "-o checked writable, nothing written");
    assert_eq!(entries(dir.path()), vec!["b"], "the work folder and all in it");
}
