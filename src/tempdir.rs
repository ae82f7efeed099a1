//! A private temporary folder removed on drop: what rtprobe's own temporary files (an external
//! glslang's input and output) and its tests use. std-only on purpose: the `tempfile` crate as a
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
        Self::new_in(&std::env::temp_dir())
    }

    /// Make a new folder under `parent`. A name already taken (another process's, or one planted
    /// there) is never reused: `create_dir` fails on it and the next name is tried.
    pub fn new_in(parent: &Path) -> std::io::Result<TempDir> {
        static N: AtomicU32 = AtomicU32::new(0);
        make(parent, || {
            let n = N.fetch_add(1, Ordering::Relaxed);
            let nanos = std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0, |d| d.subsec_nanos());
            format!("rtprobe-{}-{n}-{nanos}", std::process::id())
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
    let mut last = None;
    for _ in 0..100 {
        let p = parent.join(names());
        match std::fs::DirBuilder::new().mode(0o700).create(&p) {
            Ok(()) => return Ok(TempDir(p)),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => last = Some(e),
            Err(e) => return Err(e),
        }
    }
    Err(last.unwrap_or_else(|| std::io::Error::other("no free temporary folder name")))
}

/// `path` made (with missing parents) mode 0700, or used as it is where it already exists, but
/// only as a private folder of this user: not a link, owned by the effective user, no access for
/// group or others — checked after the make, so that a folder planted under a predictable name
/// (a run's job folder `rtprobe-<pid>` in /tmp) is refused rather than written into.
pub fn private_dir(path: &Path) -> std::io::Result<()> {
    use std::os::unix::fs::{DirBuilderExt, MetadataExt};
    std::fs::DirBuilder::new().recursive(true).mode(0o700).create(path)?;
    let m = std::fs::symlink_metadata(path)?;
    // SAFETY: geteuid has no preconditions.
    let euid = unsafe { libc::geteuid() };
    if m.is_dir() && m.uid() == euid && m.mode() & 0o077 == 0 {
        return Ok(());
    }
    Err(std::io::Error::other(format!(
        "{} exists and is not a private folder of this user (a link, another owner, or open to others); remove it",
        path.display()
    )))
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

    /// A private folder is made 0700 and used again; a planted one is refused: a link to a
    /// private folder, or a folder others can enter.
    #[test]
    fn a_private_folder_is_made_or_refused_where_planted() {
        use std::os::unix::fs::PermissionsExt;
        let parent = TempDir::new().unwrap();
        let job = parent.path().join("rtprobe-1/gpu-av");
        private_dir(&job).unwrap();
        let mode = std::fs::metadata(&job).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, 0o700);
        private_dir(&job).unwrap();
        let link = parent.path().join("link");
        std::os::unix::fs::symlink(&job, &link).unwrap();
        assert!(private_dir(&link).unwrap_err().to_string().contains("not a private folder"));
        let open = parent.path().join("open");
        std::fs::create_dir(&open).unwrap();
        std::fs::set_permissions(&open, std::fs::Permissions::from_mode(0o777)).unwrap();
        assert!(private_dir(&open).unwrap_err().to_string().contains("remove it"));
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
