//! Where `rtprobe report` puts an issue, for a run's finding (`report`) and for a reduced shader
//! (`report_reduce`) alike: `--format md|json` chooses the text, `-o FILE` gets it written
//! atomically (and its path printed), else stdout.
use super::args::ReportArgs;
use super::exit;
use super::out::{out, outln};
use crate::atomic::write_atomic;
use crate::report::issue::Format;
use anyhow::{Context, Result};
use serde::Serialize;

/// Writes the issue as `a` asks: `markdown` for `--format md`, `json` pretty-printed for json.
pub fn emit(
    a: &ReportArgs,
    markdown: impl FnOnce() -> String,
    json: &impl Serialize,
) -> Result<u8> {
    let text = match a.format {
        Format::Md => markdown(),
        Format::Json => serde_json::to_string_pretty(json)? + "\n",
    };
    match &a.out {
        Some(o) => {
            write_atomic(o, text.as_bytes()).context("writing the issue")?;
            outln!("issue: {}", o.display());
        }
        None => out!("{text}"),
    }
    Ok(exit::OK)
}
