//! A private temporary folder removed on drop: what rtprobe's own temporary files (an external
//! glslang's input and output, a supervisor's job files, `spirv-val`'s and `spirv-dis`'s input,
//! `bench`'s and `--verify`'s work) and its tests use, and [`first_free`], how every name rtprobe
//! makes beside others is chosen. Never a predictable name in /tmp: a folder `rtprobe-<pid>` that
//! an earlier process with the same pid left (or someone planted) made runs fail (CI,
//! 2026-12-04) or would have been written into. std-only on purpose: the `tempfile` crate as a
//! dev-dependency turned on `rustix`'s `fs` feature in test builds only, so `cargo test
//! --release` after `cargo build --release` recompiled `rustix`, `clap` and the whole library
//! (issue 27: one build for both).
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU32, Ordering};

/// A folder under the system's temporary folder, mode 0700, made afresh (never an existing one),
/// removed with its contents when dropped.
#[derive(Debug)]
pub struct TempDir(PathBuf);

impl TempDir {
    /// Make a new folder `rtprobe-<pid>-<n>-<nanos>` under [`std::env::temp_dir`].
    pub fn new() -> std::io::Result<TempDir> {
        Self::named("rtprobe")
    }

    /// Make a new folder `<prefix>-<pid>-<n>-<nanos>` under [`std::env::temp_dir`]: what names
    /// a folder by its use (a supervisor's job files, `spirv-val`'s input).
    /// Its error names the temporary folder and says what to do.
    pub fn named(prefix: &str) -> std::io::Result<TempDir> {
        let tmp = std::env::temp_dir();
        Self::new_in_named(&tmp, prefix).map_err(|e| {
            let what = format!(
                "cannot make a folder in {}: {e}; set TMPDIR to a folder you can write",
                tmp.display()
            );
            std::io::Error::new(e.kind(), what)
        })
    }

    /// Make a new folder under `parent`. A name already taken (another process's, or one planted
    /// there) is never reused: `create_dir` fails on it and the next name is tried.
    pub fn new_in(parent: &Path) -> std::io::Result<TempDir> {
        Self::new_in_named(parent, "rtprobe")
    }

    fn new_in_named(parent: &Path, prefix: &str) -> std::io::Result<TempDir> {
        static N: AtomicU32 = AtomicU32::new(0);
        make(parent, || {
            let n = N.fetch_add(1, Ordering::Relaxed);
            let nanos = std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0, |d| d.subsec_nanos());
            format!("{prefix}-{}-{n}-{nanos}", std::process::id())
        })
    }

    /// The folder.
    pub fn path(&self) -> &Path {
        &self.0
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// The first of `names` (at most 100 tried) that `create_dir` makes under `parent`, mode 0700.
fn make(parent: &Path, mut names: impl FnMut() -> String) -> std::io::Result<TempDir> {
    use std::os::unix::fs::DirBuilderExt;
    first_free(|_| {
        let p = parent.join(names());
        std::fs::DirBuilder::new().mode(0o700).create(&p).map(|()| TempDir(p))
    })
}

/// What `try_make(k)` makes first, for k = 0, 1, … (at most 100 tries): a candidate whose name
/// is taken (`AlreadyExists`: another process's, a killed one's, a link someone planted) is
/// skipped, never entered nor removed; any other error ends the search. The one mechanism of
/// every new file or folder rtprobe names itself beside others (temp folders, the atomic
/// writer's temp files, repro's staging folder).
pub fn first_free<T>(mut try_make: impl FnMut(u32) -> std::io::Result<T>) -> std::io::Result<T> {
    let mut last = None;
    for k in 0..100 {
        match try_make(k) {
            Ok(made) => return Ok(made),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => last = Some(e),
            Err(e) => return Err(e),
        }
    }
    Err(last.unwrap_or_else(|| std::io::Error::other("no free name")))
}

/// A new [`TempDir`] (what tests call, as they called `tempfile::tempdir`).
pub fn tempdir() -> std::io::Result<TempDir> {
    TempDir::new()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_is_new_private_and_removed_on_drop() {
        let a = TempDir::new().unwrap();
        let b = TempDir::new().unwrap();
        assert_ne!(a.path(), b.path());
        use std::os::unix::fs::PermissionsExt;
        let mode = std::fs::metadata(a.path()).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, 0o700);
        std::fs::write(a.path().join("f"), b"x").unwrap();
        let p = a.path().to_path_buf();
        drop(a);
        assert!(!p.exists());
    }

    /// Only a taken name moves on to the next; any other error ends the search at once, and
    /// nothing but taken names is `AlreadyExists` after the last try.
    #[test]
    fn first_free_skips_taken_names_only() {
        use std::io::{Error, ErrorKind};
        let mut tries = 0;
        let e = first_free::<()>(|_| {
            tries += 1;
            Err(Error::from(ErrorKind::PermissionDenied))
        })
        .unwrap_err();
        assert_eq!((e.kind(), tries), (ErrorKind::PermissionDenied, 1));
        let got =
            first_free(|k| if k < 3 { Err(Error::from(ErrorKind::AlreadyExists)) } else { Ok(k) });
        assert_eq!(got.unwrap(), 3);
        let e = first_free::<()>(|_| Err(Error::from(ErrorKind::AlreadyExists))).unwrap_err();
        assert_eq!(e.kind(), ErrorKind::AlreadyExists);
    }

    #[test]
    fn a_taken_name_is_not_reused() {
        let parent = TempDir::new().unwrap();
        std::fs::create_dir(parent.path().join("a")).unwrap();
        std::fs::write(parent.path().join("a/planted"), b"x").unwrap();
        let mut names = ["a", "a", "b"].into_iter().map(String::from);
        let got = make(parent.path(), || names.next().unwrap()).unwrap();
        assert_eq!(got.path(), parent.path().join("b"));
        // Its twin: with only taken names it fails instead of entering one.
        let err = make(parent.path(), || "a".to_string()).unwrap_err();
        assert_eq!(err.kind(), std::io::ErrorKind::AlreadyExists);
        assert!(parent.path().join("a/planted").exists());
    }
}
