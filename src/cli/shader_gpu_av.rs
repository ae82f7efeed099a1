//! `run --shader --validate=gpu-av`: each variant that faulted traced again in children whose
//! instance has GPU-Assisted Validation on (`harness::run`'s job with `gpu_av`), their outputs
//! in a folder of their own: `--repeat` attempts, then, while every one passed with no
//! invalid-access report, more up to the passes its incidence needs
//! (`report::gpu_av::passes_needed_for`, the rule of `run`'s GPU-AV round); when all passed, a
//! control — the variant again without GPU-AV, `--repeat` attempts — in the same round. What
//! they say is the variant's `gpu_av` (`model::shader_gpu_av`), which can turn the variant into
//! an `error`.
use super::exit::{self, coded};
use super::shader_exec::{run_variant, Ctx};
use super::shader_plan::ShaderPlan;
use crate::harness::child::JobModule;
use crate::model::contract::HostContract;
use crate::model::shader_gpu_av;
use crate::model::shader_run::{Judgement, ShaderAttempt, ShaderVariant};
use crate::model::Outcome;
use anyhow::Result;
use std::path::PathBuf;

/// `ctx` with its children's files in `dir`, made here, and `repeat` attempts.
fn in_dir(ctx: &Ctx, dir: PathBuf, repeat: u32, gpu_av: bool) -> Result<Ctx> {
    std::fs::create_dir_all(&dir)
        .map_err(|e| coded(exit::BAD_INPUT, format!("creating {}: {e}", dir.display())))?;
    Ok(Ctx { dir, repeat, gpu_av, ..ctx.clone() })
}

/// Attempts that leave `masks` open: every one passed, none reported an invalid access.
fn all_pass(attempts: &[ShaderAttempt]) -> bool {
    !attempts.is_empty()
        && attempts.iter().all(|a| a.attempt.outcome == Outcome::Pass && a.invalid_access == 0)
}

/// One variant's pipeline: its modules and, patched, its host contract.
struct Pipeline<'a> {
    modules: &'a [JobModule],
    contract: Option<&'a HostContract>,
}

impl Pipeline<'_> {
    fn attempts(&self, ctx: &Ctx, name: &str) -> Result<Vec<ShaderAttempt>> {
        let ran = run_variant(ctx, name, self.modules, self.contract)?;
        Ok(ran.ran.into_iter().map(|r| r.attempt).collect())
    }
}

/// The faulting variant `v` under GPU-AV, with more attempts and the control as the module doc
/// says, judged.
fn judge_one(ctx: &Ctx, v: ShaderVariant, p: &Pipeline) -> Result<ShaderVariant> {
    let gpu = in_dir(ctx, ctx.dir.join("gpu-av"), ctx.repeat, true)?;
    let mut attempts = p.attempts(&gpu, &v.name)?;
    let needed = crate::report::gpu_av::passes_needed_for(v.incidence.as_ref());
    let got = attempts.len() as u32;
    if all_pass(&attempts) && got < needed {
        tracing::info!("{}: {got} passes under GPU-AV, {needed} needed", v.name);
        let more = in_dir(ctx, ctx.dir.join("gpu-av-more"), needed - got, true)?;
        attempts.extend(p.attempts(&more, &v.name)?);
    }
    let control = if all_pass(&attempts) {
        let plain = in_dir(ctx, ctx.dir.join("gpu-av-control"), ctx.repeat, false)?;
        p.attempts(&plain, &v.name)?
    } else {
        vec![]
    };
    let g = shader_gpu_av::judge(attempts, control, v.incidence.as_ref());
    Ok(shader_gpu_av::apply(v, g))
}

/// The variants with every faulting one re-run under GPU-AV (`variants[0]` the unpatched one,
/// then `plan.variants` in order).
pub fn rerun(
    ctx: &Ctx,
    plan: &ShaderPlan,
    variants: Vec<ShaderVariant>,
) -> Result<Vec<ShaderVariant>> {
    let mut out = Vec::with_capacity(variants.len());
    for (k, v) in variants.into_iter().enumerate() {
        let faulted = match v.judgement {
            Judgement::Fault => true,
            Judgement::Pass
            | Judgement::Unstable
            | Judgement::PatchDiffers
            | Judgement::CompareDiffers
            | Judgement::Validation
            | Judgement::Error => false,
        };
        if !faulted {
            out.push(v);
            continue;
        }
        let p = match k.checked_sub(1).map(|p| &plan.variants[p]) {
            None => Pipeline { modules: &ctx.unpatched, contract: None },
            Some(p) => Pipeline { modules: &p.modules, contract: Some(&p.contract) },
        };
        out.push(judge_one(ctx, v, &p)?);
    }
    Ok(out)
}
