//! End-to-end tests of `rtprobe run` on lavapipe: the default matrix passes with canaries
//! classified, unsupported cells carry the device's reason, corrupted expectations are caught,
//! reports survive a killed supervisor and resume, isolation modes and dumps work.
mod common;
use common::*;
use serde_json::Value;
use std::path::Path;
use std::time::{Duration, Instant};

fn report(path: &Path) -> Value {
    serde_json::from_slice(&std::fs::read(path).expect("report written")).expect("report is JSON")
}

fn cells(r: &Value) -> &Vec<Value> {
    r["cells"].as_array().expect("cells")
}

#[test]
fn default_matrix_passes_on_lavapipe_and_canaries_are_classified() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let out = dir.path().join("r.json");
    let junit = dir.path().join("j.xml");
    let o = run(&[
        "run",
        "--canaries",
        "--timeout",
        "5",
        "-o",
        out.to_str().unwrap(),
        "--junit",
        junit.to_str().unwrap(),
    ]);
    let r = report(&out);
    // Lavapipe 25 reads lane 0's descriptor index in closest-hit calls where lane 0 is inactive
    // (the gallivm defect of reports/lavapipe-26/FINDINGS.md #2): in cells without nonuniformEXT
    // that is a read no active lane's index gives, a mismatch under rtprobe's other-lane
    // heuristic (the spec leaves those reads undefined). Those are the run's only findings.
    let heuristic = cells(&r).iter().filter(|c| c["outcome"] == "mismatch").count();
    let code = if heuristic > 0 { 1 } else { 0 };
    assert_eq!(o.status.code(), Some(code), "stdout: {}\nstderr: {}", stdout(&o), stderr(&o));
    assert_eq!(r["schema"], "rtprobe.report/1");
    assert_eq!(r["complete"], true);
    let cs = cells(&r);
    // (the workaround variants tried on the findings are retries, outside the plan)
    let planned = cs.iter().filter(|c| c["retry"] != true).count();
    assert_eq!(planned as u64, r["plan"]["planned"].as_u64().unwrap());
    assert!(r["plan"]["to_run"].as_u64().unwrap() >= 400, "{}", r["plan"]);
    let mut passed = 0;
    for c in cs.iter().filter(|c| c["retry"] != true) {
        let id = c["id"].as_str().unwrap();
        match c["outcome"].as_str().unwrap() {
            "pass" => passed += 1,
            "unsupported" => {
                assert!(c["reason"].as_str().is_some_and(|s| !s.is_empty()), "{id} has no reason")
            }
            other if id.starts_with("canary.") => {
                assert_eq!(c["canary_check"]["detected"], true, "{id}: {other}")
            }
            "mismatch" => {
                assert!(c["outside_spec"].is_string(), "{id}: a mismatch of a defined read");
                let reads = &c["attempts"][0]["result"]["comparison"]["element_reads"];
                assert!(reads["neither"].as_u64().unwrap() > 0, "{id}: {reads}");
                assert!(reads["heuristic"].as_str().unwrap().contains("heuristic"), "{id}");
                let by = &c["attempts"][0]["result"]["comparison"]["by_field"];
                assert_eq!(by.as_object().unwrap().keys().collect::<Vec<_>>(), ["value"], "{id}");
            }
            other => panic!("{id}: {other} ({})", c["reason"]),
        }
        for a in c["attempts"].as_array().unwrap() {
            assert!(
                a["result"]["validation_errors"].is_null(),
                "{id}: validation errors {}",
                a["result"]["validation_errors"]
            );
        }
    }
    assert!(passed >= 400, "passed {passed}");
    // Canaries: an invalid read crashes the lavapipe worker, an endless loop times out.
    let canary = |id: &str| {
        cs.iter().find(|c| c["id"] == id).unwrap()["outcome"].as_str().unwrap().to_string()
    };
    assert_eq!(canary("canary.invalid_address"), "crash");
    assert_eq!(canary("canary.infinite_loop"), "timeout");
    // Every descriptor_heap cell is unsupported, with the reason from the device.
    let heap: Vec<_> = cs.iter().filter(|c| c["descriptor_model"] == "descriptor_heap").collect();
    assert!(!heap.is_empty());
    for c in heap {
        assert_eq!(c["outcome"], "unsupported");
        assert!(c["reason"].as_str().unwrap().contains("VK_EXT_descriptor_heap"));
    }
    // Every stage, resource and index source actually ran somewhere.
    for (axis, values) in [
        (
            "stage",
            vec![
                "raygen",
                "closest_hit",
                "any_hit",
                "miss",
                "intersection",
                "callable",
                "fragment",
                "compute",
            ],
        ),
        (
            "resource",
            vec![
                "storage_buffer",
                "uniform_buffer",
                "sampled_image",
                "storage_image",
                "acceleration_structure",
            ],
        ),
        ("index", vec!["literal", "spec_constant", "push_constant", "dynamic", "dynamic_element"]),
    ] {
        for v in values {
            assert!(
                cs.iter().any(|c| c[axis] == v && c["outcome"] == "pass"),
                "no passing cell with {axis}={v}"
            );
        }
    }
    // The summary on the terminal and the JUnit file agree with the report.
    let text = stdout(&o);
    assert!(text.contains(&format!("pass {passed}")), "{text}");
    let xml = std::fs::read_to_string(&junit).unwrap();
    assert_eq!(xml.matches("<testcase ").count(), cs.len());
    assert!(xml.contains("<skipped"));
    // Detected canaries are successes, in JUnit and in the summary's outcome counts; the only
    // failures are the heuristic mismatches above.
    assert!(xml.contains(&format!("failures=\"{heuristic}\"")), "{xml}");
    assert!(xml.contains("canary detected: crash"), "{xml}");
    assert_eq!(r["tally"]["canaries_detected"], 2);
    assert_eq!(r["summary"]["crash"], 0);
    assert_eq!(r["summary"]["timeout"], 0);
}

#[test]
fn injected_wrong_values_are_reported_as_confirmed_mismatches() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let out = dir.path().join("r.json");
    let filter = "stage=raygen|closest_hit,resource=storage_buffer,descriptor_model=descriptor_indexing,reorder=none,base=push_data|none,scene_layout=none";
    let o = run(&[
        "run",
        "--inject-fault",
        &format!("{filter}@value"),
        "--patches",
        "none",
        "--filter",
        filter,
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1), "findings exit 1; stderr {}", stderr(&o));
    let r = report(&out);
    let cs = cells(&r);
    assert_eq!(cs.len(), 12, "2 stages x 5 index variants, and dynamic_element");
    for c in cs {
        assert_eq!(c["outcome"], "mismatch", "{}", c["id"]);
        assert_eq!(c["confirmed"], true, "re-run alone gives the same outcome");
        assert_eq!(c["flaky"], Value::Null, "two equal attempts are not flaky");
        assert_eq!(c["injected"], format!("{filter}@value:1"));
        let cmp = &c["attempts"][0]["result"]["comparison"];
        assert!(cmp["by_field"]["value"].as_u64().unwrap() > 0);
        assert!(cmp["worst_value"].as_f64().unwrap() >= 0.5);
        assert!(!cmp["examples"].as_array().unwrap().is_empty());
    }
    assert!(stdout(&o).contains("findings (12)"));
}

#[test]
fn reports_carry_discrimination_and_the_reads_of_cells_without_nonuniform() {
    // AS cells (the weakest probes before: miss cells always expected 0) and the dynamic cells
    // without nonuniformEXT, on lavapipe: no false finding, every exactly checked cell catches a
    // wrong slot or element on at least half of its pixels, the others count what they read.
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let out = dir.path().join("r.json");
    let o = run(&[
        "run", "--patches", "none", "--filter", "stage=miss|closest_hit|compute,resource=acceleration_structure|uniform_buffer,descriptor_model=descriptor_indexing,base=none|push_data",
        "-o", out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let r = report(&out);
    let (mut exact, mut undefined) = (0, 0);
    for c in cells(&r).iter().filter(|c| c["outcome"] == "pass") {
        let cmp = &c["attempts"][0]["result"]["comparison"];
        let id = c["id"].as_str().unwrap();
        // a dynamic descriptor index without nonuniformEXT (an address table is plain memory)
        let no_nonuniform =
            id.contains(".dynamic.") && !id.contains(".nonuniform.") && !id.contains(".address");
        if no_nonuniform {
            undefined += 1;
            let reads = &cmp["element_reads"];
            assert_eq!(reads["outside_spec"], "VUID-RuntimeSpirv-None-10148 / VUID-RuntimeSpirv-subgroupSize-10149 (Vulkan 1.4.360)", "{}", c["id"]);
            assert_eq!(
                c["outside_spec"], "VUID-RuntimeSpirv-None-10148 / VUID-RuntimeSpirv-subgroupSize-10149 (Vulkan 1.4.360)",
                "the cell is labelled: {}",
                c["id"]
            );
            assert_eq!(reads["neither"], 0);
            assert!(
                reads["own"].as_u64().unwrap() + reads["other"].as_u64().unwrap() > 50,
                "{}",
                c["id"]
            );
            assert!(cmp["discrimination"].is_null());
        } else {
            exact += 1;
            let d = cmp["discrimination"].as_f64().unwrap_or_else(|| panic!("{}: {cmp}", c["id"]));
            assert!(d >= 0.5, "{}: discrimination {d}", c["id"]);
            assert!(cmp.get("element_reads").is_none());
            assert!(c.get("outside_spec").is_none(), "{}", c["id"]);
        }
    }
    assert!(exact >= 20 && undefined >= 4, "{exact} exact, {undefined} without nonuniform");
    assert!(
        stdout(&o).contains(&format!("outside the spec's guarantees: {undefined} cells")),
        "{}",
        stdout(&o)
    );
}

#[test]
fn list_says_what_is_planned_skipped_and_not_generated() {
    let o = run(&["run", "--list"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    let to_run = out.lines().filter(|l| l.starts_with("run ")).count();
    let unsupported = out.lines().filter(|l| l.starts_with("unsupported ")).count();
    let not_implemented = out.lines().filter(|l| l.starts_with("not_implemented ")).count();
    assert!(to_run > 0 && unsupported > 0);
    assert!(
        out.contains(&format!(
            "{} planned: {to_run} to run, {unsupported} unsupported, {not_implemented} not implemented in rtprobe",
            to_run + unsupported + not_implemented
        )),
        "{out}"
    );
    assert!(out.contains("not generated: nonuniform only applies to index=dynamic"));
    assert!(out.contains("address_patched"));
    let o = run(&[
        "run",
        "--list",
        "--filter",
        "stage=closest_hit,index=dynamic,descriptor_model=descriptor_indexing",
    ]);
    let out = stdout(&o);
    assert!(out
        .lines()
        .filter(|l| l.starts_with("run "))
        .all(|l| l.contains("closest_hit.") && l.contains(".dynamic")));
}

#[test]
fn bad_run_arguments_are_usage_errors() {
    assert_one_line_error(&run(&["run", "--filter", "stage=nope"]), 2, "closest_hit");
    assert_one_line_error(&run(&["run", "--filter", "colour=red"]), 2, "unknown axis");
    assert_one_line_error(&run(&["run", "--size", "10x10"]), 2, "multiple of 8");
    assert_one_line_error(&run(&["run", "--instances", "3"]), 2, "instances");
    assert_one_line_error(&run(&["run", "--jobs", "0"]), 2, "--jobs");
    assert_one_line_error(&run(&["run", "--threads", "0"]), 2, "--threads");
    assert_one_line_error(&run(&["run", "--threads", "65"]), 2, "--threads");
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let bad = dir.path().join("bad.json");
    std::fs::write(&bad, b"{not json").unwrap();
    assert_one_line_error(
        &run(&["run", "--resume", bad.to_str().unwrap()]),
        9,
        "not an rtprobe run report",
    );
}

#[test]
fn killed_supervisor_loses_no_finished_cell_and_resume_completes() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let out = dir.path().join("r.json");
    let filter =
        "descriptor_model=descriptor_indexing,resource=storage_buffer|uniform_buffer,reorder=none,base=none|push_data";
    let mut child = bin()
        .args(["run", "--filter", filter, "-o", out.to_str().unwrap()])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let start = Instant::now();
    let finished_before_kill = loop {
        if let Ok(b) = std::fs::read(&out) {
            if let Ok(r) = serde_json::from_slice::<Value>(&b) {
                let n = cells(&r)
                    .iter()
                    .filter(|c| !c["attempts"].as_array().unwrap().is_empty())
                    .count();
                if n >= 5 {
                    break r;
                }
            }
        }
        assert!(start.elapsed() < Duration::from_secs(120), "run made no progress");
        std::thread::sleep(Duration::from_millis(5));
    };
    child.kill().unwrap();
    let _ = child.wait();
    // What is on disk is a whole report, marked incomplete, holding at least what we saw.
    let on_disk = report(&out);
    assert_eq!(on_disk["complete"], false);
    let done: Vec<(String, Value)> = cells(&on_disk)
        .iter()
        .filter(|c| !c["attempts"].as_array().unwrap().is_empty())
        .map(|c| (c["id"].as_str().unwrap().to_string(), c["attempts"].clone()))
        .collect();
    assert!(
        done.len()
            >= cells(&finished_before_kill)
                .iter()
                .filter(|c| !c["attempts"].as_array().unwrap().is_empty())
                .count()
    );

    let o = run(&["run", "--filter", filter, "--resume", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let r = report(&out);
    assert_eq!(r["complete"], true);
    assert!(cells(&r).iter().all(|c| c["outcome"] == "pass"));
    for (id, attempts) in done {
        let c = cells(&r).iter().find(|c| c["id"] == id.as_str()).unwrap();
        assert_eq!(c["attempts"], attempts, "{id} was re-run instead of kept");
    }
}

#[test]
fn process_per_cell_starts_a_worker_per_cell() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let out = dir.path().join("r.json");
    let o = run(&[
        "run",
        "--isolation",
        "process-per-cell",
        "--filter",
        "stage=raygen|compute,resource=storage_buffer,descriptor_model=descriptor_indexing",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let r = report(&out);
    assert_eq!(r["timing"]["workers_started"].as_u64().unwrap() as usize, cells(&r).len());
    assert!(cells(&r).iter().all(|c| c["attempts"][0]["isolated"] == true));
}

#[test]
fn dump_writes_glsl_and_valid_spirv() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let dump = dir.path().join("dump");
    let out = dir.path().join("r.json");
    let o = run(&[
        "run",
        "--filter",
        "stage=closest_hit,index=dynamic,nonuniform=true,descriptor_model=descriptor_indexing",
        "--dump",
        dump.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let cell = dump.join("closest_hit.storage_buffer.dynamic.nonuniform.descriptor_indexing");
    let glsl = std::fs::read_to_string(cell.join("closest_hit_triangles.rchit.glsl")).unwrap();
    assert!(glsl.contains("probeBuf[nonuniformEXT((pc.dynBase + (uint(gl_InstanceCustomIndexEXT) & pc.dynMask)))].v[probeElement]"), "{glsl}");
    let mut checked = 0;
    for e in std::fs::read_dir(&cell).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "spv") {
            let v = std::process::Command::new("spirv-val")
                .args(["--target-env", "vulkan1.2"])
                .arg(&p)
                .output()
                .expect("spirv-val (apt-get install spirv-tools)");
            assert!(v.status.success(), "{}: {}", p.display(), String::from_utf8_lossy(&v.stderr));
            checked += 1;
        }
    }
    assert!(checked >= 5);
}

#[test]
fn patched_variants_render_like_the_originals() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let out = dir.path().join("r.json");
    let o = run(&[
        "run", "--patches", "all", "--filter", "stage=closest_hit|compute|fragment,resource=storage_buffer|sampled_image|acceleration_structure,index=dynamic,descriptor_model=descriptor_indexing,base=none|push_data",
        "-o", out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}\n{}", stdout(&o), stderr(&o));
    let r = report(&out);
    let cs = cells(&r);
    for patch in ["nonuniform", "pin-index", "as-to-address", "ssbo-to-address"] {
        let n = cs.iter().filter(|c| c["patch"] == patch).count();
        assert!(n > 0, "no cell with patch {patch}");
    }
    // Every patched variant and every address_patched cell matches the CPU reference, exactly as
    // its unpatched twin does.
    for c in cs.iter().filter(|c| c["outcome"] != "unsupported") {
        assert_eq!(c["outcome"], "pass", "{}: {}", c["id"], c["reason"]);
    }
    let patched_as =
        cs.iter().filter(|c| c["as_access"] == "address_patched" && c["outcome"] == "pass").count();
    let address =
        cs.iter().filter(|c| c["as_access"] == "address" && c["outcome"] == "pass").count();
    assert!(patched_as > 0 && address > 0);
}

/// Issue 9's question per finding: does the engines' recommended pattern (one descriptor at a
/// spec-constant slot, the dynamic value inside it) work where the dynamic index faults? The
/// pattern cells are outside the filter: the run schedules them, as often as their findings ran.
#[test]
fn findings_say_whether_the_recommended_pattern_works() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let filter = "stage=closest_hit,resource=storage_buffer|sampled_image,index=dynamic,nonuniform=true,descriptor_model=descriptor_indexing,reorder=none";
    let out = dir.path().join("r.json");
    let o = run(&[
        "run",
        "--inject-fault",
        "index=dynamic@value",
        "--no-confirm",
        "--repeat",
        "2",
        "--filter",
        filter,
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let r = report(&out);
    for (resource, pattern) in [("storage_buffer", "geometry"), ("sampled_image", "materials")] {
        let base = cells(&r)
            .iter()
            .find(|c| {
                c["id"] == format!("closest_hit.{resource}.dynamic.nonuniform.descriptor_indexing")
            })
            .unwrap();
        assert_eq!(base["outcome"], "mismatch");
        let p = &base["recommended"];
        let id = format!("closest_hit.{resource}.dynamic_element.descriptor_indexing");
        assert_eq!(
            (p["pattern"].as_str(), p["cell"].as_str(), p["status"].as_str()),
            (Some(pattern), Some(id.as_str()), Some("passes")),
            "{p}"
        );
        assert_eq!(
            (p["passed"].as_u64(), p["attempts"].as_u64()),
            (Some(2), Some(2)),
            "run as often as the finding: {p}"
        );
        let pc = cells(&r).iter().find(|c| c["id"] == id).expect("scheduled");
        assert_eq!(pc["attempts"].as_array().unwrap().len(), 2);
        assert!(
            stdout(&o).contains(&format!("recommended pattern {pattern} ("))
                && stdout(&o).contains(&format!("{id}): not proven (2 passes; need ")),
            "{}",
            stdout(&o)
        );
        let m = p["miss_probability"].as_f64().expect("miss_probability");
        let inc = |k: &str| base["incidence"][k].as_u64().unwrap() as u32;
        assert!(
            (m - rtprobe::model::stats::pass_miss(inc("faulted"), inc("attempts"), 2)).abs() < 1e-9,
            "{p}"
        );
    }
    // Twin: the same fault in the pattern's shape too: the pattern fails, never "passes".
    let out2 = dir.path().join("r2.json");
    let o = run(&[
        "run",
        "--inject-fault",
        "index=dynamic|dynamic_element@value",
        "--no-confirm",
        "--filter",
        filter,
        "-o",
        out2.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let r = report(&out2);
    let base = cells(&r)
        .iter()
        .find(|c| c["id"] == "closest_hit.storage_buffer.dynamic.nonuniform.descriptor_indexing")
        .unwrap();
    assert_eq!(
        (base["recommended"]["status"].as_str(), base["recommended"]["outcome"].as_str()),
        (Some("fails"), Some("mismatch")),
        "{}",
        base["recommended"]
    );
    assert!(stdout(&o).contains("closest_hit.storage_buffer.dynamic_element.descriptor_indexing): fails: mismatch (1 of 1 attempts)"), "{}", stdout(&o));
}

/// `--validate=gpu-av`: each finding again under GPU-Assisted Validation, next to its control (the
/// literal-index sibling that passed), recorded apart from the cell's own attempts.
#[test]
fn gpu_av_reruns_each_finding_and_says_whether_it_masks_it() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let out = dir.path().join("r.json");
    let filter = "stage=closest_hit,resource=storage_buffer,index=dynamic|literal,nonuniform=false,descriptor_model=descriptor_indexing,reorder=none";
    let o = run(&[
        "run",
        "--validate=gpu-av",
        "--inject-fault",
        "index=dynamic@value",
        "--no-confirm",
        "--patches",
        "none",
        "--filter",
        filter,
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let r = report(&out);
    assert_eq!(r["options"]["gpu_av"], true);
    let f = cells(&r)
        .iter()
        .find(|c| c["id"] == "closest_hit.storage_buffer.dynamic.descriptor_indexing")
        .unwrap();
    assert_eq!(f["outcome"], "mismatch");
    assert_eq!(
        f["attempts"].as_array().unwrap().len(),
        1,
        "GPU-AV attempts never join the cell's own"
    );
    let v = &f["gpu_av"];
    let layer =
        Path::new("/usr/share/vulkan/explicit_layer.d/VkLayer_khronos_validation.json").exists();
    if layer {
        // The injected wrong value is in the shader: GPU-AV cannot hide it, and the control passes.
        assert_eq!(
            (v["verdict"].as_str(), v["outcome"].as_str()),
            (Some("still_faults"), Some("mismatch")),
            "{v}"
        );
        assert_eq!(
            v["control"],
            serde_json::json!(["closest_hit.storage_buffer.literal.descriptor_indexing", "pass"]),
            "{v}"
        );
        assert!(stdout(&o).contains("GPU-AV: still faults (mismatch, 1 of 1 attempts under GPU-AV; its control closest_hit.storage_buffer.literal.descriptor_indexing is pass under GPU-AV"), "{}", stdout(&o));
        assert_eq!(
            (v["attempts"].as_u64(), v["passed"].as_u64()),
            (Some(1), Some(0)),
            "a fault ends the repeats: {v}"
        );
    } else {
        assert_eq!(v["verdict"], "not_run", "{v}");
    }
    let control = cells(&r)
        .iter()
        .find(|c| c["id"] == "closest_hit.storage_buffer.literal.descriptor_indexing")
        .unwrap();
    assert!(control["gpu_av"].is_null() && control["outcome"] == "pass");
    // Not a validation mode: one line, usage exit.
    let o = run(&["run", "--validate=sometimes", "--list"]);
    assert_ne!(o.status.code(), Some(0));
    assert!(stderr(&o).contains("not a validation mode"), "{}", stderr(&o));
}

/// Under `--validate` a cell's validation errors are counted around its own work, so no pipeline
/// is built ahead on another thread: `--threads 4` runs with 1, and the report says so. Twin:
/// the same run without validation prebuilds on 4.
#[test]
fn validate_runs_with_one_thread() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let filter = "stage=raygen|closest_hit,resource=storage_buffer,index=literal,descriptor_model=descriptor_indexing,reorder=none";
    let go = |extra: &[&str], name: &str| {
        let out = dir.path().join(name);
        let mut args = vec![
            "run",
            "-j",
            "1",
            "--threads",
            "4",
            "--patches",
            "none",
            "--filter",
            filter,
            "-o",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        let o = run(&args);
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        (report(&out), stderr(&o))
    };
    let (r, err) = go(&["--validate"], "v.json");
    assert_eq!(r["options"]["threads"], 1, "{}", r["options"]);
    assert_eq!(r["timing"]["prebuilt_pipelines"], 0, "{}", r["timing"]);
    assert!(err.contains("--validate runs with --threads 1"), "{err}");
    let (r, _) = go(&["--validate=off"], "plain.json");
    assert_eq!(r["options"]["threads"], 4, "{}", r["options"]);
    assert!(r["timing"]["prebuilt_pipelines"].as_u64().unwrap() > 0, "{}", r["timing"]);
}

/// Re-runs start from a cold pipeline cache: the first pass loads the persisted file, the
/// `--confirm` re-run of its finding does not, so a cached binary cannot stand in for the cell's
/// own compile.
#[test]
fn confirmations_run_without_the_persisted_pipeline_cache() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let cache = dir.path().join("cache");
    let out = dir.path().join("r.json");
    let one =
        "stage=raygen,resource=storage_buffer,index=literal,descriptor_model=descriptor_indexing";
    let go = || {
        let o = run(&[
            "run",
            "-j",
            "1",
            "--patches",
            "none",
            "--inject-fault",
            &format!("{one}@value"),
            "--filter",
            one,
            "--pipeline-cache",
            cache.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ]);
        assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
        report(&out)
    };
    go(); // writes the cache file
    let r = go();
    let c = &cells(&r)[0];
    assert_eq!(c["attempts"].as_array().unwrap().len(), 2, "the finding was confirmed: {c}");
    assert_eq!(r["timing"]["workers_started"], 2, "{}", r["timing"]);
    assert_eq!(
        r["pipeline_cache"]["workers_loaded"], 1,
        "only the first pass loads the cache: {}",
        r["pipeline_cache"]
    );
    assert_eq!(r["options"]["pipeline_cache"], cache.to_str().unwrap());
    assert!(r["options"]["rerun_pipeline_cache"].is_null(), "{}", r["options"]);
}

#[test]
fn faulting_cells_are_retried_with_each_applicable_workaround() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let out = dir.path().join("r.json");
    let filter = "stage=closest_hit,resource=storage_buffer,index=dynamic,nonuniform=false,descriptor_model=descriptor_indexing";
    // The fault follows the shape wherever it goes, patched variants included: nothing verifies.
    let o = run(&[
        "run",
        "--inject-fault",
        &format!("{filter}@value"),
        "--no-confirm",
        "--filter",
        filter,
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let r = report(&out);
    let base = cells(&r)
        .iter()
        .find(|c| c["id"] == "closest_hit.storage_buffer.dynamic.descriptor_indexing")
        .unwrap();
    assert_eq!(base["outcome"], "mismatch");
    let tried: Vec<&str> = base["workarounds"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w["patch"].as_str().unwrap())
        .collect();
    assert_eq!(tried, vec!["nonuniform", "pin-index", "ssbo-to-address"]);
    assert!(base["workarounds"].as_array().unwrap().iter().all(|w| w["verified"] == false));
    assert!(stdout(&o).contains("no verified workaround (nonuniform → mismatch, pin-index → mismatch, ssbo-to-address → mismatch)"), "{}", stdout(&o));
    // A fault only the unpatched shape has, seen once: each workaround passes once, which a fault
    // as frequent as one seen once would miss with p = 0.95, so none is called verified.
    let once = dir.path().join("r1.json");
    let o = run(&[
        "run",
        "--inject-fault",
        &format!("{filter},patch=none@device"),
        "--no-confirm",
        "--filter",
        filter,
        "-o",
        once.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let r = report(&once);
    let base = cells(&r)
        .iter()
        .find(|c| c["id"] == "closest_hit.storage_buffer.dynamic.descriptor_indexing")
        .unwrap();
    assert!(
        base["workarounds"]
            .as_array()
            .unwrap()
            .iter()
            .all(|w| w["verified"] == false && w["outcome"] == "pass"),
        "{}",
        base["workarounds"]
    );
    assert!(
        stdout(&o).contains("no verified workaround (nonuniform → not proven (1 pass; need "),
        "{}",
        stdout(&o)
    );
    // Seen 6 of 6 times (--repeat 6): 6 passes each bring the miss probability below 1%, so every
    // workaround that removes it is verified.
    let out2 = dir.path().join("r2.json");
    let o = run(&[
        "run",
        "--inject-fault",
        &format!("{filter},patch=none@device"),
        "--no-confirm",
        "--repeat",
        "6",
        "--filter",
        filter,
        "-o",
        out2.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let r = report(&out2);
    let base = cells(&r)
        .iter()
        .find(|c| c["id"] == "closest_hit.storage_buffer.dynamic.descriptor_indexing")
        .unwrap();
    assert_eq!(
        base["outcome"], "crash",
        "an invalid-address load kills lavapipe's worker: {}",
        base["reason"]
    );
    assert!(
        base["workarounds"]
            .as_array()
            .unwrap()
            .iter()
            .all(|w| w["verified"] == true && w["outcome"] == "pass"),
        "{}",
        base["workarounds"]
    );
    assert!(
        stdout(&o).contains("verified workaround: nonuniform, pin-index, ssbo-to-address"),
        "{}",
        stdout(&o)
    );
    // Each pass carries the chance it would have missed a fault as frequent as the finding's.
    let inc = |k: &str| base["incidence"][k].as_u64().unwrap() as u32;
    for w in base["workarounds"].as_array().unwrap() {
        let n = w["attempts"].as_u64().unwrap() as u32;
        let m = rtprobe::model::stats::pass_miss(inc("faulted"), inc("attempts"), n);
        assert!(n > 0 && (w["miss_probability"].as_f64().unwrap() - m).abs() < 1e-9, "{w}");
        assert!(stdout(&o).contains(&format!("{} → passes ({n} of {n}; a fault as frequent as this finding's would be missed with p ≤ {m:.3})", w["patch"].as_str().unwrap())), "{}", stdout(&o));
    }
}

/// Building pipelines on several threads changes nothing but time: every cell's attempts have
/// the same outcomes, phases and details with `--threads 1` and `--threads 2`, including a
/// crash in a trace (injected) and the workers that replace crashed ones. (The pipeline creation
/// error this run used to include was ssbo-to-address's own invalid SPIR-V — its 64-bit type
/// declared after the push block that used it, issue #23 — and is gone: that variant now
/// crashes in its trace like the cell it patches.)
#[test]
fn threads_change_no_verdict() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let mut seen = vec![];
    for t in ["1", "2"] {
        let out = dir.path().join(format!("t{t}.json"));
        let o = run(&[
            // Validation off: under --validate a worker never prebuilds (one thread).
            "--validate=off", "run", "-j", "1", "--threads", t, "--patches", "all",
            "--filter", "stage=closest_hit,resource=storage_buffer,index=dynamic,descriptor_model=descriptor_indexing",
            "--inject-fault", "stage=closest_hit,resource=storage_buffer,index=dynamic,nonuniform=false",
            "-o", out.to_str().unwrap(),
        ]);
        assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
        let r = report(&out);
        type Verdicts = Vec<(String, Vec<(Value, Value, Value)>)>;
        let verdicts: Verdicts = cells(&r)
            .iter()
            .map(|c| {
                (
                    c["id"].as_str().unwrap().to_string(),
                    c["attempts"]
                        .as_array()
                        .unwrap()
                        .iter()
                        .map(|a| (a["outcome"].clone(), a["phase"].clone(), a["detail"].clone()))
                        .collect(),
                )
            })
            .collect();
        let first =
            |id: &str| verdicts.iter().find(|v| v.0 == id).and_then(|v| v.1.first().cloned());
        let ssbo =
            first("closest_hit.storage_buffer.dynamic.descriptor_indexing.patch-ssbo-to-address");
        assert_eq!(
            ssbo.map(|a| (a.0, a.1)),
            Some(("crash".into(), "trace".into())),
            "{verdicts:?}"
        );
        assert!(
            verdicts.iter().all(|(_, a)| a.first().is_none_or(|x| x.0 != "error")),
            "{verdicts:?}"
        );
        if t == "2" {
            // It prebuilt: to the end, or until the injected crash hit a cell that ran while
            // pipelines were still being made (the prebuild's death; its cells then ran alone).
            let died = r["workers"].as_array().unwrap().iter().any(|w| w["phase"] == "prebuild");
            let made = r["timing"]["prebuilt_pipelines"].as_u64().unwrap();
            assert!(made > 0 || died, "{}", r["timing"]);
        }
        seen.push(verdicts);
    }
    assert_eq!(seen[0], seen[1]);
}

fn cache_file(dir: &Path) -> std::path::PathBuf {
    let files: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "bin"))
        .collect();
    assert_eq!(files.len(), 1, "{files:?}");
    files[0].clone()
}

/// The persisted pipeline cache: saved after a run, loaded by the next; a corrupt, truncated or
/// foreign file is ignored with its reason (never a crash) and replaced by a valid one.
#[test]
fn a_corrupt_pipeline_cache_is_ignored_and_replaced() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let cache = dir.path().join("cache");
    let out = dir.path().join("r.json");
    let one =
        "stage=raygen,resource=storage_buffer,index=literal,descriptor_model=descriptor_indexing";
    let go = || {
        let o = run(&[
            "run",
            "--filter",
            one,
            "--pipeline-cache",
            cache.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ]);
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        let r = report(&out);
        assert!(cells(&r).iter().all(|c| c["outcome"] == "pass" || c["outcome"] == "unsupported"));
        r
    };
    let r = go();
    assert_eq!(r["pipeline_cache"]["saves"], 1, "{}", r["pipeline_cache"]);
    let file = cache_file(&cache);
    let good = std::fs::read(&file).unwrap();
    assert!(
        good.len() >= 32 && good[4..8] == [1, 0, 0, 0],
        "not a VkPipelineCacheHeaderVersionOne: {good:?}"
    );
    let r = go();
    assert_eq!(r["pipeline_cache"]["workers_loaded"], 1, "{}", r["pipeline_cache"]);
    assert!(r["pipeline_cache"]["ignored"].is_null(), "{}", r["pipeline_cache"]);
    let mut foreign = good.clone();
    foreign[16] ^= 0xff; // another pipelineCacheUUID
    for (what, bytes) in [
        ("garbage", b"this is not a pipeline cache, not at all".to_vec()),
        ("truncated", good[..20].to_vec()),
        ("foreign", foreign),
    ] {
        std::fs::write(&file, &bytes).unwrap();
        let r = go();
        let pc = &r["pipeline_cache"];
        assert_eq!(pc["workers_loaded"], 0, "{what}: {pc}");
        assert!(pc["ignored"].as_array().is_some_and(|a| !a.is_empty()), "{what}: {pc}");
        let now = std::fs::read(cache_file(&cache)).unwrap();
        assert_eq!(now[..32], good[..32], "{what}: the file was not replaced by a valid cache");
    }
    // Off: nothing recorded, nothing written.
    let off = dir.path().join("off.json");
    let o = run_env(
        &["run", "--filter", one, "--pipeline-cache", "off", "-o", off.to_str().unwrap()],
        &[("RTPROBE_CACHE_DIR", dir.path().join("unused").to_str().unwrap())],
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(report(&off)["pipeline_cache"].is_null());
    assert!(!dir.path().join("unused").exists());
}
