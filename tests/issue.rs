//! `rtprobe report` writes an issue a driver engineer reads on one screen (issue 30): on lavapipe,
//! an injected wrong value's issue has the one-screen facts, the failing cell's validation run,
//! real unified diffs; `common::run` holds every issue the suite writes to the screen rule, and
//! that rule fails a longer page.
mod common;
use common::*;
use std::path::Path;

/// A run with an injected wrong value at the closest-hit SSBO read (a mismatch on every attempt),
/// made without the validation layer, so that `report` makes its validation run.
fn injected_report(dir: &Path) -> std::path::PathBuf {
    let out = dir.join("r.json");
    let o = bin()
        .env_remove("RTPROBE_VALIDATE")
        .args([
            "run",
            "--patches",
            "none",
            "--no-confirm",
            "--filter",
            "stage=raygen|closest_hit,resource=storage_buffer,index=literal|dynamic,descriptor_model=descriptor_indexing,reorder=none",
            "--inject-fault",
            "stage=closest_hit,index=dynamic,nonuniform=true,base=push_data@value",
            "-o",
            out.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1), "{}\n{}", stdout(&o), stderr(&o));
    out
}

#[test]
fn an_issue_has_one_screen_of_facts_and_a_validation_run() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let report = injected_report(dir.path());
    let md = dir.path().join("issue.md");
    let o = run(&["report", report.to_str().unwrap(), "-o", md.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let text = std::fs::read_to_string(&md).unwrap();
    let n = rtprobe::report::issue::one_screen_lines(&text);
    let screen: String = text.lines().take(n).map(|l| format!("{l}\n")).collect();
    for fact in [
        "**Driver** llvmpipe",
        "`driverInfo` Mesa",
        "**Expected vs actual** at pixel (",
        "slot = base + (gl_InstanceCustomIndexEXT & 0xf), base = push constant dynBase = 3",
        "(in bounds)",
        "binding flags PARTIALLY_BOUND",
        "**SBT**: groups raygen | miss",
        "each record a 32-byte handle",
        "maxPipelineRayRecursionDepth 1",
        // The run did not validate: report re-ran the failing cell under the layer.
        "**Validation**: Clean: the failing cell re-run alone under VK_LAYER_KHRONOS_validation 1.",
        "```sh\nrtprobe repro closest_hit.storage_buffer.dynamic.nonuniform.descriptor_indexing",
        "No Amber script for this cell: the cell has an injected fault",
    ] {
        assert!(screen.contains(fact), "{fact:?} not on the first screen:\n{screen}");
    }
    // Real unified diffs, collapsed.
    assert!(
        text.contains("<details><summary>GLSL diff from the closest passing sibling"),
        "{text}"
    );
    assert!(
        text.contains("```diff\n--- passing/closest_hit_triangles.rchit (")
            && text.contains("\n@@ -"),
        "{text}"
    );
    // The twin of the validation run: asked not to, the issue says it was not made.
    let o = run(&["report", report.to_str().unwrap(), "--no-validation-run"]);
    assert!(
        stdout(&o).contains("no validation run was made (--no-validation-run)"),
        "{}",
        stdout(&o)
    );
}

#[test]
#[should_panic(expected = "lines before its first <details> (at most 60)")]
fn a_page_longer_than_one_screen_fails_the_rule() {
    let long: String = (0..61).map(|k| format!("line {k}\n")).collect();
    assert_one_screen(&format!("{long}<details><summary>x</summary>\n</details>\n"));
}

#[test]
fn a_lanes_report_of_another_device_is_refused() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let report = injected_report(dir.path());
    let other = dir.path().join("other.json");
    let mut v: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    v["device"]["driver_uuid"] = "00000000000000000000000000000000".into();
    std::fs::write(&other, serde_json::to_vec(&v).unwrap()).unwrap();
    assert_one_line_error(
        &run(&["report", report.to_str().unwrap(), "--lanes", other.to_str().unwrap()]),
        9,
        "not of the report's device",
    );
    // A report of the same device without lane evidence for the issue's cell (the run itself:
    // lavapipe lists no subgroups in closest-hit) is refused, not silently ignored.
    assert_one_line_error(
        &run(&["report", report.to_str().unwrap(), "--lanes", report.to_str().unwrap()]),
        9,
        "no lane evidence for closest_hit.",
    );
}
