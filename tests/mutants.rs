//! `run --mutants` on lavapipe: CI's share of the kill matrix (a seeded sample of the applicable
//! (cell, mutant) pairs, in well under 3 minutes on a 2-core machine): every sampled mutant that
//! must be caught is killed by a real mismatch, survivors are only those the cell's own rule
//! allows (with the rule), no mutant attempt joins a cell's own; bad mutant arguments are one
//! line and exit 2.
mod common;
use common::*;
use serde_json::Value;
use std::time::{Duration, Instant};

/// The share CI runs: set-based cells of three stages (every mutant but the heap's sampler index
/// has a target among them), 24 applicable pairs drawn with seed 3.
// (bases from push data or none: lavapipe 25's closest-hit cells with their base in the shader
// record or a buffer mismatch without nonuniformEXT, lane 0's index read while lane 0 is inactive)
const FILTER: &str =
    "stage=raygen|closest_hit|compute,descriptor_model=descriptor_indexing,base=none|push_data";
const SAMPLE: &str = "24:3";

#[test]
fn a_sampled_share_of_the_mutants_is_all_caught_in_under_three_minutes() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let out = dir.path().join("r.json");
    let t = Instant::now();
    let o =
        run(&["run", "--filter", FILTER, "--mutants-sample", SAMPLE, "-o", out.to_str().unwrap()]);
    let wall = t.elapsed();
    assert_eq!(o.status.code(), Some(0), "{}\n{}", stdout(&o), stderr(&o));
    assert!(wall < Duration::from_secs(180), "CI's share took {wall:?}");
    let text = stdout(&o);
    assert!(text.contains("mutants: ") && !text.contains("PROBE DEFECT"), "{text}");
    let r: Value = serde_json::from_slice(&std::fs::read(&out).unwrap()).unwrap();
    assert_eq!(r["options"]["mutants_sample"], SAMPLE);
    let m = &r["mutants"];
    let entries = m["entries"].as_array().unwrap();
    let status = |e: &Value| e["status"].as_str().unwrap().to_string();
    let ran: Vec<&Value> = entries.iter().filter(|e| !e["outcome"].is_null()).collect();
    assert_eq!(ran.len(), 24, "the sample's pairs ran");
    for e in &ran {
        let p = &e["prediction"];
        match status(e).as_str() {
            // A kill is a real mismatch the reference predicted.
            "killed" => {
                assert!(e["outcome"] == "mismatch" && p["caught"].as_u64().unwrap() > 0, "{e}")
            }
            // A survivor only where the cell's rule allows every differing pixel, with the rule.
            "survived" => assert!(
                e["probe_defect"].is_null()
                    && e["allowed_by"].as_str().unwrap().starts_with("VUID-")
                    && p["caught"] == 0,
                "{e}"
            ),
            other => panic!("{other}: {e}"),
        }
    }
    assert!(ran.iter().any(|e| status(e) == "killed"));
    let total = |k: &str| {
        m["counts"].as_object().unwrap().values().map(|c| c[k].as_u64().unwrap()).sum::<u64>()
    };
    assert_eq!((total("probe_defects"), total("faults")), (0, 0));
    assert_eq!(total("killed") + total("survived"), 24);
    // Every pair of a sampled cell has its verdict, the unrun ones with why: not applicable, or
    // a broadcast where lavapipe lists no subgroup ballot (its ray tracing stages).
    for e in entries.iter().filter(|e| e["outcome"].is_null()) {
        let why = e["why"].as_str().unwrap();
        let ok = match status(e).as_str() {
            "equivalent" | "no_target" => !why.is_empty(),
            "not_run" => {
                e["mutant"] == "index-broadcast" && why.contains("VUID-RuntimeSpirv-None-06343")
            }
            _ => false,
        };
        assert!(ok, "{e}");
    }
    // The cells' own verdicts: the plan's cells only, each with its one passing attempt.
    for c in r["cells"].as_array().unwrap().iter().filter(|c| c["outcome"] == "pass") {
        assert!(c["mutant"].is_null() && c["attempts"].as_array().unwrap().len() == 1, "{c}");
    }
}

#[test]
fn bad_mutant_arguments_are_one_line_and_exit_2() {
    let o = run(&["run", "--mutant", "index-one", "--list"]);
    assert_one_line_error(&o, 2, "unknown mutant \"index-one\"");
    let o = run(&["run", "--mutants-sample", "0:1", "--list"]);
    assert_one_line_error(&o, 2, "N must be at least 1");
    let o = run(&["run", "--mutants-sample", "x", "--list"]);
    assert_one_line_error(&o, 2, "is not N[:SEED]");
}
