//! Reading one of rtprobe's own JSON files back (a run report, a bisection), with what went wrong
//! when it cannot be: unreadable, not that kind of file, or another schema.
use serde::de::DeserializeOwned;
use std::path::{Path, PathBuf};

#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    #[error("cannot read {}: {err}", .path.display())]
    Read { path: PathBuf, err: std::io::Error },
    /// The bytes are not JSON of that kind (`what`: "run report", "bisection").
    #[error("{} is not an rtprobe {what}: {err}", .path.display())]
    NotThatKind { path: PathBuf, what: &'static str, err: serde_json::Error },
    #[error("{} has schema {schema:?}, expected {expected:?}", .path.display())]
    Schema { path: PathBuf, schema: String, expected: &'static str },
}

/// The file at `path` as a `T` (`what` names the kind of file for the message); the caller checks
/// the schema it read with [`check_schema`].
pub fn read_json<T: DeserializeOwned>(path: &Path, what: &'static str) -> Result<T, LoadError> {
    let bytes = std::fs::read(path).map_err(|err| LoadError::Read { path: path.into(), err })?;
    serde_json::from_slice(&bytes).map_err(|err| LoadError::NotThatKind {
        path: path.into(),
        what,
        err,
    })
}

/// `Ok` when the file's `schema` is `expected`.
pub fn check_schema(path: &Path, schema: &str, expected: &'static str) -> Result<(), LoadError> {
    if schema != expected {
        return Err(LoadError::Schema { path: path.into(), schema: schema.into(), expected });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_name_the_file_and_what_is_wrong() {
        let dir = std::env::temp_dir().join(format!("rtprobe-load-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let missing = dir.join("missing.json");
        let e = read_json::<serde_json::Value>(&missing, "run report").unwrap_err();
        assert!(e.to_string().starts_with(&format!("cannot read {}: ", missing.display())), "{e}");
        let junk = dir.join("junk.json");
        std::fs::write(&junk, b"{").unwrap();
        let e = read_json::<serde_json::Value>(&junk, "bisection").unwrap_err();
        assert!(
            e.to_string().starts_with(&format!("{} is not an rtprobe bisection: ", junk.display())),
            "{e}"
        );
        let e = check_schema(&junk, "x/1", "rtprobe.report/1").unwrap_err();
        assert_eq!(
            e.to_string(),
            format!("{} has schema \"x/1\", expected \"rtprobe.report/1\"", junk.display())
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}
