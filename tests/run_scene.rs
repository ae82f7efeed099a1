//! `run --scene` on lavapipe: the test scene written by `scene make`, a filtered matrix run on it
//! and on the procedural scene; every cell gets the same verdict on both, the scene is recorded
//! (path and content hash), the cells the scene cannot discriminate are named with why, and a
//! broken scene is the loader's one line before any device work.
mod common;
use common::*;
use serde_json::Value;
use std::collections::BTreeMap;

/// CI's share: raygen, closest-hit and intersection cells on storage buffers, set-based.
const FILTER: &str =
    "stage=raygen|closest_hit|intersection,descriptor_model=descriptor_indexing,resource=storage_buffer";

fn outcomes(r: &Value) -> BTreeMap<String, String> {
    r["cells"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| (c["id"].as_str().unwrap().into(), c["outcome"].as_str().unwrap().into()))
        .collect()
}

#[test]
fn the_test_scene_gives_the_procedural_verdicts_and_names_its_limits() {
    let dir = tempfile::tempdir().unwrap();
    let o = run(&["scene", "make", dir.path().to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let scene = dir.path().join("scene.gltf");
    let (s, p) = (dir.path().join("s.json"), dir.path().join("p.json"));
    let o = run(&[
        "run",
        "--scene",
        scene.to_str().unwrap(),
        "--filter",
        FILTER,
        "-o",
        s.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}\n{}", stdout(&o), stderr(&o));
    assert!(stdout(&o).contains("undiscriminating: "), "{}", stdout(&o));
    let o_scene = o;
    let o = run(&["run", "--filter", FILTER, "-o", p.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let read = |p: &std::path::Path| -> Value {
        serde_json::from_slice(&std::fs::read(p).unwrap()).unwrap()
    };
    let (rs, rp) = (read(&s), read(&p));
    let (a, b) = (outcomes(&rs), outcomes(&rp));
    assert!(!a.is_empty());
    assert_eq!(a, b, "every cell: the procedural verdict");
    let file = &rs["scene"]["params"]["file"];
    assert_eq!(file["hash"].as_str().unwrap().len(), 32);
    assert_eq!(rs["scene"]["instances"], 5);
    assert!(rp["scene"]["params"]["file"].is_null() && rp["scene"]["limits"].is_null());
    let limits = rs["scene"]["limits"].as_array().unwrap();
    let named = |needle: &str| -> Vec<String> {
        limits
            .iter()
            .filter(|l| l["why"].as_str().unwrap().contains(needle))
            .flat_map(|l| {
                l["cells"].as_array().unwrap().iter().map(|c| c.as_str().unwrap().to_string())
            })
            .collect()
    };
    let intersection: Vec<&String> = a.keys().filter(|k| k.starts_with("intersection.")).collect();
    assert!(!intersection.is_empty());
    assert_eq!(named("no procedural").len(), intersection.len());
    assert!(named("custom index").iter().all(|c| c.starts_with("closest_hit.")));
    assert!(!named("custom index").is_empty());
    assert!(cost_is_measured(&rs["scene"]["cost"]));
    assert!(as_build_is_timed(&rs["timing"]), "{}", rs["timing"]);
    assert!(stdout(&o_scene).contains("AS build "), "{}", stdout(&o_scene));
}

/// Every worker built the scene's AS, timed apart from (and within) its device setup.
fn as_build_is_timed(t: &Value) -> bool {
    let (mean, max) =
        (t["as_build_ms_mean"].as_f64().unwrap(), t["as_build_ms_max"].as_f64().unwrap());
    t["as_builds"] == t["workers_started"]
        && t["as_builds"].as_u64().is_some_and(|n| n > 0)
        && mean > 0.0
        && max >= mean
        && mean <= t["device_ms_mean"].as_f64().unwrap()
}

/// The AS build's twin: a worker whose cells never trace the scene builds no AS, and the report
/// says so instead of a made-up time.
#[test]
fn a_run_that_traces_no_scene_times_no_as_build() {
    let dir = tempfile::tempdir().unwrap();
    let r = dir.path().join("c.json");
    let filter =
        "stage=compute,descriptor_model=descriptor_indexing,resource=storage_buffer,index=literal";
    let o = run(&["run", "--filter", filter, "-o", r.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let rep: Value = serde_json::from_slice(&std::fs::read(&r).unwrap()).unwrap();
    let t = &rep["timing"];
    assert!(t["workers_started"].as_u64().is_some_and(|n| n > 0), "{t}");
    assert_eq!(t["as_builds"], 0, "{t}");
    assert!(!as_build_is_timed(t));
    assert!(!stdout(&o).contains("AS build"), "{}", stdout(&o));
}

fn cost_is_measured(c: &Value) -> bool {
    c["load_ms"].as_f64().is_some_and(|x| x >= 0.0)
        && c["reference_ms"].as_f64().is_some_and(|x| x > 0.0)
}

#[test]
fn a_broken_scene_is_one_line_before_the_device() {
    let o = run(&["run", "--scene", "/nonexistent.glb", "--filter", FILTER]);
    assert_one_line_error(&o, 9, "cannot read scene");
}
