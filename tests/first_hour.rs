//! A new user's first hour, as issue #29 tried it on lavapipe: every command in order, with bad
//! input everywhere and the output read by a person and by a CI log. Each test names the item it
//! holds; each ran against the code before the fix and failed there (a panic on a closed pipe, a
//! green run of nothing, a lost report, a `--resume` that did not work as printed, a silent log,
//! counts that did not add up, no verdict line, debug text, a merge that dropped the baseline).
mod common;
use common::*;
use serde_json::Value;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

/// Raygen and miss shaders reading storage buffers: 12 cells, seconds on lavapipe.
const SMALL: &str =
    "stage=raygen|miss,resource=storage_buffer,descriptor_model=descriptor_indexing";
/// A crash planted in the miss shaders' dynamic reads (with and without nonuniformEXT).
const CRASH: &str = "stage=miss,index=dynamic";

fn report(path: &Path) -> Value {
    serde_json::from_slice(&std::fs::read(path).expect("report written")).expect("report is JSON")
}

fn spawn(args: &[&str], dir: &Path) -> Child {
    bin()
        .args(args)
        .current_dir(dir)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn rtprobe")
}

/// Wait until the report at `p` holds at least `n` cells with an attempt.
fn wait_for_cells(p: &Path, n: usize) {
    let start = Instant::now();
    loop {
        let done = std::fs::read(p)
            .ok()
            .and_then(|b| serde_json::from_slice::<Value>(&b).ok())
            .map(|r| {
                r["cells"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .filter(|c| !c["attempts"].as_array().unwrap().is_empty())
                    .count()
            })
            .unwrap_or(0);
        if done >= n {
            return;
        }
        assert!(start.elapsed() < Duration::from_secs(180), "the run made no progress");
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn no_panic(o: &std::process::Output) {
    assert!(!stderr(o).contains("panicked"), "{}", stderr(o));
}

// ---- 1. a closed stdout ----

#[test]
fn a_closed_stdout_is_a_normal_end() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    // `rtprobe run --list | head -2`: two lines read, the pipe closed, the rest never written.
    let mut c = spawn(&["run", "--list"], dir.path());
    let mut lines = BufReader::new(c.stdout.take().unwrap()).lines();
    assert!(lines.next().unwrap().unwrap().starts_with("run "));
    assert!(lines.next().is_some());
    drop(lines);
    let o = c.wait_with_output().unwrap();
    no_panic(&o);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    // `devices | true`, `run … | true`, `bisect … | true`: stdout closed before a line is written;
    // each ends with its own exit code.
    let r = dir.path().join("r.json");
    let cases: Vec<(Vec<&str>, i32)> = vec![
        (vec!["devices"], 0),
        (
            vec![
                "run",
                "--filter",
                SMALL,
                "--inject-fault",
                CRASH,
                "--patches",
                "none",
                "-o",
                "r.json",
            ],
            1,
        ),
        (vec!["bisect", "--offline", "r.json"], 0),
    ];
    for (args, code) in cases {
        let mut c = spawn(&args, dir.path());
        drop(c.stdout.take());
        let o = c.wait_with_output().unwrap();
        no_panic(&o);
        assert_eq!(o.status.code(), Some(code), "{args:?}: {}", stderr(&o));
    }
    assert_eq!(report(&r)["complete"], true, "the run finished its report all the same");
}

// ---- 2. a filter that matches nothing ----

#[test]
fn a_filter_that_matches_nothing_fails_with_the_reason() {
    // Repeated --filters must all match: two stages never do.
    let o = run(&["run", "--filter", "stage=closest_hit", "--filter", "stage=raygen"]);
    assert_one_line_error(&o, 2, "have no cell in common: repeated --filters must all match");
    // Two terms no cell has together are named.
    let o = run(&["run", "--filter", "resource=storage_buffer,as_access=descriptor"]);
    assert_one_line_error(
        &o,
        2,
        "no cell of the matrix has both resource=storage_buffer and as_access=descriptor",
    );
    // One axis twice in a filter: refused, with the term to write.
    let o = run(&["run", "--filter", "stage=closest_hit,stage=raygen"]);
    assert_one_line_error(&o, 2, "stage=closest_hit|raygen");
    // --list shows the empty plan, then fails the same way.
    let o = run(&["run", "--list", "--filter", "stage=closest_hit", "--filter", "stage=raygen"]);
    assert!(stdout(&o).contains("0 planned: 0 to run"), "{}", stdout(&o));
    assert_one_line_error(&o, 2, "no cell in common");
    // A plan the device can run none of is exit 5, with the device's reason.
    let o = run(&["run", "--filter", "reorder=reorder"]);
    assert_one_line_error(&o, 5, "VK_NV_ray_tracing_invocation_reorder");
}

// ---- 3. report names and the lock ----

#[test]
fn runs_started_together_never_share_a_default_report() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let args = [
        "run",
        "--filter",
        "stage=raygen,resource=storage_buffer,descriptor_model=descriptor_indexing",
    ];
    let (a, b) = (spawn(&args, dir.path()), spawn(&args, dir.path()));
    for c in [a, b] {
        let o = c.wait_with_output().unwrap();
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    }
    let reports: Vec<PathBuf> = std::fs::read_dir(dir.path().join("reports"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "json"))
        .collect();
    assert_eq!(reports.len(), 2, "{reports:?}");
    for r in &reports {
        assert_eq!(report(r)["complete"], true, "{}", r.display());
    }
    let leftovers = std::fs::read_dir(dir.path().join("reports")).unwrap().count();
    assert_eq!(leftovers, 2, "no lock file left behind");
}

#[test]
fn a_report_being_written_is_neither_overwritten_nor_resumed() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let x = dir.path().join("x.json");
    // A run that takes a while: every cell hangs until its 2 s deadline.
    let mut first = spawn(
        &[
            "run",
            "--filter",
            SMALL,
            "--inject-fault",
            "stage=raygen|miss@hang",
            "--timeout",
            "2",
            "--patches",
            "none",
            "--no-confirm",
            "-o",
            "x.json",
        ],
        dir.path(),
    );
    while !x.exists() {
        std::thread::sleep(Duration::from_millis(20));
    }
    let o = run(&["run", "--filter", SMALL, "-o", x.to_str().unwrap()]);
    assert_one_line_error(&o, 9, "is being written by another rtprobe run (pid");
    let o = run(&["run", "--resume", x.to_str().unwrap()]);
    assert_one_line_error(&o, 9, "cannot resume");
    first.kill().unwrap();
    let _ = first.wait();
    // Killed: the kernel dropped its lock, and the report resumes at once.
    let o = run(&["run", "--resume", x.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1), "the hangs are findings: {}", stderr(&o));
    assert_eq!(report(&x)["complete"], true, "{}", stderr(&o));
}

// ---- 4. --resume as printed ----

#[test]
fn an_interrupted_run_resumes_with_the_command_it_prints() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let x = dir.path().join("r.json");
    // Options that differ from every default: the printed command alone must carry them.
    let args = [
        "run",
        "--filter",
        SMALL,
        "--inject-fault",
        CRASH,
        "--seed",
        "3",
        "--size",
        "32x32",
        "--patches",
        "none",
        "--timeout",
        "9",
        "-o",
        "r.json",
    ];
    let c = spawn(&args, dir.path());
    wait_for_cells(&x, 3);
    // SAFETY: kill(2) on the child this test started.
    unsafe { libc::kill(c.id() as i32, libc::SIGINT) };
    let o = c.wait_with_output().unwrap();
    assert_eq!(o.status.code(), Some(130), "{}", stderr(&o));
    let err = stderr(&o);
    let command = err
        .split("finish it with `")
        .nth(1)
        .and_then(|s| s.split('`').next())
        .unwrap_or_else(|| panic!("no command in: {err}"));
    assert_eq!(command, "rtprobe run --resume r.json");
    let kept = report(&x)["cells"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|c| !c["attempts"].as_array().unwrap().is_empty())
        .count();
    let words: Vec<&str> = command.split_whitespace().collect();
    let o = bin().args(&words[1..]).current_dir(dir.path()).output().unwrap();
    assert_eq!(o.status.code(), Some(1), "the planted crash is a finding: {}", stderr(&o));
    let r = report(&x);
    assert_eq!(r["complete"], true);
    assert_eq!(r["scene"]["params"]["seed"], 3);
    assert_eq!(r["resumed"][0]["kept"], kept);
    assert!(
        stdout(&o).contains(&format!("resumed: {kept} cells kept from the interrupted run")),
        "{}",
        stdout(&o)
    );
    // A differing option given explicitly is still another run.
    let o = run(&["run", "--resume", x.to_str().unwrap(), "--seed", "4"]);
    assert_one_line_error(&o, 9, "its scene differs (--seed 3 in the report, 4 here)");
}

/// #20's review, item 8: resuming a report that is already complete (its findings confirmed and
/// their workarounds tried) runs nothing again: not the confirm round, not the workaround cells.
#[test]
fn resuming_a_complete_report_runs_no_cell_again() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let x = dir.path().join("done.json");
    let args = ["run", "--filter", SMALL, "--inject-fault", CRASH, "-o", "done.json"];
    let o = bin().args(args).current_dir(dir.path()).output().unwrap();
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let before = report(&x);
    let workaround_cells = before["cells"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|c| c["id"].as_str().unwrap().contains(".patch-"))
        .count();
    assert!(workaround_cells > 0, "the run tried workarounds on its findings: {}", stdout(&o));
    let attempts = |r: &Value| -> usize {
        r["cells"].as_array().unwrap().iter().map(|c| c["attempts"].as_array().unwrap().len()).sum()
    };
    let o = run(&["run", "--resume", x.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1), "the same findings: {}", stderr(&o));
    assert!(stdout(&o).contains(", 0 cells run now"), "{}", stdout(&o));
    assert_eq!(attempts(&report(&x)), attempts(&before), "no attempt was added");
}

// ---- 6.–9., 11. what a run prints ----

/// `run --filter SMALL --inject-fault CRASH` as a CI log gets it (progress every line, `CI=true`:
/// output only, the run is the same): its output and report, made once for the CI-log test and as
/// the baseline of the merge test.
fn crash_run() -> &'static (PathBuf, std::process::Output, PathBuf) {
    static R: OnceLock<(PathBuf, std::process::Output, PathBuf)> = OnceLock::new();
    R.get_or_init(|| {
        let dir = tempdir_until_exit();
        let r = dir.join("r.json");
        let o = run_env(
            &["run", "--filter", SMALL, "--inject-fault", CRASH, "-o", r.to_str().unwrap()],
            &[("RTPROBE_PROGRESS_SECS", "0"), ("CI", "true")],
        );
        (dir, o, r)
    })
}

#[test]
fn a_ci_log_shows_progress_counts_that_add_up_and_one_verdict_line() {
    let (_, o, r) = crash_run();
    assert_eq!(o.status.code(), Some(1), "{}", stderr(o));
    let (out, err) = (stdout(o), stderr(o));
    // 6: progress lines on a stderr that is no terminal.
    assert!(err.lines().any(|l| l.starts_with('[') && l.contains(" attempts (pass ")), "{err}");
    assert!(err.contains("round confirm: 2 attempts, each alone in a fresh worker"), "{err}");
    assert!(err.lines().any(|l| l.contains("] done: ")), "{err}");
    // 7: the outcomes add up to the plan; the retries are counted apart.
    let j = report(r);
    let planned = j["plan"]["planned"].as_u64().unwrap();
    let outcomes = out.lines().find(|l| l.starts_with("outcomes:")).unwrap();
    let sum: u64 = outcomes.split_whitespace().filter_map(|w| w.parse::<u64>().ok()).sum();
    assert_eq!(sum, planned, "{outcomes}");
    assert_eq!(
        j["summary"].as_object().unwrap().values().map(|v| v.as_u64().unwrap()).sum::<u64>(),
        planned
    );
    assert!(out.contains("retries (not in the plan, not counted above): "), "{out}");
    assert!(j["retries"].as_object().is_some_and(|m| !m.is_empty()), "{}", j["retries"]);
    // 8: the last line is the verdict, after the findings.
    assert_eq!(
        out.trim_end().lines().last().unwrap(),
        "verdict: FAIL — 2 findings (1 outside the spec's guarantees, judged by rtprobe's heuristic)"
    );
    // 9, 11: words, not Rust or JSON; no emoji or escape codes in a log.
    assert!(out.contains(" cells misbehave on purpose (stage=miss,index=dynamic@device)"), "{out}");
    for bad in ["[\"", "{\"", " 1 cells", " 1 workers", "(s)", "✅", "💥", "\u{1b}["] {
        assert!(!out.contains(bad) && !err.contains(bad), "{bad:?} in:\n{out}\n{err}");
    }
    assert!(out.contains("not proven (2 passes; need 19 for 99%)"), "{out}");
    // Every re-run alone compiled its pipeline afresh (the driver's cache off: lavapipe has no
    // pipelineBinaryInternalCacheControl, so by the environment switch) and ran the SPIR-V the
    // matrix compiled (rtprobe's own GLSL cache, not the driver's).
    let reruns = j["cells"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|c| c["attempts"].as_array().unwrap())
        .filter(|a| a["isolated"] == true)
        .count() as u64;
    let dc = &j["driver_cache"];
    assert!(reruns >= 2, "{dc}");
    assert_eq!(dc["fresh_workers"], reruns, "{dc}");
    assert_eq!(
        dc["env_switch"].as_u64().unwrap() + dc["internal_cache_disabled"].as_u64().unwrap(),
        reruns,
        "{dc}"
    );
    assert_eq!(dc["glsl_cache"], reruns, "{dc}");
    // 9: RFC 3339 times.
    for k in ["started", "finished"] {
        let t = j[k].as_str().unwrap();
        assert!(t.len() == 20 && t.as_bytes()[10] == b'T' && t.ends_with('Z'), "{k}: {t}");
    }
}

#[test]
fn a_baseline_that_expects_the_findings_passes_and_retries_are_no_regressions() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let (first, base) = (dir.path().join("first.json"), dir.path().join("base.json"));
    // The baseline of a run without workaround retries.
    let o = run(&[
        "run",
        "--filter",
        SMALL,
        "--inject-fault",
        CRASH,
        "--patches",
        "none",
        "-o",
        first.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let o = run(&["baseline", first.to_str().unwrap(), "-o", base.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    // The same faults, now with their workaround retries (which crash or error): as expected.
    let o = run(&[
        "run",
        "--filter",
        SMALL,
        "--inject-fault",
        CRASH,
        "--baseline",
        base.to_str().unwrap(),
        "-o",
        dir.path().join("again.json").to_str().unwrap(),
    ]);
    let out = stdout(&o);
    assert_eq!(o.status.code(), Some(0), "{out}");
    assert!(!out.contains("REGRESSION"), "{out}");
    assert!(out.contains("findings (2, all expected by baseline "), "{out}");
    assert!(out.contains("[expected]"), "{out}");
    assert!(
        out.trim_end().ends_with(&format!(
            "verdict: PASS — 2 findings, all expected by baseline {}",
            base.display()
        )),
        "{out}"
    );
}

// ---- 10. caps and the registry's axes ----

/// Each axis of `names` with its values, from `run --help`'s --filter text (`  axis: help (v1,
/// v2, …)`, however clap wrapped it).
fn help_axes(help: &str, names: &[String]) -> Vec<(String, Vec<String>)> {
    let text: String = help.split_whitespace().collect::<Vec<_>>().join(" ");
    let text = &text[text.find("Axes: stage: ").expect("--filter's axes") + 6..];
    let mut out = vec![];
    for (i, name) in names.iter().enumerate() {
        let at = text.find(&format!("{name}: ")).unwrap_or_else(|| panic!("{name} in {text}"));
        let rest = &text[at..];
        let end = names.get(i + 1).and_then(|n| rest.find(&format!(") {n}: "))).map(|e| e + 1);
        let seg = &rest[..end.unwrap_or_else(|| rest.find(')').unwrap() + 1)];
        let values = seg.rsplit_once(" (").unwrap().1.trim_end_matches(')');
        out.push((name.clone(), values.split(", ").map(String::from).collect()));
    }
    out
}

#[test]
fn caps_ends_with_a_first_run_and_lists_the_axes_run_and_its_errors_list() {
    let o = run(&["caps", "--no-device-check"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = stdout(&o);
    let last = text.trim_end().lines().last().unwrap();
    let cmd = last.strip_prefix("next: a first run (").unwrap_or_else(|| panic!("{last}"));
    let (n, cmd) = cmd.split_once(" cells of the matrix): rtprobe ").unwrap();
    // The command it gives plans that many cells.
    let filter = cmd.split('\'').nth(1).unwrap();
    let o = run(&["run", "--list", "--filter", filter]);
    assert!(stdout(&o).contains(&format!(": {n} to run,")), "{}", stdout(&o));
    // caps's matrix, run --help's --filter and the bad-axis error name the same axes and values.
    let mut caps_axes: Vec<(String, Vec<String>)> = vec![];
    for l in text.lines().skip_while(|l| !l.starts_with("matrix")).skip(1) {
        let words: Vec<&str> = l.split_whitespace().collect();
        match (l.starts_with("  ") && !l.starts_with("   "), words.first()) {
            (true, Some(name)) => caps_axes
                .push((name.to_string(), words[1..].iter().map(|w| w.to_string()).collect())),
            (false, Some(&"✗")) => caps_axes.last_mut().unwrap().1.push(words[1].to_string()),
            _ => break,
        }
    }
    let err = stderr(&run(&["run", "--filter", "colour=red"]));
    let err_axes: Vec<String> =
        err.trim_end().rsplit_once("axes: ").unwrap().1.split(", ").map(String::from).collect();
    let help = stdout(&run(&["run", "--help"]));
    let run_axes = help_axes(&help, &err_axes);
    let names = |v: &[(String, Vec<String>)]| v.iter().map(|(n, _)| n.clone()).collect::<Vec<_>>();
    assert_eq!(names(&caps_axes), err_axes, "caps and the error:\n{text}\n{err}");
    let short = stdout(&run(&["run", "-h"])).split_whitespace().collect::<Vec<_>>().join(" ");
    assert!(short.contains(&format!("Axes: {}", err_axes.join(", "))), "{short}");
    for ((a, cv), (_, rv)) in caps_axes.iter().zip(&run_axes) {
        let (mut cv, mut rv) = (cv.clone(), rv.clone());
        cv.sort();
        rv.sort();
        assert_eq!(cv, rv, "{a}: caps and run --help");
        let e = stderr(&run(&["run", "--filter", &format!("{a}=nonsense")]));
        let mut ev: Vec<String> =
            e.trim_end().rsplit_once("values: ").unwrap().1.split(", ").map(String::from).collect();
        ev.sort();
        assert_eq!(ev, rv, "{a}: the bad-value error and run --help");
    }
}

// ---- 11. clap's errors ----

#[test]
fn usage_errors_are_rtprobes_one_line_with_the_help_to_read() {
    let o = run(&["run", "--outptu", "x.json"]);
    assert_eq!(o.status.code(), Some(2));
    let err = stderr(&o);
    let lines: Vec<&str> = err.lines().collect();
    assert_eq!(lines.len(), 1, "{err}");
    assert!(lines[0].starts_with("rtprobe: error: unexpected argument '--outptu' found (a similar argument exists: '--output')"), "{err}");
    assert!(lines[0].ends_with("; `rtprobe run --help` lists every option"), "{err}");
    let o = run(&["run", "--patches", "fault"]);
    assert_one_line_error(&o, 2, "(a similar value exists: 'faults')");
    let o = run(&["run", "--filter", "stage=closesthit"]);
    assert_one_line_error(&o, 2, "(did you mean closest_hit?)");
    // --output is -o.
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let out = dir.path().join("o.json");
    let o = run(&[
        "run",
        "--filter",
        "stage=raygen,index=literal,resource=storage_buffer,descriptor_model=descriptor_indexing",
        "--output",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!(report(&out)["complete"], true);
    // No escape codes in help that goes to a pipe.
    assert!(!stdout(&run(&["--help"])).contains('\u{1b}'));
}

/// The review of #29: clap's detail lines were dropped (the missing argument unnamed, the
/// possible values lost), no command printed the about text as an error, and an unknown
/// command's hint named itself.
#[test]
fn usage_errors_keep_the_detail_and_name_a_real_command() {
    let o = run(&["report"]);
    assert_one_line_error(&o, 2, "the following required arguments were not provided: <REPORT>");
    let o = run(&["run", "--patches"]);
    assert_one_line_error(&o, 2, "[possible values: none, faults, all]");
    let o = run(&[]);
    assert_one_line_error(&o, 2, "no command given: one of devices, caps, run,");
    assert!(!stderr(&o).contains("__worker"), "hidden commands stay hidden: {}", stderr(&o));
    let o = run(&["bogus"]);
    assert_one_line_error(&o, 2, "unrecognized subcommand 'bogus'");
    assert!(stderr(&o).contains("`rtprobe --help`"), "{}", stderr(&o));
}

// ---- 12. outputs checked first ----

#[test]
fn unwritable_outputs_fail_before_any_work_in_one_line() {
    let start = Instant::now();
    let o = run(&["stress", "--json", "/proc/rtprobe-nowhere/s.json"]);
    assert_one_line_error(
        &o,
        9,
        "--json /proc/rtprobe-nowhere/s.json: cannot write in /proc/rtprobe-nowhere",
    );
    assert!(stdout(&o).is_empty(), "no case ran: {}", stdout(&o));
    assert!(start.elapsed() < Duration::from_secs(20), "checked first");
    let o = run(&["run", "--filter", SMALL, "--junit", "/proc/rtprobe-nowhere/j.xml"]);
    assert_one_line_error(&o, 9, "--junit");
    assert_eq!(stderr(&o).matches("os error").count(), 1, "the OS error once: {}", stderr(&o));
    for args in [
        vec!["bisect", "r.json", "--json", "/proc/rtprobe-nowhere/b.json"],
        vec!["report", "r.json", "-o", "/proc/rtprobe-nowhere/i.md"],
        vec!["caps", "-o", "/proc/rtprobe-nowhere/c.json"],
    ] {
        assert_one_line_error(&run(&args), 9, "/proc/rtprobe-nowhere");
    }
    // A temporary folder that takes no folder: one line before any cell runs, not a report of
    // every cell as an `error` finding (the job files go there).
    let r = tempdir_until_exit().join("tmp-r.json");
    let o = run_env(
        &["run", "--filter", SMALL, "-o", r.to_str().unwrap()],
        &[("TMPDIR", "/proc/rtprobe-nowhere")],
    );
    assert_one_line_error(&o, 9, "set TMPDIR to a folder you can write");
    assert!(!r.exists(), "no report begun");
}

/// A tmpfs of `kib` KiB at a fresh folder (root only), unmounted when dropped.
struct Tmpfs(rtprobe::tempdir::TempDir);

impl Tmpfs {
    fn new(kib: u32) -> Option<Tmpfs> {
        let d = rtprobe::tempdir::tempdir().ok()?;
        let ok = std::process::Command::new("mount")
            .args([
                "-t",
                "tmpfs",
                "-o",
                &format!("size={kib}k"),
                "rtprobe-test",
                d.path().to_str()?,
            ])
            .status()
            .is_ok_and(|s| s.success());
        ok.then_some(Tmpfs(d))
    }
}

impl Drop for Tmpfs {
    fn drop(&mut self) {
        let _ = std::process::Command::new("umount").arg(self.0.path()).status();
    }
}

#[test]
fn a_full_disk_says_the_report_on_it_is_whole_and_resumable() {
    let Some(fs) = Tmpfs::new(1024) else {
        eprintln!("skipped: no tmpfs (needs root)");
        return;
    };
    let x = fs.0.path().join("r.json");
    let c = spawn(
        &[
            "run",
            "--filter",
            SMALL,
            "--inject-fault",
            "stage=miss@hang",
            "--timeout",
            "2",
            "--patches",
            "none",
            "--no-confirm",
            "-o",
            x.to_str().unwrap(),
        ],
        Path::new("."),
    );
    wait_for_cells(&x, 1);
    // Fill the disk: the run's next saves fail.
    let mut filler = std::fs::File::create(fs.0.path().join("filler")).unwrap();
    let block = vec![7u8; 4096];
    while std::io::Write::write_all(&mut filler, &block).is_ok() {}
    drop(filler);
    let o = c.wait_with_output().unwrap();
    assert_one_line_error(&o, 9, "No space left on device");
    let err = stderr(&o);
    assert!(
        err.contains("the report on disk is the last one saved whole, valid and resumable"),
        "{err}"
    );
    assert_eq!(report(&x)["complete"], false, "a whole, unfinished report");
    std::fs::remove_file(fs.0.path().join("filler")).unwrap();
    let command = err.split('`').nth(1).unwrap();
    let words: Vec<&str> = command.split_whitespace().collect();
    let o = bin().args(&words[1..]).output().unwrap();
    assert_eq!(o.status.code(), Some(1), "the hangs are findings: {}", stderr(&o));
    assert_eq!(report(&x)["complete"], true);
}

// ---- 13.–15. CI ----

fn shard_runs(dir: &Path, name: &str, extra: &[&str]) -> Vec<PathBuf> {
    (1..=2)
        .map(|i| {
            let p = dir.join(format!("{name}-{i}.json"));
            let shard = format!("{i}/2");
            let mut args = vec![
                "run",
                "--filter",
                SMALL,
                "--inject-fault",
                CRASH,
                "--shard",
                &shard,
                "-o",
                p.to_str().unwrap(),
            ];
            args.extend_from_slice(extra);
            let o = run(&args);
            assert!(matches!(o.status.code(), Some(0 | 1)), "{}", stderr(&o));
            p
        })
        .collect()
}

#[test]
fn merging_shards_held_to_a_baseline_gives_the_ci_verdict() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let (first, base) = (&crash_run().2, dir.path().join("base.json"));
    assert!(run(&["baseline", first.to_str().unwrap(), "-o", base.to_str().unwrap()])
        .status
        .success());
    let shards = shard_runs(dir.path(), "held", &["--baseline", base.to_str().unwrap()]);
    let merged = dir.path().join("merged.json");
    let mut args = vec!["merge", "-o", merged.to_str().unwrap()];
    args.extend(shards.iter().map(|p| p.to_str().unwrap()));
    let o = run(&args);
    let out = stdout(&o);
    assert_eq!(o.status.code(), Some(0), "{out}{}", stderr(&o));
    assert!(out.contains(&format!("baseline {}: ", base.display())), "{out}");
    let verdict =
        format!("verdict: PASS — 2 findings, all expected by baseline {}", base.display());
    assert_eq!(out.trim_end().lines().last().unwrap(), verdict, "{out}");
    let m = report(&merged);
    assert_eq!(m["baseline"]["source"], base.display().to_string());
    // Shards with a new fault: the merge fails and names it.
    let new_fault = [
        "--baseline",
        base.to_str().unwrap(),
        "--inject-fault",
        "stage=raygen,index=literal@value",
    ];
    let shards = shard_runs(dir.path(), "new", &new_fault);
    let mut args = vec!["merge", "-o", merged.to_str().unwrap()];
    args.extend(shards.iter().map(|p| p.to_str().unwrap()));
    let o = run(&args);
    let out = stdout(&o);
    assert_eq!(o.status.code(), Some(1), "{out}");
    assert!(out.contains("REGRESSION: raygen.storage_buffer.literal.descriptor_indexing expected pass got mismatch"), "{out}");
    assert!(
        out.trim_end()
            .lines()
            .last()
            .unwrap()
            .starts_with("verdict: FAIL — 1 regression against baseline"),
        "{out}"
    );
    // Shards run without a baseline: `merge --baseline` checks the merged report.
    let plain =
        shard_runs(dir.path(), "plain", &["--inject-fault", "stage=raygen,index=literal@value"]);
    let mut args =
        vec!["merge", "-o", merged.to_str().unwrap(), "--baseline", base.to_str().unwrap()];
    args.extend(plain.iter().map(|p| p.to_str().unwrap()));
    let o = run(&args);
    assert_eq!(o.status.code(), Some(1), "{}", stdout(&o));
    assert!(
        stdout(&o).contains("REGRESSION: raygen.storage_buffer.literal.descriptor_indexing"),
        "{}",
        stdout(&o)
    );
    // One shard held to the baseline, one not: no verdict to carry, and merge says what to do.
    let mut args = vec![
        "merge",
        "-o",
        merged.to_str().unwrap(),
        shards[0].to_str().unwrap(),
        plain[1].to_str().unwrap(),
    ];
    args.push("--force");
    let o = run(&args);
    assert_one_line_error(&o, 9, "give merge --baseline FILE");
}

#[test]
fn diff_warns_of_two_devices_and_writes_its_file_alone() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let a = dir.path().join("a.json");
    let o = run(&["run", "--filter", SMALL, "--patches", "none", "-o", a.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let mut other = report(&a);
    other["device"]["name"] = Value::String("Another GPU".into());
    let b = dir.path().join("b.json");
    std::fs::write(&b, serde_json::to_vec(&other).unwrap()).unwrap();
    let md = dir.path().join("d.md");
    let o = run(&[
        "diff",
        a.to_str().unwrap(),
        b.to_str().unwrap(),
        "--format",
        "md",
        "-o",
        md.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("rtprobe: warning: the reports were made on different devices"),
        "{}",
        stderr(&o)
    );
    assert_eq!(stdout(&o), format!("diff: {}\n", md.display()), "only where it went");
    assert!(std::fs::read_to_string(&md).unwrap().contains("no outcome changes"));
    // One device, another driver build: no warning.
    let o = run(&["diff", a.to_str().unwrap(), a.to_str().unwrap()]);
    assert!(!stderr(&o).contains("warning"), "{}", stderr(&o));
}

#[test]
fn output_dir_holds_deqp_runners_files() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let out = dir.path().join("out");
    let skips = dir.path().join("skips.txt");
    std::fs::write(&skips, "# not these\nraygen\\..*\\.push_constant\\.\n").unwrap();
    let flakes = dir.path().join("flakes.txt");
    std::fs::write(&flakes, "miss\\.storage_buffer\\.dynamic\\.descriptor\n").unwrap();
    let o = run(&[
        "run",
        "--filter",
        SMALL,
        "--inject-fault",
        CRASH,
        "--skips",
        skips.to_str().unwrap(),
        "--flakes",
        flakes.to_str().unwrap(),
        "--output-dir",
        out.to_str().unwrap(),
    ]);
    let (o_out, o_err) = (stdout(&o), stderr(&o));
    // The miss shaders' dynamic reads crash: one is a known flake, the nonuniform one is not.
    assert_eq!(o.status.code(), Some(1), "{o_out}{o_err}");
    let r = report(&out.join("report.json"));
    let results = std::fs::read_to_string(out.join("results.csv")).unwrap();
    assert_eq!(results.lines().count(), 11, "12 cells, one skipped: {results}");
    assert!(!results.contains("raygen.storage_buffer.push_constant"), "{results}");
    assert!(
        results.contains("miss.storage_buffer.dynamic.descriptor_indexing,KnownFlake,"),
        "{results}"
    );
    assert!(
        results.contains("miss.storage_buffer.dynamic.nonuniform.descriptor_indexing,Crash,"),
        "{results}"
    );
    assert!(
        results
            .lines()
            .all(|l| l.split(',').count() == 3
                && l.split(',').nth(2).unwrap().parse::<f64>().is_ok()),
        "{results}"
    );
    let failures = std::fs::read_to_string(out.join("failures.csv")).unwrap();
    assert_eq!(failures.lines().count(), 1, "{failures}");
    let junit = std::fs::read_to_string(out.join("junit.xml")).unwrap();
    assert!(junit.contains("failures=\"1\""), "{junit}");
    assert_eq!(r["options"]["skips"][0], "raygen\\..*\\.push_constant\\.");
    // An expected fault that passes now is deqp-runner's UnexpectedPass.
    let base = dir.path().join("base.csv");
    std::fs::write(&base, "raygen.storage_buffer.literal.descriptor_indexing,Crash\n").unwrap();
    let out2 = dir.path().join("out2");
    let o = run(&[
        "run",
        "--filter",
        SMALL,
        "--patches",
        "none",
        "--baseline",
        base.to_str().unwrap(),
        "--output-dir",
        out2.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stdout(&o));
    assert!(stdout(&o).contains("UnexpectedPass: raygen.storage_buffer.literal.descriptor_indexing expected crash got pass"), "{}", stdout(&o));
    let failures = std::fs::read_to_string(out2.join("failures.csv")).unwrap();
    assert!(
        failures.starts_with("raygen.storage_buffer.literal.descriptor_indexing,UnexpectedPass,"),
        "{failures}"
    );
    // A bad list is one line naming the line.
    std::fs::write(&skips, "(unclosed\n").unwrap();
    let o = run(&["run", "--filter", SMALL, "--skips", skips.to_str().unwrap()]);
    assert_one_line_error(&o, 9, "line 1: \"(unclosed\" is not a regular expression");
}
