//! One writer per report file. A run holds an advisory lock (`flock`) on `.<report>.lock` beside
//! its report for as long as it writes it: a second run given the same `-o`, a `--resume` of a
//! report still being written, or a `merge -o` onto it is refused, and two runs started in the
//! same second never pick the same default name ([`ReportLock::unique`]). The kernel drops the lock
//! when its process dies, however it dies, so a killed run's report can be resumed at once; the
//! lock file itself is removed when the lock is released in order (a killed run leaves it behind,
//! empty of meaning, and the next lock of that report takes it over).
use std::fs::File;
use std::io::{Read, Seek, Write};
use std::os::unix::fs::{MetadataExt, OpenOptionsExt};
use std::os::unix::io::AsRawFd;
use std::path::{Path, PathBuf};

/// Why a report could not be locked.
#[derive(Debug, thiserror::Error)]
pub enum LockError {
    /// Another process holds the lock (`pid`: what it wrote in the lock file, if readable).
    #[error("{} is being written by another rtprobe run{}", .report.display(), .pid.map(|p| format!(" (pid {p})")).unwrap_or_default())]
    Busy { report: PathBuf, pid: Option<u32> },
    #[error("cannot lock {}: {err}", .lock.display())]
    Io { lock: PathBuf, err: std::io::Error },
}

/// The lock of one report file, held until dropped.
#[derive(Debug)]
pub struct ReportLock {
    lock: PathBuf,
    /// Open for as long as the lock is held (closing it releases the lock).
    _file: File,
}

/// The lock file of `report`: `.<name>.lock` in its folder.
pub fn lock_path(report: &Path) -> PathBuf {
    let name = report.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    report.with_file_name(format!(".{name}.lock"))
}

impl ReportLock {
    /// Lock `report` for this process; [`LockError::Busy`] at once when another one holds it.
    pub fn acquire(report: &Path) -> Result<ReportLock, LockError> {
        let lock = lock_path(report);
        let io = |err| LockError::Io { lock: lock.clone(), err };
        if let Some(dir) = lock.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).map_err(io)?;
        }
        loop {
            // O_NOFOLLOW: a link planted under the lock's name is refused (ELOOP), never written
            // through.
            let mut file = std::fs::OpenOptions::new()
                .read(true)
                .write(true)
                .create(true)
                .truncate(false)
                .custom_flags(libc::O_NOFOLLOW)
                .open(&lock)
                .map_err(io)?;
            // SAFETY: flock(2) on a descriptor this function owns.
            if unsafe { libc::flock(file.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) } != 0 {
                let err = std::io::Error::last_os_error();
                if err.raw_os_error() == Some(libc::EWOULDBLOCK) {
                    let mut text = String::new();
                    let _ = file.read_to_string(&mut text);
                    return Err(LockError::Busy {
                        report: report.to_path_buf(),
                        pid: text.trim().parse().ok(),
                    });
                }
                return Err(io(err));
            }
            // The holder before us may have removed the file between our open and our lock: a
            // lock on an unlinked file guards nothing, so lock the file now at that path.
            let same = match (file.metadata(), std::fs::metadata(&lock)) {
                (Ok(a), Ok(b)) => a.dev() == b.dev() && a.ino() == b.ino(),
                _ => false,
            };
            if !same {
                continue;
            }
            file.set_len(0).map_err(io)?;
            file.rewind().map_err(io)?;
            let _ = write!(file, "{}", std::process::id());
            return Ok(ReportLock { lock, _file: file });
        }
    }

    /// The first free report name of `dir`/`stem`.json, `stem`-2.json, … : not there yet and not
    /// locked by another run; locked for this one.
    pub fn unique(dir: &Path, stem: &str) -> Result<(PathBuf, ReportLock), LockError> {
        for n in 1.. {
            let name = if n == 1 { format!("{stem}.json") } else { format!("{stem}-{n}.json") };
            let path = dir.join(name);
            match ReportLock::acquire(&path) {
                Ok(lock) if !path.exists() => return Ok((path, lock)),
                Ok(_) | Err(LockError::Busy { .. }) => continue,
                Err(e) => return Err(e),
            }
        }
        unreachable!("some name is free")
    }
}

impl Drop for ReportLock {
    fn drop(&mut self) {
        // Removed while still locked, so that no other run locks this file after us: one that
        // opened it meanwhile sees it gone and opens the path anew.
        let _ = std::fs::remove_file(&self.lock);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_report_has_one_writer_and_is_free_again_after_it() {
        let d = crate::tempdir::tempdir().unwrap();
        let r = d.path().join("r.json");
        let first = ReportLock::acquire(&r).unwrap();
        // flock locks belong to the open file: a second open, even in this process, is refused.
        match ReportLock::acquire(&r) {
            Err(LockError::Busy { pid, .. }) => assert_eq!(pid, Some(std::process::id())),
            other => panic!("{other:?}"),
        }
        drop(first);
        assert!(!lock_path(&r).exists(), "the lock file goes with the lock");
        let again = ReportLock::acquire(&r).unwrap();
        assert!(lock_path(&r).exists());
        drop(again);
    }

    /// A link planted under the lock's name is refused, and what it points to is untouched.
    #[test]
    fn a_planted_lock_link_is_refused_not_written_through() {
        let d = crate::tempdir::tempdir().unwrap();
        let victim = d.path().join("victim");
        std::fs::write(&victim, b"keep").unwrap();
        let r = d.path().join("r.json");
        std::os::unix::fs::symlink(&victim, lock_path(&r)).unwrap();
        match ReportLock::acquire(&r) {
            Err(LockError::Io { err, .. }) => assert_eq!(err.raw_os_error(), Some(libc::ELOOP)),
            other => panic!("{other:?}"),
        }
        assert_eq!(std::fs::read(&victim).unwrap(), b"keep");
    }

    #[test]
    fn default_names_skip_reports_that_exist_or_are_being_written() {
        let d = crate::tempdir::tempdir().unwrap();
        let (a, la) = ReportLock::unique(d.path(), "run-x").unwrap();
        assert_eq!(a.file_name().unwrap(), "run-x.json");
        // A second run in the same second, while the first still writes (its report not yet
        // on disk): another name.
        let (b, lb) = ReportLock::unique(d.path(), "run-x").unwrap();
        assert_eq!(b.file_name().unwrap(), "run-x-2.json");
        std::fs::write(&a, b"{}").unwrap();
        drop(la);
        // The first finished: its report exists, so it is not reused either.
        let (c, _lc) = ReportLock::unique(d.path(), "run-x").unwrap();
        assert_eq!(c.file_name().unwrap(), "run-x-3.json");
        drop(lb);
    }
}
