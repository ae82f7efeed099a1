//! The Amber scripts of descriptor-indexing ray tracing cells (issue 30). Lavapipe runs the cells
//! with `--dump`, which keeps the records each trace wrote; `rtprobe repro` writes each cell's
//! `cell.amber`, and every EXPECT of it must hold against those records, read as Amber's verifier
//! reads them (`report::amber::check`). A planted wrong expectation fails the same check, and so do
//! the records of a driver that reads the wrong value (an injected fault). Where an Amber binary is
//! installed (`RTPROBE_AMBER`, or `amber` on PATH: Amber is not packaged in Debian), Amber itself
//! runs every script on the same driver, and fails the planted one.
mod common;
use common::*;
use rtprobe::model::Cell;
use rtprobe::report::amber::{check, script, RECORDS};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

const FILTER: &str = "stage=raygen|closest_hit|any_hit|miss|intersection|callable,resource=storage_buffer|uniform_buffer,index=push_constant|dynamic,descriptor_model=descriptor_indexing,reorder=none";
/// One cell read wrong on purpose (an injected wrong value): its records must fail its script.
const WRONG: &str = "stage=miss,resource=storage_buffer,index=push_constant@value";
const WRONG_ID: &str = "miss.storage_buffer.push_constant.descriptor_indexing";
/// The cell the planted expectation goes into.
const PLANTED_ID: &str = "closest_hit.storage_buffer.dynamic.nonuniform.descriptor_indexing";

struct Run {
    /// Removed when the test process exits (a `static`'s `TempDir` is never dropped: this
    /// suite's folder once stayed in /tmp after every run).
    dir: PathBuf,
    v: serde_json::Value,
    /// Per cell of the run: its id, its script (None: refused) and the README's line on it.
    bundles: Vec<(String, Option<String>, String)>,
}

/// The run, its `--dump` folder, its report and every cell's bundle (shared by the tests).
fn shared() -> &'static Run {
    static S: OnceLock<Run> = OnceLock::new();
    S.get_or_init(|| {
        let dir = tempdir_until_exit();
        let report = dir.join("r.json");
        let dump = dir.join("dump");
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
        let bundles = v["cells"]
            .as_array()
            .unwrap()
            .iter()
            .map(|c| {
                let id = c["id"].as_str().unwrap().to_string();
                let bundle = dir.join("bundles").join(&id);
                let r = report.to_str().unwrap();
                let o = run(&["repro", &id, "--from", r, "-o", bundle.to_str().unwrap()]);
                assert_eq!(o.status.code(), Some(0), "{id}: {}", stderr(&o));
                let readme = std::fs::read_to_string(bundle.join("README.txt")).unwrap();
                let line = readme.lines().find(|l| l.contains("cell.amber")).unwrap_or("");
                let script = std::fs::read_to_string(bundle.join("cell.amber")).ok();
                (id, script, line.to_string())
            })
            .collect();
        Run { dir, v, bundles }
    })
}

fn cell_report<'a>(r: &'a Run, id: &str) -> &'a serde_json::Value {
    r.v["cells"].as_array().unwrap().iter().find(|c| c["id"] == id).unwrap()
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

/// `script` with the probed value.z of its first probed hit's EXPECT one slot off (the value
/// 1000 + 4·slot + element): (the planted script, its 1-based line).
fn plant(script: &str) -> (String, usize) {
    let k = script
        .lines()
        .position(|l| l.starts_with("EXPECT records IDX ") && l.split(' ').nth(7) == Some("3"))
        .expect("an EXPECT of a probed hit");
    let mut lines: Vec<String> = script.lines().map(String::from).collect();
    let mut w: Vec<String> = lines[k].split(' ').map(String::from).collect();
    let z: f32 = w[21].parse().unwrap();
    w[21] = format!("{:?}", z + 4.0);
    lines[k] = w.join(" ");
    (lines.join("\n") + "\n", k + 1)
}

#[test]
fn every_expect_of_every_ray_tracing_script_holds_against_rtprobes_records() {
    let r = shared();
    let dump = r.dir.join("dump");
    let mut scripts = 0;
    for (id, script, _) in &r.bundles {
        let Some(amber) = script else { continue };
        let c = cell_report(r, id);
        assert!(amber.contains("ACCELERATION_STRUCTURE TOP_LEVEL scene\n"), "{id}");
        assert_eq!(c["outcome"], "pass", "{id}: lavapipe passes every plain cell here");
        let n = assert_expectations_hold(id, amber, &records(&dump, id));
        let compared =
            c["attempts"][0]["result"]["comparison"]["compared"].as_u64().unwrap() as usize;
        // An EXPECT per pixel the reference can state; the run compared about as many (it
        // also leaves out pixels whose recorded hit is ambiguous).
        assert!(n + 16 >= compared && n <= compared + 16, "{id}: {n} EXPECTs, {compared} compared");
        scripts += 1;
    }
    // Every plain cell of the filter has a script but the one read wrong on purpose (an
    // injected fault); the bases from the shader record or a buffer are refused with what
    // AmberScript lacks; so are the scene-layout cells (an address in push constants, or the
    // per-mesh buffers rtprobe does not write).
    let refused: Vec<_> = r.bundles.iter().filter(|(_, s, _)| s.is_none()).collect();
    assert_eq!(scripts, 35, "{refused:?}");
    assert_eq!(refused.len(), 11, "{refused:?}");
    let why = |id: &str| -> &str {
        match id.rsplit('.').next() {
            Some("base_shader_record") => "no shader record data",
            Some("base_buffer") => "device addresses from push constants (baseAddress)",
            Some("shared_buffers") => "device addresses from push constants (sceneDesc)",
            Some("per_mesh") => "per-mesh scene buffers",
            _ => "injected fault",
        }
    };
    assert!(refused.iter().all(|(id, _, line)| line.contains(why(id))), "{refused:?}");
}

/// The twin: one planted wrong value in an EXPECT fails the check on that line.
#[test]
#[should_panic(expected = "1 of ")]
fn a_planted_wrong_expectation_fails() {
    let r = shared();
    let (_, script, _) = r.bundles.iter().find(|(id, _, _)| id == PLANTED_ID).unwrap();
    let (planted, _) = plant(script.as_ref().unwrap());
    assert_expectations_hold(PLANTED_ID, &planted, &records(&r.dir.join("dump"), PLANTED_ID));
}

/// The records of a driver that read a wrong value fail the cell's script (its own bundle has
/// none: an injected fault is not reproducible in Amber; the script is the plain cell's).
#[test]
fn a_wrong_read_fails_the_script() {
    let r = shared();
    let c = cell_report(r, WRONG_ID);
    assert_eq!(c["outcome"], "mismatch", "{c}");
    let cell = Cell::parse_id(WRONG_ID).unwrap();
    let shaders = rtprobe::report::shaders::cell_shaders(&cell, None, false).unwrap();
    let params: rtprobe::model::SceneParams =
        serde_json::from_value(r.v["scene"]["params"].clone()).unwrap();
    let amber = script(&cell, &shaders, &params, None, false, "test").unwrap();
    let (failures, _) = check(&amber, RECORDS, &records(&r.dir.join("dump"), WRONG_ID)).unwrap();
    let mismatched =
        c["attempts"][0]["result"]["comparison"]["mismatched_pixels"].as_u64().unwrap() as usize;
    assert!(
        failures.len() >= mismatched && mismatched > 0,
        "{} failures, {mismatched} pixels",
        failures.len()
    );
}

/// The Amber binary, where one is installed: `RTPROBE_AMBER`, else `amber` on PATH.
fn amber_bin() -> Option<PathBuf> {
    if let Some(p) = std::env::var_os("RTPROBE_AMBER") {
        return Some(PathBuf::from(p));
    }
    std::env::var_os("PATH")?
        .to_str()?
        .split(':')
        .map(|d| Path::new(d).join("amber"))
        .find(|p| p.is_file())
}

/// `amber -d -v 1.2 SCRIPT`: whether it passed, and its output.
fn amber(bin: &Path, script: &Path) -> (bool, String) {
    let o = std::process::Command::new(bin)
        .args(["-d", "-v", "1.2"])
        .arg(script)
        .output()
        .expect("spawn amber");
    let out = stdout(&o) + &stderr(&o);
    (o.status.success() && out.contains("Summary: 1 pass, 0 fail"), out)
}

#[test]
fn amber_itself_passes_every_script_and_fails_the_planted_one() {
    let Some(bin) = amber_bin() else {
        eprintln!("no Amber here (RTPROBE_AMBER, or amber on PATH): skipped");
        return;
    };
    let r = shared();
    let mut ran = 0;
    for (id, script, _) in &r.bundles {
        if script.is_none() {
            continue;
        }
        let path = r.dir.join("bundles").join(id).join("cell.amber");
        let (passed, out) = amber(&bin, &path);
        assert!(passed, "{id}: {out}");
        eprintln!("amber {}: {id}: passed", bin.display());
        ran += 1;
    }
    assert_eq!(ran, 35);
    let (_, script, _) = r.bundles.iter().find(|(id, _, _)| id == PLANTED_ID).unwrap();
    let (planted, line) = plant(script.as_ref().unwrap());
    let path = r.dir.join("planted.amber");
    std::fs::write(&path, planted).unwrap();
    let (passed, out) = amber(&bin, &path);
    assert!(!passed && out.contains(&format!("Line {line}: Verifier failed: ")), "{out}");
    let why = out.lines().find(|l| l.contains("Verifier failed")).unwrap_or_default();
    eprintln!("amber: {ran} scripts passed; the planted one failed: {why}");
}
