//! The Amber scripts of descriptor-indexing ray tracing cells (issue 30), checked without Amber
//! (not packaged in Debian): lavapipe runs the cells with `--dump`, which keeps the records each
//! trace wrote; `rtprobe repro` writes each cell's `cell.amber`, and every EXPECT of it must hold
//! against those records, read as Amber's verifier reads them (`report::amber::check`). A planted
//! wrong expectation fails the same check, and so do the records of a driver that reads the wrong
//! value (an injected fault).
mod common;
use common::*;
use rtprobe::model::Cell;
use rtprobe::report::amber::{check, script, RECORDS};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

const FILTER: &str = "stage=raygen|closest_hit|any_hit|miss|intersection|callable,resource=storage_buffer|uniform_buffer,index=push_constant|dynamic,descriptor_model=descriptor_indexing,reorder=none";
/// One cell read wrong on purpose (an injected wrong value): its records must fail its script.
const WRONG: &str = "stage=miss,resource=storage_buffer,index=push_constant@value";

/// The run, its `--dump` folder, and the report (shared by the tests).
fn shared() -> &'static (tempfile::TempDir, PathBuf, serde_json::Value) {
    static S: OnceLock<(tempfile::TempDir, PathBuf, serde_json::Value)> = OnceLock::new();
    S.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let report = dir.path().join("r.json");
        let dump = dir.path().join("dump");
        let o = run(&[
            "run",
            "--patches",
            "none",
            "--no-confirm",
            "--filter",
            FILTER,
            "--inject-fault",
            WRONG,
            "--dump",
            dump.to_str().unwrap(),
            "-o",
            report.to_str().unwrap(),
        ]);
        assert_eq!(o.status.code(), Some(1), "{}\n{}", stdout(&o), stderr(&o));
        let v: serde_json::Value =
            serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
        (dir, report, v)
    })
}

fn records(dump: &Path, id: &str) -> Vec<u8> {
    std::fs::read(dump.join(id).join("records.bin")).unwrap_or_else(|e| panic!("{id}: {e}"))
}

/// Every EXPECT of `amber` holds against `bytes`; the number of EXPECTs.
fn assert_expectations_hold(id: &str, amber: &str, bytes: &[u8]) -> usize {
    let (failures, n) = check(amber, RECORDS, bytes).unwrap_or_else(|e| panic!("{id}: {e}"));
    assert!(
        failures.is_empty(),
        "{id}: {} of {n} EXPECTs fail, first: {}",
        failures.len(),
        failures[0]
    );
    assert!(n > 0, "{id}: no EXPECT");
    n
}

#[test]
fn every_expect_of_every_ray_tracing_script_holds_against_rtprobes_records() {
    let (dir, report, v) = shared();
    let dump = dir.path().join("dump");
    let (mut scripts, mut refused) = (0, vec![]);
    for c in v["cells"].as_array().unwrap() {
        let id = c["id"].as_str().unwrap();
        let bundle = dir.path().join("bundles").join(id);
        let o =
            run(&["repro", id, "--from", report.to_str().unwrap(), "-o", bundle.to_str().unwrap()]);
        assert_eq!(o.status.code(), Some(0), "{id}: {}", stderr(&o));
        let Ok(amber) = std::fs::read_to_string(bundle.join("cell.amber")) else {
            let readme = std::fs::read_to_string(bundle.join("README.txt")).unwrap();
            refused.push((
                id.to_string(),
                readme.lines().find(|l| l.contains("no cell.amber")).unwrap_or("").to_string(),
            ));
            continue;
        };
        assert!(amber.contains("ACCELERATION_STRUCTURE TOP_LEVEL scene\n"), "{id}");
        scripts += 1;
        assert_eq!(c["outcome"], "pass", "{id}: lavapipe passes every plain cell here");
        let n = assert_expectations_hold(id, &amber, &records(&dump, id));
        let compared =
            c["attempts"][0]["result"]["comparison"]["compared"].as_u64().unwrap() as usize;
        // An EXPECT per pixel the reference can state; the run compared about as many (it
        // also leaves out pixels whose recorded hit is ambiguous).
        assert!(n + 16 >= compared && n <= compared + 16, "{id}: {n} EXPECTs, {compared} compared");
    }
    // Every plain cell of the filter has a script but the one read wrong on purpose (an
    // injected fault); the bases from the shader record or a buffer are refused with what
    // AmberScript lacks.
    assert_eq!(scripts, 35, "{refused:?}");
    assert_eq!(refused.len(), 9, "{refused:?}");
    let why = |id: &str| -> &str {
        match id.rsplit('.').next() {
            Some("base_shader_record") => "no shader record data",
            Some("base_buffer") => "device addresses from push constants (baseAddress)",
            _ => "injected fault",
        }
    };
    assert!(refused.iter().all(|(id, line)| line.contains(why(id))), "{refused:?}");
}

/// The twin: one planted wrong value in an EXPECT fails the check on that line.
#[test]
#[should_panic(expected = "1 of ")]
fn a_planted_wrong_expectation_fails() {
    let (dir, report, _) = shared();
    let id = "closest_hit.storage_buffer.dynamic.nonuniform.descriptor_indexing";
    let bundle = dir.path().join("planted");
    let o = run(&["repro", id, "--from", report.to_str().unwrap(), "-o", bundle.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let amber = std::fs::read_to_string(bundle.join("cell.amber")).unwrap();
    // The first EXPECT of a probed hit: its value.z (1000 + 4·slot + element) one slot off.
    let hit = amber
        .lines()
        .find(|l| l.starts_with("EXPECT records IDX ") && l.split(' ').nth(7) == Some("3"))
        .unwrap();
    let mut w: Vec<String> = hit.split(' ').map(String::from).collect();
    let z: f32 = w[21].parse().unwrap();
    w[21] = format!("{:?}", z + 4.0);
    let planted = amber.replacen(hit, &w.join(" "), 1);
    assert_expectations_hold(id, &planted, &records(&dir.path().join("dump"), id));
}

/// The records of a driver that read a wrong value fail the cell's script (its own bundle has
/// none: an injected fault is not reproducible in Amber; the script is the plain cell's).
#[test]
fn a_wrong_read_fails_the_script() {
    let (dir, _, v) = shared();
    let id = "miss.storage_buffer.push_constant.descriptor_indexing";
    let c = v["cells"].as_array().unwrap().iter().find(|c| c["id"] == id).unwrap();
    assert_eq!(c["outcome"], "mismatch", "{c}");
    let cell = Cell::parse_id(id).unwrap();
    let shaders = rtprobe::report::shaders::cell_shaders(&cell, None, false).unwrap();
    let params: rtprobe::model::SceneParams =
        serde_json::from_value(v["scene"]["params"].clone()).unwrap();
    let amber = script(&cell, &shaders, &params, None, false, "test").unwrap();
    let (failures, _) = check(&amber, RECORDS, &records(&dir.path().join("dump"), id)).unwrap();
    let mismatched =
        c["attempts"][0]["result"]["comparison"]["mismatched_pixels"].as_u64().unwrap() as usize;
    assert!(
        failures.len() >= mismatched && mismatched > 0,
        "{} failures, {mismatched} pixels",
        failures.len()
    );
}
