//! `run --shader --validate=gpu-av`: a variant that faulted, re-run under GPU-Assisted
//! Validation, its attempts kept apart from the variant's, and what they say
//! ([`judge`]): GPU-AV **masks** the fault (every attempt passes without a message: the fault
//! is gone under GPU-AV, as engines that debug with it see), **reports** it (messages: the
//! shader's own invalid access — an out-of-range index, a bad address — which makes the variant
//! an `error` of the shader or harness, not a driver finding), or the variant **still faults**.
pub use super::shader_run::{GpuAvJudgement, ShaderGpuAv};
use super::shader_run::{Judgement, ShaderAttempt, ShaderVariant};
use super::Outcome;

fn faulted(a: &ShaderAttempt) -> bool {
    match a.attempt.outcome {
        Outcome::DeviceLost | Outcome::Crash | Outcome::Timeout => true,
        Outcome::Pass
        | Outcome::Mismatch
        | Outcome::Error
        | Outcome::Unsupported
        | Outcome::NotImplemented => false,
    }
}

/// What the attempts under GPU-AV say of the variant's fault (messages first: a report
/// explains a fault that also happened).
pub fn judge(attempts: Vec<ShaderAttempt>) -> ShaderGpuAv {
    let n = attempts.len();
    let messages: u64 = attempts.iter().map(|a| a.validation_messages).sum();
    let faults = attempts.iter().filter(|a| faulted(a)).count();
    let passes = attempts.iter().filter(|a| a.attempt.outcome == Outcome::Pass).count();
    let (judgement, line) = if messages > 0 {
        let first = attempts.iter().flat_map(|a| &a.validation).next();
        let first = first.map(|t| format!(" (first: {t})")).unwrap_or_default();
        (
            GpuAvJudgement::Reports,
            format!("GPU-AV reports {messages} validation messages in {n} attempts{first}: the shader's own invalid access, an error of the shader or the harness, not a driver finding"),
        )
    } else if faults > 0 {
        (
            GpuAvJudgement::StillFaults,
            format!("still faults under GPU-AV ({faults} of {n} attempts), no GPU-AV message"),
        )
    } else if n > 0 && passes == n {
        (
            GpuAvJudgement::Masks,
            format!("GPU-AV masks the fault: {n} of {n} attempts pass under GPU-AV, no message"),
        )
    } else {
        let why = attempts.iter().find_map(|a| a.attempt.detail.clone());
        let why = why.map(|d| format!(": {d}")).unwrap_or_default();
        (GpuAvJudgement::Error, format!("GPU-AV re-run did not run{why}"))
    };
    ShaderGpuAv { attempts, judgement, line }
}

/// `v` with its GPU-AV re-run: one GPU-AV reports is the shader's or the harness's `error`
/// (judgement `validation`), no finding; else its verdict stands.
pub fn apply(mut v: ShaderVariant, g: ShaderGpuAv) -> ShaderVariant {
    if g.judgement == GpuAvJudgement::Reports {
        v.outcome = Outcome::Error;
        v.judgement = Judgement::Validation;
        v.detail = Some(g.line.clone());
        v.incidence = None;
    }
    v.gpu_av = Some(g);
    v
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::Attempt;

    fn attempt(outcome: Outcome, messages: u64) -> ShaderAttempt {
        ShaderAttempt {
            attempt: Attempt::new(outcome, true),
            validation_messages: messages,
            validation: (0..messages).map(|k| format!("VUID-x {k}")).collect(),
            outputs: vec![],
            differs: None,
            against: None,
        }
    }

    #[test]
    fn masks_reports_or_still_faults() {
        let p = || attempt(Outcome::Pass, 0);
        assert_eq!(judge(vec![p(), p()]).judgement, GpuAvJudgement::Masks);
        let g = judge(vec![p(), attempt(Outcome::Pass, 2)]);
        assert_eq!(g.judgement, GpuAvJudgement::Reports);
        assert!(g.line.contains("VUID-x 0") && g.line.contains("not a driver finding"));
        // A report explains a fault that also happened.
        let g = judge(vec![attempt(Outcome::Crash, 1)]);
        assert_eq!(g.judgement, GpuAvJudgement::Reports);
        let g = judge(vec![p(), attempt(Outcome::DeviceLost, 0)]);
        assert_eq!(g.judgement, GpuAvJudgement::StillFaults);
        assert!(g.line.contains("1 of 2"));
        assert_eq!(judge(vec![attempt(Outcome::Error, 0)]).judgement, GpuAvJudgement::Error);
        assert_eq!(judge(vec![]).judgement, GpuAvJudgement::Error);
    }
}
