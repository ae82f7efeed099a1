//! `rtprobe reduce`'s outputs in DIR, each written atomically: `reduced.spv`, `reduced.spvasm`
//! (spirv-dis), `access.txt` (the remaining descriptor accesses GLSL-like, `shape::render`) and
//! `reduce.json` (`rtprobe.reduce/1`), and the summary lines: instruction counts, steps,
//! interestingness runs, wall time, the classification and its `--filter` predicate, and the
//! miss probability of the final step.
use super::args::ReduceArgs;
use super::exit::{self, coded};
use super::out::outln;
use super::reduce_job::{InterestingJob, RunLine};
use crate::model::reduce::{predicate, Counts, ReduceReport, SCHEMA};
use crate::model::shader_run::ShaderRunReport;
use crate::tools::spirv::{self as spirv_tools, SpirvTool};
use anyhow::Result;
use std::path::Path;

/// What a finished reduction hands the writer.
pub struct Done<'a> {
    pub report: &'a ShaderRunReport,
    pub a: &'a ReduceArgs,
    pub file: &'a str,
    pub why: &'a str,
    pub job: &'a InterestingJob,
    pub device: &'a str,
    pub miss: f64,
    pub wall_s: f64,
    pub runs: &'a [RunLine],
}

fn put(dir: &Path, name: &str, bytes: &[u8]) -> Result<()> {
    let p = dir.join(name);
    crate::atomic::write_atomic(&p, bytes)
        .map_err(|e| coded(exit::BAD_INPUT, format!("writing {}: {e}", p.display())))
}

fn module(words: &[u32], what: &str) -> Result<rspirv::dr::Module> {
    crate::patches::load(&spirv_tools::bytes(words))
        .map_err(|e| coded(exit::INTERNAL, format!("the {what} module does not load: {e}")))
}

/// The report's data for `done`, from the original and reduced words (no workaround or slice
/// yet: `reduce` adds them).
pub fn report(d: &Done, original: &[u32], reduced: &[u32]) -> Result<ReduceReport> {
    let (before, after) = (module(original, "original")?, module(reduced, "reduced")?);
    let found = crate::shape::classify(&after);
    let classification: Vec<_> = found.into_iter().map(|f| f.class).collect();
    let interesting = d.runs.iter().filter(|r| r.interesting).count() as u32;
    let input = &d.report.inputs[d.job.target];
    Ok(ReduceReport {
        schema: SCHEMA.into(),
        rtprobe_version: env!("CARGO_PKG_VERSION").into(),
        report: d.a.report.display().to_string(),
        cell: d.report.cell.clone(),
        device: d.device.into(),
        module: d.file.into(),
        original_hash: input.hash.clone(),
        chosen_because: d.why.into(),
        outcomes: d.job.outcomes.clone(),
        injection: d.job.injection.clone(),
        attempts_per_candidate: d.job.attempts,
        final_miss_probability: d.miss,
        // The first run is spirv-reduce's check of the original.
        steps: interesting.saturating_sub(1),
        interestingness_runs: d.runs.len() as u32,
        refused_statically: d.runs.iter().filter(|r| r.refused_statically).count() as u32,
        wall_s: d.wall_s,
        instructions: Counts {
            before: crate::shape::count::function_body(&before),
            after: crate::shape::count::function_body(&after),
        },
        reducer: spirv_tools::tool(SpirvTool::Reduce).map(|t| t.describe()).unwrap_or_default(),
        predicate: predicate(&classification),
        classification,
        workarounds: vec![],
        not_applicable: vec![],
        slice: None,
    })
}

/// Write DIR's files and print the summary; the exit code.
pub fn write(d: &Done, r: &ReduceReport, reduced: &[u32]) -> Result<u8> {
    let dir = &d.a.out;
    let dis = spirv_tools::disassemble(reduced, false)
        .unwrap_or_else(|e| format!("; spirv-dis failed: {e}\n"));
    let after = module(reduced, "reduced")?;
    let access = crate::shape::render::render(&after, &crate::shape::classify(&after));
    put(dir, "reduced.spv", &spirv_tools::bytes(reduced))?;
    put(dir, "reduced.spvasm", dis.as_bytes())?;
    put(dir, "access.txt", access.as_bytes())?;
    put(dir, "reduce.json", &serde_json::to_vec_pretty(r)?)?;
    outln!("reduced: {}", r.reduction_text());
    for a in &r.classification {
        outln!("  access: {}", a.sentence());
    }
    outln!(
        "  final step: {} attempt{} per candidate; a fault as frequent as the finding's is missed with p = {:.3}",
        r.attempts_per_candidate,
        if r.attempts_per_candidate == 1 { "" } else { "s" },
        r.final_miss_probability
    );
    if r.predicate.is_empty() {
        outln!("predicate: none (no descriptor access remains)");
    } else {
        outln!("predicate: --filter {}", r.predicate);
    }
    for w in &r.workarounds {
        outln!("workaround {}", w.line);
        if w.verified {
            outln!(
                "  wrote {} with {}: {}",
                w.files.join(", "),
                w.contract_file.as_deref().unwrap_or(""),
                w.host_contract
            );
        }
    }
    for l in &r.not_applicable {
        outln!("workaround {l}");
    }
    if let Some(s) = &r.slice {
        outln!("slice: {}", s.line);
        if !s.command.is_empty() {
            outln!("  ran: {} (report: {})", s.command, dir.join(&s.report).display());
        }
    }
    outln!("wrote: {}", dir.join("reduce.json").display());
    Ok(exit::OK)
}
