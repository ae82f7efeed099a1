//! `rtprobe reduce REPORT [--cell ID] -o DIR`: a `run --shader` finding's pipeline re-created
//! from the report's inputs (each must still hash as recorded), the module to reduce picked
//! (the one the finding's injection matched, else the first hit stage, else the first given),
//! and `spirv-reduce` driven with `rtprobe __interesting` as its test ([`super::reduce_job`]);
//! then the reduced module classified (`shape`) and written with its disassembly, its
//! accesses GLSL-like and `reduce.json` ([`super::reduce_out`]), after each applicable patch
//! was verified on the original modules ([`super::reduce_patch`]) and the matrix's slice of the
//! predicate ran ([`super::reduce_slice`]).
use super::args::{Cli, Command, ReduceArgs, RunArgs};
use super::commands::Globals;
use super::exit::{self, coded};
use super::out::outln;
use super::reduce_job::{is_fault, InterestingJob, RunLine};
use super::shader_exec::Ctx;
use super::shader_plan::ShaderPlan;
use crate::harness::inject::Request;
use crate::model::reduce::ReduceReport;
use crate::model::shader_run::{ShaderRunReport, ShaderVariant, SCHEMA};
use crate::model::{stats, Outcome};
use crate::runner::self_exe;
use crate::tools::spirv::{self as spirv_tools, SpirvTool};
use anyhow::Result;
use clap::Parser;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Set: DIR/.reduce-work (the job, spirv-reduce's files, the runs' log) is kept.
pub const KEEP_ENV: &str = "RTPROBE_REDUCE_KEEP";
/// The most a fault seen less than always is re-run per candidate.
const MAX_ATTEMPTS: u32 = 20;
/// The miss probability a candidate's attempts are held to.
const MAX_MISS: f64 = 0.05;

/// The report, checked: its schema and `--cell`.
fn load(a: &ReduceArgs) -> Result<ShaderRunReport> {
    let bad = |e: String| coded(exit::BAD_INPUT, format!("{}: {e}", a.report.display()));
    let r: ShaderRunReport = crate::model::load::read_json(&a.report, "a run --shader report")
        .map_err(|e| bad(e.to_string()))?;
    crate::model::load::check_schema(&a.report, &r.schema, SCHEMA)
        .map_err(|e| bad(e.to_string()))?;
    if let Some(c) = a.cell.as_ref().filter(|c| **c != r.cell) {
        return Err(bad(format!("has no cell {c}; its one cell is {}", r.cell)));
    }
    Ok(r)
}

/// The variant with the finding: the unpatched one when it faulted, else the first that did.
fn finding(r: &ShaderRunReport) -> Result<&ShaderVariant> {
    let faulted = |v: &&ShaderVariant| is_fault(v.outcome);
    r.variants.iter().find(|v| v.patch.is_none()).filter(faulted).or_else(|| {
        r.variants.iter().find(faulted)
    }).ok_or_else(|| {
        coded(
            exit::USAGE,
            format!("{}: no variant faulted (outcome {}); reduce shrinks a fault (device_lost, crash, timeout)", r.cell, r.outcome.as_str()),
        )
    })
}

/// `run --shader`'s arguments as the report recorded them, without `--inject-fault`.
fn run_args(r: &ShaderRunReport, device: Option<&str>) -> Result<RunArgs> {
    let o = &r.options;
    let mut argv: Vec<String> = vec!["rtprobe".into(), "run".into()];
    for i in &r.inputs {
        argv.extend(["--shader".into(), i.file.clone()]);
    }
    let mut flag = |name: &str, v: &serde_json::Value| match v {
        serde_json::Value::Null => {}
        serde_json::Value::String(s) => argv.extend([name.to_string(), s.clone()]),
        serde_json::Value::Array(list) => {
            for x in list {
                argv.extend([name.to_string(), x.as_str().map_or(x.to_string(), String::from)]);
            }
        }
        other => argv.extend([name.to_string(), other.to_string()]),
    };
    flag("--entry", &o["entry"]);
    flag("-I", &o["include_dirs"]);
    flag("-D", &o["defines"]);
    flag("--spec", &o["spec"]);
    flag("--heap-layout", &o["heap_layout"]);
    flag("--array-size", &o["array_size"]);
    flag("--sink-size", &o["sink_size"]);
    flag("--timeout", &o["timeout_s"]);
    flag("--descriptor-model", &o["descriptor_model"]);
    flag("--scene", &o["scene"]);
    flag("--hit-group", &o["hit_groups"]);
    for f in fill_args(r)? {
        argv.extend(["--fill".into(), f]);
    }
    if let Some(p) = &r.profile {
        argv.extend(["--profile".into(), p.file.clone()]);
    }
    let env = match o["target_env"].as_str() {
        Some("Vulkan1_3") => "vulkan1.3",
        Some("Vulkan1_4") => "vulkan1.4",
        _ => "vulkan1.2",
    };
    argv.extend(["--target-env".into(), env.into()]);
    if let Some(d) = device {
        argv.extend(["--device".into(), d.into()]);
    }
    let cli = Cli::try_parse_from(&argv).map_err(|e| {
        coded(
            exit::BAD_INPUT,
            format!(
                "the report's options do not make a run: {}",
                e.to_string().lines().next().unwrap_or("")
            ),
        )
    })?;
    match cli.command {
        Command::Run(a) => Ok(a),
        _ => Err(coded(exit::INTERNAL, "the report's options parsed as another command")),
    }
}

/// `--fill` as the run had it: the arguments it recorded, else its cell options' words when
/// none names a file (reports before `fill_args` recorded a file only by its hash).
fn fill_args(r: &ShaderRunReport) -> Result<Vec<String>> {
    if let Some(list) = r.options["fill_args"].as_array() {
        return Ok(list.iter().filter_map(|v| v.as_str().map(String::from)).collect());
    }
    let words = &r.cell_options.fill;
    if let Some(f) = words.iter().find(|w| w.contains("=file:")) {
        return Err(coded(exit::BAD_INPUT, format!("the report's --fill {f} names its file only by its hash: run run --shader again with this rtprobe, then reduce its report")));
    }
    Ok(words.clone())
}

/// `--fill`'s bytes and `--profile`'s file as the run had them, else one line.
fn same_harness(r: &ShaderRunReport, p: &super::shader::Prepared) -> Result<()> {
    if p.cell_options.fill != r.cell_options.fill {
        return Err(coded(exit::BAD_INPUT, format!("--fill's sources changed since the run ({:?}, the report's {:?}): reduce needs the harness the run had", p.cell_options.fill, r.cell_options.fill)));
    }
    let (now, then) = (p.profile.as_ref().map(|x| &x.hash), r.profile.as_ref().map(|x| &x.hash));
    if now != then {
        return Err(coded(
            exit::BAD_INPUT,
            format!(
                "--profile {} changed since the run: reduce needs the harness the run had",
                r.profile.as_ref().map_or("", |x| x.file.as_str())
            ),
        ));
    }
    Ok(())
}

/// The module to reduce and why: the one the injection matched, else the first hit stage.
fn target(r: &ShaderRunReport) -> (usize, String) {
    let injected = r.injection.as_ref().and_then(|inj| {
        let m = inj.modules.iter().find(|m| m.matched > 0)?;
        r.inputs.iter().position(|i| i.file == m.file)
    });
    if let Some(k) = injected {
        return (k, "the finding's injection matched it".into());
    }
    let hit = ["closest_hit", "any_hit", "intersection"];
    match r.inputs.iter().position(|i| hit.contains(&i.stage.as_str())) {
        Some(k) => (k, format!("the first hit stage ({})", r.inputs[k].stage)),
        None => (0, "the first module given (no hit stage)".into()),
    }
}

/// Refuse a non-empty DIR without `--force`; make it and its scratch folder.
fn out_dir(a: &ReduceArgs) -> Result<PathBuf> {
    let d = &a.out;
    if d.exists() && !d.is_dir() {
        return Err(coded(exit::USAGE, format!("-o {}: is a file; give a folder", d.display())));
    }
    let busy = d.read_dir().map(|mut r| r.next().is_some()).unwrap_or(false);
    if busy && !a.force {
        return Err(coded(
            exit::USAGE,
            format!("-o {}: is not empty; give an empty folder or --force", d.display()),
        ));
    }
    // Absolute: spirv-reduce runs in it, and is given the paths of files in it.
    let work = std::path::absolute(d.join(".reduce-work"))
        .map_err(|e| coded(exit::BAD_INPUT, format!("-o {}: {e}", d.display())))?;
    let _ = std::fs::remove_dir_all(&work);
    std::fs::create_dir_all(&work)
        .map_err(|e| coded(exit::BAD_INPUT, format!("-o {}: {e}", d.display())))?;
    Ok(work)
}

/// Attempts per candidate from the finding's incidence, and their miss probability.
fn attempts(v: &ShaderVariant) -> (u32, f64) {
    let p = v.incidence.as_ref().map_or(1.0, |i| i.faulted as f64 / i.attempts.max(1) as f64);
    let n = stats::attempts_needed(p, MAX_MISS, MAX_ATTEMPTS);
    (n, stats::miss(p, n))
}

pub fn reduce(g: &Globals, a: &ReduceArgs) -> Result<u8> {
    let report = load(a)?;
    let variant = finding(&report)?;
    let mut outcomes: Vec<Outcome> =
        variant.attempts.iter().map(|x| x.attempt.outcome).filter(|o| is_fault(*o)).collect();
    outcomes.sort_by_key(|o| o.as_str());
    outcomes.dedup();
    let args = run_args(&report, a.device.as_deref())?;
    let validate = report.options["validate"].as_bool().unwrap_or(false);
    let g = Globals { validate: validate || g.validate, gpu_av: false };
    let p = super::shader::prepare(&g, &args)?;
    same_harness(&report, &p)?;
    let (plan, ctx, device) = (p.plan, p.ctx, p.device_name);
    same_inputs(&plan, &report)?;
    bounded_recursion(&plan)?;
    let (k, why) = target(&report);
    let work = out_dir(a)?;
    let original = ctx.unpatched[k].words.clone();
    let (_, val) = spirv_tools::validate_input(&original);
    let (n, miss) = attempts(variant);
    let job = InterestingJob {
        device_index: ctx.device_index,
        validate: ctx.validate,
        scalar: ctx.scalar,
        timeout_ms: ctx.timeout.as_millis() as u64,
        setup_timeout_ms: ctx.setup_timeout.as_millis() as u64,
        model: ctx.model,
        spec: ctx.spec.clone(),
        heap_layout: ctx.heap_layout.clone(),
        sizes: ctx.sizes,
        fills: ctx.fills.clone(),
        profile: ctx.profile,
        scene: ctx.scene.clone(),
        scene_fills: ctx.scene_fills.clone(),
        modules: ctx.unpatched.clone(),
        target: k,
        val_env: spirv_tools::tool(SpirvTool::Val).map(|_| val.env.clone()),
        val_scalar: val.scalar_block_layout,
        val_ubo_standard: val.uniform_buffer_standard_layout,
        injection: report.injection.as_ref().map(|i| i.spec.clone()),
        outcomes: outcomes.clone(),
        attempts: n,
        runtime_len: ctx.sizes.array.unwrap_or(crate::harness::reflect::RUNTIME_ELEMENTS),
        dir: work.clone(),
        log: work.join("runs.jsonl"),
    };
    let file = &report.inputs[k].file;
    outln!(
        "reduce: {} ({why}) of {} on {device}: {} attempt{} per candidate",
        file,
        report.cell,
        n,
        if n == 1 { "" } else { "s" }
    );
    let started = Instant::now();
    let reduced = run_reducer(&job, &work, &original, &val, a.step_limit)?;
    let reduced = strip_dead(&work, reduced)?;
    let wall_s = started.elapsed().as_secs_f64();
    let runs = read_log(&job.log);
    let done = super::reduce_out::Done {
        report: &report,
        a,
        file,
        why: &why,
        job: &job,
        device: &device,
        miss,
        wall_s,
        runs: &runs,
    };
    let mut r = super::reduce_out::report(&done, &original, &reduced)?;
    generalize(&mut r, (&ctx, &plan), (n, variant.incidence.as_ref()), &work, a)?;
    let code = super::reduce_out::write(&done, &r, &reduced)?;
    if std::env::var_os(KEEP_ENV).is_none() {
        let _ = std::fs::remove_dir_all(&work);
    }
    Ok(code)
}

/// A pipeline whose recursion depth is its shaders' own guard's is refused: spirv-reduce may drop
/// the guard, and a candidate recursing past the device's limit faults by the shader's undefined
/// behaviour (VUID-vkCmdTraceRaysKHR-maxPipelineRayRecursionDepth-03679), not the driver's.
fn bounded_recursion(plan: &ShaderPlan) -> Result<()> {
    let refs: Vec<&crate::harness::UserModule> = plan.modules.iter().collect();
    match crate::harness::traces::unbounded_recursion(&refs) {
        Some(cycle) => Err(coded(exit::BAD_INPUT, format!("{cycle}. reduce refuses it: spirv-reduce may drop that guard, and a candidate recursing past the limit faults by the shader's undefined behaviour, not the driver's; reduce a copy whose hit shaders do not trace again"))),
        None => Ok(()),
    }
}

/// Each input still hashes as the report recorded it.
fn same_inputs(plan: &ShaderPlan, report: &ShaderRunReport) -> Result<()> {
    for (now, then) in plan.inputs.iter().zip(&report.inputs) {
        if now.hash != then.hash {
            return Err(coded(exit::BAD_INPUT, format!("{} changed since the run (hash {}, the report's {}): reduce needs the inputs the run had", now.file, &now.hash[..12], &then.hash[..12.min(then.hash.len())])));
        }
    }
    Ok(())
}

/// Steps 6 and 5 after the reduction: each applicable patch verified on the original modules
/// (`n` attempts, the finding's request applied again when injected), then the predicate's
/// matrix slice.
fn generalize(
    r: &mut ReduceReport,
    (ctx, plan): (&Ctx, &ShaderPlan),
    (n, incidence): (u32, Option<&crate::model::Incidence>),
    work: &Path,
    a: &ReduceArgs,
) -> Result<()> {
    let request = r.injection.as_deref().and_then(|s| Request::parse(s).ok());
    r.workarounds =
        super::reduce_patch::verify(ctx, plan, (request.as_ref(), n, incidence), work, &a.out)?;
    r.not_applicable = plan
        .notes
        .iter()
        .filter(|l| l.contains(" does not apply") || l.contains(" not run"))
        .cloned()
        .collect();
    let slice = super::reduce_slice::SliceArgs {
        predicate: &r.predicate,
        injection: r.injection.as_deref(),
        attempts: n,
        cap: a.slice_cells,
        device: a.device.as_deref(),
    };
    r.slice = super::reduce_slice::run(&slice, &a.out)?;
    Ok(())
}

/// spirv-reduce on `original`, its temporary files in `work`: the reduced module's words.
fn run_reducer(
    job: &InterestingJob,
    work: &Path,
    original: &[u32],
    val: &spirv_tools::ValOptions,
    step_limit: u32,
) -> Result<Vec<u32>> {
    let tool = spirv_tools::tool(SpirvTool::Reduce).ok_or_else(|| {
        coded(exit::BAD_INPUT, "spirv-reduce is not installed: scripts/setup-sid makes a root with SPIRV-Tools 2026 (or apt-get install spirv-tools)")
    })?;
    let job_path = work.join("job.json");
    let bytes = serde_json::to_vec(job)?;
    crate::atomic::write_atomic(&job_path, &bytes)
        .map_err(|e| coded(exit::BAD_INPUT, format!("writing {}: {e}", job_path.display())))?;
    let (input, output) = (work.join("original.spv"), work.join("reduced.spv"));
    crate::atomic::write_atomic(&input, &spirv_tools::bytes(original))
        .map_err(|e| coded(exit::BAD_INPUT, format!("writing {}: {e}", input.display())))?;
    // This very file, even when a build replaces its path while spirv-reduce runs.
    let exe = self_exe::shared_path();
    let mut c = tool.command();
    if val.scalar_block_layout {
        c.arg("--scalar-block-layout");
    }
    c.arg(format!("--step-limit={step_limit}"))
        .arg(format!("--temp-file-prefix={}", work.join("temp_").display()))
        .arg(&input)
        .arg("-o")
        .arg(&output)
        .arg("--")
        .arg(&exe)
        .arg("__interesting")
        .arg(&job_path)
        .current_dir(work);
    let out = c
        .output()
        .map_err(|e| coded(exit::BAD_INPUT, format!("starting {}: {e}", tool.describe())))?;
    let words = std::fs::read(&output).ok().filter(|_| out.status.success());
    let Some(bytes) = words else {
        let runs = read_log(&job.log);
        let first = runs.first().map(|r| r.why.clone()).unwrap_or_default();
        let said = String::from_utf8_lossy(&out.stderr)
            .lines()
            .chain(String::from_utf8_lossy(&out.stdout).lines())
            .last()
            .unwrap_or("")
            .to_string();
        return Err(coded(
            exit::BAD_INPUT,
            format!(
                "spirv-reduce stopped ({said}); the original was {}: {first}",
                if runs.first().is_some_and(|r| r.interesting) {
                    "interesting"
                } else {
                    "not interesting (the fault did not reproduce)"
                }
            ),
        ));
    };
    Ok(bytes.chunks_exact(4).map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect())
}

/// The reduced module without the dead decorated instructions spirv-reduce cannot remove
/// (`shape::dead`), when the interestingness test still says yes; else as it was.
fn strip_dead(work: &Path, reduced: Vec<u32>) -> Result<Vec<u32>> {
    let Ok(mut m) = crate::patches::load(&spirv_tools::bytes(&reduced)) else {
        return Ok(reduced);
    };
    if crate::shape::dead::strip(&mut m) == 0 {
        return Ok(reduced);
    }
    let words = crate::patches::assemble(&m);
    let path = work.join("stripped.spv");
    crate::atomic::write_atomic(&path, &spirv_tools::bytes(&words))
        .map_err(|e| coded(exit::BAD_INPUT, format!("writing {}: {e}", path.display())))?;
    let status = std::process::Command::new(self_exe::spawn_path())
        .arg("__interesting")
        .arg(work.join("job.json"))
        .arg(&path)
        .status()
        .map_err(|e| {
            coded(exit::BAD_INPUT, self_exe::start_error("the dead-code strip's check", &e))
        })?;
    Ok(if status.success() { words } else { reduced })
}

/// The interestingness runs the log holds.
pub fn read_log(path: &Path) -> Vec<RunLine> {
    std::fs::read_to_string(path)
        .unwrap_or_default()
        .lines()
        .filter_map(|l| serde_json::from_str(l).ok())
        .collect()
}
