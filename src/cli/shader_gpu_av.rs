//! `run --shader --validate=gpu-av`: each variant that faulted traced again, as many attempts,
//! in children whose instance has GPU-Assisted Validation on (`harness::run`'s job with
//! `gpu_av`), their outputs in a folder of their own; the attempts and what they say are the
//! variant's `gpu_av` (`model::shader_gpu_av`), which can turn the variant into an `error`.
use super::exit::{self, coded};
use super::shader_exec::{run_variant, Ctx};
use super::shader_plan::ShaderPlan;
use crate::model::shader_gpu_av;
use crate::model::shader_run::{Judgement, ShaderVariant};
use anyhow::Result;

/// The variants with every faulting one re-run under GPU-AV (`variants[0]` the unpatched one,
/// then `plan.variants` in order).
pub fn rerun(
    ctx: &Ctx,
    plan: &ShaderPlan,
    variants: Vec<ShaderVariant>,
) -> Result<Vec<ShaderVariant>> {
    let mut gpu = ctx.clone();
    gpu.gpu_av = true;
    gpu.dir = ctx.dir.join("gpu-av");
    std::fs::create_dir_all(&gpu.dir)
        .map_err(|e| coded(exit::BAD_INPUT, format!("creating {}: {e}", gpu.dir.display())))?;
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
        let ran = match k.checked_sub(1).map(|p| &plan.variants[p]) {
            None => run_variant(&gpu, &v.name, &ctx.unpatched, None)?,
            Some(p) => run_variant(&gpu, &v.name, &p.modules, Some(&p.contract))?,
        };
        let attempts = ran.ran.into_iter().map(|r| r.attempt).collect();
        out.push(shader_gpu_av::apply(v, shader_gpu_av::judge(attempts)));
    }
    Ok(out)
}
