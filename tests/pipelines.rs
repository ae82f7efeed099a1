//! How pipelines are made and how many cells a run makes: `run --cells-scale N` runs exactly N
//! distinct cells (copies past the matrix, each with shaders of its own, that pass as their base
//! cells do), `--pipelines` is resolved for the device and recorded, and linked pipelines give the
//! verdicts whole ones give. Linked ray tracing pipelines run in the Debian sid root (lavapipe
//! 26): lavapipe 25.0.7's are wrong (docs/performance.md), so the host only checks the records;
//! the sid tests skip without the root unless RTPROBE_REQUIRE_SID=1.
mod common;
use common::*;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const COMPUTE: &str = "stage=compute,descriptor_model=descriptor_indexing,resource=storage_buffer";

fn report(path: &Path) -> Value {
    serde_json::from_slice(&std::fs::read(path).expect("report written")).expect("report JSON")
}

fn ran(r: &Value) -> Vec<&Value> {
    r["cells"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|c| !c["attempts"].as_array().unwrap().is_empty())
        .collect()
}

#[test]
fn cells_scale_runs_exactly_n_distinct_cells_and_bad_counts_are_refused() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let out = dir.path().join("r.json");
    let o = out.to_str().unwrap();
    let args = ["run", "--filter", COMPUTE, "--no-confirm", "--patches", "none", "-o", o];
    let base = run(&args);
    assert!(base.status.success(), "{}", stderr(&base));
    let n = ran(&report(&out)).len();
    assert!(n >= 2, "the filter runs {n} cells");
    // Past the matrix: every cell once, then copies, all distinct, all passing.
    let want = n + n / 2 + 1;
    let o2 = run(&[&args[..], &["--cells-scale", &want.to_string()]].concat());
    assert!(o2.status.success(), "{}", stderr(&o2));
    let r = report(&out);
    let cells = ran(&r);
    assert_eq!(cells.len(), want);
    let ids: std::collections::HashSet<&str> =
        cells.iter().map(|c| c["id"].as_str().unwrap()).collect();
    assert_eq!(ids.len(), want, "every cell distinct");
    let copies = cells.iter().filter(|c| c["id"].as_str().unwrap().ends_with(".copy-1")).count();
    assert_eq!(copies, want - n);
    assert!(cells.iter().all(|c| c["outcome"] == "pass"), "copies pass as their base cells do");
    assert_eq!(r["options"]["cells_scale"], want);
    // Below the matrix: the first cells only.
    let o3 = run(&[&args[..], &["--cells-scale", "1"]].concat());
    assert!(o3.status.success(), "{}", stderr(&o3));
    assert_eq!(ran(&report(&out)).len(), 1);
    // The twins: no count, or one past the limit, is a usage error and runs nothing.
    for bad in ["0", "100001"] {
        let e = run(&[
            "run",
            "--filter",
            COMPUTE,
            "--cells-scale",
            bad,
            "-o",
            dir.path().join("x.json").to_str().unwrap(),
        ]);
        assert_one_line_error(&e, 2, "--cells-scale must be 1..=100000");
        assert!(!dir.path().join("x.json").exists());
    }
}

#[test]
fn pipelines_auto_is_whole_on_lavapipe_and_linked_is_recorded() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let out = dir.path().join("r.json");
    let o = out.to_str().unwrap();
    let filter =
        "stage=raygen,resource=storage_buffer,index=literal,descriptor_model=descriptor_indexing";
    let auto = run(&["run", "--filter", filter, "--no-confirm", "--patches", "none", "-o", o]);
    assert!(auto.status.success(), "{}", stderr(&auto));
    let r = report(&out);
    assert_eq!(r["options"]["pipelines"], "whole", "a CPU device makes whole pipelines");
    let features = |r: &Value| -> Vec<String> {
        ran(r)[0]["attempts"][0]["device_features"]
            .as_array()
            .unwrap()
            .iter()
            .map(|f| f.as_str().unwrap().to_string())
            .collect()
    };
    assert!(!features(&r).iter().any(|f| f == "VK_KHR_pipeline_library"));
    // Linked on request: recorded, and the device enables the extension (its verdict on lavapipe
    // 25 is the driver's, see the module doc).
    let _ = run(&[
        "run",
        "--pipelines",
        "linked",
        "--filter",
        filter,
        "--no-confirm",
        "--patches",
        "none",
        "-o",
        o,
    ]);
    let r = report(&out);
    assert_eq!(r["options"]["pipelines"], "linked");
    assert!(features(&r).iter().any(|f| f == "VK_KHR_pipeline_library"));
}

fn sid_root() -> PathBuf {
    std::env::var_os("RTPROBE_SID_ROOT")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("/var/lib/rtprobe/sid-root"))
}

/// Whether the sid root exists and may be entered (as in tests/heap.rs).
fn have_sid() -> bool {
    let can_chroot = unsafe { libc::geteuid() } == 0
        || Command::new("sudo").args(["-n", "true"]).output().is_ok_and(|o| o.status.success());
    let ok = sid_root().join("etc/rtprobe-sid.stamp").exists() && can_chroot;
    if !ok && std::env::var("RTPROBE_REQUIRE_SID").is_ok_and(|v| v == "1") {
        panic!("RTPROBE_REQUIRE_SID=1 but there is no sid root at {}", sid_root().display());
    }
    if !ok {
        eprintln!("skipped: no sid root at {}", sid_root().display());
    }
    ok
}

fn in_sid(args: &[&str]) -> Output {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/in-sid");
    Command::new(script)
        .arg("rtprobe")
        .args(args)
        .env("RTPROBE_CACHE_DIR", cache_dir())
        .env_remove("RUST_LOG")
        .output()
        .expect("scripts/in-sid")
}

/// Every ray tracing stage's probe, linked from group libraries on lavapipe 26, gives the
/// verdicts whole pipelines give: each shader group's handle lands where the SBT expects it (a
/// group out of order would run another stage's shader: the records would say so).
#[test]
fn linked_pipelines_give_whole_pipelines_verdicts_on_lavapipe_26() {
    if !have_sid() {
        return;
    }
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/test-pipelines");
    std::fs::create_dir_all(&dir).unwrap();
    let filter = "stage=raygen|miss|closest_hit|any_hit|intersection|callable,resource=storage_buffer,index=literal|dynamic,nonuniform=true|false,descriptor_model=descriptor_indexing";
    let mut verdicts = vec![];
    for mode in ["linked", "whole"] {
        let out = dir.join(format!("{mode}.json"));
        let o = in_sid(&[
            "run",
            "--pipelines",
            mode,
            "--filter",
            filter,
            "--no-confirm",
            "--patches",
            "none",
            "-o",
            out.to_str().unwrap(),
        ]);
        assert!(o.status.success() || o.status.code() == Some(1), "{}", stderr(&o));
        let r = report(&out);
        assert_eq!(r["options"]["pipelines"], mode);
        let mut v: Vec<(String, String)> = ran(&r)
            .iter()
            .map(|c| {
                (c["id"].as_str().unwrap().to_string(), c["outcome"].as_str().unwrap().to_string())
            })
            .collect();
        v.sort();
        assert!(v.len() >= 6, "{mode}: {} cells", v.len());
        verdicts.push(v);
    }
    assert_eq!(verdicts[0], verdicts[1]);
    assert!(verdicts[0].iter().all(|(_, o)| o == "pass"), "{:?}", verdicts[0]);
}
