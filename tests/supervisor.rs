//! End-to-end tests of the supervisor on lavapipe: faults are classified in the phase where they
//! happen (setup, pipeline, between cells, teardown), deadlines fire whatever the worker does,
//! every attempt records the device features its worker enabled, and no worker outlives the
//! supervisor (SIGINT, SIGKILL). Misbehaving workers come from the supervisor's own test hook,
//! `RTPROBE_WORKER_FAULT=<phase>:<hang|crash|spam|lose|no_compiler>` (src/runner/misbehave.rs).
mod common;
use common::*;
use serde_json::Value;
use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

/// One raygen cell.
const ONE: &str =
    "stage=raygen,resource=storage_buffer,index=literal,descriptor_model=descriptor_indexing";
/// Two cells (raygen and compute).
const TWO: &str = "stage=raygen|compute,resource=storage_buffer,index=literal,descriptor_model=descriptor_indexing";

fn report(path: &Path) -> Value {
    serde_json::from_slice(&std::fs::read(path).expect("report written")).expect("report is JSON")
}

fn cells(r: &Value) -> Vec<Value> {
    r["cells"]
        .as_array()
        .expect("cells")
        .iter()
        .filter(|c| c["outcome"] != "unsupported")
        .cloned()
        .collect()
}

fn workers(r: &Value) -> Vec<Value> {
    r["workers"].as_array().expect("workers").clone()
}

/// `rtprobe run` with the worker fault `fault` (if any), killed and failed after `limit`: a
/// supervisor that hangs fails the test instead of hanging it.
fn run_bounded(args: &[&str], fault: Option<&str>, limit: Duration) -> (Output, Duration) {
    let mut c = bin();
    if let Some(f) = fault {
        c.env("RTPROBE_WORKER_FAULT", f);
    }
    // `-vv` logs can be huge when the supervisor fails to stop a flooding worker: not kept.
    let err = if args.contains(&"-vv") { Stdio::null() } else { Stdio::piped() };
    let child = c.args(args).stdout(Stdio::piped()).stderr(err).spawn().expect("spawn rtprobe");
    let pid = child.id() as i32;
    let (tx, rx) = std::sync::mpsc::channel();
    let t = Instant::now();
    std::thread::spawn(move || {
        let _ = tx.send(child.wait_with_output());
    });
    match rx.recv_timeout(limit) {
        Ok(o) => (o.expect("wait"), t.elapsed()),
        Err(_) => {
            unsafe { libc::kill(pid, libc::SIGKILL) };
            panic!("rtprobe run {args:?} with {fault:?} did not finish within {limit:?}: the supervisor hangs");
        }
    }
}

fn fault_run(
    fault: &str,
    filter: &str,
    extra: &[&str],
    limit: Duration,
) -> (Output, Value, Duration) {
    fault_run_with(&[], fault, filter, extra, limit)
}

fn fault_run_with(
    global: &[&str],
    fault: &str,
    filter: &str,
    extra: &[&str],
    limit: Duration,
) -> (Output, Value, Duration) {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let out = dir.path().join("r.json");
    let mut args = global.to_vec();
    args.extend_from_slice(&[
        "run",
        "-j",
        "1",
        "--no-confirm",
        "--patches",
        "none",
        "--filter",
        filter,
        "-o",
        out.to_str().unwrap(),
    ]);
    args.extend_from_slice(extra);
    let (o, took) = run_bounded(&args, Some(fault), limit);
    let r = report(&out);
    (o, r, took)
}

#[test]
fn device_loss_in_setup_is_the_setups_outcome_and_no_cell_runs() {
    let (o, r, _) = fault_run("setup:lose", TWO, &[], Duration::from_secs(180));
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let ws = workers(&r);
    // Retried once in a fresh worker, then given up: two setup records, each a device loss.
    assert_eq!(ws.len(), 2, "{ws:?}");
    for w in &ws {
        assert_eq!(w["phase"], "setup");
        assert_eq!(w["outcome"], "device_lost");
        assert!(
            w["detail"].as_str().unwrap().contains("acceleration structures and resources"),
            "{w}"
        );
    }
    let cs = cells(&r);
    assert_eq!(cs.len(), 2);
    for c in &cs {
        // Every cell is recorded, none blamed: not run, with the setup's outcome.
        assert_eq!(c["outcome"], "device_lost", "{c}");
        assert_eq!(c["attempts"][0]["phase"], "setup");
        assert!(c["attempts"][0]["result"].is_null(), "a cell ran on a lost device: {c}");
        assert!(c["reason"].as_str().unwrap().starts_with("not run:"), "{c}");
    }
}

#[test]
fn hung_device_creation_makes_the_cells_timeout_in_setup() {
    let (o, r, took) =
        fault_run("setup:hang", TWO, &["--setup-timeout", "2"], Duration::from_secs(120));
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(took < Duration::from_secs(60), "took {took:?}");
    let ws = workers(&r);
    assert_eq!(ws.len(), 2, "{ws:?}");
    for w in &ws {
        assert_eq!(
            (w["phase"].as_str(), w["outcome"].as_str()),
            (Some("setup"), Some("timeout")),
            "{w}"
        );
        assert!(w["detail"].as_str().unwrap().contains("vkCreateDevice"), "{w}");
    }
    for c in cells(&r) {
        assert_eq!(c["outcome"], "timeout", "{c}");
        assert_eq!(c["attempts"][0]["phase"], "setup");
    }
}

#[test]
fn a_worker_without_a_shader_compiler_stops_the_run_with_exit_12() {
    // Two workers at once: the first whose shader compiler cannot start halts the run. The other
    // is killed, no worker is retried, no cell is given up as not run, and the CLI exits 12.
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let out = dir.path().join("r.json");
    let args = [
        "run",
        "-j",
        "2",
        "--no-confirm",
        "--patches",
        "none",
        "--filter",
        TWO,
        "-o",
        out.to_str().unwrap(),
    ];
    let (o, took) = run_bounded(&args, Some("setup:no_compiler"), Duration::from_secs(120));
    assert_one_line_error(&o, 12, "could not start the shader compiler (shaderc)");
    let err = stderr(&o);
    // The hook is named as the cause (not memory), and the resume command is the real one.
    assert!(err.contains("RTPROBE_WORKER_FAULT=setup:no_compiler made it fail"), "{err}");
    assert!(err.contains(&format!("--resume {}", out.display())), "{err}");
    assert!(took < Duration::from_secs(60), "took {took:?}");
    let r = report(&out);
    let ws = workers(&r);
    assert_eq!(ws.len(), 1, "halted at the first, not retried: {ws:?}");
    assert_eq!(
        (ws[0]["phase"].as_str(), ws[0]["outcome"].as_str()),
        (Some("setup"), Some("error"))
    );
    let detail = ws[0]["detail"].as_str().unwrap();
    assert!(detail.contains("(shader compiler (shaderc)): "), "blames its own step: {detail}");
    assert_eq!(ws[0]["halt"], "no_shader_compiler", "{}", ws[0]);
    // Its cells stay without an attempt, and the report says the run did not complete.
    assert!(cells(&r).is_empty(), "{:?}", cells(&r));
    assert_eq!(r["complete"], false);
    // Once the compiler starts again, `--resume` runs them, and the halted worker is no driver
    // fault: the run passes (exit 0), and a baseline made from it expects no worker fault.
    let mut resumed = args[..args.len() - 2].to_vec();
    resumed.extend(["--resume", out.to_str().unwrap()]);
    let (o, _) = run_bounded(&resumed, None, Duration::from_secs(120));
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let r = report(&out);
    assert!(!cells(&r).is_empty() && r["complete"] == true, "{r}");
    let base = dir.path().join("b.json");
    let o = bin().args(["baseline", out.to_str().unwrap(), "-o", base.to_str().unwrap()]).output();
    assert!(o.unwrap().status.success());
    let b: serde_json::Value = serde_json::from_slice(&std::fs::read(&base).unwrap()).unwrap();
    assert!(b.get("worker_faults").is_none_or(|w| w.as_array().unwrap().is_empty()), "{b}");
}

#[test]
fn a_hang_in_pipeline_creation_is_a_timeout_in_pipeline() {
    let (o, r, _) = fault_run("pipeline:hang", ONE, &["--timeout", "3"], Duration::from_secs(120));
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let cs = cells(&r);
    assert_eq!(cs.len(), 1);
    let a = &cs[0]["attempts"][0];
    assert_eq!(cs[0]["outcome"], "timeout");
    assert_eq!(a["phase"], "pipeline", "{a}");
    assert!(a["detail"].as_str().unwrap().contains("in pipeline"), "{a}");
    // Its worker got ready first: setup is recorded as passed, with what the device enabled.
    let ws = workers(&r);
    assert_eq!(ws[0]["phase"], "setup");
    assert_eq!(ws[0]["outcome"], "pass");
}

#[test]
fn a_worker_that_keeps_printing_still_times_out() {
    // With debug logs on (`-vv`, as when someone investigates a hang) the supervisor handles each
    // line slower than the worker prints them: its queue never runs dry, and the deadline must
    // still fire.
    let (o, r, took) =
        fault_run_with(&["-vv"], "trace:spam", ONE, &["--timeout", "3"], Duration::from_secs(60));
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(took < Duration::from_secs(60), "took {took:?}");
    let cs = cells(&r);
    assert_eq!(cs[0]["outcome"], "timeout", "{}", cs[0]);
    assert_eq!(cs[0]["attempts"][0]["phase"], "trace");
}

#[test]
fn a_crash_between_cells_is_recorded_and_the_rest_still_run() {
    let (o, r, _) = fault_run("between_cells:crash", TWO, &[], Duration::from_secs(180));
    // A crash outside any cell is a finding: it is recorded for its worker, never blamed on a cell.
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let cs = cells(&r);
    assert_eq!(cs.len(), 2);
    for c in &cs {
        assert_eq!(c["outcome"], "pass", "{c}");
        assert_eq!(c["attempts"].as_array().unwrap().len(), 1);
    }
    let crashes: Vec<_> = workers(&r).into_iter().filter(|w| w["outcome"] == "crash").collect();
    assert_eq!(crashes.len(), 1, "{:?}", workers(&r));
    assert_eq!(crashes[0]["phase"], "between_cells");
    assert_eq!(crashes[0]["worker_exit"]["signal"], 11);
    // The replacement worker ran the second cell.
    assert_ne!(cs[0]["attempts"][0]["worker"], cs[1]["attempts"][0]["worker"]);
    assert!(stdout(&o).contains("worker faults outside cells (1)"), "{}", stdout(&o));
}

/// A real fault (an invalid write, as a driver's crash) mid-cell: the cell's crash, and the
/// worker's stderr tail carries its native backtrace — the signal, the address, frames naming
/// the binary and offsets — which the report keeps. Twin of `crash` (a raised SIGSEGV, no fault
/// address): no backtrace line there — that injection puts the default action back before it
/// raises, so the handler never runs (a raised signal with the handler in place is not tested).
#[test]
fn a_real_fault_mid_cell_comes_with_its_native_backtrace() {
    let (o, r, _) = fault_run("trace:fault", TWO, &[], Duration::from_secs(180));
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let crashed: Vec<Value> = cells(&r).into_iter().filter(|c| c["outcome"] == "crash").collect();
    assert!(!crashed.is_empty(), "{:?}", cells(&r));
    let exit = &crashed[0]["attempts"][0]["worker_exit"];
    assert_eq!(exit["signal"], 11, "{exit}");
    let tail = exit["stderr_tail"].as_str().unwrap_or_default();
    assert!(tail.contains("rtprobe worker: fatal signal 11 (fault address 0x"), "{tail}");
    assert!(
        tail.lines().filter(|l| l.contains("(+0x") || l.contains("[0x")).count() >= 3,
        "{tail}"
    );
    let (_, raised, _) = fault_run("trace:crash", TWO, &[], Duration::from_secs(180));
    let c = cells(&raised).into_iter().find(|c| c["outcome"] == "crash").expect("a crash");
    let tail = c["attempts"][0]["worker_exit"]["stderr_tail"].as_str().unwrap_or_default();
    assert!(!tail.contains("fatal signal"), "{tail}");
}

#[test]
fn a_hang_between_cells_is_the_workers_and_the_next_cell_still_runs() {
    let (o, r, took) =
        fault_run("between_cells:hang", TWO, &["--timeout", "3"], Duration::from_secs(120));
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(took < Duration::from_secs(60), "took {took:?}");
    assert!(cells(&r).iter().all(|c| c["outcome"] == "pass"), "{:?}", cells(&r));
    let hung: Vec<_> = workers(&r).into_iter().filter(|w| w["outcome"] == "timeout").collect();
    assert_eq!(hung.len(), 1, "{:?}", workers(&r));
    assert_eq!(hung[0]["phase"], "between_cells");
}

#[test]
fn a_hang_in_teardown_is_bounded_and_reported() {
    let (o, r, took) =
        fault_run("teardown:hang", ONE, &["--timeout", "3"], Duration::from_secs(120));
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(took < Duration::from_secs(60), "took {took:?}");
    assert_eq!(cells(&r)[0]["outcome"], "pass");
    let hung: Vec<_> = workers(&r).into_iter().filter(|w| w["phase"] == "teardown").collect();
    assert_eq!(hung.len(), 1, "{:?}", workers(&r));
    assert_eq!(hung[0]["outcome"], "timeout");
}

#[test]
fn every_attempt_records_the_features_its_worker_enabled() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let out = dir.path().join("r.json");
    let (o, _) = run_bounded(
        &[
            "run",
            "--isolation",
            "process-per-cell",
            "--patches",
            "none",
            "--filter",
            TWO,
            "-o",
            out.to_str().unwrap(),
        ],
        None,
        Duration::from_secs(180),
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let r = report(&out);
    let features = |stage: &str| -> Vec<String> {
        let c = cells(&r).into_iter().find(|c| c["stage"] == stage).unwrap();
        c["attempts"][0]["device_features"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_str().unwrap().to_string())
            .collect()
    };
    let rt = features("raygen");
    assert!(
        rt.iter().any(|f| f == "VK_KHR_ray_tracing_pipeline")
            && rt.iter().any(|f| f == "rayTracingPipeline"),
        "{rt:?}"
    );
    // A compute cell alone needs no ray tracing pipeline: its worker did not enable one.
    let compute = features("compute");
    assert!(compute.iter().any(|f| f == "bufferDeviceAddress"), "{compute:?}");
    assert!(
        !compute.iter().any(|f| f == "VK_KHR_ray_tracing_pipeline" || f == "rayTracingPipeline"),
        "{compute:?}"
    );
    // And the workers' setup records say the same.
    let ws = workers(&r);
    assert_eq!(ws.len(), 2);
    assert!(ws.iter().all(|w| w["phase"] == "setup" && w["outcome"] == "pass"));
}

// ---- no orphans ----------------------------------------------------------------------------

/// Live `rtprobe __worker` processes whose job file lies in `job_dir`.
fn live_workers(job_dir: &str) -> Vec<i32> {
    live_processes(job_dir, "__worker", 0)
}

/// Start a run (with the worker fault `fault`, if any), wait until a worker runs (and, without a
/// fault, a cell finished), then `kill` the supervisor with `sig`, and check that no worker of
/// this run is left. Returns the supervisor's exit and its stderr.
fn interrupt_mid_run(
    out: &Path,
    sig: i32,
    filter: &str,
    fault: Option<&str>,
) -> (std::process::ExitStatus, String) {
    let mut c = bin();
    if let Some(f) = fault {
        c.env("RTPROBE_WORKER_FAULT", f);
    }
    // Its temporary folders next to the report, for the tests to look at.
    c.env("TMPDIR", out.parent().unwrap());
    let mut child = c
        .args([
            "run",
            "-j",
            "2",
            "--timeout",
            "60",
            "--patches",
            "none",
            "--filter",
            filter,
            "-o",
            out.to_str().unwrap(),
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // The supervisor's job folder, `rtprobe-jobs-<pid>-<n>-<nanos>`.
    let job_dir = format!("rtprobe-jobs-{}-", child.id());
    let start = Instant::now();
    loop {
        let done = std::fs::read(out)
            .ok()
            .and_then(|b| serde_json::from_slice::<Value>(&b).ok())
            .map(|r| {
                cells(&r).iter().filter(|c| !c["attempts"].as_array().unwrap().is_empty()).count()
            })
            .unwrap_or(0);
        if (done >= 1 || fault.is_some()) && !live_workers(&job_dir).is_empty() {
            break;
        }
        assert!(start.elapsed() < Duration::from_secs(120), "run made no progress");
        std::thread::sleep(Duration::from_millis(20));
    }
    if fault.is_some() {
        // Let the worker reach its hang.
        std::thread::sleep(Duration::from_millis(1500));
    }
    unsafe { libc::kill(child.id() as i32, sig) };
    let status = child.wait().unwrap();
    let mut err = String::new();
    use std::io::Read;
    child.stderr.take().unwrap().read_to_string(&mut err).unwrap();
    // Nothing of this run may still be running (SIGKILL and reaping take a moment).
    let start = Instant::now();
    loop {
        let left = live_workers(&job_dir);
        if left.is_empty() {
            break;
        }
        if start.elapsed() > Duration::from_secs(3) {
            for pid in &left {
                unsafe { libc::kill(*pid, libc::SIGKILL) };
            }
            panic!("workers outlived the supervisor: {left:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    (status, err)
}

const MANY: &str = "descriptor_model=descriptor_indexing,resource=storage_buffer|uniform_buffer,stage=raygen|closest_hit|miss|compute,base=none|push_data";

#[test]
fn ctrl_c_kills_every_worker_keeps_the_report_and_resume_finishes() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let out = dir.path().join("r.json");
    let (status, err) = interrupt_mid_run(&out, libc::SIGINT, MANY, None);
    assert_eq!(status.code(), Some(130), "{status:?}");
    assert!(err.contains("interrupted (SIGINT)") && err.contains("--resume"), "{err}");
    let r = report(&out);
    assert_eq!(r["complete"], false);
    // The handler removed the job folder, with any job file no worker had read yet.
    assert_eq!(job_folders(dir.path()), Vec::<String>::new());
    // The same result-changing options as the interrupted run (a different --timeout is refused).
    let o = run(&[
        "run",
        "-j",
        "2",
        "--timeout",
        "20",
        "--patches",
        "none",
        "--filter",
        MANY,
        "--resume",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(9), "{}", stderr(&o));
    assert!(stderr(&o).contains("--timeout differs"), "{}", stderr(&o));
    let o = run(&[
        "run",
        "-j",
        "2",
        "--timeout",
        "60",
        "--patches",
        "none",
        "--filter",
        MANY,
        "--resume",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let r = report(&out);
    assert_eq!(r["complete"], true);
    assert!(cells(&r).iter().all(|c| c["outcome"] == "pass"));
}

#[test]
fn sigterm_kills_a_hung_worker_too() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let (status, err) =
        interrupt_mid_run(&dir.path().join("r.json"), libc::SIGTERM, ONE, Some("pipeline:hang"));
    assert_eq!(status.code(), Some(143), "{status:?}");
    assert!(err.contains("terminated (SIGTERM)"), "{err}");
    // The handler removed the supervisor's job folder too (the hung worker had read its job).
    assert_eq!(job_folders(dir.path()), Vec::<String>::new());
}

/// The `rtprobe-jobs-*` folders in `dir`.
fn job_folders(dir: &Path) -> Vec<String> {
    let names = std::fs::read_dir(dir).unwrap().flatten();
    names
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with("rtprobe-jobs-"))
        .collect()
}

/// A run's job files lie in a fresh private folder of its own, removed when the run ends: never
/// a predictable name. The old one, `rtprobe-<pid>`, made runs fail in CI (every cell an `error`
/// at 0.0 s) when an earlier process with the same pid had left it with mode 0755: planted here
/// under the run's own pid (`exec` keeps the shell's), the run passes and leaves it alone.
#[test]
fn a_folder_left_under_the_runs_pid_is_no_matter_and_the_run_leaves_none() {
    let tmp = rtprobe::tempdir::tempdir().unwrap();
    let out = tmp.path().join("r.json");
    let mut c = Command::new("sh");
    let plant = r#"mkdir -m 755 "$TMPDIR/rtprobe-$$" && exec "$0" "$@""#;
    c.args(["-c", plant, env!("CARGO_BIN_EXE_rtprobe")]);
    c.args(["run", "--patches", "none", "--filter", ONE, "-o", out.to_str().unwrap()]);
    for (k, v) in bin().get_envs() {
        match v {
            Some(v) => c.env(k, v),
            None => c.env_remove(k),
        };
    }
    c.env("TMPDIR", tmp.path());
    let child = c.stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().unwrap();
    let pid = child.id();
    let o = child.wait_with_output().unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(cells(&report(&out)).iter().all(|c| c["outcome"] == "pass"));
    let mut left: Vec<String> = std::fs::read_dir(tmp.path())
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    left.sort();
    assert_eq!(left, ["r.json".to_string(), format!("rtprobe-{pid}")]);
}

#[test]
fn a_killed_supervisor_leaves_no_worker_running() {
    // The worker hangs in pipeline creation: nothing but the supervisor's death can end it.
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let (status, _) =
        interrupt_mid_run(&dir.path().join("r.json"), libc::SIGKILL, ONE, Some("pipeline:hang"));
    use std::os::unix::process::ExitStatusExt;
    assert_eq!(status.signal(), Some(libc::SIGKILL));
}

/// A fault while a worker builds its batch on several threads (`--threads 2`) cannot be blamed on
/// one cell: it is the worker's record (phase `prebuild`), and the batch runs again in a fresh
/// worker with each cell building at its turn. No cell is lost, none is blamed.
#[test]
fn a_fault_while_prebuilding_is_the_workers_and_the_batch_runs_cell_by_cell() {
    for (fault, outcome) in [
        ("prebuild:crash", "crash"),
        ("prebuild:hang", "timeout"),
        ("prebuild:lose", "device_lost"),
    ] {
        let (r, _) = prebuild_fault(fault, outcome);
        assert_eq!(r["options"]["threads"], 2);
    }
}

/// A `--threads 2` run of [`TWO`] with `fault` injected (validation off: under --validate a
/// worker never prebuilds, one thread), held to what every fault before `prebuilt` gives: exit 1
/// within a minute, one `prebuild` worker entry of `outcome` whose batch runs again cell by cell,
/// and both cells passing on another worker, one attempt each. The report and that entry.
fn prebuild_fault(fault: &str, outcome: &str) -> (Value, Value) {
    let (o, r, took) = fault_run_with(
        &["--validate=off"],
        fault,
        TWO,
        &["--threads", "2", "--timeout", "3"],
        Duration::from_secs(120),
    );
    assert_eq!(o.status.code(), Some(1), "{fault}: {}", stderr(&o));
    assert!(took < Duration::from_secs(60), "{fault} took {took:?}");
    let ws = workers(&r);
    let pre: Vec<_> = ws.iter().filter(|w| w["phase"] == "prebuild").collect();
    assert_eq!(pre.len(), 1, "{fault}: {ws:?}");
    let pre = pre[0].clone();
    assert_eq!(pre["outcome"], outcome, "{fault}: {pre}");
    let detail = pre["detail"].as_str().unwrap();
    assert!(detail.contains("each cell building at its turn"), "{fault}: {detail}");
    let cs = cells(&r);
    assert_eq!(cs.len(), 2, "{fault}");
    for c in &cs {
        assert_eq!(c["outcome"], "pass", "{fault}: {c}");
        assert_eq!(c["attempts"].as_array().unwrap().len(), 1, "{fault}: {c}");
        assert_ne!(
            c["attempts"][0]["worker"], pre["worker"],
            "{fault}: the failed prebuild's worker has no attempt: {c}"
        );
    }
    (r, pre)
}

/// Twin: with one thread the worker never prebuilds, so the same hook never fires.
#[test]
fn one_thread_never_prebuilds() {
    let (o, r, _) = fault_run("prebuild:crash", TWO, &["--threads", "1"], Duration::from_secs(120));
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(
        workers(&r).iter().all(|w| w["phase"] == "setup" && w["outcome"] == "pass"),
        "{:?}",
        workers(&r)
    );
    assert_eq!(r["timing"]["prebuilt_pipelines"], 0);
    assert!(cells(&r).iter().all(|c| c["outcome"] == "pass"));
}

/// A crash in pipeline creation at a cell's turn is still that cell's, in `pipeline`, when the
/// worker prebuilds (the prebuilt cell enters its `pipeline` phase at its turn).
#[test]
fn a_crash_in_pipeline_with_threads_is_one_cells_verdict() {
    let (o, r, _) = fault_run_with(
        &["--validate=off"],
        "pipeline:crash",
        TWO,
        &["--threads", "2"],
        Duration::from_secs(180),
    );
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    // The first worker prebuilt; its first cell crashed at its turn, or, when that cell ran
    // while the other pipeline was still being made (overlapped), the crash was the prebuild's
    // and the cells crashed again, each alone.
    let overlapped =
        workers(&r).iter().any(|w| w["phase"] == "prebuild" && w["outcome"] == "crash");
    assert!(
        overlapped || r["timing"]["prebuilt_pipelines"].as_u64().unwrap() >= 1,
        "{}",
        r["timing"]
    );
    for c in cells(&r) {
        assert_eq!(c["outcome"], "crash", "{c}");
        assert_eq!(c["attempts"][0]["phase"], "pipeline", "{c}");
    }
}

/// A fault in a cell that runs while the prebuild's other pipelines are still being made (an
/// overlapped cell; `overlap:` holds the pool so that the first cell always overlaps) cannot be
/// pinned on that cell: it is the worker's record in `prebuild`, naming the cell's phase, and the
/// batch runs again with each cell at its turn, nothing else running. No cell is blamed; the
/// fault stays in the report.
#[test]
fn a_fault_in_an_overlapped_cell_is_the_prebuilds_and_its_cells_run_again_alone() {
    for (fault, outcome) in
        [("overlap:crash", "crash"), ("overlap:hang", "timeout"), ("overlap:lose", "device_lost")]
    {
        let (r, pre) = prebuild_fault(fault, outcome);
        let detail = pre["detail"].as_str().unwrap();
        assert!(detail.contains(": trace"), "{fault}: the overlapped cell's phase named: {detail}");
        let ids: Vec<Value> = cells(&r).iter().map(|c| c["id"].clone()).collect();
        assert!(ids.contains(&pre["overlapped_cell"]), "{fault}: the entry names it: {pre}");
        assert_eq!(r["timing"]["overlapped_cells"], 0, "{fault}: the re-run overlaps nothing");
    }
}

/// Twin: the same hold without a fault. The first cell runs while the second pipeline waits
/// (overlapped), its lines come after `prebuilt`, and both cells pass in the prebuilding worker.
#[test]
fn an_overlapped_cell_without_a_fault_is_reported_after_the_prebuild() {
    let (o, r, _) = fault_run_with(
        &["--validate=off"],
        "overlap:hold",
        TWO,
        &["--threads", "2"],
        Duration::from_secs(120),
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let ws = workers(&r);
    assert!(ws.iter().all(|w| w["phase"] == "setup" && w["outcome"] == "pass"), "{ws:?}");
    assert!(r["timing"]["overlapped_cells"].as_u64().unwrap() >= 1, "{}", r["timing"]);
    assert_eq!(r["timing"]["prebuilt_pipelines"], 2, "{}", r["timing"]);
    let cs = cells(&r);
    assert_eq!(cs.len(), 2);
    for c in &cs {
        assert_eq!(c["outcome"], "pass", "{c}");
        assert_eq!(c["attempts"][0]["worker"], ws[0]["worker"], "{c}");
        let wall = c["attempts"][0]["wall_ms"].as_f64().unwrap();
        let total = c["attempts"][0]["result"]["timings"]["total_ms"].as_f64().unwrap();
        assert!(wall >= total, "the held lines keep the worker's time: {c}");
    }
    let t = &r["timing"];
    let own = t["own_ms"].as_f64().expect("own time recorded");
    let wall = t["wall_ms"].as_f64().unwrap();
    assert!(own > 0.0 && own < wall, "own {own} of {wall}");
    // The setup waited on the queue for the scene's AS build: the driver's, left out of `own`.
    let ms = |k: &str| t[k].as_f64().unwrap_or_else(|| panic!("timing.{k}: {t}"));
    let setup_wait = ms("setup_wait_ms");
    let setups = ms("device_ms_mean") * ms("workers_started");
    assert!(setup_wait > 0.0 && setup_wait < setups, "{t}");
    let driver = ms("device_create_ms") + setup_wait + ms("pipeline_wait_ms") + ms("trace_ms");
    assert!((own - (wall - driver).max(0.0)).abs() < 1e-6, "own {own}, wall {wall}: {t}");
}

/// Twin of the checker thread (`exec::checker`): an overlapped cell's records are judged off the
/// cell thread, and a wrong value there is still that cell's mismatch — garbage (NaN) in the
/// raygen cell, which runs first and overlapped — while the other cell passes; no cell is lost
/// or swapped on the way back.
#[test]
fn an_overlapped_cells_wrong_values_are_its_mismatch_when_judged_off_the_cell_thread() {
    let (o, r, _) = fault_run_with(
        &["--validate=off"],
        "overlap:hold",
        TWO,
        &["--threads", "2", "--inject-fault", "stage=raygen@nan"],
        Duration::from_secs(120),
    );
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(r["timing"]["overlapped_cells"].as_u64().unwrap() >= 1, "{}", r["timing"]);
    // (the overlapped cell's check did go to the checker thread)
    assert!(r["timing"]["checked_apart"].as_u64().unwrap() >= 1, "{}", r["timing"]);
    let ws = workers(&r);
    assert!(ws.iter().all(|w| w["phase"] == "setup" && w["outcome"] == "pass"), "{ws:?}");
    let cs = cells(&r);
    assert_eq!(cs.len(), 2);
    for c in &cs {
        let want = if c["stage"] == "raygen" { "mismatch" } else { "pass" };
        assert_eq!(c["outcome"], want, "{c}");
        assert_eq!(c["attempts"][0]["worker"], ws[0]["worker"], "{c}");
    }
    let raygen = cs.iter().find(|c| c["stage"] == "raygen").unwrap();
    let cmp = &raygen["attempts"][0]["result"]["comparison"];
    assert!(cmp["mismatched_pixels"].as_u64().unwrap() > 0, "{cmp}");
}

/// A real hang in an overlapped cell (an injected endless loop in the raygen cell, which runs
/// first): the worker's fence deadline ends it, in `prebuild`, blamed on no cell; the cell then
/// runs alone and its timeout is pinned on it, in `trace`, while the other cell passes.
#[test]
fn a_hang_in_an_overlapped_cell_times_out_and_is_pinned_when_it_runs_alone() {
    let (o, r, took) = fault_run_with(
        &["--validate=off"],
        "overlap:hold",
        TWO,
        &["--threads", "2", "--timeout", "3", "--inject-fault", "stage=raygen@hang"],
        Duration::from_secs(180),
    );
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(took < Duration::from_secs(90), "took {took:?}");
    let ws = workers(&r);
    let pre: Vec<_> = ws.iter().filter(|w| w["phase"] == "prebuild").collect();
    assert_eq!(pre.len(), 1, "{ws:?}");
    assert_eq!(pre[0]["outcome"], "timeout", "{}", pre[0]);
    let detail = pre[0]["detail"].as_str().unwrap();
    assert!(detail.contains("while pipelines were still being made"), "{detail}");
    for c in cells(&r) {
        let first = &c["attempts"][0];
        assert_ne!(first["worker"], pre[0]["worker"], "{c}");
        if c["stage"] == "raygen" {
            assert_eq!(c["outcome"], "timeout", "{c}");
            assert_eq!(first["phase"], "trace", "{c}");
        } else {
            assert_eq!(c["outcome"], "pass", "{c}");
        }
    }
}

/// Twin of the overlap, through the CLI: under `--validate` the CLI runs one thread, so the
/// worker never prebuilds and an `overlap:` fault never fires. The worker's own rule (validation
/// with several threads never overlaps) is `runner::protocol`'s unit test
/// `validation_never_overlaps_whatever_the_threads`, since this run cannot reach it.
#[test]
fn validation_never_overlaps() {
    let (o, r, _) = fault_run_with(
        &["--validate"],
        "overlap:crash",
        TWO,
        &["--threads", "2"],
        Duration::from_secs(180),
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!(r["timing"]["overlapped_cells"], 0, "{}", r["timing"]);
    assert!(cells(&r).iter().all(|c| c["outcome"] == "pass"));
}

/// Ctrl-C during `run --shader` (here in its index check or a variant's child): every child is
/// killed, the work folder `rtprobe-shader-<pid>-…` goes with its job and output files, no
/// report is written, and the message says so (not `run`'s `--resume`). Twin: before the
/// handler was installed there, the folder stayed in TMPDIR.
#[test]
fn ctrl_c_during_run_shader_kills_its_children_and_leaves_nothing() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let out = dir.path().join("r.json");
    let hit = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/shaders/user/object_table.rchit");
    let mut c = Command::new(env!("CARGO_BIN_EXE_rtprobe"));
    c.args(["run", "--repeat", "50", "--shader", hit.to_str().unwrap(), "-o"])
        .arg(&out)
        .env("TMPDIR", dir.path());
    let work = |pid: u32| {
        let prefix = format!("rtprobe-shader-{pid}-");
        entries(dir.path()).into_iter().filter(|n| n.starts_with(&prefix)).count()
    };
    let (status, err) =
        interrupt_once_children_run(c, (dir.path(), "__shader"), libc::SIGINT, |pid| {
            assert_eq!(work(pid), 1, "the work folder while it runs")
        });
    assert_eq!(status.code(), Some(130), "{status:?} {err}");
    assert!(err.contains("interrupted (SIGINT)") && err.contains("no report was written"), "{err}");
    assert!(!err.contains("--resume"), "{err}");
    assert!(!out.exists());
    // The report's lock file stays, as after any killed run (`report::lock`: the next lock of
    // that report takes it over); nothing else.
    assert_eq!(entries(dir.path()), vec![".r.json.lock"]);
}
