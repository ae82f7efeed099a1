//! `run --shader --validate=gpu-av`: a variant that faulted, re-run under GPU-Assisted
//! Validation, its attempts kept apart from the variant's, and what they say ([`judge`]), held
//! to the evidence standard of `run`'s GPU-AV round (`report::gpu_av`):
//! - **reports**: a GPU-AV error reports an invalid access by the shader (an out-of-range
//!   index, an uninitialised descriptor, an address no buffer holds; the rule and its VUIDs in
//!   `super::validation_message`). That access is undefined behaviour, so the fault is the
//!   shader's or the harness's own, an `error`, not a driver finding. Other messages (GPU-AV's
//!   setup, warnings, API usage not about the access) are counted and shown, never decide.
//! - **still_faults**: an attempt faulted under GPU-AV too.
//! - **masks**: every attempt passed, the control — the same variant without GPU-AV, traced
//!   again in the same round — faulted again, and the chance that the passes all missed a
//!   fault as frequent as the variant's (`super::stats::pass_miss` on its incidence) is below
//!   [`MAX_MISS`], the verified-workaround rule `run`'s round holds `masked` to.
//! - **inconclusive**: every attempt passed, but the control did not fault (the fault did not
//!   repeat in this round), too few passes for the variant's incidence, or GPU-AV reported a
//!   setup problem (it may not have instrumented the pipeline).
//! - **error**: the attempts under GPU-AV could not run.
pub use super::shader_run::{GpuAvJudgement, GpuAvMessages, ShaderGpuAv};
use super::shader_run::{Judgement, ShaderAttempt, ShaderVariant};
use super::validation_message::{kind, MessageKind};
use super::{Incidence, Outcome};

/// The miss probability passes under GPU-AV must get below for `masks` (`run`'s rule).
pub const MAX_MISS: f64 = super::stats::DEFAULT_MAX_MISS;

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

impl GpuAvMessages {
    /// The messages of `attempts` by kind.
    pub fn of(attempts: &[ShaderAttempt]) -> GpuAvMessages {
        let sum = |f: fn(&ShaderAttempt) -> u64| attempts.iter().map(f).sum::<u64>();
        let invalid_access = sum(|a| a.invalid_access);
        GpuAvMessages {
            invalid_access,
            other_errors: sum(|a| a.validation_messages).saturating_sub(invalid_access),
            warnings: sum(|a| a.validation_warnings),
        }
    }

    /// `; 2 other messages, not about the access (1 error, 1 warning): no verdict`, or nothing.
    fn others(&self) -> String {
        let n = self.other_errors + self.warnings;
        if n == 0 {
            return String::new();
        }
        format!(
            "; {n} other message{}, not about the access ({} error{}, {} warning{}): no verdict",
            s(n),
            self.other_errors,
            s(self.other_errors),
            self.warnings,
            s(self.warnings)
        )
    }
}

fn s(n: u64) -> &'static str {
    if n == 1 {
        ""
    } else {
        "s"
    }
}

/// The first kept text that is GPU-AV's own setup message.
fn setup_message(attempts: &[ShaderAttempt]) -> Option<&String> {
    attempts.iter().flat_map(|a| &a.validation).find(|t| kind(t) == MessageKind::GpuAvSetup)
}

/// The first kept text that reports an invalid access, else the first kept text.
fn first_access(attempts: &[ShaderAttempt]) -> Option<&String> {
    let texts = || attempts.iter().flat_map(|a| &a.validation);
    texts().find(|t| kind(t) == MessageKind::InvalidAccess).or_else(|| texts().next())
}

/// What the attempts under GPU-AV say of the variant's fault: an invalid-access report first
/// (it explains a fault that also happened), then a fault, then passes held to the `control`
/// (the variant's attempts without GPU-AV in the same round; empty: none ran) and to the
/// variant's `incidence` (from its own attempts).
pub fn judge(
    attempts: Vec<ShaderAttempt>,
    control: Vec<ShaderAttempt>,
    incidence: Option<&Incidence>,
) -> ShaderGpuAv {
    let n = attempts.len();
    let messages = GpuAvMessages::of(&attempts);
    let others = messages.others();
    let faults = attempts.iter().filter(|a| faulted(a)).count();
    let passes = attempts.iter().filter(|a| a.attempt.outcome == Outcome::Pass).count() as u32;
    let mut miss_probability = None;
    let (judgement, line) = if messages.invalid_access > 0 {
        let first = first_access(&attempts).map(|t| format!(" (first: {t})")).unwrap_or_default();
        let k = messages.invalid_access;
        (
            GpuAvJudgement::Reports,
            format!("GPU-AV reports the harness's own fault: {k} invalid-access error{} in {n} attempts{first}: the shader's own invalid access, an error of the shader or the harness, not a driver finding{others}", s(k)),
        )
    } else if faults > 0 {
        let none = if others.is_empty() { ", no GPU-AV message" } else { "" };
        (
            GpuAvJudgement::StillFaults,
            format!("still faults under GPU-AV ({faults} of {n} attempts){none}{others}"),
        )
    } else if let Some(t) = setup_message(&attempts).filter(|_| passes as usize == n) {
        // Passes beside a GPU-AV setup error are passes of a pipeline GPU-AV may not have
        // instrumented: they cannot show that GPU-AV masks anything.
        (
            GpuAvJudgement::Inconclusive,
            format!("inconclusive: {passes} of {n} attempts pass, but GPU-AV reported a setup problem, so it may not have instrumented the pipeline ({t}){others}"),
        )
    } else if n > 0 && passes as usize == n {
        miss_probability =
            incidence.map(|i| super::stats::pass_miss(i.faulted, i.attempts, passes));
        passed(passes, &control, miss_probability, &others)
    } else {
        let why = attempts.iter().find_map(|a| a.attempt.detail.clone());
        let why = why.map(|d| format!(": {d}")).unwrap_or_default();
        (GpuAvJudgement::Error, format!("GPU-AV re-run did not run{why}{others}"))
    };
    ShaderGpuAv { attempts, judgement, line, control, miss_probability, messages }
}

/// Every attempt under GPU-AV passed: `masks` only beside a control that faulted again and
/// with a miss probability below [`MAX_MISS`]; else `inconclusive`, saying which is missing.
fn passed(
    passes: u32,
    control: &[ShaderAttempt],
    miss: Option<f64>,
    others: &str,
) -> (GpuAvJudgement, String) {
    let shown = super::stats::passes_text(passes, passes, miss);
    let c = control.iter().filter(|a| faulted(a)).count();
    let m = control.len();
    if c == 0 {
        let ran = if m == 0 {
            "no control ran".to_string()
        } else {
            format!("its control, the variant without GPU-AV in the same round, faulted 0 of {m} attempts")
        };
        let line = format!("not masks: {shown} under GPU-AV, but the fault did not repeat ({ran}), so the passes show nothing about GPU-AV{others}");
        return (GpuAvJudgement::Inconclusive, line);
    }
    let ctl = format!(
        "its control, the variant without GPU-AV in the same round, faulted {c} of {m} attempts"
    );
    match miss {
        Some(p) if p < MAX_MISS => {
            (GpuAvJudgement::Masks, format!("GPU-AV masks the fault: {shown} under GPU-AV; {ctl}{others}"))
        }
        _ => (
            GpuAvJudgement::Inconclusive,
            format!("inconclusive: {shown} under GPU-AV, not below the {:.0}% needed to call it masked; {ctl}{others}", 100.0 * MAX_MISS),
        ),
    }
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

    fn attempt(outcome: Outcome) -> ShaderAttempt {
        ShaderAttempt::bare(Attempt::new(outcome, true))
    }

    fn pass() -> ShaderAttempt {
        attempt(Outcome::Pass)
    }

    fn passes(n: usize) -> Vec<ShaderAttempt> {
        (0..n).map(|_| pass()).collect()
    }

    /// An attempt with `text` as its one error message, counted as the messenger counts it.
    fn with_error(outcome: Outcome, text: &str) -> ShaderAttempt {
        let access = kind(text) == MessageKind::InvalidAccess;
        ShaderAttempt {
            validation_messages: 1,
            invalid_access: access as u64,
            validation: vec![text.into()],
            ..attempt(outcome)
        }
    }

    const OOB: &str = "Validation Error: [ UNASSIGNED-Descriptor index out of bounds ] Index of 63 used to index descriptor array of length 2.";
    const SETUP: &str = "Validation Error: [ UNASSIGNED-GPU-Assisted Validation Error. ] Unable to reserve descriptor binding slot";

    /// A variant that faulted `k` of `n` attempts.
    fn incidence(k: u32, n: u32) -> Incidence {
        Incidence { faulted: k, attempts: n, reproduced_alone: None, miss_probability: 0.0 }
    }

    fn fault_variant() -> ShaderVariant {
        let a = vec![attempt(Outcome::Crash), attempt(Outcome::Crash)];
        ShaderVariant::judged("unpatched", None, vec![], a, None)
    }

    /// Twin of the OOB report: GPU-AV's invalid-access error makes the variant the harness's
    /// `error` (judgement `validation`), whether or not the attempt also crashed.
    #[test]
    fn an_out_of_bounds_report_is_the_harness_error() {
        let g = judge(vec![pass(), with_error(Outcome::Crash, OOB)], vec![], None);
        assert_eq!(g.judgement, GpuAvJudgement::Reports);
        assert_eq!(g.messages, GpuAvMessages { invalid_access: 1, other_errors: 0, warnings: 0 });
        assert!(g.line.starts_with("GPU-AV reports the harness's own fault: 1 invalid-access error in 2 attempts (first: Validation Error: [ UNASSIGNED-Descriptor index out of bounds ]"), "{}", g.line);
        let v = apply(fault_variant(), g);
        assert_eq!((v.outcome, v.judgement), (Outcome::Error, Judgement::Validation));
        assert!(v.incidence.is_none() && v.detail.unwrap().contains("not a driver finding"));
    }

    /// A setup error or a warning alone is counted and shown, never the verdict: the fault
    /// under GPU-AV still stands; passes are judged as passes.
    #[test]
    fn a_setup_message_alone_is_not_an_error() {
        let warned = ShaderAttempt { validation_warnings: 2, ..attempt(Outcome::Crash) };
        let g = judge(vec![with_error(Outcome::Crash, SETUP), warned], vec![], None);
        assert_eq!(g.judgement, GpuAvJudgement::StillFaults);
        assert_eq!(g.messages, GpuAvMessages { invalid_access: 0, other_errors: 1, warnings: 2 });
        assert_eq!(g.line, "still faults under GPU-AV (2 of 2 attempts); 3 other messages, not about the access (1 error, 2 warnings): no verdict");
        let v = apply(fault_variant(), g);
        assert_eq!((v.outcome, v.judgement), (Outcome::Crash, Judgement::Fault));
        // The setup error next to passes: not `error`, and not `masks` either (GPU-AV may not
        // have instrumented the pipeline); the same passes without it are `masks`.
        let mut ok = passes(6);
        ok[0] = with_error(Outcome::Pass, SETUP);
        let g = judge(ok, vec![attempt(Outcome::Crash)], Some(&incidence(5, 5)));
        assert_eq!(g.judgement, GpuAvJudgement::Inconclusive, "{}", g.line);
        assert!(g.line.contains("may not have instrumented"), "{}", g.line);
        let g = judge(passes(6), vec![attempt(Outcome::Crash)], Some(&incidence(5, 5)));
        assert_eq!(g.judgement, GpuAvJudgement::Masks, "{}", g.line);
    }

    #[test]
    fn a_fault_under_gpu_av_still_faults() {
        let g = judge(vec![pass(), attempt(Outcome::DeviceLost)], vec![], Some(&incidence(2, 2)));
        assert_eq!(g.judgement, GpuAvJudgement::StillFaults);
        assert_eq!(g.line, "still faults under GPU-AV (1 of 2 attempts), no GPU-AV message");
        assert_eq!(g.miss_probability, None);
    }

    /// `masks` needs passes enough for the variant's incidence (5 of 5: bound 55%, 6 passes
    /// miss it with p < 1%, 5 do not) and a control that faulted again.
    #[test]
    fn masks_needs_enough_passes_and_a_control_that_faults() {
        let steady = incidence(5, 5);
        let ctl = || vec![pass(), attempt(Outcome::Crash)];
        let g = judge(passes(6), ctl(), Some(&steady));
        assert_eq!(g.judgement, GpuAvJudgement::Masks, "{}", g.line);
        let m = crate::model::stats::pass_miss(5, 5, 6);
        // The same function as `run`'s round (f64 rounding aside: its bound is an iteration).
        assert!(g.miss_probability.is_some_and(|p| (p - m).abs() < 1e-12), "{g:?}");
        assert!(m < MAX_MISS);
        assert!(g.line.starts_with("GPU-AV masks the fault: passes (6 of 6; a fault as frequent as this finding's would be missed with p ≤"), "{}", g.line);
        assert!(g.line.ends_with("its control, the variant without GPU-AV in the same round, faulted 1 of 2 attempts"), "{}", g.line);
        let five = judge(passes(5), ctl(), Some(&steady));
        assert_eq!(five.judgement, GpuAvJudgement::Inconclusive);
        assert!(
            five.line
                .starts_with("inconclusive: not proven (5 passes; need 6 for 99%) under GPU-AV"),
            "{}",
            five.line
        );
        // A fault seen once (bound 5%): 20 passes miss it with p ≈ 0.36.
        let once = judge(passes(20), ctl(), Some(&incidence(1, 1)));
        assert_eq!(once.judgement, GpuAvJudgement::Inconclusive);
        assert!(once.miss_probability.is_some_and(|m| (m - 0.358).abs() < 0.001));
    }

    /// Twin of `masks`: the same passes beside a control that did not fault again are no proof.
    #[test]
    fn a_control_that_does_not_fault_is_not_masks() {
        let g = judge(passes(6), vec![pass(), pass()], Some(&incidence(5, 5)));
        assert_eq!(g.judgement, GpuAvJudgement::Inconclusive);
        assert!(g.line.contains("the fault did not repeat (its control, the variant without GPU-AV in the same round, faulted 0 of 2 attempts)"), "{}", g.line);
        let none = judge(passes(6), vec![], Some(&incidence(5, 5)));
        assert_eq!(none.judgement, GpuAvJudgement::Inconclusive);
        assert!(none.line.contains("(no control ran)"), "{}", none.line);
        // A control that ran but could not trace is no fault either.
        let broken = judge(passes(6), vec![attempt(Outcome::Error)], Some(&incidence(5, 5)));
        assert_eq!(broken.judgement, GpuAvJudgement::Inconclusive);
    }

    #[test]
    fn attempts_that_did_not_run_are_an_error() {
        let failed = ShaderAttempt {
            attempt: Attempt::new(Outcome::Error, true).with_detail("setup: no device"),
            ..pass()
        };
        let g = judge(vec![failed], vec![], None);
        assert_eq!(
            (g.judgement, g.line.as_str()),
            (GpuAvJudgement::Error, "GPU-AV re-run did not run: setup: no device")
        );
        assert_eq!(judge(vec![], vec![], None).judgement, GpuAvJudgement::Error);
        // A half run (one pass, one error) proves nothing either.
        assert_eq!(
            judge(vec![pass(), attempt(Outcome::Error)], vec![], None).judgement,
            GpuAvJudgement::Error
        );
    }

    #[test]
    fn only_reports_change_the_variant() {
        for j in [
            GpuAvJudgement::Masks,
            GpuAvJudgement::Inconclusive,
            GpuAvJudgement::StillFaults,
            GpuAvJudgement::Error,
        ] {
            let g = ShaderGpuAv { judgement: j, ..judge(vec![], vec![], None) };
            let v = apply(fault_variant(), g);
            assert_eq!((v.outcome, v.judgement), (Outcome::Crash, Judgement::Fault));
            assert!(v.incidence.is_some());
        }
    }
}
