//! The capability probe: what a device can do for ray tracing ([`caps_json`], schema
//! `rtprobe.caps/2`), a text rendering of it, a Vulkan Profiles export, and — in [`support`] —
//! which matrix axis values the device can run, with reasons.
pub mod fields;
pub mod profile;
pub mod profile_check;
pub mod support;
pub mod text;

use crate::model::registry;
use crate::vk::{driver_version, features::TRACKED_EXTENSIONS, DeviceInfo};
use serde_json::{json, Map, Value};
use std::collections::BTreeMap;

/// `/2`: `matrix` lists every axis and value `--filter` takes (the registry's); `/1` had
/// `nonuniform_by_resource` and lacked `sampler`, `patch`, `canary` and `base=push_data`.
pub const SCHEMA: &str = "rtprobe.caps/2";

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
        "driver_uuid": info.properties.v11.map(|v| hex(&v.driver_uuid)),
        "device_uuid": info.properties.v11.map(|v| hex(&v.device_uuid)),
        "subgroup_size": info.properties.v11.map(|v| v.subgroup_size),
        "subgroup_ballot_stages": crate::model::Stage::ALL
            .iter()
            .filter(|s| info.subgroup_ballot(**s))
            .map(|s| s.as_str())
            .collect::<Vec<_>>(),
    })
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// Per axis value: supported, unsupported (with the device's reason) or not implemented; every
/// axis and value `--filter` accepts (the registry's), stand-ins included.
pub fn matrix_json(info: &DeviceInfo) -> Value {
    let mut m = Map::new();
    for axis in registry::AXES {
        let values: Map<String, Value> = axis
            .filter_values()
            .map(|v| {
                (
                    v.to_string(),
                    serde_json::to_value(support::value(info, axis.id, v))
                        .expect("Support serializes"),
                )
            })
            .collect();
        m.insert(axis.name.into(), Value::Object(values));
    }
    Value::Object(m)
}

/// Tracked extensions: present or not, with the spec version when present and the group the
/// text rendering lists them under.
pub fn extensions_json(info: &DeviceInfo) -> Value {
    extensions_json_of(&info.extensions)
}

fn extensions_json_of(present: &BTreeMap<String, u32>) -> Value {
    let mut m = Map::new();
    for e in TRACKED_EXTENSIONS {
        let name = e.name.to_string_lossy().into_owned();
        let v = match present.get(&name) {
            Some(spec) => json!({ "present": true, "spec_version": spec, "group": e.group }),
            None => json!({ "present": false, "group": e.group }),
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
pub fn caps_json(
    info: &DeviceInfo,
    loader_version: u32,
    check: Option<&DeviceCreationCheck>,
) -> Value {
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
    use support::Support;

    #[test]
    fn support_serializes_with_status_and_reason() {
        let v = serde_json::to_value(Support::Unsupported { reason: "x".into() }).unwrap();
        assert_eq!(v, json!({"status": "unsupported", "reason": "x"}));
        let v = serde_json::to_value(Support::Supported).unwrap();
        assert_eq!(v, json!({"status": "supported"}));
    }

    /// Every ray tracing extension the Vulkan headers (1.4.359) define is listed, present or
    /// not. The names are spelled out here, not taken from `TRACKED_EXTENSIONS`, so dropping one
    /// from the list fails this test.
    const EVERY_RT_EXTENSION: &[&str] = &[
        "VK_KHR_ray_tracing_pipeline",
        "VK_KHR_acceleration_structure",
        "VK_KHR_ray_query",
        "VK_KHR_deferred_host_operations",
        "VK_KHR_ray_tracing_maintenance1",
        "VK_KHR_ray_tracing_position_fetch",
        "VK_KHR_pipeline_library",
        "VK_EXT_pipeline_library_group_handles",
        "VK_NV_ray_tracing",
        "VK_NV_ray_tracing_validation",
        "VK_NV_ray_tracing_invocation_reorder",
        "VK_EXT_ray_tracing_invocation_reorder",
        "VK_NV_cluster_acceleration_structure",
        "VK_NV_partitioned_acceleration_structure",
        "VK_AMDX_dense_geometry_format",
        "VK_NV_ray_tracing_motion_blur",
        "VK_NV_ray_tracing_linear_swept_spheres",
        "VK_EXT_opacity_micromap",
        "VK_KHR_opacity_micromap",
        "VK_ARM_pipeline_opacity_micromap",
        "VK_NV_displacement_micromap",
    ];

    #[test]
    fn every_rt_extension_is_listed_present_or_not() {
        let present: BTreeMap<String, u32> = [
            ("VK_NV_ray_tracing_invocation_reorder".to_string(), 1),
            ("VK_KHR_ray_query".to_string(), 1),
        ]
        .into();
        let v = extensions_json_of(&present);
        for name in EVERY_RT_EXTENSION {
            let e = &v[*name];
            let want = present.contains_key(*name);
            assert_eq!(e["present"], json!(want), "{name}: {e}");
            assert_eq!(e["spec_version"].is_u64(), want, "{name}: {e}");
            assert!(e["group"].as_str().is_some_and(|g| !g.is_empty()), "{name}: {e}");
        }
        assert_eq!(v["VK_NV_ray_tracing_invocation_reorder"]["group"], "invocation reorder");
    }
}
