//! This executable, as rtprobe starts it again for its children (workers, `__shader`,
//! `__interesting`, the slice's and `bench`'s `run`). Through `/proc/self/exe` (or, for a
//! command another process runs, `/proc/PID/exe`), which starts the very file running now even
//! after its path was replaced or deleted: a `cargo build` beside a long `reduce` replaces
//! `target/release/rtprobe`, `current_exe()` then names `PATH (deleted)`, and starting that
//! failed with a bare `No such file or directory (os error 2)`. Where `/proc` is not mounted,
//! the executable's path as `current_exe()` says it.
use std::path::{Path, PathBuf};

/// The kernel's link to the running process's file.
const PROC_SELF: &str = "/proc/self/exe";

/// The path this process starts itself by.
pub fn spawn_path() -> PathBuf {
    of_proc(Path::new(PROC_SELF))
}

/// The path another process (spirv-reduce's shell) starts this process's file by, valid while
/// this process lives.
pub fn shared_path() -> PathBuf {
    of_proc(&PathBuf::from(format!("/proc/{}/exe", std::process::id())))
}

/// `link` when it leads to a file, else `current_exe()`'s path (or `rtprobe`, for `$PATH`).
fn of_proc(link: &Path) -> PathBuf {
    if link.is_file() {
        return link.to_path_buf();
    }
    std::env::current_exe().unwrap_or_else(|_| PathBuf::from("rtprobe"))
}

/// The executable in words, for an error: its path (`PATH (deleted)` when a build replaced it
/// since it started).
pub fn describe() -> String {
    match std::env::current_exe() {
        Ok(p) => p.display().to_string(),
        Err(e) => format!("rtprobe (its path unknown: {e})"),
    }
}

/// One line for a child that did not start: what it was for, the executable, the OS's reason.
pub fn start_error(what: &str, e: &std::io::Error) -> String {
    format!("starting {} for {what}: {e}", describe())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_running_file_starts_after_its_path_is_gone() {
        // A copy of a small executable, started, then its path removed: /proc/PID/exe still
        // starts the file, as spawn_path and shared_path give it.
        let d = crate::tempdir::tempdir().unwrap();
        let exe = d.path().join("sleeper");
        std::fs::copy("/bin/sleep", &exe).unwrap();
        let mut child = std::process::Command::new(&exe).arg("5").spawn().unwrap();
        std::fs::remove_file(&exe).unwrap();
        let link = PathBuf::from(format!("/proc/{}/exe", child.id()));
        let target = std::fs::read_link(&link).unwrap();
        assert!(target.display().to_string().ends_with(" (deleted)"), "{}", target.display());
        assert_eq!(of_proc(&link), link);
        let ok = std::process::Command::new(&link).arg("0").status().unwrap();
        assert!(ok.success());
        // Twin: the path current_exe() would name does not start.
        let gone = std::process::Command::new(&target).arg("0").status();
        assert_eq!(gone.unwrap_err().kind(), std::io::ErrorKind::NotFound);
        child.kill().unwrap();
        child.wait().unwrap();
    }

    #[test]
    fn this_process_starts_itself_through_proc() {
        assert_eq!(spawn_path(), PathBuf::from(PROC_SELF));
        assert_eq!(shared_path(), PathBuf::from(format!("/proc/{}/exe", std::process::id())));
        let e = std::io::Error::from(std::io::ErrorKind::NotFound);
        let line = start_error("the dead-code strip's check", &e);
        assert!(line.starts_with("starting /") && line.contains("strip's check: "), "{line}");
    }
}
