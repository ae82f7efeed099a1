//! `run --shader`'s descriptor-index check on lavapipe, with an engine-like closest-hit written
//! for these tests (`tests/shaders/user/object_table.rchit`: `textures[material.textureId +
//! object.textureOffset]`, two buffer words summed, as renderers that append each mesh's
//! textures to one bindless array index them). The harness's integer words are below 64 each,
//! so the sum reaches past a 64-element array: the check sizes runtime arrays up (the run
//! passes, the report says so), and refuses what it may not size — a `--array-size` the user
//! gave, a fixed-size array — in one line, exit 9, no report. Its twins: an in-bounds shader is
//! left at its size; the check's figure is the index the pipeline itself read
//! (`light_table.rchit` writes it: the check's buffer shifting the harness's data once made them
//! differ); a user raygen that traces its TLAS leaves the check on; and a shader without
//! `nonuniformEXT` whose `nonuniform` variant differs stays `patch_differs`, its detail saying
//! what the check saw of the index (on lavapipe, whose ray tracing stages have no subgroup vote,
//! its range over the trace) and the rule.
mod common;
use common::*;
use serde_json::Value;

fn run(
    files: &[&str],
    extra: &[&str],
) -> (std::process::Output, Option<Value>, rtprobe::tempdir::TempDir) {
    let d = rtprobe::tempdir::tempdir().unwrap();
    let mut args = vec!["--repeat", "2"];
    args.extend_from_slice(extra);
    let (o, report) = run_user_shaders(files, &d.path().join("report.json"), &args, &[]);
    (o, report, d)
}

fn variant<'a>(r: &'a Value, name: &str) -> &'a Value {
    r["variants"].as_array().unwrap().iter().find(|v| v["name"] == name).unwrap()
}

/// The sum reaches past 64: the runtime arrays are sized up to 128, the indices the check saw
/// are in the report (the texture array's above 64, so the size-up was needed), and the run
/// passes with no fault and no validation message — with the user's own raygen and miss, whose
/// TLAS and image loads are no descriptor-array access the check must follow.
#[test]
fn data_past_a_runtime_array_sizes_it_up_and_the_run_passes() {
    let files = ["raygen.rgen", "miss.rmiss", "object_table.rchit"];
    let (o, r, _d) = run(&files, &[]);
    let r = r.unwrap_or_else(|| panic!("no report: {}", stderr(&o)));
    assert_eq!(o.status.code(), Some(0), "{}{}", stdout(&o), stderr(&o));
    let b = &r["index_bounds"];
    assert_eq!(b["grown"], serde_json::json!([64, 128]), "{b}");
    let textures = b["arrays"].as_array().unwrap().iter().find(|a| a["binding"] == 2).unwrap();
    assert!(textures["seen"]["largest"].as_u64().unwrap() >= 64, "{textures}");
    assert!(textures["seen"]["largest"].as_u64().unwrap() < 128, "{textures}");
    assert_eq!(textures["elements"], 128);
    assert_eq!(r["options"]["array_size"], 128, "what ran, for reduce");
    assert!(stdout(&o).contains("runtime arrays sized 128 instead of 64"), "{}", stdout(&o));
    assert_eq!(variant(&r, "unpatched")["judgement"], "pass");
    // What ran is what `--array-size 128` runs: the same cell id.
    let (o, sized, _d) = run(&files, &["--array-size", "128"]);
    let sized = sized.unwrap_or_else(|| panic!("no report: {}", stderr(&o)));
    assert!(sized.get("index_bounds").unwrap().get("grown").is_none());
    assert_eq!(r["cell"], sized["cell"]);
}

/// The check's largest index is the one the unpatched pipeline read (the shader writes it to
/// `set 1 binding 2`): the check traces the variants' data.
#[test]
fn the_checks_index_is_the_one_the_pipeline_reads() {
    let (o, r, _d) = run(&["light_table.rchit"], &[]);
    let r = r.unwrap_or_else(|| panic!("no report: {}", stderr(&o)));
    assert_eq!(o.status.code(), Some(0), "{}{}", stdout(&o), stderr(&o));
    let data = variant(&r, "unpatched")["data"].as_array().unwrap();
    let used = data.iter().find(|d| d["label"] == "storage buffer set 1 binding 2[0]").unwrap();
    let bytes = unb64(used["bytes"].as_str().unwrap());
    let read = u32::from_le_bytes(bytes[..4].try_into().unwrap());
    let a = &r["index_bounds"]["arrays"][0];
    assert_eq!((a["set"].as_u64(), a["binding"].as_u64()), (Some(1), Some(1)), "{a}");
    assert_eq!(a["seen"]["largest"].as_u64(), Some(read as u64), "{a}");
    assert_eq!(a["seen"]["smallest"].as_u64(), Some(read as u64), "one light: {a}");
}

/// Twins that make the check fail: the user's own `--array-size 64` is not sized up, and a
/// fixed-size array cannot be; each is one line naming the binding and the rule, exit 9, and
/// no report.
#[test]
fn an_index_past_a_size_rtprobe_may_not_change_is_refused() {
    let cases: [(&[&str], &str); 2] = [
        (&["--array-size", "64"], "as --array-size gave"),
        (&["-D", "FIXED_TEXTURES=8"], "an array of 8"),
    ];
    for (extra, what) in cases {
        let (o, r, _d) = run(&["object_table.rchit"], extra);
        assert_one_line_error(&o, 9, "set 1 binding 2");
        let e = stderr(&o);
        assert!(e.contains(what) && e.contains("undefined"), "{extra:?}: {e}");
        assert!(r.is_none(), "{extra:?}: no report");
    }
}

/// A shader whose indices stay inside (the bindless test shader masks its bases) keeps the
/// harness's size, and the check records what it saw.
#[test]
fn indices_inside_their_arrays_leave_the_sizes_alone() {
    let (o, r, _d) = run(&["bindless.rchit"], &[]);
    let r = r.unwrap_or_else(|| panic!("no report: {}", stderr(&o)));
    let b = &r["index_bounds"];
    assert!(b.get("grown").is_none(), "{b}");
    let arrays = b["arrays"].as_array().unwrap();
    assert!(!arrays.is_empty(), "{b}");
    assert!(arrays.iter().all(|a| a["seen"]["largest"].as_u64() < a["elements"].as_u64()), "{b}");
    assert!(r["options"]["array_size"].is_null());
}

/// Without `nonuniformEXT` lavapipe's unpatched and `nonuniform` pipelines differ: the variant
/// stays `patch_differs` (exit 1), with what the check saw — lavapipe's ray tracing stages have
/// no subgroup vote, so each binding's range over the trace — and the rule that would apply.
#[test]
fn a_nonuniform_difference_without_subgroup_evidence_stays_the_patchs() {
    let (o, r, _d) = run(&["object_table.rchit"], &["-D", "NO_NONUNIFORM"]);
    let r = r.unwrap_or_else(|| panic!("no report: {}", stderr(&o)));
    assert_eq!(o.status.code(), Some(1), "{}{}", stdout(&o), stderr(&o));
    let arrays = r["index_bounds"]["arrays"].as_array().unwrap();
    assert!(
        arrays.iter().all(|a| a["seen"].get("nonuniform").is_none()),
        "not measured: {arrays:?}"
    );
    let v = variant(&r, "nonuniform");
    assert_eq!(v["judgement"], "patch_differs", "{v}");
    let d = v["detail"].as_str().unwrap();
    assert!(d.contains("set 1 binding 1 (") && d.contains("set 1 binding 2 ("), "{d}");
    assert!(d.contains("over the trace, no subgroup vote here"), "{d}");
    assert!(d.contains("VUID-RuntimeSpirv-subgroupSize-10149"), "{d}");
    assert!(d.contains("add nonuniformEXT"), "{d}");
}

/// A binding declared twice — `textures[]` in the closest-hit, `textures[8]` in the any-hit —
/// is one binding of the larger count (the harness's) with each declaration held to its own
/// size: the any-hit's element 1 inside its eight, the closest-hit's sums inside the runtime
/// array, no refusal (it once merged them at the smaller count and refused).
#[test]
fn each_declaration_is_held_to_its_own_size() {
    let (o, r, _d) = run(&["object_table.rchit", "alpha_table.rahit"], &[]);
    let r = r.unwrap_or_else(|| panic!("no report: {}{}", stdout(&o), stderr(&o)));
    let arrays = r["index_bounds"]["arrays"].as_array().unwrap();
    let of = |runtime: bool| {
        arrays.iter().find(|a| a["binding"] == 2 && a["runtime"] == runtime).unwrap().clone()
    };
    let (fixed, runtime) = (of(false), of(true));
    let largest = |a: &Value| a["seen"]["largest"].as_u64();
    assert_eq!((fixed["elements"].as_u64(), largest(&fixed)), (Some(8), Some(1)));
    assert!(largest(&runtime).unwrap() >= 8, "{runtime}");
    assert_eq!(variant(&r, "unpatched")["judgement"], "pass", "{r}");
}
