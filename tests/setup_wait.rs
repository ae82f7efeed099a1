//! A worker's setup waits for the scene's acceleration-structure build as long as the
//! supervisor's setup deadline allows, never only a cell's fence deadline, and never frees what a
//! build it gave up on may still read. lavapipe 26 (the Debian sid root of scripts/setup-sid)
//! builds acceleration structures with compute shaders that a worker compiling afresh (`--confirm`
//! and the other re-runs alone: driver cache off) compiles first, 1.7 s on a quiet machine: before,
//! the build's fence wait ran out at the cell's deadline, the scratch buffers were freed under the
//! running build and the worker died of SIGSEGV in setup, so every confirm of a crashing heap cell
//! on a loaded machine read "not run" (reports/lavapipe-26/FINDINGS.md). Skips without the root,
//! unless RTPROBE_REQUIRE_SID=1.
mod common;
use common::*;
use std::path::Path;
use std::process::Command;

/// The runs of one RT cell with a `--timeout` far below the build's time, and their report: every
/// worker must get past setup, and each attempt must reach the cell.
#[test]
fn sid_a_slow_acceleration_structure_build_is_no_setup_crash() {
    if !have_sid() {
        return;
    }
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = repo.join("target/setup-wait-tests");
    std::fs::create_dir_all(&dir).unwrap();
    let report = dir.join(format!("slow-build-{}.json", std::process::id()));
    let _ = std::fs::remove_file(&report);
    // --timeout 0.1: the cell's fence deadline is 100 ms, shorter than lavapipe 26's AS build;
    // the injected crash makes the cell fault, so it is confirmed in a fresh worker (driver cache
    // off: the build shaders compile again there).
    let o = Command::new(repo.join("scripts/in-sid"))
        .arg(env!("CARGO_BIN_EXE_rtprobe"))
        .args(["run", "-o", report.to_str().unwrap(), "--patches", "none", "--timeout", "0.1"])
        .args(["--filter", "stage=raygen,resource=storage_buffer,index=literal"])
        .args(["--filter", "descriptor_model=descriptor_indexing"])
        .args(["--inject-fault", "stage=raygen@device"])
        .env_remove("RUST_LOG")
        .env_remove("RTPROBE_VALIDATE")
        .env_remove("RTPROBE_INJECT_FAULT")
        .output()
        .expect("spawn scripts/in-sid");
    let bytes =
        std::fs::read(&report).unwrap_or_else(|e| panic!("no report ({e}): {}", stderr(&o)));
    let r: serde_json::Value = serde_json::from_slice(&bytes).unwrap();
    let workers = r["workers"].as_array().unwrap();
    let setups: Vec<_> = workers.iter().filter(|w| w["phase"] == "setup").collect();
    assert!(setups.len() >= 2, "the matrix worker and the confirm's: {workers:?}");
    for w in &setups {
        assert_eq!(w["outcome"], "pass", "a setup failed: {w}");
    }
    let cell = &r["cells"][0];
    let attempts = cell["attempts"].as_array().unwrap();
    assert_eq!(attempts.len(), 2, "the matrix attempt and its confirmation: {cell}");
    assert!(attempts.iter().any(|a| a["isolated"] == true), "{cell}");
    for a in attempts {
        assert_ne!(a["phase"], "setup", "an attempt did not reach the cell: {a}");
        assert_ne!(a["outcome"], "pass", "the injected fault was not seen: {a}");
    }
    let _ = std::fs::remove_file(&report);
}
