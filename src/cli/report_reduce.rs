//! `rtprobe report DIR/reduce.json [-o FILE] [--format md|json]`: the vendor issue of a reduced
//! user shader (`report::reduce_issue`), from `rtprobe reduce`'s file and the `access.txt` and
//! `reduced.spvasm` beside it, written atomically.
use super::args::ReportArgs;
use super::exit::{self, coded};
use crate::model::reduce::{ReduceReport, SCHEMA};
use crate::report::reduce_issue;
use anyhow::Result;

/// Whether `a.report` is a `reduce.json` (its `schema`), read without judging the rest.
pub fn is_reduce(a: &ReportArgs) -> bool {
    let Ok(bytes) = std::fs::read(&a.report) else { return false };
    let v: serde_json::Value = serde_json::from_slice(&bytes).unwrap_or_default();
    v["schema"].as_str().is_some_and(|s| s.starts_with("rtprobe.reduce/"))
}

pub fn report(a: &ReportArgs) -> Result<u8> {
    super::paths::writable_files(&[("-o", a.out.as_deref())])?;
    let path = &a.report;
    if a.bisect.is_some() || a.lanes.is_some() {
        return Err(coded(
            exit::USAGE,
            format!(
                "{}: --bisect and --lanes take a run report, not a reduce.json; drop them",
                path.display()
            ),
        ));
    }
    let r: ReduceReport = crate::model::load::read_json(path, "a reduce.json")
        .map_err(|e| coded(exit::BAD_INPUT, format!("{}: {e}", path.display())))?;
    crate::model::load::check_schema(path, &r.schema, SCHEMA)
        .map_err(|e| coded(exit::BAD_INPUT, format!("{}: {e}", path.display())))?;
    let dir = path.parent().unwrap_or(std::path::Path::new("."));
    let read = |name: &str| {
        std::fs::read_to_string(dir.join(name)).map_err(|e| {
            coded(
                exit::BAD_INPUT,
                format!(
                    "{}: {e}; the issue needs reduce's files beside reduce.json",
                    dir.join(name).display()
                ),
            )
        })
    };
    let issue = reduce_issue::build(&r, read("access.txt")?, read("reduced.spvasm")?);
    super::issue_out::emit(a, || issue.markdown(), &issue)
}
