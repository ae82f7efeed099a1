//! The capability probe: what a device can do for ray tracing ([`caps_json`], schema
//! `rtprobe.caps/1`), a text rendering of it, a Vulkan Profiles export, and — in [`support`] —
//! which matrix axis values the device can run, with reasons.
pub mod fields;
pub mod profile;
pub mod support;
pub mod text;

use crate::matrix::{AsAccess, DescriptorModel, HeapAccess, IndexSource, Resource, Stage};
use crate::vk::{driver_version, features::TRACKED_EXTENSIONS, DeviceInfo};
use serde_json::{json, Map, Value};
use support::Support;

pub const SCHEMA: &str = "rtprobe.caps/1";

/// The `device` object shared by caps and run reports.
pub fn device_json(info: &DeviceInfo) -> Value {
    let p = &info.properties.core;
    let conformance = info.properties.v12.map(|v| {
        let c = v.conformance_version;
        format!("{}.{}.{}.{}", c.major, c.minor, c.subminor, c.patch)
    });
    json!({
        "index": info.index,
        "name": info.name(),
        "vendor_id": p.vendor_id,
        "vendor": driver_version::vendor_name(p.vendor_id),
        "device_id": p.device_id,
        "device_type": format!("{:?}", p.device_type).to_lowercase(),
        "driver_id": format!("{:?}", info.driver_id()).to_lowercase(),
        "driver_name": info.driver_name(),
        "driver_info": info.driver_info(),
        "driver_version": { "raw": p.driver_version, "decoded": info.driver_version() },
        "api_version": driver_version::format_api_version(p.api_version),
        "conformance_version": conformance,
    })
}

fn support_map<T: Copy>(all: &[T], name: impl Fn(T) -> &'static str, f: impl Fn(T) -> Support) -> Value {
    let mut m = Map::new();
    for v in all {
        m.insert(name(*v).into(), serde_json::to_value(f(*v)).expect("Support serializes"));
    }
    Value::Object(m)
}

/// Per axis value: supported, unsupported (with the device's reason) or not implemented.
pub fn matrix_json(info: &DeviceInfo) -> Value {
    let nonuniform = support_map(Resource::ALL, Resource::as_str, |r| support::dynamic_index(info, r, true));
    json!({
        "stage": support_map(Stage::ALL, Stage::as_str, |s| support::stage(info, s)),
        "resource": support_map(Resource::ALL, Resource::as_str, |r| support::resource(info, r)),
        "index": support_map(IndexSource::ALL, IndexSource::as_str, |i| support::index(info, i)),
        "nonuniform_by_resource": nonuniform,
        "as_access": support_map(AsAccess::ALL, AsAccess::as_str, |a| support::as_access(info, a)),
        "descriptor_model": support_map(DescriptorModel::ALL, DescriptorModel::as_str, |m| support::descriptor_model(info, m)),
        "heap_access": support_map(HeapAccess::ALL, HeapAccess::as_str, |h| Support::all([support::descriptor_model(info, DescriptorModel::DescriptorHeap), support::heap_access(info, h)])),
    })
}

/// Tracked extensions: present or not, with the spec version when present.
pub fn extensions_json(info: &DeviceInfo) -> Value {
    let mut m = Map::new();
    for e in TRACKED_EXTENSIONS {
        let name = e.to_string_lossy().into_owned();
        let v = match info.extensions.get(&name) {
            Some(spec) => json!({ "present": true, "spec_version": spec }),
            None => json!({ "present": false }),
        };
        m.insert(name, v);
    }
    Value::Object(m)
}

/// Result of actually creating a logical device with everything the matrix may need.
#[derive(Clone, Debug)]
pub struct DeviceCreationCheck {
    pub ok: bool,
    pub ms: f64,
    pub error: Option<String>,
}

/// The full caps report of one device.
pub fn caps_json(info: &DeviceInfo, loader_version: u32, check: Option<&DeviceCreationCheck>) -> Value {
    let missing = info.rt_pipeline_missing();
    json!({
        "schema": SCHEMA,
        "tool": { "name": "rtprobe", "version": env!("CARGO_PKG_VERSION") },
        "loader_api_version": driver_version::format_api_version(loader_version),
        "device": device_json(info),
        "ray_tracing_pipeline": { "supported": missing.is_empty(), "missing": missing },
        "extensions": extensions_json(info),
        "features": fields::features(info),
        "limits": fields::properties(info),
        "matrix": matrix_json(info),
        "device_creation": check.map(|c| json!({ "ok": c.ok, "ms": (c.ms * 100.0).round() / 100.0, "error": c.error })),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn support_serializes_with_status_and_reason() {
        let v = serde_json::to_value(Support::Unsupported { reason: "x".into() }).unwrap();
        assert_eq!(v, json!({"status": "unsupported", "reason": "x"}));
        let v = serde_json::to_value(Support::Supported).unwrap();
        assert_eq!(v, json!({"status": "supported"}));
    }
}
