//! The `stress` command: parse the cases, check the device has what the stress pipeline needs
//! and the shaders compile, run each case in a worker process of its own (`stress::supervised`:
//! a crash, hang or device loss is that case's outcome, and the next case runs), print the
//! tables, write the JSON and SVG atomically.
use super::args::StressArgs;
use super::commands::{open_instance, Globals};
use super::exit;
use super::out::out;
use crate::atomic::write_atomic;
use crate::stress::gpu::Mode;
use crate::stress::supervised::Supervised;
use crate::stress::{self, report, CaseKind, StressOptions};
use crate::vk::features;
use anyhow::{Context, Result};
use std::time::Duration;

fn parse_cases(names: &[String]) -> Result<Vec<CaseKind>> {
    if names.is_empty() {
        return Ok(CaseKind::ALL.to_vec());
    }
    names
        .iter()
        .map(|n| {
            CaseKind::parse(n.trim()).ok_or_else(|| {
                let all: Vec<&str> = CaseKind::ALL.iter().map(|c| c.as_str()).collect();
                exit::coded(
                    exit::USAGE,
                    format!("unknown stress case `{n}` (cases: {})", all.join(", ")),
                )
            })
        })
        .collect()
}

pub fn stress(g: &Globals, args: &StressArgs) -> Result<u8> {
    let cases = parse_cases(&args.cases)?;
    // Before any case runs: a long run that cannot write its files fails at once.
    super::paths::writable_files(&[
        ("--json", args.json.as_deref()),
        ("--svg", args.svg.as_deref()),
    ])?;
    if !(args.timeout > 0.0 && args.timeout.is_finite()) {
        return Err(exit::coded(
            exit::USAGE,
            format!("--timeout must be a positive number of seconds, got {}", args.timeout),
        ));
    }
    let opts = StressOptions { cases, seed: args.seed, full: args.full };
    let inst = open_instance(g)?;
    let all = features::query_all(&inst)?;
    let info = features::select(&all, args.device.as_deref())?.clone();
    let device_json = crate::caps::device_json(&info);
    let mode = if args.ray_query { Mode::RayQuery } else { Mode::Pipeline };
    can_run(&info, mode)?;
    let validation_active = inst.validation;
    let name = format!(
        "{} ({} {}), {}",
        info.name(),
        info.driver_name(),
        info.driver_version(),
        mode.as_str()
    );
    // An interrupt kills the case's worker and removes the workers' folder; nothing written.
    crate::runner::groups::handle_interrupts(crate::runner::groups::Left::Nothing);
    // A private folder of its own (mode 0700, never an existing one), removed below.
    let tmp = super::paths::work_dir("rtprobe-stress")?;
    let dir = tmp.path().to_path_buf();
    let runner = Supervised {
        device_index: info.index,
        timeout: Duration::from_secs_f64(args.timeout),
        ray_query: args.ray_query,
        validate: g.validate,
        dir: dir.clone(),
        say: Box::new(|l: &str| super::out::stderr(&format!("{l}\n"))),
        every: super::progress::interval(),
    };
    let mut validation_errors = 0;
    let results: Vec<_> = opts
        .cases
        .iter()
        .map(|&kind| {
            let (r, errors) = runner.case(kind, &opts);
            validation_errors += errors;
            r
        })
        .collect();
    drop(tmp);
    crate::runner::groups::handle_interrupts(crate::runner::groups::Left::Writing);
    out!("{}", report::text(&name, &results));
    if let Some(path) = &args.json {
        let validation = (validation_active, validation_errors);
        let doc =
            report::json(&device_json, mode.as_str(), opts.seed, opts.full, validation, &results);
        let text = serde_json::to_string_pretty(&doc)? + "\n";
        write_atomic(path, text.as_bytes()).context("writing the stress report")?;
    }
    if let Some(path) = &args.svg {
        match results
            .iter()
            .find(|c| c.name == CaseKind::Far.as_str())
            .and_then(|far| stress::svg::far_plot(far, &name))
        {
            Some(svg) => write_atomic(path, svg.as_bytes()).context("writing the SVG")?,
            None => {
                return Err(exit::coded(
                    exit::BAD_INPUT,
                    "--svg needs the far case with at least one compared hit",
                ))
            }
        }
    }
    Ok(if report::all_passed(&results) { exit::OK } else { exit::FINDINGS })
}

/// The device has what the stress pipeline of `mode` needs, and its shaders compile here (a
/// one-line error with its exit code before any worker starts).
fn can_run(info: &crate::vk::DeviceInfo, mode: Mode) -> Result<()> {
    let req = mode.requirements();
    let missing = req.missing_on(info);
    if !missing.is_empty() {
        return Err(exit::coded(
            exit::UNSUPPORTED_DEVICE,
            format!(
                "{} cannot run the stress suite with {}: missing {}",
                info.name(),
                mode.as_str(),
                missing.join(", ")
            ),
        ));
    }
    stress::gpu::spirv(mode).map(|_| ()).map_err(|e| {
        exit::coded(
            exit::compiler_or(&e, exit::INTERNAL),
            format!("setting up the stress pipeline: {e}"),
        )
    })
}
