//! Every file rtprobe wrote and reads back still loads into the typed data layer (`model`): run
//! reports, bisections, baselines and repro bundles' `cell.json`, from `reports/`, `baselines/`
//! and the fixtures of earlier releases (`tests/fixtures/compat/`). Each is read by its `schema`,
//! written back, and read again: no field it held may be lost or changed (the JSON written back
//! holds every value of the original; fields newer than the file may be added), and a second
//! round trip changes nothing. Files rtprobe writes but never reads back (caps, stress, bench and
//! the Khronos profiles) must still carry a known schema, so that a new kind of file is sorted
//! here before it ships.
mod common;
use common::*;
use rtprobe::model::bundle::CellSpec;
use rtprobe::model::{Baseline, BisectFile, RunReport};
use serde::de::DeserializeOwned;
use serde::Serialize;
use serde_json::Value;
use std::path::{Path, PathBuf};

/// Schemas of files rtprobe writes and never loads as a whole (they are for people and scripts).
const WRITE_ONLY: &[&str] = &[
    "rtprobe.caps/1",
    "rtprobe.caps/2",
    "rtprobe.stress/1",
    "rtprobe.stress/2",
    "rtprobe.stress/3",
    "rtprobe.bench/1",
];

fn json_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let p = e.path();
        // reports/tmp/ is scratch space (git ignores it): what a developer left there is no
        // release's output.
        if p.is_dir() && !p.ends_with("reports/tmp") {
            json_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "json") {
            out.push(p);
        }
    }
}

/// Whether every value of `old` stands in `new` at the same place (`new` may hold more keys).
fn holds(old: &Value, new: &Value, at: &str) -> Result<(), String> {
    match (old, new) {
        (Value::Object(a), Value::Object(b)) => a.iter().try_for_each(|(k, v)| match b.get(k) {
            Some(w) => holds(v, w, &format!("{at}.{k}")),
            None => Err(format!("{at}.{k} was dropped")),
        }),
        (Value::Array(a), Value::Array(b)) if a.len() == b.len() => a
            .iter()
            .zip(b)
            .enumerate()
            .try_for_each(|(i, (v, w))| holds(v, w, &format!("{at}[{i}]"))),
        (a, b) if a == b => Ok(()),
        (a, b) => Err(format!("{at}: {a} became {b}")),
    }
}

fn round_trip<T: DeserializeOwned + Serialize>(v: &Value) -> Result<(), String> {
    let typed: T = serde_json::from_value(v.clone()).map_err(|e| format!("does not load: {e}"))?;
    let back = serde_json::to_value(&typed).map_err(|e| e.to_string())?;
    holds(v, &back, "")?;
    let again: T = serde_json::from_value(back.clone())
        .map_err(|e| format!("its own output does not load: {e}"))?;
    let twice = serde_json::to_value(&again).map_err(|e| e.to_string())?;
    (back == twice).then_some(()).ok_or_else(|| "a second round trip changed it".into())
}

/// Load the file at `path` with the loader rtprobe itself uses for its schema (which also checks
/// the schema, and for a bundle the id, the scene and that its SPIR-V is there).
fn load(path: &Path, schema: &str) -> Result<(), String> {
    match schema {
        s if s == rtprobe::model::report::SCHEMA => {
            RunReport::load(path).map(|_| ()).map_err(|e| e.to_string())
        }
        s if s == rtprobe::model::bisection::SCHEMA => {
            BisectFile::load(path).map(|_| ()).map_err(|e| e.to_string())
        }
        s if s == rtprobe::model::baseline::SCHEMA => {
            Baseline::parse(&path.display().to_string(), &std::fs::read_to_string(path).unwrap())
                .map(|_| ())
                .map_err(|e| e.to_string())
        }
        s if s == rtprobe::model::bundle::SCHEMA => CellSpec::load(path)
            .and_then(|c| c.spirv_dir(path))
            .map(|_| ())
            .map_err(|e| e.to_string()),
        _ => Ok(()),
    }
}

/// Load `v` by its schema; `Ok(false)` for a write-only file.
fn check(v: &Value) -> Result<bool, String> {
    let schema = v.get("schema").or_else(|| v.get("$schema")).and_then(Value::as_str).unwrap_or("");
    match schema {
        s if s == rtprobe::model::report::SCHEMA => round_trip::<RunReport>(v).map(|_| true),
        s if s == rtprobe::model::bisection::SCHEMA => round_trip::<BisectFile>(v).map(|_| true),
        s if s == rtprobe::model::baseline::SCHEMA => round_trip::<Baseline>(v).map(|_| true),
        s if s == rtprobe::model::bundle::SCHEMA => round_trip::<CellSpec>(v).map(|_| true),
        s if WRITE_ONLY.contains(&s)
            || s.starts_with("https://schema.khronos.org/vulkan/profiles") =>
        {
            Ok(false)
        }
        s => Err(format!("unknown schema {s:?}: load it here, or list it as write-only")),
    }
}

#[test]
fn every_file_an_earlier_release_wrote_still_loads() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut files = Vec::new();
    for d in ["reports", "baselines", "tests/fixtures/compat"] {
        json_files(&root.join(d), &mut files);
    }
    files.sort();
    let (mut loaded, mut write_only, mut failed) = (0, 0, Vec::new());
    for f in &files {
        let v: Value = serde_json::from_slice(&std::fs::read(f).unwrap())
            .unwrap_or_else(|e| panic!("{}: not JSON: {e}", f.display()));
        let schema = v.get("schema").and_then(Value::as_str).unwrap_or("");
        match check(&v).and_then(|typed| load(f, schema).map(|_| typed)) {
            Ok(true) => loaded += 1,
            Ok(false) => write_only += 1,
            Err(e) => failed.push(format!("{}: {e}", f.strip_prefix(root).unwrap_or(f).display())),
        }
    }
    println!(
        "compat: {} files, {loaded} loaded and round-tripped, {write_only} write-only",
        files.len()
    );
    assert!(failed.is_empty(), "{}", failed.join("\n"));
    // Each kind rtprobe reads back is among them (else this test would prove nothing about it).
    for kind in ["rtprobe.report/1", "rtprobe.bisect/1", "rtprobe.baseline/1", "rtprobe.cell/1"] {
        assert!(
            files.iter().any(|f| std::fs::read_to_string(f).unwrap().contains(kind)),
            "no {kind} file to check"
        );
    }
}

#[test]
fn a_dropped_or_changed_field_is_caught() {
    let old = serde_json::json!({"a": 1, "b": {"c": [1, 2], "d": "x"}});
    assert!(holds(&old, &serde_json::json!({"a": 1, "b": {"c": [1, 2], "d": "x", "e": null}}), "")
        .is_ok());
    assert!(holds(&old, &serde_json::json!({"a": 1, "b": {"c": [1, 2]}}), "")
        .unwrap_err()
        .contains(".b.d was dropped"));
    assert!(holds(&old, &serde_json::json!({"a": 1, "b": {"c": [1, 3], "d": "x"}}), "")
        .unwrap_err()
        .contains(".b.c[1]"));
    // A report whose options lose a field on the way through the typed model fails the check.
    let report =
        std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join("reports/lavapipe/run.json"))
            .unwrap();
    let mut v: Value = serde_json::from_slice(&report).unwrap();
    // Options of another release are kept; a field of the typed model that a report lacks takes
    // the default an untyped read gave it (the first reports had no `patches` or `inject`).
    v["options"]["not_a_field"] = Value::Bool(true);
    v["options"].as_object_mut().unwrap().remove("patches");
    v["options"].as_object_mut().unwrap().remove("inject");
    check(&v).unwrap();
    let r: RunReport = serde_json::from_value(v.clone()).unwrap();
    assert_eq!((r.options.patches, r.options.inject.len()), (rtprobe::model::PatchMode::Faults, 0));
    // A key the typed model does not hold is caught where nothing keeps unknown keys.
    v["cells"][0]["not_a_field"] = Value::Bool(true);
    assert!(check(&v).unwrap_err().contains("not_a_field was dropped"), "{:?}", check(&v));
    v["schema"] = "rtprobe.nonsense/9".into();
    assert!(check(&v).unwrap_err().contains("unknown schema"));
}

#[test]
fn a_bundle_an_earlier_release_wrote_runs_and_gives_its_verdict() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let spec = root.join("tests/fixtures/compat/bundle/cell.json");
    let original: Value = serde_json::from_slice(&std::fs::read(&spec).unwrap()).unwrap();
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let out = dir.path().join("rerun.json");
    let o = run(&["run", "--cell-spec", spec.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    assert!(o.status.code().is_some_and(|c| c <= 1), "{}", stderr(&o));
    let report: Value = serde_json::from_slice(&std::fs::read(&out).unwrap()).unwrap();
    let cell = report["cells"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["id"] == original["id"])
        .expect("the bundle's cell ran");
    // The bundle injects a wrong value on every pixel: the verdict it recorded is a mismatch.
    assert_eq!(cell["outcome"], original["original"]["outcome"]);
    assert_eq!(cell["outcome"], "mismatch");
}
