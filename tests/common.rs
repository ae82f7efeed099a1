//! Helpers shared by the end-to-end tests: run the real binary, parse its JSON.
#![allow(dead_code)]
use std::process::{Command, Output};

pub fn bin() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_rtprobe"));
    // Validation on by default in tests when the layer is installed (see docs/environment.md).
    if std::path::Path::new("/usr/share/vulkan/explicit_layer.d/VkLayer_khronos_validation.json")
        .exists()
    {
        c.env("RTPROBE_VALIDATE", "1");
    }
    c.env_remove("RUST_LOG");
    // Never the user's pipeline cache: one folder per test binary.
    c.env("RTPROBE_CACHE_DIR", cache_dir());
    c
}

/// The pipeline cache folder of this test binary's runs.
pub fn cache_dir() -> std::path::PathBuf {
    std::env::temp_dir().join(format!("rtprobe-test-cache-{}", std::process::id()))
}

pub fn run(args: &[&str]) -> Output {
    bin().args(args).output().expect("spawn rtprobe")
}

pub fn run_env(args: &[&str], env: &[(&str, &str)]) -> Output {
    let mut c = bin();
    for (k, v) in env {
        c.env(k, v);
    }
    c.args(args).output().expect("spawn rtprobe")
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
    assert!(!err.contains("panicked"), "panic: {err}");
}
