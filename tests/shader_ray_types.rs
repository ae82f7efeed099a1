//! `run --shader` with ray types (issue 24: SBT record offsets other than 0): a closest-hit that
//! shades and casts a shadow ray of ray type 1 (sbtRecordOffset 1, sbtRecordStride 2, miss
//! index 1, terminate | skip-closest-hit | opaque) with its shadow miss, and the same with an
//! alpha-test any-hit in ray type 1's hit group, run on lavapipe under `--validate` with no
//! message, no fault, and counters that show each shadow stage reached by shadow rays only.
//! The twins: the shadow miss given at index 0, a shadow ray at offset 2 with none at 1, and an
//! any-hit without a payload (refused until `--hit-group` says its ray type).
mod common;
use common::*;
use serde_json::Value;

/// `run --validate --shader F… extra`: the output and the report, if written.
fn shader_run(files: &[&str], extra: &[&str]) -> (std::process::Output, Option<Value>) {
    let d = rtprobe::tempdir::tempdir().unwrap();
    run_user_shaders(files, &d.path().join("report.json"), extra, &[])
}

/// The counters of `shadow_types.glsl` (set 0 binding 1) in the unpatched variant, less their
/// initial values, after every attempt passed without a validation message.
#[derive(Debug)]
struct Counters {
    shadowed: u32,
    lit: u32,
    shadow_misses: u32,
    wrong_misses: u32,
    alpha_tests: u32,
    wrong_alpha_tests: u32,
}

fn clean_counters(o: &std::process::Output, r: Option<Value>) -> Counters {
    let r = r.unwrap_or_else(|| panic!("no report: {}{}", stdout(o), stderr(o)));
    assert_eq!(o.status.code(), Some(0), "{}{}", stdout(o), stderr(o));
    let variants = r["variants"].as_array().unwrap();
    for v in variants {
        assert_eq!(v["outcome"], "pass", "{v}");
        for a in v["attempts"].as_array().unwrap() {
            assert_eq!(a["validation_messages"], 0, "{a}");
        }
    }
    let data = variants[0]["data"].as_array().unwrap();
    let d = data
        .iter()
        .find(|d| d["label"].as_str().unwrap().contains("set 0 binding 1["))
        .unwrap_or_else(|| panic!("no counters: {data:?}"));
    let (now, then) = (unb64(d["bytes"].as_str().unwrap()), unb64(d["initial"].as_str().unwrap()));
    let w = |k: usize| {
        let at = |b: &[u8]| u32::from_le_bytes(b[4 * k..4 * k + 4].try_into().unwrap());
        at(&now).wrapping_sub(at(&then))
    };
    Counters {
        shadowed: w(0),
        lit: w(1),
        shadow_misses: w(2),
        wrong_misses: w(3),
        alpha_tests: w(4),
        wrong_alpha_tests: w(5),
    }
}

const SHADOW: [&str; 3] = ["shadow_types.rchit", "miss.rmiss", "shadow.rmiss"];

/// Shadow rays of ray type 1 reach the shadow miss at index 1 and ray type 1's empty hit group:
/// some hits shadowed, some lit, exactly one shadow miss per lit hit, no primary ray in the
/// shadow miss. Then the alpha-test any-hit, assigned to ray type 1 by its `bool` payload, runs
/// for shadow rays only and lets more light through.
#[test]
fn a_shadow_ray_type_runs_with_its_own_miss_and_hit_group() {
    let (o, r) = shader_run(&SHADOW, &[]);
    let c = clean_counters(&o, r);
    assert!(c.shadowed > 0 && c.lit > 0, "{c:?}");
    assert_eq!((c.shadow_misses, c.wrong_misses, c.alpha_tests), (c.lit, 0, 0), "{c:?}");
    let mut files = SHADOW.to_vec();
    files.push("shadow_alpha.rahit");
    let (o, r) = shader_run(&files, &["-D", "ALPHA_SHADOW"]);
    let a = clean_counters(&o, r);
    assert!(a.alpha_tests > 0 && a.shadowed > 0, "{a:?}");
    assert_eq!((a.wrong_alpha_tests, a.wrong_misses, a.shadow_misses), (0, 0, a.lit), "{a:?}");
    assert!(a.lit > c.lit, "the cutout lets light through: {a:?} against {c:?}");
}

/// An any-hit without a payload cannot be placed by it: refused naming `--hit-group`, which
/// then places it in ray type 1's group (its tests come from shadow rays only).
#[test]
fn an_any_hit_without_a_payload_needs_hit_group() {
    let mut files = SHADOW.to_vec();
    files.push("shadow_alpha.rahit");
    let defines = ["-D", "ALPHA_SHADOW", "-D", "ALPHA_NO_PAYLOAD"];
    let (o, r) = shader_run(&files, &defines);
    assert!(r.is_none());
    assert_one_line_error(&o, 9, "shadow_alpha.rahit (any_hit) has no incoming payload");
    assert!(stderr(&o).contains("--hit-group K=FILE"), "{}", stderr(&o));
    let mut extra = defines.to_vec();
    extra.extend(["--hit-group", "1=shadow_alpha.rahit"]);
    let (o, r) = shader_run(&files, &extra);
    let a = clean_counters(&o, r);
    assert!(a.alpha_tests > 0 && a.wrong_alpha_tests == 0, "{a:?}");
    // A file that is none of the inputs is a usage error.
    extra.extend(["--hit-group", "1=nothing.rahit"]);
    let (o, _) = shader_run(&files, &extra);
    assert_one_line_error(&o, 2, "nothing.rahit is none of the --shader files");
}

/// The twins: the shadow miss given first sits at miss index 0, where the primary rays'
/// `Shade` payload meets its `bool`; a shadow ray at offset 2 leaves ray type 1 without rays.
/// Each is refused in one line, without a report.
#[test]
fn a_shadow_miss_at_the_wrong_index_or_a_gap_in_the_offsets_is_refused() {
    let (o, r) = shader_run(&["shadow_types.rchit", "shadow.rmiss", "miss.rmiss"], &[]);
    assert!(r.is_none());
    assert_one_line_error(&o, 9, "shadow.rmiss (miss)");
    let (o, r) = shader_run(&SHADOW, &["-D", "SHADOW_OFFSET=2"]);
    assert!(r.is_none());
    assert_one_line_error(&o, 9, "offset 2 but none uses offset 1");
}
