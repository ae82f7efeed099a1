//! `run --shader`'s descriptor-index check on lavapipe, with an engine-like closest-hit written
//! for these tests (`tests/shaders/user/object_table.rchit`: `textures[material.textureId +
//! object.textureOffset]`, two buffer words summed, as renderers that append each mesh's
//! textures to one bindless array index them). The harness's integer words are below 64 each,
//! so the sum reaches past a 64-element array: the check sizes runtime arrays up (the run
//! passes, the report says so), and refuses what it may not size — a `--array-size` the user
//! gave, a fixed-size array — in one line, exit 9, no report. Its twins: an in-bounds shader is
//! left at its size, and a shader without `nonuniformEXT` whose `nonuniform` variant differs is
//! judged the shader's (`shader_undefined`), never `patch_differs`.
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
/// passes with no fault and no validation message.
#[test]
fn data_past_a_runtime_array_sizes_it_up_and_the_run_passes() {
    let (o, r, _d) = run(&["object_table.rchit"], &[]);
    let r = r.unwrap_or_else(|| panic!("no report: {}", stderr(&o)));
    assert_eq!(o.status.code(), Some(0), "{}{}", stdout(&o), stderr(&o));
    let b = &r["index_bounds"];
    assert_eq!(b["grown"], serde_json::json!([64, 128]), "{b}");
    let textures = b["arrays"].as_array().unwrap().iter().find(|a| a["binding"] == 2).unwrap();
    assert!(textures["largest"].as_u64().unwrap() >= 64, "{textures}");
    assert!(textures["largest"].as_u64().unwrap() < 128, "{textures}");
    assert_eq!(textures["elements"], 128);
    assert_eq!(r["options"]["array_size"], 128, "what ran, for reduce");
    assert!(stdout(&o).contains("runtime arrays sized 128 instead of 64"), "{}", stdout(&o));
    assert_eq!(variant(&r, "unpatched")["judgement"], "pass");
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
    assert!(arrays.iter().all(|a| a["largest"].as_u64() < a["elements"].as_u64()), "{b}");
    assert!(r["options"]["array_size"].is_null());
}

/// Without `nonuniformEXT` the unpatched reads are undefined where the index differs in a
/// subgroup; lavapipe's unpatched and `nonuniform` pipelines then differ, and the variant is
/// the shader's failure (exit 1, `shader_undefined`, the bindings and the VUID named).
#[test]
fn a_nonuniform_difference_of_an_undecorated_shader_is_the_shaders() {
    let (o, r, _d) = run(&["object_table.rchit"], &["-D", "NO_NONUNIFORM"]);
    let r = r.unwrap_or_else(|| panic!("no report: {}", stderr(&o)));
    assert_eq!(o.status.code(), Some(1), "{}{}", stdout(&o), stderr(&o));
    let v = variant(&r, "nonuniform");
    assert_eq!(v["judgement"], "shader_undefined", "{v}");
    assert_eq!(v["outcome"], "mismatch");
    let d = v["detail"].as_str().unwrap();
    assert!(
        d.contains("set 1 binding 1, set 1 binding 2")
            && d.contains("VUID-RuntimeSpirv-None-10148"),
        "{d}"
    );
    assert!(stdout(&o).contains("mismatch of nonuniform (shader_undefined)"), "{}", stdout(&o));
}
