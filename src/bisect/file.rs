//! The bisection file (`bisect --json FILE`, schema `rtprobe.bisect/1`) that `report --bisect`
//! reads: the [`Bisection`] with where it came from.
use super::Bisection;
use serde::{Deserialize, Serialize};
use serde_json::Value;
use std::path::{Path, PathBuf};

pub const SCHEMA: &str = "rtprobe.bisect/1";

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct BisectFile {
    pub schema: String,
    pub report: PathBuf,
    /// The bisected report's `started` stamp: `report --bisect` refuses another report.
    #[serde(default)]
    pub report_started: String,
    pub device: Value,
    /// The scope's filters (empty: the whole matrix).
    pub scope: Vec<String>,
    pub full_matrix: usize,
    pub inject: Vec<String>,
    pub offline: bool,
    /// The device UUID of the card the bisection re-ran cells on when the report's card was not
    /// on the machine (another card of the same name and driver build); absent on the same card.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub device_uuid_rerun: Option<String>,
    #[serde(flatten)]
    pub bisection: Bisection,
    /// The text `bisect` printed.
    pub text: String,
}

impl BisectFile {
    /// The file for `bisection` of the report at `path` (rendered as `bisect` prints it).
    pub fn new(path: &Path, report: &crate::report::run_report::RunReport, scope: &[crate::matrix::Filter], inject: &[crate::matrix::inject::Injection], offline: bool, bisection: Bisection) -> Self {
        let text = super::render(&bisection, report.plan.generated);
        BisectFile {
            schema: SCHEMA.into(),
            report: path.to_path_buf(),
            report_started: report.started.clone(),
            device: report.device.clone(),
            scope: scope.iter().map(super::predicate).collect(),
            full_matrix: report.plan.generated,
            inject: inject.iter().map(|i| i.spec.clone()).collect(),
            offline,
            device_uuid_rerun: None,
            bisection,
            text,
        }
    }

    pub fn load(path: &Path) -> Result<BisectFile, String> {
        let bytes = std::fs::read(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
        let f: BisectFile = serde_json::from_slice(&bytes).map_err(|e| format!("{} is not an rtprobe bisection: {e}", path.display()))?;
        if f.schema != SCHEMA {
            return Err(format!("{} has schema {:?}, expected {SCHEMA:?}", path.display(), f.schema));
        }
        Ok(f)
    }
}
