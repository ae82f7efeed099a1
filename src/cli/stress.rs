//! The `stress` command: parse the cases, open the device with what the stress pipeline needs,
//! run the cases in this process (fence deadlines; a lost device or a timeout ends the remaining
//! cases with that reason), print the tables, write the JSON and SVG atomically.
use super::args::StressArgs;
use super::commands::{open_instance, Globals};
use super::exit;
use super::out::out;
use crate::atomic::write_atomic;
use crate::stress::gpu::{GpuTracer, Mode};
use crate::stress::{self, report, CaseKind, StressOptions, Tracer};
use crate::vk::{features, Gpu, Requirements};
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
    let req = Requirements {
        rt_pipeline: mode == Mode::Pipeline,
        ray_query: mode == Mode::RayQuery,
        buffer_device_address: true,
        int64: true,
        ..Requirements::default()
    };
    let missing = req.missing_on(&info);
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
    let validation_active = inst.validation;
    let gpu = Gpu::new(inst, info, req)?;
    let mut tracer =
        GpuTracer::new(gpu, Duration::from_secs_f64(args.timeout), mode).map_err(|e| {
            exit::coded(
                exit::compiler_or(&e, exit::INTERNAL),
                format!("setting up the stress pipeline: {e}"),
            )
        })?;
    let name = tracer.name();
    let results = stress::run(&mut tracer, &opts);
    out!("{}", report::text(&name, &results));
    if let Some(path) = &args.json {
        let validation = (validation_active, crate::vk::instance::validation_error_count());
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
