//! `rtprobe stress` end to end on lavapipe: the report's contract, lavapipe's figures held to
//! what the spec rules allow, and bad input as one-line errors.
mod common;
use common::*;

fn stress(args: &[&str]) -> (std::process::Output, serde_json::Value, rtprobe::tempdir::TempDir) {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let json = dir.path().join("stress.json");
    let mut all = vec!["stress", "--json", json.to_str().unwrap()];
    all.extend_from_slice(args);
    let out = run(&all);
    assert!(!stderr(&out).contains("panicked"), "{}", stderr(&out));
    let text = std::fs::read_to_string(&json)
        .unwrap_or_else(|e| panic!("no report ({e}); stderr: {}", stderr(&out)));
    (out, serde_json::from_str(&text).unwrap(), dir)
}

fn case<'a>(doc: &'a serde_json::Value, name: &str) -> &'a serde_json::Value {
    doc["cases"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["name"] == name)
        .unwrap_or_else(|| panic!("no case {name}"))
}

fn n(c: &serde_json::Value, field: &str) -> u64 {
    c[field].as_u64().unwrap_or_else(|| panic!("{field} missing in {c}"))
}

fn f(c: &serde_json::Value, field: &str) -> f64 {
    c[field].as_f64().unwrap_or_else(|| panic!("{field} missing in {c}"))
}

#[test]
fn stress_report_has_every_case_with_the_contract_fields() {
    let svg_dir = rtprobe::tempdir::tempdir().unwrap();
    let svg_path = svg_dir.path().join("far.svg");
    let (out, doc, _dir) = stress(&["--svg", svg_path.to_str().unwrap()]);
    assert_eq!(doc["schema"], "rtprobe.stress/3");
    // The stress pipeline itself is valid usage (when the layer is installed, tests enable it).
    assert_eq!(doc["validation"]["errors"], 0, "{}", stderr(&out));
    let names: Vec<&str> =
        doc["cases"].as_array().unwrap().iter().map(|c| c["name"].as_str().unwrap()).collect();
    assert_eq!(names, ["watertight", "far", "grazing", "degenerate", "tmin", "transform", "self"]);
    for c in doc["cases"].as_array().unwrap() {
        for field in [
            "name",
            "rays",
            "ambiguous",
            "disagreements",
            "leaks",
            "double_hits",
            "double_hit_warnings",
            "double_hits_in_margin",
            "t_err_max_ulps",
            "t_err_p99",
            "bary_err_max",
            "verdict",
        ] {
            assert!(c.get(field).is_some(), "{field} missing in {}", c["name"]);
        }
    }
    // A failing case makes the exit status 1 (a warning does not), and the table says which.
    for c in doc["cases"].as_array().unwrap() {
        let warned = n(c, "double_hit_warnings") > 0;
        match c["verdict"].as_str().unwrap() {
            "warn" => assert!(warned, "{c}"),
            "pass" => assert!(!warned, "{c}"),
            _ => {}
        }
    }
    let failed = doc["cases"].as_array().unwrap().iter().any(|c| c["verdict"] == "fail");
    assert_eq!(out.status.code(), Some(if failed { 1 } else { 0 }), "{}", stdout(&out));
    assert!(stdout(&out).contains("watertight —"));
    let svg = std::fs::read_to_string(&svg_path).unwrap();
    assert!(
        svg.starts_with("<svg")
            && svg.trim_end().ends_with("</svg>")
            && svg.matches("<polyline").count() == 6
    );
}

/// What lavapipe does must stay within what the rules allow; where it deviates (leaks, double
/// hits, a zero-area hit) the deviation must be the one documented in docs/stress.md.
#[test]
fn lavapipe_figures_stay_within_the_rules() {
    let (_out, doc, _dir) =
        stress(&["--cases", "watertight,far,grazing,degenerate,tmin,transform"]);
    for c in doc["cases"].as_array().unwrap() {
        // Every compared hit within the tolerance; no hit on a primitive the ray misses; any-hit
        // never sees one primitive twice (NO_DUPLICATE_ANY_HIT_INVOCATION).
        assert_eq!(n(c, "over_tolerance"), 0, "{}", c["name"]);
        assert_eq!(n(c, "wrong_hits"), 0, "{}", c["name"]);
        assert_eq!(n(c, "duplicate_any_hits"), 0, "{}", c["name"]);
        assert!(n(c, "rays") >= 96, "{}", c["name"]); // tmin: 8 parts of 12 rays
                                                      // Every leak has a subnormal ray component (flush to zero near a fan's centre vertex).
        assert_eq!(n(c, "leaks"), n(c, "leaks_subnormal"), "{}", c["name"]);
        // Every double hit is within the ambiguity margin of a shared edge (what f32 rounding
        // can explain); the warnings are those exactly on the edge (the spec's "should not").
        assert_eq!(n(c, "double_hits"), n(c, "double_hits_in_margin"), "{}", c["name"]);
        assert_eq!(n(c, "double_hit_warnings"), n(c, "double_hits_on_edge"), "{}", c["name"]);
    }
    let w = case(&doc, "watertight");
    assert!(n(w, "rays") > 10_000 && n(w, "hits") > 10_000);
    // lavapipe 25's largest barycentric error is on square-1024's slivers (2.4e-3 since issue
    // 22's sample of interior edges), within its ray-space tolerance (over_tolerance is 0).
    assert!(f(w, "bary_err_max") <= 5e-3 && f(w, "t_rel_err_max") < 1e-4);
    // transform: facing is a function of the object-space winding (mirrors included), culling
    // keeps exactly the other facing, object-space built-ins within the CTS's 3.8e-6.
    let tr = case(&doc, "transform");
    assert_eq!(n(tr, "facing_errors"), 0, "{tr}");
    assert!(f(tr, "builtin_err_max") < 4e-6, "{tr}");
    for name in ["grazing", "tmin", "transform"] {
        let c = case(&doc, name);
        assert_eq!(c["verdict"], "pass", "{c}");
        assert!(f(c, "t_rel_err_max") < 1e-3 && f(c, "bary_err_max") < 1e-3, "{c}");
    }
    // far: one point per distance and mode. Hit/miss always agrees; t stays within 1e-3
    // relative; double hits, and barycentric errors over 1e-3, only for rays from the origin to
    // a scene far away, where ulp(S) is a sizeable part of a unit triangle.
    let far = case(&doc, "far");
    assert_eq!(far["parts"].as_array().unwrap().len(), 24);
    assert_eq!(n(far, "disagreements"), 0);
    assert!(f(far, "t_rel_err_max") < 1e-3);
    for p in far["parts"].as_array().unwrap() {
        let camera = p["label"].as_str().unwrap().starts_with("camera");
        let d = f(p, "distance");
        if !camera || d <= 1e4 {
            assert_eq!(n(p, "double_hits"), 0, "{p}");
        }
        if !camera || d <= 1e3 {
            assert!(f(p, "bary_err_max") < 1e-3, "{p}");
        }
    }
    // tmin: only offsets outside the t margin (issue 22), each certain in or out, none
    // excluded as ambiguous.
    let tmin = case(&doc, "tmin");
    assert_eq!(n(tmin, "excluded"), 0, "{tmin}");
    for p in tmin["parts"].as_array().unwrap() {
        let label = p["label"].as_str().unwrap();
        let hits = n(p, "hits");
        match label {
            "tmin-1024ulp" | "tmin-256ulp" | "tmax+256ulp" | "tmax+1024ulp" => {
                assert_eq!(hits, n(p, "rays"), "{label}")
            }
            "tmin+256ulp" | "tmin+1024ulp" | "tmax-256ulp" | "tmax-1024ulp" => {
                assert_eq!(hits, 0, "{label}")
            }
            other => panic!("unexpected part {other}"),
        }
    }
    // Issue 22: no case but self (its secondary rays start on the surface, by construction
    // within their own triangle's t margin) leaves more than 4% of its rays to ambiguity.
    for c in doc["cases"].as_array().unwrap() {
        assert!(n(c, "excluded") * 25 <= n(c, "rays"), "{}: {}", c["name"], n(c, "excluded"));
    }
    // degenerate: NaN-X and coincident vertices never hit; the one false hit lavapipe shows is the
    // collinear triangle (primitive 1), written up in docs/stress.md.
    let d = case(&doc, "degenerate");
    for e in d["examples"].as_array().unwrap().iter().filter(|e| e["kind"] == "false_hit") {
        assert_eq!(e["hit"][0], 1, "{e}");
    }
}

/// Secondary rays from the device's own hit points: raw origins self-hit (the reference agrees:
/// the rounded point lies below the surface), Wächter & Binder's offset removes nearly all.
#[test]
fn self_hits_are_counted_and_the_offset_removes_them() {
    let (_out, doc, _dir) = stress(&["--cases", "self"]);
    let c = case(&doc, "self");
    assert_eq!(n(c, "disagreements"), 0, "{c}");
    let part = |label: &str| {
        c["parts"].as_array().unwrap().iter().find(|p| p["label"] == label).unwrap().clone()
    };
    let (raw, off) = (part("secondary-raw"), part("secondary-offset"));
    assert!(n(&raw, "self_hits") > 100, "{raw}");
    assert!(n(&off, "self_hits") * 10 < n(&raw, "self_hits"), "{off}");
}

fn stress_env(args: &[&str], env: &[(&str, &str)]) -> (std::process::Output, serde_json::Value) {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let json = dir.path().join("stress.json");
    let mut all = vec!["stress", "--json", json.to_str().unwrap()];
    all.extend_from_slice(args);
    let out = run_env(&all, env);
    let text = std::fs::read_to_string(&json)
        .unwrap_or_else(|e| panic!("no report ({e}); stderr: {}", stderr(&out)));
    (out, serde_json::from_str(&text).unwrap())
}

/// A submission past its fence deadline is that case's `timeout`, said by the worker itself (not
/// a worker killed for its silence, which reads the same but for the detail); each case runs in
/// a worker of its own, so the next case still runs and passes (under the same 5 s deadline,
/// unheld, as tmin does in the other tests). The device is made slower than the deadline by the
/// test hook `stall` (tmin's first submission held behind a timeline semaphore the worker signals
/// only once its fence wait has run out): the driver's own wait times out, whatever the
/// machine's load. With a 1 µs deadline and no hook, a small case could finish before its wait
/// began and pass, one CI run in many.
#[test]
fn a_fence_past_its_deadline_is_that_cases_timeout_and_the_next_case_runs() {
    let (out, doc) = stress_env(
        &["--cases", "tmin,transform", "--timeout", "5"],
        &[("RTPROBE_STRESS_FAULT", "tmin:stall")],
    );
    assert_eq!(out.status.code(), Some(1), "{}", stdout(&out));
    let tmin = case(&doc, "tmin");
    assert_eq!(tmin["verdict"], "timeout", "{tmin}");
    assert_eq!(tmin["detail"], "the trace did not finish within 5s", "{tmin}");
    assert!(n(tmin, "rays") > 0, "the rays that could not run are counted");
    assert_eq!(case(&doc, "transform")["verdict"], "pass");
}

/// A GPU that never finishes (`stall_forever`: the submission held for good): the worker still
/// reports its own timeout and exits — it leaves the device as it is rather than wait for work
/// that never ends (waiting, it was killed for its silence instead). The deadline below a
/// millisecond reaches the worker as given (it was once sent in whole milliseconds: zero).
#[test]
fn a_hung_gpu_is_the_workers_own_timeout_and_a_short_deadline_is_kept() {
    let (out, doc) = stress_env(
        &["--cases", "tmin", "--timeout", "0.0009"],
        &[("RTPROBE_STRESS_FAULT", "tmin:stall_forever")],
    );
    assert_eq!(out.status.code(), Some(1), "{}", stdout(&out));
    let tmin = case(&doc, "tmin");
    assert_eq!(tmin["detail"], "the trace did not finish within 900µs", "{tmin}");
}

/// Issue 22 item 4: a driver crash in one case (SIGSEGV in its worker, planted by the test
/// hook) is that case's `crash`, with the part it was tracing; the other cases run and pass, the
/// report is written and the exit status is 1.
#[test]
fn a_crash_in_one_case_is_that_cases_outcome_and_the_others_run() {
    let (out, doc) =
        stress_env(&["--cases", "tmin,transform"], &[("RTPROBE_STRESS_FAULT", "tmin:crash")]);
    assert_eq!(out.status.code(), Some(1), "{}", stdout(&out));
    let tmin = case(&doc, "tmin");
    assert_eq!(tmin["verdict"], "crash", "{tmin}");
    let detail = tmin["detail"].as_str().unwrap();
    assert!(detail.contains("signal 11 (SIGSEGV) at `trace tmin-1024ulp`"), "{detail}");
    assert_eq!(case(&doc, "transform")["verdict"], "pass");
    assert!(stdout(&out).contains("tmin — crash"), "{}", stdout(&out));
}

/// A worker that hangs outside any fence (silent past its deadline: twice the fence deadline
/// plus 10 s) is killed, and its case is a `timeout`; the next case runs.
#[test]
fn a_hung_worker_is_killed_and_its_case_is_a_timeout() {
    let t = std::time::Instant::now();
    let (out, doc) = stress_env(
        &["--cases", "tmin,transform", "--timeout", "1"],
        &[("RTPROBE_STRESS_FAULT", "tmin:hang")],
    );
    assert_eq!(out.status.code(), Some(1), "{}", stdout(&out));
    let tmin = case(&doc, "tmin");
    assert_eq!(tmin["verdict"], "timeout", "{tmin}");
    assert!(
        tmin["detail"].as_str().unwrap().contains("was silent for 12s and was killed"),
        "{tmin}"
    );
    assert_eq!(case(&doc, "transform")["verdict"], "pass");
    assert!(t.elapsed() < std::time::Duration::from_secs(120));
}

/// A check longer than the silence deadline (twice `--timeout` plus 10 s: 12 s here) that keeps
/// judging rays — a heartbeat line every 2 s in which more were judged — is not killed: the case
/// ends with its own verdict, and the progress lines say which case and how far it got.
#[test]
fn a_check_slower_than_the_deadline_with_heartbeats_is_not_killed() {
    let (out, doc) = stress_env(
        &["--cases", "tmin", "--timeout", "1"],
        &[("RTPROBE_STRESS_FAULT", "tmin:slow_check:16"), ("RTPROBE_PROGRESS_SECS", "5")],
    );
    let tmin = case(&doc, "tmin");
    assert_eq!(tmin["verdict"], "pass", "{tmin}");
    assert!(f(tmin, "ms") > 16_000.0, "{tmin}");
    let err = stderr(&out);
    let moved = err.lines().any(|l| {
        l.split("stress tmin: check: ")
            .nth(1)
            .is_some_and(|r| r.ends_with("/96 rays") && !r.starts_with("0/"))
    });
    assert!(moved, "a line with rays judged: {err}");
}

/// The twin: a check that stalls (no ray judged for longer than the deadline, its heartbeat
/// thread alive but with nothing new to say) is killed at the deadline and the case is a
/// `timeout` at `check` — a heartbeat alone cannot keep a hung check alive.
#[test]
fn a_check_slower_than_the_deadline_without_heartbeats_is_killed() {
    let (out, doc) = stress_env(
        &["--cases", "tmin", "--timeout", "1"],
        &[("RTPROBE_STRESS_FAULT", "tmin:stalled_check:16")],
    );
    assert_eq!(out.status.code(), Some(1), "{}", stdout(&out));
    let tmin = case(&doc, "tmin");
    assert_eq!(tmin["verdict"], "timeout", "{tmin}");
    let detail = tmin["detail"].as_str().unwrap();
    assert!(detail.contains("was silent for 12s and was killed at `check`"), "{detail}");
}

/// Issue 22 leftovers, item 3: building the reference's grid (`stress::index::Index::build`)
/// slower than the silence deadline (12 s here) — the test hook spreads 16 s over the case's
/// triangles — reports the triangles placed (`index: k/n triangles`), so the worker is not
/// killed and the case ends with its own verdict.
#[test]
fn an_index_build_slower_than_the_deadline_with_progress_is_not_killed() {
    let (out, doc) = stress_env(
        &["--cases", "tmin", "--timeout", "1"],
        &[("RTPROBE_STRESS_FAULT", "tmin:slow_index:16"), ("RTPROBE_PROGRESS_SECS", "5")],
    );
    let tmin = case(&doc, "tmin");
    assert_eq!(tmin["verdict"], "pass", "{tmin}");
    assert!(f(tmin, "ms") > 16_000.0, "the hook ran: {tmin}");
    let err = stderr(&out);
    let moved = err.lines().any(|l| {
        l.split("stress tmin: index: ")
            .nth(1)
            .is_some_and(|r| r.ends_with(" triangles") && !r.starts_with("0/"))
    });
    assert!(moved, "a line with triangles placed: {err}");
}

/// The twin: a grid build that stalls (no triangle placed for longer than the deadline) is
/// killed at `index`, its case a `timeout`: the heartbeat speaks only on progress.
#[test]
fn an_index_build_that_stalls_is_killed_at_index() {
    let (out, doc) = stress_env(
        &["--cases", "tmin", "--timeout", "1"],
        &[("RTPROBE_STRESS_FAULT", "tmin:stalled_index:16")],
    );
    assert_eq!(out.status.code(), Some(1), "{}", stdout(&out));
    let tmin = case(&doc, "tmin");
    assert_eq!(tmin["verdict"], "timeout", "{tmin}");
    let detail = tmin["detail"].as_str().unwrap();
    assert!(detail.contains("was silent for 12s and was killed at `index`"), "{detail}");
}

/// Ray queries in a compute shader trace the same rays: on lavapipe (one intersection routine)
/// every count agrees with the pipeline's, and the report says which tracer ran.
#[test]
fn ray_query_traces_the_same_rays() {
    let cases = "watertight,degenerate,tmin,transform";
    let (_o1, rt, _d1) = stress(&["--cases", cases]);
    let (_o2, rq, _d2) = stress(&["--cases", cases, "--ray-query"]);
    assert_eq!(rt["tracer"], "pipeline");
    assert_eq!(rq["tracer"], "ray_query");
    for name in cases.split(',') {
        let (a, b) = (case(&rt, name), case(&rq, name));
        for field in [
            "rays",
            "hits",
            "leaks",
            "false_hits",
            "wrong_hits",
            "double_hits",
            "facing_errors",
            "over_tolerance",
        ] {
            assert_eq!(a[field], b[field], "{name}.{field}");
        }
    }
}

#[test]
fn stress_bad_input_is_one_line() {
    assert_one_line_error(
        &run(&["stress", "--cases", "watertight,nope"]),
        2,
        "unknown stress case `nope`",
    );
    assert_one_line_error(&run(&["stress", "--timeout", "0"]), 2, "--timeout");
    let dir = rtprobe::tempdir::tempdir().unwrap();
    std::fs::write(dir.path().join("a-file"), b"").unwrap();
    let bad = dir.path().join("a-file").join("x.json");
    let o = run(&["stress", "--cases", "tmin", "--json", bad.to_str().unwrap()]);
    // Checked before any case runs (no table printed), in one line.
    assert_one_line_error(&o, 9, "--json");
    assert!(stderr(&o).contains("cannot write in"), "{}", stderr(&o));
    assert!(stdout(&o).is_empty(), "{}", stdout(&o));
    let o =
        run(&["stress", "--cases", "tmin", "--svg", dir.path().join("f.svg").to_str().unwrap()]);
    assert_one_line_error(&o, 9, "--svg needs the far case");
}

/// Ctrl-C while a stress case's worker runs (held by the test hook `hang`): the worker is
/// killed, the workers' folder `rtprobe-stress-<pid>-…` goes with its job file, and the message
/// says nothing was written — not `run`'s report and `--resume`, which stress has none of.
/// Twin: stress once said `run`'s message and left its folder in TMPDIR.
#[test]
fn ctrl_c_during_stress_kills_its_worker_and_leaves_nothing() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let json = dir.path().join("s.json");
    let tmp = dir.path().join("tmp");
    std::fs::create_dir(&tmp).unwrap();
    let mut c = bin();
    c.args(["stress", "--cases", "tmin", "--json"])
        .arg(&json)
        .env("TMPDIR", &tmp)
        .env("RTPROBE_STRESS_FAULT", "tmin:hang");
    let (status, err) = interrupt_once_children_run(c, (&tmp, "__stress"), libc::SIGINT, |_| {});
    assert_eq!(status.code(), Some(130), "{status:?} {err}");
    assert!(err.contains("interrupted (SIGINT)") && err.contains("nothing was written"), "{err}");
    assert!(!err.contains("--resume"), "{err}");
    assert!(!json.exists());
    assert_eq!(entries(&tmp), Vec::<String>::new(), "the workers' folder and its job file");
}
