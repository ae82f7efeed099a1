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
    /// Another of rtprobe's files, given where `what` was asked for: what to do with it.
    #[error("{} is {kind}, not an rtprobe {what}: {todo}", .path.display())]
    OtherFile { path: PathBuf, what: &'static str, kind: &'static str, todo: &'static str },
}

/// rtprobe's files by schema: the `what` its own readers name it by, what it is, and the command
/// that takes it.
const KINDS: &[(&str, &str, &str, &str)] = &[
    ("rtprobe.shader-run/", "a run --shader report", "a `run --shader` report", "reduce its finding with `rtprobe reduce FILE -o DIR`, then `rtprobe report DIR/reduce.json` writes the issue"),
    ("rtprobe.reduce/", "a reduce.json", "`rtprobe reduce`'s file", "`rtprobe report DIR/reduce.json` writes its issue"),
    ("rtprobe.report/", "run report", "an `rtprobe run` report", "`rtprobe bisect`, `report` and `repro` take it"),
    ("rtprobe.bisect/", "bisection", "a bisection", "give it to `rtprobe report RUN.json --bisect FILE`"),
];

/// The kind of file `bytes` holds when its `schema` is one of [`KINDS`] other than `what`'s
/// (a file of `what`'s kind that does not parse keeps serde's message).
fn other_kind(bytes: &[u8], what: &'static str, path: &Path) -> Option<LoadError> {
    let v: serde_json::Value = serde_json::from_slice(bytes).ok()?;
    let schema = v["schema"].as_str()?;
    let &(_, own, kind, todo) = KINDS.iter().find(|(p, ..)| schema.starts_with(p))?;
    (own != what).then(|| LoadError::OtherFile { path: path.into(), what, kind, todo })
}

/// The file at `path` as a `T` (`what` names the kind of file for the message); the caller checks
/// the schema it read with [`check_schema`].
pub fn read_json<T: DeserializeOwned>(path: &Path, what: &'static str) -> Result<T, LoadError> {
    let bytes = std::fs::read(path).map_err(|err| LoadError::Read { path: path.into(), err })?;
    serde_json::from_slice(&bytes).map_err(|err| {
        other_kind(&bytes, what, path).unwrap_or(LoadError::NotThatKind {
            path: path.into(),
            what,
            err,
        })
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
        let tmp = crate::tempdir::tempdir().unwrap();
        let dir = tmp.path();
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
        // Another of rtprobe's files says what it is and what takes it; a broken file of the
        // asked kind keeps serde's message.
        let shader = dir.join("shader.json");
        std::fs::write(&shader, br#"{"schema": "rtprobe.shader-run/1", "cell": "x"}"#).unwrap();
        let e = read_json::<crate::model::RunReport>(&shader, "run report").unwrap_err();
        assert!(e.to_string().contains("is a `run --shader` report, not an rtprobe run report: reduce its finding with `rtprobe reduce"), "{e}");
        let e = read_json::<crate::model::RunReport>(&shader, "a run --shader report").unwrap_err();
        assert!(matches!(e, LoadError::NotThatKind { .. }), "{e}");
    }
}
