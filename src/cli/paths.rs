//! Output paths checked before any work: a command that would run for minutes and then fail to
//! write its file (`stress --json` into a folder it cannot write) fails first instead, in one
//! line. The check writes and removes a probe file where the output will go (creating the folder,
//! as the write itself would).
use super::exit::{self, coded};
use anyhow::Result;
use std::path::Path;

/// A fresh private work folder `<prefix>-<pid>-…` under the temporary folder (children's job
/// and result files), removed when dropped and by the interrupt handler where the command
/// installs it; or a one-line error (exit 9) that says what to do.
pub fn work_dir(prefix: &str) -> Result<crate::runner::groups::JobFolder> {
    crate::runner::groups::JobFolder::named(prefix)
        .map_err(|e| coded(exit::BAD_INPUT, e.to_string()))
}

/// The temporary folder takes a private work folder (the supervisor's job files go there), or a
/// one-line error (exit 9) before any GPU work: else every cell would be an `error` finding.
pub fn temp_usable() -> Result<()> {
    work_dir("rtprobe-check").map(drop)
}

/// `flag`'s output file `path` can be written (its folder exists or can be made, and takes a
/// file), or a one-line error (exit 9) that says what to do.
pub fn writable_file(path: &Path, flag: &str) -> Result<()> {
    if path.is_dir() {
        return Err(coded(
            exit::BAD_INPUT,
            format!("{flag} {} is a folder; give a file name", path.display()),
        ));
    }
    let dir = path.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
    crate::atomic::can_write_in(dir).map_err(|e| {
        coded(
            exit::BAD_INPUT,
            format!(
                "{flag} {}: cannot write in {}: {e}; choose another path",
                path.display(),
                dir.display()
            ),
        )
    })
}

/// `flag`'s output folder `dir` can be made and written in.
pub fn writable_dir(dir: &Path, flag: &str) -> Result<()> {
    if dir.exists() && !dir.is_dir() {
        return Err(coded(
            exit::BAD_INPUT,
            format!("{flag} {} is a file, not a folder", dir.display()),
        ));
    }
    crate::atomic::can_write_in(dir).map_err(|e| {
        coded(
            exit::BAD_INPUT,
            format!("{flag} {}: cannot write there: {e}; choose another folder", dir.display()),
        )
    })
}

/// [`writable_file`] for each given (flag, path).
pub fn writable_files(outputs: &[(&str, Option<&Path>)]) -> Result<()> {
    for (flag, path) in outputs {
        if let Some(p) = path {
            writable_file(p, flag)?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_unwritable_output_is_one_line_before_any_work() {
        let d = crate::tempdir::tempdir().unwrap();
        writable_file(&d.path().join("new/sub/r.json"), "-o").unwrap();
        assert!(d.path().join("new/sub").is_dir(), "made, as the write would");
        assert_eq!(
            std::fs::read_dir(d.path().join("new/sub")).unwrap().count(),
            0,
            "no probe left"
        );
        let e = writable_file(Path::new("/proc/rtprobe-nowhere/r.json"), "--json").unwrap_err();
        assert_eq!(exit::code_for(&e), exit::BAD_INPUT);
        let line = format!("{e:#}");
        assert!(line.starts_with("--json /proc/rtprobe-nowhere/r.json: cannot write in"), "{line}");
        assert!(!line.contains('\n'));
        let e = writable_file(d.path(), "-o").unwrap_err();
        assert!(format!("{e:#}").contains("is a folder"));
        writable_dir(&d.path().join("out"), "--output-dir").unwrap();
        std::fs::write(d.path().join("f"), b"x").unwrap();
        assert!(writable_dir(&d.path().join("f"), "--output-dir").is_err());
    }
}
