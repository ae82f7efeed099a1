//! The `devices` and `caps` commands: glue between parsed arguments and the library modules.
use super::args::{CapsArgs, DevicesArgs};
use super::exit;
use crate::caps::{self, support, DeviceCreationCheck};
use crate::matrix::{DescriptorModel, Resource, Stage};
use crate::report::write_atomic;
use crate::vk::{driver_version::format_api_version, features, DeviceInfo, Gpu, Instance, InstanceOptions, Requirements, VkError};
use anyhow::{Context, Result};
use serde_json::json;
use std::sync::Arc;
use std::time::Instant;

pub struct Globals {
    pub validate: bool,
}

pub fn open_instance(g: &Globals) -> Result<Arc<Instance>> {
    Ok(Arc::new(Instance::new(&InstanceOptions { validate: g.validate })?))
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
        println!("{}", serde_json::to_string_pretty(&v)?);
        return Ok(exit::OK);
    }
    for d in &all {
        let missing = d.rt_pipeline_missing();
        let rt = if missing.is_empty() { "yes".to_string() } else { format!("no (missing {})", missing.join(", ")) };
        let p = &d.properties.core;
        println!(
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

/// Everything the matrix could ask of `info` that `info` supports.
pub fn full_requirements(info: &DeviceInfo) -> Requirements {
    let fragment = support::stage(info, Stage::Fragment).is_supported();
    Requirements {
        rt_pipeline: support::stage(info, Stage::Raygen).is_supported(),
        ray_query: info.features.ray_query.is_some_and(|r| r.ray_query == ash::vk::TRUE),
        buffer_device_address: info.features.v12.is_some_and(|v| v.buffer_device_address == ash::vk::TRUE),
        descriptor_indexing: support::descriptor_model(info, DescriptorModel::DescriptorIndexing).is_supported(),
        descriptor_buffer: support::descriptor_model(info, DescriptorModel::DescriptorBuffer).is_supported(),
        device_fault: info.features.fault.is_some_and(|f| f.device_fault == ash::vk::TRUE),
        int64: info.features.core.shader_int64 == ash::vk::TRUE,
        fragment_stores: fragment && support::resource(info, Resource::StorageBuffer).is_supported(),
        dynamic_rendering: fragment,
    }
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
        print!("{pretty}");
    } else {
        print!("{}", caps::text::render(&report));
    }
    Ok(exit::OK)
}

/// Today's date (UTC) as YYYY-MM-DD, from the system clock.
pub fn today() -> String {
    let secs = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map(|d| d.as_secs()).unwrap_or(0);
    crate::report::time::civil_date(secs)
}
