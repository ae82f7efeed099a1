//! External tools rtprobe runs: SPIRV-Tools ([`spirv`]: `spirv-val`, `spirv-dis`, `spirv-as`,
//! `spirv-reduce`) and `glslangValidator`. Each is looked for in two places, and the newest
//! version found wins:
//! - the Debian sid root of `scripts/setup-sid` (`RTPROBE_SID_ROOT`, default
//!   `/var/lib/rtprobe/sid-root`, recognised by its `etc/rtprobe-sid.stamp`), run through the
//!   root's own dynamic loader with the root's libraries — no chroot and no root rights, and the
//!   tool reads and writes host paths as given;
//! - `PATH` (inside `scripts/in-sid` that is the root's own `/usr/bin`).
//!
//! Each tool is resolved once per process. A tool that is missing, or does not print a version,
//! is `None`; callers say what that means for them.
pub mod spirv;

use std::collections::HashMap;
use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::{Mutex, OnceLock};

/// Where a tool was found.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Origin {
    /// In the sid root at this path, run through its dynamic loader.
    SidRoot(PathBuf),
    /// On PATH (or a path given through an environment variable).
    Path,
}

/// One external tool, found and accepted.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Tool {
    pub name: &'static str,
    /// (major, minor): SPIRV-Tools `2026.4`, glslang `16.6`.
    pub version: (u32, u32),
    /// The version as the tool prints it, e.g. "v2026.4" or "16.6.0".
    pub version_text: String,
    pub origin: Origin,
    program: PathBuf,
    prefix: Vec<OsString>,
}

impl Tool {
    /// A command running the tool (stdin closed); add its arguments.
    pub fn command(&self) -> Command {
        let mut c = Command::new(&self.program);
        c.args(&self.prefix).stdin(Stdio::null());
        c
    }

    /// `spirv-val v2026.4 (sid root /var/lib/rtprobe/sid-root)`.
    pub fn describe(&self) -> String {
        match &self.origin {
            Origin::SidRoot(root) => {
                format!("{} {} (sid root {})", self.name, self.version_text, root.display())
            }
            Origin::Path if self.program.components().count() == 1 => {
                format!("{} {} (on PATH)", self.name, self.version_text)
            }
            Origin::Path => {
                format!("{} {} ({})", self.name, self.version_text, self.program.display())
            }
        }
    }
}

/// The sid root made by `scripts/setup-sid`, when this machine has one.
pub fn sid_root() -> Option<PathBuf> {
    let root = std::env::var_os("RTPROBE_SID_ROOT")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("/var/lib/rtprobe/sid-root"));
    root.join("etc/rtprobe-sid.stamp").is_file().then_some(root)
}

/// The root's dynamic loader and library folder for this machine's architecture.
fn loader(root: &Path) -> Option<(PathBuf, PathBuf)> {
    let pairs = [
        ("lib64/ld-linux-x86-64.so.2", "usr/lib/x86_64-linux-gnu"),
        ("lib/ld-linux-aarch64.so.1", "usr/lib/aarch64-linux-gnu"),
    ];
    pairs.iter().map(|(l, d)| (root.join(l), root.join(d))).find(|(l, d)| l.exists() && d.is_dir())
}

/// The sid root's `name`, as a program and the arguments before the tool's own.
fn in_sid_root(root: &Path, name: &str) -> Option<(PathBuf, Vec<OsString>)> {
    let (ld, libs) = loader(root)?;
    let bin = root.join("usr/bin").join(name);
    bin.is_file().then(|| (ld, vec!["--library-path".into(), libs.into_os_string(), bin.into()]))
}

/// Reads a tool's `--version` output: ((major, minor), the version as printed).
pub type ParseVersion = fn(&str) -> Option<((u32, u32), String)>;

/// Run `program prefix --version` and read the version with `parse` (stdout, then stderr).
fn probe(
    name: &'static str,
    (program, prefix): (PathBuf, Vec<OsString>),
    origin: Origin,
    parse: ParseVersion,
) -> Option<Tool> {
    let out =
        Command::new(&program).args(&prefix).arg("--version").stdin(Stdio::null()).output().ok()?;
    let text =
        String::from_utf8_lossy(&out.stdout).to_string() + &String::from_utf8_lossy(&out.stderr);
    let (version, version_text) = parse(&text)?;
    Some(Tool { name, version, version_text, origin, program, prefix })
}

/// The newest of `name` in the sid root and on PATH (`env` names a variable that replaces the
/// PATH lookup with a path), found once per process.
pub fn find(name: &'static str, env: Option<&str>, parse: ParseVersion) -> Option<&'static Tool> {
    static FOUND: OnceLock<Mutex<HashMap<&'static str, Option<&'static Tool>>>> = OnceLock::new();
    let map = FOUND.get_or_init(Default::default);
    if let Some(t) = map.lock().unwrap_or_else(|e| e.into_inner()).get(name) {
        return *t;
    }
    let mut found = Vec::new();
    if let Some(root) = sid_root() {
        if let Some(c) = in_sid_root(&root, name) {
            found.extend(probe(name, c, Origin::SidRoot(root), parse));
        }
    }
    let on_path = env.and_then(std::env::var_os).map(PathBuf::from).unwrap_or_else(|| name.into());
    found.extend(probe(name, (on_path, Vec::new()), Origin::Path, parse));
    // The newest; at equal versions the sid root's (the first found).
    let best = found.into_iter().rev().max_by_key(|t| t.version);
    let best: Option<&'static Tool> = best.map(|t| &*Box::leak(Box::new(t)));
    map.lock().unwrap_or_else(|e| e.into_inner()).insert(name, best);
    best
}

/// `Glslang Version: 11:16.6.0` → ((16, 6), "16.6.0").
pub fn parse_glslang_version(out: &str) -> Option<((u32, u32), String)> {
    let line = out.lines().find(|l| l.starts_with("Glslang Version:"))?;
    let v = line.rsplit(':').next()?.trim();
    let mut it = v.split('.').map(|p| p.parse::<u32>().ok());
    Some(((it.next()??, it.next()??), v.to_string()))
}

/// The newest glslangValidator (`RTPROBE_GLSLANG` replaces the PATH lookup).
pub fn glslang() -> Option<&'static Tool> {
    find("glslangValidator", Some("RTPROBE_GLSLANG"), parse_glslang_version)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn glslang_versions_parse() {
        let v = parse_glslang_version("Glslang Version: 11:16.6.0\nESSL Version: ...");
        assert_eq!(v, Some(((16, 6), "16.6.0".into())));
        assert_eq!(parse_glslang_version("Glslang Version: 11:12.0.0").unwrap().0, (12, 0));
        assert_eq!(parse_glslang_version("garbage"), None);
    }

    #[test]
    fn a_root_without_its_stamp_or_loader_offers_nothing() {
        let d = crate::tempdir::tempdir().unwrap();
        assert!(in_sid_root(d.path(), "spirv-val").is_none());
        std::fs::create_dir_all(d.path().join("usr/bin")).unwrap();
        std::fs::write(d.path().join("usr/bin/spirv-val"), "").unwrap();
        assert!(in_sid_root(d.path(), "spirv-val").is_none(), "no loader");
    }
}
