//! End-to-end tests that every verdict can fail, on lavapipe: injected faults of each kind land on
//! exactly the cells their predicate names, with the expected outcome; a fault that does not
//! repeat stays a finding (flaky, k of N, miss probability), also with its re-runs side by side
//! on a CPU device; `--resume` refuses a report it cannot continue.
mod common;
use common::*;
use serde_json::Value;
use std::path::Path;

fn report(path: &Path) -> Value {
    serde_json::from_slice(&std::fs::read(path).expect("report written")).expect("report is JSON")
}

fn cells(r: &Value) -> &Vec<Value> {
    r["cells"].as_array().expect("cells")
}

/// Does `cell` (a report entry) satisfy `axis=value[|value],…`?
fn satisfies(cell: &Value, predicate: &str) -> bool {
    predicate.split(',').all(|term| {
        let (axis, values) = term.split_once('=').unwrap();
        let v = match &cell[axis] {
            Value::String(s) => s.clone(),
            Value::Bool(b) => b.to_string(),
            Value::Null => "none".into(),
            other => other.to_string(),
        };
        values.split('|').any(|x| x == v)
    })
}

#[test]
fn each_fault_kind_lands_on_exactly_its_cells_with_the_expected_outcome() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let out = dir.path().join("r.json");
    let junit = dir.path().join("j.xml");
    // Predicates: a single axis value set, two axes, three axes; disjoint, so each cell has one.
    let injections = [
        ("stage=closest_hit,index=dynamic", "device", "crash"),
        ("stage=raygen,index=push_constant", "hang", "timeout"),
        (
            "stage=raygen,resource=uniform_buffer,index=literal|spec_constant",
            "value:0.1",
            "mismatch",
        ),
        ("stage=closest_hit,resource=storage_buffer,index=literal", "nan", "mismatch"),
    ];
    let mut args = vec![
        "run".to_string(), "--patches".into(), "none".into(), "--timeout".into(), "4".into(),
        "--filter".into(), "stage=raygen|closest_hit,resource=storage_buffer|uniform_buffer,descriptor_model=descriptor_indexing,reorder=none,base=push_data|none,scene_layout=none".into(),
        "-o".into(), out.to_str().unwrap().into(), "--junit".into(), junit.to_str().unwrap().into(),
    ];
    for (p, k, _) in &injections {
        args.push("--inject-fault".into());
        args.push(format!("{p}@{k}"));
    }
    let o = run(&args.iter().map(String::as_str).collect::<Vec<_>>());
    assert_eq!(o.status.code(), Some(1), "findings exit 1\n{}\n{}", stdout(&o), stderr(&o));
    let r = report(&out);
    let cs = cells(&r);
    assert_eq!(
        cs.len(),
        22,
        "2 stages x 2 resources x 5 index variants, and the 2 storage-buffer dynamic_element cells"
    );
    let mut injected = 0;
    for c in cs {
        let id = c["id"].as_str().unwrap();
        match injections.iter().find(|(p, _, _)| satisfies(c, p)) {
            Some((p, k, expect)) => {
                injected += 1;
                assert_eq!(c["outcome"], *expect, "{id} with {k}: {}", c["reason"]);
                assert_eq!(c["injected"].as_str().unwrap(), format!("{p}@{k}"), "{id}");
                assert_eq!(c["confirmed"], true, "{id}: a deterministic fault repeats alone");
            }
            None => {
                assert_eq!(c["outcome"], "pass", "{id} has no injection: {}", c["reason"]);
                assert!(c["injected"].is_null(), "{id}");
            }
        }
    }
    assert_eq!(injected, 4 + 2 + 2 + 1, "device: 2 resources x 2 dynamic; hang 2; value 2; nan 1");
    // The value fault hit about 10% of the pixels, not all of them.
    let v =
        cs.iter().find(|c| c["id"] == "raygen.uniform_buffer.literal.descriptor_indexing").unwrap();
    let cmp = &v["attempts"][0]["result"]["comparison"];
    let (bad, compared) =
        (cmp["mismatched_pixels"].as_f64().unwrap(), cmp["compared"].as_f64().unwrap());
    assert!(bad / compared > 0.03 && bad / compared < 0.2, "{bad} of {compared}");
    // NaN never compares as exact.
    let n = cs
        .iter()
        .find(|c| c["id"] == "closest_hit.storage_buffer.literal.descriptor_indexing")
        .unwrap();
    assert!(n["attempts"][0]["result"]["comparison"]["by_field"]["value"].as_u64().unwrap() > 0);
    assert_eq!(r["tally"]["findings"], injected);
    let xml = std::fs::read_to_string(&junit).unwrap();
    assert!(xml.contains(&format!("failures=\"{injected}\"")), "{xml}");
}

#[test]
fn a_fault_that_does_not_repeat_stays_a_finding_with_its_rate() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let out = dir.path().join("r.json");
    let junit = dir.path().join("j.xml");
    // 10 cells each faulting with probability 0.5 per attempt: all pass the first attempt with
    // probability 2^-10.
    let filter =
        "stage=raygen|compute,resource=storage_buffer,descriptor_model=descriptor_indexing";
    // The supervisor's timeline (each worker's lines in order) and the rounds' progress lines.
    let o = run_env(
        &[
            "run",
            "--patches",
            "none",
            "--repeat",
            "8",
            "--filter",
            filter,
            "--inject-fault",
            &format!("{filter}@flaky:0.5"),
            "-o",
            out.to_str().unwrap(),
            "--junit",
            junit.to_str().unwrap(),
        ],
        &[
            ("RUST_LOG", "rtprobe::runner::supervisor=trace"),
            ("RTPROBE_PROGRESS_SECS", "0"),
            ("CI", "true"),
        ],
    );
    assert_eq!(o.status.code(), Some(1), "{}", stdout(&o));
    let r = report(&out);
    reruns_ran_side_by_side_each_alone(&r, &stderr(&o));
    let findings: Vec<&Value> = cells(&r).iter().filter(|c| c["outcome"] != "pass").collect();
    assert!(!findings.is_empty());
    let mut flaky = 0;
    for c in &findings {
        let id = c["id"].as_str().unwrap();
        assert_eq!(c["outcome"], "crash", "{id}: the worst attempt is the verdict");
        let attempts = c["attempts"].as_array().unwrap();
        assert_eq!(attempts.len(), 8, "{id}: --repeat 8");
        // Every attempt says whether its die armed the fault, and the verdict counts them.
        let armed = attempts.iter().filter(|a| a["injected"]["armed"] == true).count();
        let crashed = attempts.iter().filter(|a| a["outcome"] == "crash").count() as u64;
        assert_eq!(
            crashed as usize, armed,
            "{id}: every armed attempt crashed, no unarmed one did"
        );
        let inc = &c["incidence"];
        assert_eq!(inc["attempts"], 8);
        assert_eq!(inc["faulted"].as_u64().unwrap(), crashed);
        let expect = (1.0 - crashed as f64 / 8.0).powi(8);
        assert!((inc["miss_probability"].as_f64().unwrap() - expect).abs() < 1e-12, "{id}: {inc}");
        assert_eq!(c["flaky"] == true, crashed < 8, "{id}");
        if crashed < 8 {
            flaky += 1;
            assert!(
                c["reason"].as_str().unwrap().contains(&format!("{crashed} of 8 attempts")),
                "{id}: {}",
                c["reason"]
            );
        }
    }
    // With p = 0.5 a run of 8 crashes has probability 2^-7 per cell.
    assert!(flaky > 0, "no flaky cell among {}", findings.len());
    assert_eq!(r["tally"]["flaky"], flaky);
    let text = stdout(&o);
    assert!(text.contains("[FLAKY]") && text.contains("of 8 attempts"), "{text}");
    let xml = std::fs::read_to_string(&junit).unwrap();
    assert!(xml.contains("(flaky)") && xml.contains("name=\"flaky\""), "{xml}");
}

/// On a CPU device (lavapipe) the re-runs alone run side by side, one per core at most
/// (`options.rerun_jobs`), and each is still alone in its own worker: every re-run attempt has a
/// worker of its own, and with two cores or more some re-run worker was ready before another's
/// result came (`err`: the supervisor's trace, after the first re-run round's progress line).
fn reruns_ran_side_by_side_each_alone(r: &Value, err: &str) {
    let cores = std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1);
    let jobs = r["options"]["jobs"].as_u64().unwrap() as usize;
    assert_eq!(r["options"]["rerun_jobs"].as_u64(), Some(jobs.min(cores) as u64));
    let isolated: Vec<u64> = cells(r)
        .iter()
        .flat_map(|c| c["attempts"].as_array().unwrap())
        .filter(|a| a["isolated"] == true)
        .map(|a| a["worker"].as_u64().unwrap())
        .collect();
    let mut distinct = isolated.clone();
    distinct.sort();
    distinct.dedup();
    assert!(!isolated.is_empty());
    assert_eq!(distinct.len(), isolated.len(), "each re-run alone in its worker: {isolated:?}");
    let reruns = &err[err.find("round confirm:").expect("a confirm round")..];
    // (worker, ready) in the order the supervisor read them: `true` its `ready`, `false` the end
    // of its cell (its result, or the end of its output where the injected crash killed it).
    let lines: Vec<(u64, bool)> = reruns
        .lines()
        .filter_map(|l| {
            let (_, rest) = l.split_once(" worker ")?;
            let (id, input) = rest.split_once(": ")?;
            let ready = input.starts_with("Msg(Ready");
            let end = input.starts_with("Msg(Result") || input.starts_with("Eof");
            (ready || end).then_some((id.parse().ok()?, ready))
        })
        .collect();
    // Some worker was ready while another was between its `ready` and its cell's end.
    let side_by_side = lines.iter().enumerate().any(|(i, &(a, ready))| {
        ready && lines[i + 1..].iter().take_while(|&&(w, r)| w != a || r).any(|&(w, r)| r && w != a)
    });
    assert_eq!(side_by_side, jobs.min(cores) > 1, "{lines:?}");
}

#[test]
fn resume_refuses_another_device_scene_or_injection() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let out = dir.path().join("r.json");
    let filter =
        "stage=raygen,resource=storage_buffer,index=literal,descriptor_model=descriptor_indexing";
    let o = run(&["run", "--filter", filter, "-o", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let o = run(&["run", "--filter", filter, "--seed", "2", "--resume", out.to_str().unwrap()]);
    assert_one_line_error(&o, 9, "scene differs");
    let o = run(&[
        "run",
        "--filter",
        filter,
        "--inject-fault",
        "stage=raygen@nan",
        "--resume",
        out.to_str().unwrap(),
    ]);
    assert_one_line_error(&o, 9, "--inject-fault differs");
    let mut r = report(&out);
    r["device"]["driver_uuid"] = Value::String("00".repeat(16));
    std::fs::write(&out, serde_json::to_vec(&r).unwrap()).unwrap();
    let o = run(&["run", "--filter", filter, "--resume", out.to_str().unwrap()]);
    assert_one_line_error(&o, 9, "another device (driver_uuid");
}

#[test]
fn bad_injections_are_usage_errors() {
    assert_one_line_error(
        &run(&["run", "--inject-fault", "stage=raygen@boom"]),
        2,
        "unknown fault kind",
    );
    assert_one_line_error(
        &run(&["run", "--inject-fault", "stage=raygen@flaky:2"]),
        2,
        "flaky probability",
    );
    assert_one_line_error(&run(&["run", "--inject-fault", "colour=red"]), 2, "unknown axis");
    assert_one_line_error(&run(&["run", "--repeat", "0"]), 2, "--repeat");
}
