//! What a finding's report says beside its attempts: whether the recommended pattern works
//! and whether GPU-Assisted Validation masks it (the data; `report::recommended` and
//! `report::gpu_av` schedule and judge).
use crate::model::{Outcome, Pattern};
use serde::{Deserialize, Serialize};

/// What the report says about a finding's recommended pattern.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct PatternResult {
    /// `geometry` / `materials`; `None` where no pattern applies.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub pattern: Option<Pattern>,
    /// The pattern's cell id.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub cell: Option<String>,
    #[serde(flatten)]
    pub status: PatternStatus,
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(tag = "status", rename_all = "snake_case")]
pub enum PatternStatus {
    /// Every attempt of the pattern's cell passed.
    /// `miss_probability`: the chance these passes would all have missed a fault as frequent as
    /// the finding's ([`super::stats::pass_miss`](crate::model::stats::pass_miss)).
    Passes {
        passed: u32,
        attempts: u32,
        #[serde(skip_serializing_if = "Option::is_none", default)]
        miss_probability: Option<f64>,
    },
    /// The pattern's cell has a finding too (its verdict and how often).
    Fails { outcome: Outcome, faulted: u32, attempts: u32 },
    /// The pattern's cell did not run (unsupported, not implemented, not planned), with why.
    NotRun { reason: String },
    /// No recommended pattern applies to the finding, with why.
    NotApplicable { reason: String },
}

impl PatternResult {
    /// `recommended pattern geometry (one storage buffer …; cell): not proven (2 passes; need 19
    /// for 99%)`
    pub fn line(&self) -> String {
        let status = match &self.status {
            PatternStatus::Passes { passed, attempts, miss_probability } => {
                crate::model::stats::passes_text(*passed, *attempts, *miss_probability)
            }
            PatternStatus::Fails { outcome, faulted, attempts } => {
                format!("fails: {} ({faulted} of {attempts} attempts)", outcome.as_str())
            }
            PatternStatus::NotRun { reason } => format!("not run ({reason})"),
            PatternStatus::NotApplicable { reason } => {
                return format!("recommended pattern: none ({reason})")
            }
        };
        match (self.pattern, &self.cell) {
            (Some(p), Some(c)) => {
                format!("recommended pattern {} ({}; {c}): {status}", p.as_str(), p.description())
            }
            _ => format!("recommended pattern: {status}"),
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GpuAvVerdict {
    /// Every attempt under GPU-AV passed, enough of them that a fault as frequent as the
    /// finding's would have shown (miss probability below 1%, the verified-workaround rule).
    Masked,
    /// Every attempt under GPU-AV passed, but too few to say (the finding's own attempts bound its
    /// rate too loosely: confirm it more, `--repeat`).
    Inconclusive,
    StillFaults,
    GpuAvFailed,
    NotRun,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GpuAvResult {
    pub verdict: GpuAvVerdict,
    /// The outcome under GPU-AV (`unsupported` / `not_implemented` when it did not run).
    pub outcome: Outcome,
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub detail: Option<String>,
    /// Validation errors the layer reported during the attempt.
    #[serde(default)]
    pub validation_errors: u64,
    /// The control cell and its outcome under GPU-AV, when one ran.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub control: Option<(String, Outcome)>,
    /// Attempts under GPU-AV and how many of them passed.
    #[serde(default)]
    pub attempts: u32,
    #[serde(default)]
    pub passed: u32,
    /// For `masked` and `inconclusive`: the chance that these passes would all have missed a
    /// fault as frequent as the finding's ([`super::stats::pass_miss`]).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub miss_probability: Option<f64>,
}

impl GpuAvResult {
    pub fn not_run(outcome: Outcome, reason: String) -> Self {
        GpuAvResult {
            verdict: GpuAvVerdict::NotRun,
            outcome,
            detail: Some(reason),
            validation_errors: 0,
            control: None,
            attempts: 0,
            passed: 0,
            miss_probability: None,
        }
    }

    /// `GPU-AV: masked (passes under GPU-AV; 0 validation errors)`
    pub fn line(&self) -> String {
        let errors = if self.validation_errors > 0 {
            format!("; GPU-AV reported {} validation errors", self.validation_errors)
        } else {
            String::new()
        };
        match self.verdict {
            GpuAvVerdict::Masked => format!(
                "GPU-AV: masked ({} under GPU-AV{errors})",
                super::stats::passes_text(self.passed, self.attempts, self.miss_probability)
            ),
            GpuAvVerdict::Inconclusive => format!(
                "GPU-AV: inconclusive ({} under GPU-AV, not below the {:.0}% needed to call it masked{errors}; more attempts of the finding itself (--repeat) tighten its rate)",
                super::stats::passes_text(self.passed, self.attempts, self.miss_probability),
                100.0 * super::stats::DEFAULT_MAX_MISS
            ),
            GpuAvVerdict::StillFaults => {
                let control = match &self.control {
                    Some((c, o)) => format!("its control {c} is {} under GPU-AV", o.as_str()),
                    None => {
                        "no control ran, so GPU-AV itself breaking the pipeline is not ruled out"
                            .into()
                    }
                };
                format!(
                    "GPU-AV: still faults ({}, {} of {} attempts under GPU-AV; {control}{errors})",
                    self.outcome.as_str(),
                    self.attempts - self.passed,
                    self.attempts
                )
            }
            GpuAvVerdict::GpuAvFailed => {
                let control = match &self.control {
                    Some((c, o)) => format!(
                        "its control {c} passes without GPU-AV and is {} with it",
                        o.as_str()
                    ),
                    None => "no control".into(),
                };
                format!(
                    "GPU-AV: GPU-AV itself failed ({} under GPU-AV; {control}{errors})",
                    self.outcome.as_str()
                )
            }
            GpuAvVerdict::NotRun => format!(
                "GPU-AV: not run ({}: {})",
                self.outcome.as_str(),
                self.detail.as_deref().unwrap_or("no reason")
            ),
        }
    }
}
