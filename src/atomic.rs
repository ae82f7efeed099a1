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
    let (tmp, mut f) = create_temp(path).map_err(err)?;
    let result = (|| {
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

/// The number of the next temp name [`create_temp`] tries (process-wide).
static NEXT_TEMP: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

/// A new file beside `path`, `.NAME.tmp-PID-N` (`O_EXCL`), by [`crate::tempdir::first_free`]:
/// a name that is taken — another writer's live temp file (a process of this pid in another pid
/// namespace sharing the folder), a killed writer's, a link someone planted — is never written
/// through nor removed.
fn create_temp(path: &Path) -> std::io::Result<(PathBuf, std::fs::File)> {
    // One name per call (threads of one process may write the same file: the GLSL cache).
    let name =
        path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_else(|| "out".into());
    crate::tempdir::first_free(|_| {
        let n = NEXT_TEMP.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let tmp = path.with_file_name(format!(".{name}.tmp-{}-{n}", std::process::id()));
        let f = std::fs::OpenOptions::new().write(true).create_new(true).open(&tmp)?;
        Ok((tmp, f))
    })
}

/// Whether a file can be written in `dir` (made when missing): a new temp file is made there
/// ([`create_temp`]: nothing there is followed or removed) and removed. The OS error when not.
pub fn can_write_in(dir: &Path) -> std::io::Result<()> {
    std::fs::create_dir_all(dir)?;
    let (tmp, _) = create_temp(&dir.join("rtprobe-write-check"))?;
    std::fs::remove_file(tmp)
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

    /// Every temp name this process would try next taken by a planted link: the write still
    /// lands, through none of them, and none is removed. Its twin, a plain `File::create` of the
    /// name, writes into the victim.
    #[test]
    fn a_planted_link_is_neither_written_through_nor_removed() {
        let d = crate::tempdir::tempdir().unwrap();
        let victim = d.path().join("victim");
        std::fs::write(&victim, b"keep").unwrap();
        let r = d.path().join("r.json");
        let pid = std::process::id();
        // The counter is the process's: plant the next names other tests may take meanwhile too.
        let from = NEXT_TEMP.load(std::sync::atomic::Ordering::Relaxed);
        let planted: Vec<PathBuf> =
            (from..from + 40).map(|n| d.path().join(format!(".r.json.tmp-{pid}-{n}"))).collect();
        for p in &planted {
            std::os::unix::fs::symlink(&victim, p).unwrap();
        }
        write_atomic(&r, b"new").unwrap();
        assert_eq!(std::fs::read(&r).unwrap(), b"new");
        assert_eq!(std::fs::read(&victim).unwrap(), b"keep");
        assert!(planted.iter().all(|p| std::fs::symlink_metadata(p).unwrap().is_symlink()));
        std::fs::File::create(&planted[0]).unwrap().write_all(b"twin").unwrap();
        assert_eq!(std::fs::read(&victim).unwrap(), b"twin", "the twin writes through");
    }

    /// The write check makes its own file and removes only that: a link planted under the
    /// name it tries first is neither followed nor removed.
    #[test]
    fn the_write_check_follows_and_removes_nothing_planted() {
        let d = crate::tempdir::tempdir().unwrap();
        let victim = d.path().join("victim");
        std::fs::write(&victim, b"keep").unwrap();
        let (pid, from) =
            (std::process::id(), NEXT_TEMP.load(std::sync::atomic::Ordering::Relaxed));
        let planted = d.path().join(format!(".rtprobe-write-check.tmp-{pid}-{from}"));
        std::os::unix::fs::symlink(&victim, &planted).unwrap();
        can_write_in(d.path()).unwrap();
        assert_eq!(std::fs::read(&victim).unwrap(), b"keep");
        assert!(std::fs::symlink_metadata(&planted).unwrap().is_symlink());
        assert_eq!(std::fs::read_dir(d.path()).unwrap().count(), 2, "its own file removed");
        assert!(can_write_in(Path::new("/proc/rtprobe-nowhere")).is_err());
    }

    #[test]
    fn reports_the_path_on_failure() {
        let e = write_atomic(Path::new("/proc/definitely/not/here.json"), b"x").unwrap_err();
        assert!(e.to_string().contains("/proc/definitely/not/here.json"));
    }
}
