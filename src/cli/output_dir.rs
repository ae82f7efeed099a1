//! `run --output-dir DIR`: the folder a deqp-runner user looks for — `results.csv`,
//! `failures.csv` and `junit.xml` (`fleet::deqp_files`, `report::junit`) beside rtprobe's own report
//! (DIR/report.json unless `-o` puts it elsewhere). Each file is written atomically at the end.
use crate::atomic::write_atomic;
use crate::fleet::deqp_files as deqp;
use crate::model::RunReport;
use crate::report::junit;
use anyhow::{Context, Result};
use std::path::{Path, PathBuf};

/// The report's path in `dir` when `-o` does not give one.
pub fn report_path(dir: &Path) -> PathBuf {
    dir.join("report.json")
}

/// Write the folder's files for `r`.
pub fn write(dir: &Path, r: &RunReport) -> Result<()> {
    let files = [
        ("results.csv", deqp::results_csv(r)),
        ("failures.csv", deqp::failures_csv(r)),
        ("junit.xml", junit::render(r)),
    ];
    for (name, text) in files {
        write_atomic(&dir.join(name), text.as_bytes())
            .with_context(|| format!("writing {name} into --output-dir"))?;
    }
    Ok(())
}
