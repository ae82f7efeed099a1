//! Helpers shared by the end-to-end tests: run the real binary, parse its JSON.
#![allow(dead_code)]
use std::process::{Command, Output};

pub fn bin() -> Command {
    bin_at(std::path::Path::new(env!("CARGO_BIN_EXE_rtprobe")))
}

/// [`bin`] of the executable at `exe` (a copy of the binary).
pub fn bin_at(exe: &std::path::Path) -> Command {
    let mut c = Command::new(exe);
    // Validation on by default in tests when the layer is installed (see docs/environment.md).
    if std::path::Path::new("/usr/share/vulkan/explicit_layer.d/VkLayer_khronos_validation.json")
        .exists()
    {
        c.env("RTPROBE_VALIDATE", "1");
    }
    c.env_remove("RUST_LOG");
    // Never the user's pipeline cache: one folder per test binary.
    c.env("RTPROBE_CACHE_DIR", cache_dir());
    // Its temporary folders (job files, work folders) in one of this test process's, removed
    // when it exits: a run a test kills (SIGKILL: no handler runs) leaves nothing in /tmp.
    c.env("TMPDIR", temp_dir());
    c
}

/// The temporary folder of the runs this test process starts.
pub fn temp_dir() -> std::path::PathBuf {
    static DIR: std::sync::OnceLock<std::path::PathBuf> = std::sync::OnceLock::new();
    DIR.get_or_init(tempdir_until_exit).clone()
}

/// The cache folder (pipeline cache, compiled GLSL) of this test binary's runs: its own, or the
/// one `RTPROBE_TEST_CACHE_DIR` names, which `.ci/run` shares between every suite of one CI run
/// (a fresh folder per CI run: the first suite to compile a shader pays for it). Never the user's.
pub fn cache_dir() -> std::path::PathBuf {
    match std::env::var_os("RTPROBE_TEST_CACHE_DIR") {
        Some(d) if !d.is_empty() => d.into(),
        _ => {
            // This process's own cache (a fresh name: never a folder an earlier process with the
            // same pid left), removed with the shared folders when it exits.
            static DIR: std::sync::OnceLock<std::path::PathBuf> = std::sync::OnceLock::new();
            DIR.get_or_init(|| tempdir_until_exit_named("rtprobe-test-cache")).clone()
        }
    }
}

/// Folders removed when this test process exits. A `static` is never dropped, so a `TempDir` a
/// suite shares through one (made once, read by several tests) used to stay in /tmp after every
/// run (bisect's shared report with its bundles and dumps: 50 MB a run), and so did the
/// per-process cache folder.
static AT_EXIT: std::sync::Mutex<Vec<rtprobe::tempdir::TempDir>> =
    std::sync::Mutex::new(Vec::new());

fn remove_when_exiting(dir: rtprobe::tempdir::TempDir) {
    static REGISTERED: std::sync::Once = std::sync::Once::new();
    REGISTERED.call_once(|| {
        // SAFETY: `remove_at_exit` is a plain `extern "C" fn()`.
        unsafe { libc::atexit(remove_at_exit) };
    });
    AT_EXIT.lock().unwrap_or_else(|e| e.into_inner()).push(dir);
}

extern "C" fn remove_at_exit() {
    drop(std::mem::take(&mut *AT_EXIT.lock().unwrap_or_else(|e| e.into_inner())));
}

/// A fresh temporary folder that lives until this test process exits (the test harness returns
/// from `main`, or exits on a failure: both run `atexit` handlers), for a `static` to share.
pub fn tempdir_until_exit() -> std::path::PathBuf {
    tempdir_until_exit_named("rtprobe")
}

/// [`tempdir_until_exit`], named `<prefix>-<pid>-…`.
pub fn tempdir_until_exit_named(prefix: &str) -> std::path::PathBuf {
    let dir = rtprobe::tempdir::TempDir::named(prefix).expect("a temporary folder");
    let path = dir.path().to_path_buf();
    remove_when_exiting(dir);
    path
}

pub fn run(args: &[&str]) -> Output {
    let o = bin().args(args).output().expect("spawn rtprobe");
    hold_issue_to_one_screen(args, &o);
    o
}

pub fn run_env(args: &[&str], env: &[(&str, &str)]) -> Output {
    let mut c = bin();
    for (k, v) in env {
        c.env(k, v);
    }
    let o = c.args(args).output().expect("spawn rtprobe");
    hold_issue_to_one_screen(args, &o);
    o
}

/// Issue 30: every Markdown issue the test suite writes (`rtprobe report`, to `-o FILE` or
/// stdout) fits one screen: at most `ONE_SCREEN_LINES` lines before its first `<details>`.
pub fn hold_issue_to_one_screen(args: &[&str], o: &Output) {
    if args.first() != Some(&"report") || !o.status.success() {
        return;
    }
    let after = |flag: &str| args.iter().position(|a| *a == flag).and_then(|k| args.get(k + 1));
    if after("--format") == Some(&"json") {
        return;
    }
    let md = match after("-o").or(after("--out")) {
        Some(path) => std::fs::read_to_string(path).expect("the issue rtprobe wrote"),
        None => stdout(o),
    };
    assert_one_screen(&md);
}

/// `md` has at most `ONE_SCREEN_LINES` lines before its first `<details>`.
pub fn assert_one_screen(md: &str) {
    use rtprobe::report::issue::{one_screen_lines, ONE_SCREEN_LINES};
    let n = one_screen_lines(md);
    assert!(
        n <= ONE_SCREEN_LINES,
        "the issue has {n} lines before its first <details> (at most {ONE_SCREEN_LINES}):\n{md}"
    );
}

pub fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

pub fn json(o: &Output) -> serde_json::Value {
    assert!(o.status.success(), "rtprobe failed: {:?}\nstderr: {}", o.status, stderr(o));
    serde_json::from_slice(&o.stdout).unwrap_or_else(|e| panic!("not JSON ({e}): {}", stdout(o)))
}

/// Asserts a failed run with `code` and exactly one `rtprobe: error:` line on stderr.
pub fn assert_one_line_error(o: &Output, code: i32, needle: &str) {
    let err = stderr(o);
    assert_eq!(o.status.code(), Some(code), "exit code; stderr: {err}");
    let lines: Vec<&str> = err.lines().filter(|l| l.starts_with("rtprobe: error:")).collect();
    assert_eq!(lines.len(), 1, "one error line expected, got: {err}");
    assert!(lines[0].contains(needle), "{needle:?} not in {:?}", lines[0]);
    // Nothing else may look like an error either: no second hint line, no compiler output.
    let noisy = err.lines().filter(|l| l.to_lowercase().contains("error") || l.contains("hint:"));
    assert_eq!(noisy.count(), 1, "one line mentioning the error expected, got: {err}");
    assert!(!err.contains("panicked"), "panic: {err}");
}

/// Standard base64 encode and decode ([`unb64`]), to read and edit an embedded output (the
/// tests' own, not rtprobe's).
pub fn b64(bytes: &[u8]) -> String {
    const A: &[u8] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::new();
    for c in bytes.chunks(3) {
        let n = (c[0] as u32) << 16
            | (*c.get(1).unwrap_or(&0) as u32) << 8
            | *c.get(2).unwrap_or(&0) as u32;
        for k in 0..4 {
            s.push(if k <= c.len() { A[(n >> (18 - 6 * k) & 63) as usize] as char } else { '=' });
        }
    }
    s
}

pub fn unb64(s: &str) -> Vec<u8> {
    const A: &[u8] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = Vec::new();
    for c in s.as_bytes().chunks(4) {
        let pad = c.iter().filter(|b| **b == b'=').count();
        let n =
            c.iter().fold(0u32, |n, b| n << 6 | A.iter().position(|a| a == b).unwrap_or(0) as u32);
        out.extend_from_slice(&n.to_be_bytes()[1..4 - pad]);
    }
    out
}

/// The Debian sid root made by scripts/setup-sid (lavapipe 26, VK_EXT_descriptor_heap).
pub fn sid_root() -> std::path::PathBuf {
    std::env::var_os("RTPROBE_SID_ROOT")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| std::path::PathBuf::from("/var/lib/rtprobe/sid-root"))
}

/// Whether the sid root exists and scripts/in-sid may enter it (root, or sudo without a
/// password); panics when it must (RTPROBE_REQUIRE_SID=1).
pub fn have_sid() -> bool {
    let can_chroot = unsafe { libc::geteuid() } == 0
        || Command::new("sudo").args(["-n", "true"]).output().is_ok_and(|o| o.status.success());
    let ok = sid_root().join("etc/rtprobe-sid.stamp").exists() && can_chroot;
    if !ok && std::env::var("RTPROBE_REQUIRE_SID").is_ok_and(|v| v == "1") {
        panic!("RTPROBE_REQUIRE_SID=1 but there is no sid root at {} (make it with scripts/setup-sid), or no root rights to enter it", sid_root().display());
    }
    if !ok {
        eprintln!("skipped: no sid root at {} (scripts/setup-sid makes it), or no root rights to enter it", sid_root().display());
    }
    ok
}

/// `rtprobe run --validate --shader F… -o OUT extra…` over the test shaders `files` of
/// `tests/shaders/user`, with `env`: the output and the report at `out`, if written. `extra`'s
/// own `--validate=…` replaces the plain one.
pub fn run_user_shaders(
    files: &[&str],
    out: &std::path::Path,
    extra: &[&str],
    env: &[(&str, &str)],
) -> (Output, Option<serde_json::Value>) {
    let user = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/shaders/user");
    let mut args: Vec<String> = vec!["run".into()];
    if !extra.iter().any(|e| e.starts_with("--validate")) {
        args.push("--validate".into());
    }
    for f in files {
        args.push("--shader".into());
        args.push(user.join(f).to_string_lossy().into_owned());
    }
    args.extend(["-o".to_string(), out.to_string_lossy().into_owned()]);
    args.extend(extra.iter().map(|s| s.to_string()));
    let argv: Vec<&str> = args.iter().map(String::as_str).collect();
    let o = run_env(&argv, env);
    let report = std::fs::read(out).ok().map(|b| serde_json::from_slice(&b).unwrap());
    (o, report)
}

/// Live (not zombie or dead) processes other than `except` whose command line names `dir` and
/// holds `marker` (`__worker`, `__shader`; "" for any): a command's children, whose job and
/// output paths lie under the TMPDIR the test gave it.
pub fn live_processes(dir: &str, marker: &str, except: u32) -> Vec<i32> {
    let mut found = vec![];
    for e in std::fs::read_dir("/proc").unwrap().flatten() {
        let Ok(pid) = e.file_name().to_string_lossy().parse::<i32>() else {
            continue;
        };
        let cmd = std::fs::read(format!("/proc/{pid}/cmdline")).unwrap_or_default();
        let cmd = String::from_utf8_lossy(&cmd).replace('\0', " ");
        if pid as u32 == except || !cmd.contains(dir) || !cmd.contains(marker) {
            continue;
        }
        let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).unwrap_or_default();
        let state = stat.rsplit_once(')').and_then(|(_, r)| r.split_whitespace().next());
        if !matches!(state, Some("Z" | "X") | None) {
            found.push(pid);
        }
    }
    found
}

/// [`live_processes`] naming `dir`, any command.
pub fn live_processes_naming(dir: &std::path::Path, except: u32) -> Vec<i32> {
    live_processes(dir.to_str().unwrap(), "", except)
}

/// Start `c` (TMPDIR set to `dir` by the caller), wait until one of its children whose command
/// line holds `marker` is alive (another may come first: a validator on a temporary file),
/// call `while_running` with its pid, send it `sig`, and return how it ended and its stderr;
/// then wait (3 s at most) until no process naming `dir` is left, panicking if one outlives it.
pub fn interrupt_once_children_run(
    mut c: Command,
    (dir, marker): (&std::path::Path, &str),
    sig: i32,
    while_running: impl FnOnce(u32),
) -> (std::process::ExitStatus, String) {
    use std::io::Read;
    use std::time::{Duration, Instant};
    let mut child = c
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("spawn rtprobe");
    let start = Instant::now();
    while live_processes(dir.to_str().unwrap(), marker, child.id()).is_empty() {
        assert!(start.elapsed() < Duration::from_secs(60), "no child started");
        std::thread::sleep(Duration::from_millis(20));
    }
    while_running(child.id());
    unsafe { libc::kill(child.id() as i32, sig) };
    let status = child.wait().unwrap();
    let mut err = String::new();
    child.stderr.take().unwrap().read_to_string(&mut err).unwrap();
    let start = Instant::now();
    while !live_processes_naming(dir, child.id()).is_empty() {
        assert!(start.elapsed() < Duration::from_secs(3), "children outlived rtprobe: {err}");
        std::thread::sleep(Duration::from_millis(20));
    }
    (status, err)
}

/// The names of `dir`'s entries.
pub fn entries(dir: &std::path::Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}
