//! Atomic file writes: write a sibling temp file, fsync, rename over the target. A reader (or a
//! killed writer) never sees a half-written report.
use std::io::Write;
use std::path::{Path, PathBuf};

/// A file that could not be written: the path and the OS error (said once: it is the message's
/// end, not a `source` a caller would print again).
#[derive(Debug, thiserror::Error)]
#[error("cannot write {}: {err}", .path.display())]
pub struct WriteError {
    pub path: PathBuf,
    pub err: std::io::Error,
}

impl WriteError {
    /// The disk (or the user's quota) is full: the write can succeed later.
    pub fn storage_full(&self) -> bool {
        matches!(self.err.raw_os_error(), Some(libc::ENOSPC | libc::EDQUOT))
    }
}

pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), WriteError> {
    write_atomic_with(path, bytes, true)
}

/// As [`write_atomic`]; `sync` = false skips the fsync (the rename is still atomic against a
/// killed writer, just not against power loss) for the frequent incremental report saves.
pub fn write_atomic_with(path: &Path, bytes: &[u8], sync: bool) -> Result<(), WriteError> {
    let err = |err| WriteError { path: path.to_path_buf(), err };
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(err)?;
    }
    let name =
        path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_else(|| "out".into());
    // One name per call (threads of one process may write the same file: the GLSL cache).
    static N: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let n = N.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let tmp = path.with_file_name(format!(".{name}.tmp-{}-{n}", std::process::id()));
    let result = (|| {
        let mut f = create_new(&tmp)?;
        f.write_all(bytes)?;
        if sync {
            f.sync_all()?;
        }
        std::fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result.map_err(err)
}

/// `path` made new (`O_EXCL`): what is there already — a killed writer's temp file of this pid,
/// or a link someone planted under the name — is removed (the link, not what it points to) and
/// never written through.
fn create_new(path: &Path) -> std::io::Result<std::fs::File> {
    let open = || std::fs::OpenOptions::new().write(true).create_new(true).open(path);
    match open() {
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
            std::fs::remove_file(path)?;
            open()
        }
        r => r,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_and_replaces() {
        let d = crate::tempdir::tempdir().unwrap();
        let p = d.path().join("sub/r.json");
        write_atomic(&p, b"one").unwrap();
        write_atomic(&p, b"two").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"two");
        assert_eq!(std::fs::read_dir(p.parent().unwrap()).unwrap().count(), 1, "no temp file left");
    }

    /// A link planted where the temp file goes is removed, not written through; its twin, a
    /// plain `File::create`, would have written into the victim.
    #[test]
    fn a_planted_link_is_not_written_through() {
        let d = crate::tempdir::tempdir().unwrap();
        let victim = d.path().join("victim");
        std::fs::write(&victim, b"keep").unwrap();
        let planted = d.path().join(".r.json.tmp");
        std::os::unix::fs::symlink(&victim, &planted).unwrap();
        let mut f = create_new(&planted).unwrap();
        f.write_all(b"new").unwrap();
        assert_eq!(std::fs::read(&victim).unwrap(), b"keep");
        assert!(std::fs::symlink_metadata(&planted).unwrap().file_type().is_file());
        std::fs::remove_file(&planted).unwrap();
        std::os::unix::fs::symlink(&victim, &planted).unwrap();
        std::fs::File::create(&planted).unwrap().write_all(b"twin").unwrap();
        assert_eq!(std::fs::read(&victim).unwrap(), b"twin", "the twin writes through");
    }

    #[test]
    fn reports_the_path_on_failure() {
        let e = write_atomic(Path::new("/proc/definitely/not/here.json"), b"x").unwrap_err();
        assert!(e.to_string().contains("/proc/definitely/not/here.json"));
    }
}
