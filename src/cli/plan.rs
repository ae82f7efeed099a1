//! `run`'s plan from its checked arguments: the matrix filtered (`--filter`, `--skips`), the
//! device's support, the shard; `--list`; and the one-line error when it holds nothing to run — a
//! filter that matches no cell (with why: `matrix::empty`) is a usage error, a plan the device can
//! run none of is exit 5. An empty plan never passes.
use super::exit::{self, coded};
use super::out::outln;
use crate::fleet::deqp_files::Patterns;
use crate::fleet::shard::Shard;
use crate::matrix::plan::{self, PlanOptions};
use crate::model::{plural, Filter, Injection, PatchMode, PlanStatus, RunPlan};
use crate::vk::DeviceInfo;
use std::collections::HashSet;

/// What the plan is made from.
pub struct PlanArgs<'a> {
    pub filters: &'a [Filter],
    pub skips: &'a Patterns,
    pub canaries: bool,
    pub patches: PatchMode,
    pub inject: &'a [Injection],
    pub shard: Option<Shard>,
}

/// A plan made, and what it left out after the matrix's filters.
pub struct Made {
    pub plan: RunPlan,
    /// How many of its cells went to other shards.
    pub sharded_out: usize,
    /// The ids `--skips` left out or other shards run: baseline entries for them are not this
    /// run's to miss (`fleet::baseline::Scope`).
    pub elsewhere: HashSet<String>,
}

/// The plan, and what went to other shards or `--skips`.
pub fn make(info: &DeviceInfo, p: &PlanArgs) -> Made {
    let mut the_plan = plan::plan(
        info,
        &PlanOptions {
            filters: p.filters.to_vec(),
            canaries: p.canaries,
            patches: p.patches,
            inject: p.inject.to_vec(),
        },
    );
    let ids =
        |plan: &RunPlan| -> HashSet<String> { plan.cells.iter().map(|c| c.cell.id()).collect() };
    let before = ids(&the_plan);
    the_plan.cells.retain(|c| c.cell.canary.is_some() || !p.skips.matches(&c.cell.id()));
    the_plan.filtered_out += before.len() - the_plan.cells.len();
    let sharded_out = p.shard.map(|s| s.apply(&mut the_plan)).unwrap_or(0);
    let kept = ids(&the_plan);
    let elsewhere = before.into_iter().filter(|id| !kept.contains(id)).collect();
    Made { plan: the_plan, sharded_out, elsewhere }
}

/// Why the plan holds no probe cell at all (a usage error, exit 2), or `None`.
pub fn nothing_planned(
    the_plan: &RunPlan,
    p: &PlanArgs,
    sharded_out: usize,
) -> Option<anyhow::Error> {
    if sharded_out > 0 || the_plan.cells.iter().any(|c| c.cell.canary.is_none()) {
        return None;
    }
    let why = crate::matrix::empty::why_empty(p.filters, p.patches).unwrap_or_else(|| {
        if p.skips.lines.is_empty() {
            "no cell of the matrix matches".into()
        } else {
            "--skips leaves out every cell the filters select".into()
        }
    });
    Some(coded(exit::USAGE, format!("nothing to run: {why}")))
}

/// Why none of the planned cells can run on the device (exit 5), or `None`. A shard that got no
/// cell of a small plan runs nothing and passes.
pub fn nothing_runs(
    the_plan: &RunPlan,
    info: &DeviceInfo,
    sharded_out: usize,
) -> Option<anyhow::Error> {
    if the_plan.to_run().next().is_some() || (sharded_out > 0 && the_plan.cells.is_empty()) {
        return None;
    }
    let mut reasons: Vec<&str> = the_plan
        .cells
        .iter()
        .filter_map(|c| match &c.status {
            PlanStatus::Run => None,
            PlanStatus::Unsupported { reason } | PlanStatus::NotImplemented { reason } => {
                Some(reason.as_str())
            }
        })
        .collect();
    reasons.sort();
    reasons.dedup();
    Some(coded(
        exit::UNSUPPORTED_DEVICE,
        format!(
            "nothing to run: {} cannot run any of the {} planned ({}); `rtprobe run --list` gives each cell's reason",
            info.name(),
            plural(the_plan.cells.len(), "cell"),
            reasons.iter().take(3).copied().collect::<Vec<_>>().join("; ")
        ),
    ))
}

/// `--list`: the plan, cell by cell, and its counts.
pub fn print_list(the_plan: &RunPlan, shard: Option<Shard>, sharded_out: usize) {
    for pc in &the_plan.cells {
        match &pc.status {
            PlanStatus::Run => outln!("run          {}", pc.cell.id()),
            PlanStatus::Unsupported { reason } => {
                outln!("unsupported  {}  ({reason})", pc.cell.id())
            }
            PlanStatus::NotImplemented { reason } => {
                outln!("not_implemented  {}  ({reason})", pc.cell.id())
            }
        }
    }
    let to_run = the_plan.to_run().count();
    outln!(
        "{} planned: {} to run, {} unsupported, {} not implemented in rtprobe; {} filtered out",
        the_plan.cells.len(),
        to_run,
        the_plan.unsupported_count(),
        the_plan.not_implemented_count(),
        the_plan.filtered_out
    );
    if let Some(s) = shard {
        outln!("shard {}: {} left to the other shards", s.label(), plural(sharded_out, "cell"));
    }
    for ng in &the_plan.not_generated {
        outln!("not generated: {} ({} combinations)", ng.rule, ng.count);
    }
    if the_plan.to_run().any(|c| c.heap_access == Some(crate::model::HeapAccess::Direct)) {
        if let Some(g) = crate::shadergen::glslang::find() {
            outln!(
                "compiler: heap_access=direct shaders by {}; all others by {}",
                g.describe(),
                crate::shadergen::compile::SHADERC
            );
        }
    }
}
