//! The `devices` and `caps` commands: glue between parsed arguments and the library modules.
use super::args::{CapsArgs, DevicesArgs};
use super::exit;
use super::out::{out, outln};
use crate::atomic::write_atomic;
use crate::caps::{self, DeviceCreationCheck};
use crate::matrix::plan::{self, PlanOptions};
use crate::model::PatchMode;
use crate::vk::{
    driver_version::format_api_version, features, DeviceInfo, Gpu, Instance, InstanceOptions,
    Requirements, VkError,
};
use anyhow::{Context, Result};
use serde_json::json;
use std::sync::Arc;
use std::time::Instant;

#[derive(Debug)]
pub struct Globals {
    pub validate: bool,
    /// `--validate=gpu-av`: `run` re-runs each finding under GPU-Assisted Validation.
    pub gpu_av: bool,
}

pub fn open_instance(g: &Globals) -> Result<Arc<Instance>> {
    Ok(Arc::new(Instance::new(&InstanceOptions { validate: g.validate, gpu_av: false })?))
}

pub fn devices(g: &Globals, args: &DevicesArgs) -> Result<u8> {
    let inst = open_instance(g)?;
    let all = features::query_all(&inst)?;
    if args.json {
        let v: Vec<_> = all
            .iter()
            .map(|d| {
                let missing = d.rt_pipeline_missing();
                json!({ "device": caps::device_json(d), "ray_tracing_pipeline": { "supported": missing.is_empty(), "missing": missing } })
            })
            .collect();
        outln!("{}", serde_json::to_string_pretty(&v)?);
        return Ok(exit::OK);
    }
    for d in &all {
        let missing = d.rt_pipeline_missing();
        let rt = if missing.is_empty() {
            "yes".to_string()
        } else {
            format!("no (missing {})", missing.join(", "))
        };
        let p = &d.properties.core;
        outln!(
            "{}  {}  vendor {} ({:#06x})  driver {} {}  Vulkan {}  rt-pipeline: {}",
            d.index,
            d.name(),
            crate::vk::driver_version::vendor_name(p.vendor_id),
            p.vendor_id,
            d.driver_name(),
            d.driver_version(),
            format_api_version(p.api_version),
            rt
        );
    }
    Ok(exit::OK)
}

/// What the whole matrix (every workaround, canaries) needs of `info`, as far as `info` can run it:
/// the same rule a worker uses for its own cells.
pub fn full_requirements(info: &DeviceInfo) -> Requirements {
    let opts =
        PlanOptions { filters: vec![], canaries: true, patches: PatchMode::All, inject: vec![] };
    let cells: Vec<_> = plan::plan(info, &opts).to_run().copied().collect();
    crate::runner::worker::requirements(info, &cells)
}

fn check_device_creation(inst: &Arc<Instance>, info: &DeviceInfo) -> DeviceCreationCheck {
    let t = Instant::now();
    let r = Gpu::new(inst.clone(), info.clone(), full_requirements(info));
    let ms = t.elapsed().as_secs_f64() * 1e3;
    match r {
        Ok(gpu) => {
            drop(gpu);
            DeviceCreationCheck { ok: true, ms, error: None }
        }
        Err(e) => DeviceCreationCheck { ok: false, ms, error: Some(e.to_string()) },
    }
}

pub fn caps_cmd(g: &Globals, args: &CapsArgs) -> Result<u8> {
    super::paths::writable_files(&[
        ("-o", args.out.as_deref()),
        ("--profile", args.profile.as_deref()),
    ])?;
    let inst = open_instance(g)?;
    let all = features::query_all(&inst)?;
    let info = features::select(&all, args.device.as_deref()).map_err(|e| match e {
        VkError::NoRtDevice { details } => anyhow::Error::from(VkError::NoRtDevice {
            details: format!("{details}; `rtprobe caps --device N` shows any device's caps"),
        }),
        e => e.into(),
    })?;
    let check = (!args.no_device_check).then(|| check_device_creation(&inst, info));
    let report = caps::caps_json(info, inst.loader_version, check.as_ref());
    let pretty = serde_json::to_string_pretty(&report)? + "\n";
    if let Some(out) = &args.out {
        write_atomic(out, pretty.as_bytes()).context("writing the caps report")?;
    }
    if let Some(p) = &args.profile {
        let date = today();
        let prof = serde_json::to_string_pretty(&caps::profile::export(&report, &date))? + "\n";
        write_atomic(p, prof.as_bytes()).context("writing the Vulkan profile")?;
    }
    if args.json {
        out!("{pretty}");
    } else {
        out!("{}", caps::text::render(&report));
        outln!("{}", first_run(info));
    }
    Ok(exit::OK)
}

/// The first run to try after `caps`: closest-hit and raygen shaders reading storage buffers
/// through descriptor indexing (the README's tour), with how many cells it runs on `info`.
pub fn first_run(info: &DeviceInfo) -> String {
    const FILTER: &str =
        "stage=closest_hit|raygen,resource=storage_buffer,descriptor_model=descriptor_indexing";
    let filters = vec![crate::model::Filter::parse(FILTER).expect("a valid filter")];
    let opts = PlanOptions { filters, canaries: false, patches: PatchMode::Faults, inject: vec![] };
    let n = plan::plan(info, &opts).to_run().count();
    let flag = if info.index == 0 { String::new() } else { format!(" --device {}", info.index) };
    format!(
        "next: a first run ({} of the matrix): rtprobe run{flag} --filter '{FILTER}' -o first.json",
        crate::model::plural(n, "cell")
    )
}

/// Today's date (UTC) as YYYY-MM-DD, from the system clock.
pub fn today() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs())
        .unwrap_or(0);
    crate::report::time::civil_date(secs)
}
