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
    let tmp = path.with_file_name(format!(".{name}.tmp-{}", std::process::id()));
    let result = (|| {
        let mut f = std::fs::File::create(&tmp)?;
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

    #[test]
    fn reports_the_path_on_failure() {
        let e = write_atomic(Path::new("/proc/definitely/not/here.json"), b"x").unwrap_err();
        assert!(e.to_string().contains("/proc/definitely/not/here.json"));
    }
}
