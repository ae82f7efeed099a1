//! Plain-text rendering of a caps report (the `rtprobe caps` default), read from the same JSON
//! value `--json` prints, so the two can never disagree.
use serde_json::Value;
use std::fmt::Write;

fn flag(v: &Value, path: &[&str]) -> &'static str {
    let mut cur = v;
    for p in path {
        cur = &cur[*p];
    }
    match cur.as_bool() {
        Some(true) => "yes",
        Some(false) => "no",
        None => "absent",
    }
}

/// The feature that says whether a present extension is usable: (struct, member).
fn headline_feature(ext: &str) -> Option<(&'static str, &'static str)> {
    Some(match ext {
        "VK_KHR_ray_tracing_pipeline" => {
            ("VkPhysicalDeviceRayTracingPipelineFeaturesKHR", "rayTracingPipeline")
        }
        "VK_KHR_acceleration_structure" => {
            ("VkPhysicalDeviceAccelerationStructureFeaturesKHR", "accelerationStructure")
        }
        "VK_KHR_ray_query" => ("VkPhysicalDeviceRayQueryFeaturesKHR", "rayQuery"),
        "VK_KHR_ray_tracing_maintenance1" => {
            ("VkPhysicalDeviceRayTracingMaintenance1FeaturesKHR", "rayTracingMaintenance1")
        }
        "VK_KHR_ray_tracing_position_fetch" => {
            ("VkPhysicalDeviceRayTracingPositionFetchFeaturesKHR", "rayTracingPositionFetch")
        }
        "VK_EXT_pipeline_library_group_handles" => (
            "VkPhysicalDevicePipelineLibraryGroupHandlesFeaturesEXT",
            "pipelineLibraryGroupHandles",
        ),
        "VK_NV_ray_tracing_validation" => {
            ("VkPhysicalDeviceRayTracingValidationFeaturesNV", "rayTracingValidation")
        }
        "VK_NV_ray_tracing_invocation_reorder" => {
            ("VkPhysicalDeviceRayTracingInvocationReorderFeaturesNV", "rayTracingInvocationReorder")
        }
        "VK_EXT_ray_tracing_invocation_reorder" => (
            "VkPhysicalDeviceRayTracingInvocationReorderFeaturesEXT",
            "rayTracingInvocationReorder",
        ),
        "VK_NV_cluster_acceleration_structure" => (
            "VkPhysicalDeviceClusterAccelerationStructureFeaturesNV",
            "clusterAccelerationStructure",
        ),
        "VK_NV_partitioned_acceleration_structure" => (
            "VkPhysicalDevicePartitionedAccelerationStructureFeaturesNV",
            "partitionedAccelerationStructure",
        ),
        "VK_AMDX_dense_geometry_format" => {
            ("VkPhysicalDeviceDenseGeometryFormatFeaturesAMDX", "denseGeometryFormat")
        }
        "VK_NV_ray_tracing_motion_blur" => {
            ("VkPhysicalDeviceRayTracingMotionBlurFeaturesNV", "rayTracingMotionBlur")
        }
        "VK_NV_ray_tracing_linear_swept_spheres" => {
            ("VkPhysicalDeviceRayTracingLinearSweptSpheresFeaturesNV", "linearSweptSpheres")
        }
        "VK_EXT_opacity_micromap" => ("VkPhysicalDeviceOpacityMicromapFeaturesEXT", "micromap"),
        "VK_KHR_opacity_micromap" => ("VkPhysicalDeviceOpacityMicromapFeaturesKHR", "micromap"),
        "VK_ARM_pipeline_opacity_micromap" => {
            ("VkPhysicalDevicePipelineOpacityMicromapFeaturesARM", "pipelineOpacityMicromap")
        }
        "VK_NV_displacement_micromap" => {
            ("VkPhysicalDeviceDisplacementMicromapFeaturesNV", "displacementMicromap")
        }
        "VK_EXT_descriptor_buffer" => {
            ("VkPhysicalDeviceDescriptorBufferFeaturesEXT", "descriptorBuffer")
        }
        "VK_EXT_descriptor_heap" => ("VkPhysicalDeviceDescriptorHeapFeaturesEXT", "descriptorHeap"),
        "VK_KHR_pipeline_binary" => {
            ("VkPhysicalDevicePipelineBinaryFeaturesKHR", "pipelineBinaries")
        }
        _ => return None,
    })
}

/// The tracked extensions by group: present ones with their spec version (and headline feature
/// when it is off), absent ones on a line of their own.
fn render_extensions(caps: &Value, s: &mut String) {
    let Some(exts) = caps["extensions"].as_object() else {
        return;
    };
    let mut groups: Vec<(&str, Vec<String>, Vec<&str>)> = Vec::new();
    for (name, e) in exts {
        let group = e["group"].as_str().unwrap_or("other");
        let i = match groups.iter().position(|g| g.0 == group) {
            Some(i) => i,
            None => {
                groups.push((group, Vec::new(), Vec::new()));
                groups.len() - 1
            }
        };
        if e["present"].as_bool() == Some(true) {
            let mut item = format!("{name} v{}", e["spec_version"]);
            if let Some((st, member)) = headline_feature(name) {
                if flag(&caps["features"], &[st, member]) != "yes" {
                    item.push_str(&format!(
                        " ({member} {})",
                        flag(&caps["features"], &[st, member])
                    ));
                }
            }
            groups[i].1.push(item);
        } else {
            groups[i].2.push(name);
        }
    }
    let _ = writeln!(s, "extensions:");
    for (group, present, absent) in groups {
        let _ = writeln!(
            s,
            "  {group:<24} {}",
            if present.is_empty() { "-".to_string() } else { present.join(", ") }
        );
        if !absent.is_empty() {
            let _ = writeln!(s, "  {:<24} ✗ {}", "", absent.join(", "));
        }
    }
}

/// The headline features under the device line: (label, [struct, member]).
const FEATURE_ROWS: &[(&str, &[&str])] = &[
    (
        "accel struct",
        &["VkPhysicalDeviceAccelerationStructureFeaturesKHR", "accelerationStructure"],
    ),
    ("ray query", &["VkPhysicalDeviceRayQueryFeaturesKHR", "rayQuery"]),
    (
        "position fetch",
        &["VkPhysicalDeviceRayTracingPositionFetchFeaturesKHR", "rayTracingPositionFetch"],
    ),
    (
        "reorder (NV)",
        &["VkPhysicalDeviceRayTracingInvocationReorderFeaturesNV", "rayTracingInvocationReorder"],
    ),
    (
        "reorder (EXT)",
        &["VkPhysicalDeviceRayTracingInvocationReorderFeaturesEXT", "rayTracingInvocationReorder"],
    ),
    ("buffer address", &["VkPhysicalDeviceVulkan12Features", "bufferDeviceAddress"]),
    ("desc indexing", &["VkPhysicalDeviceVulkan12Features", "descriptorIndexing"]),
    ("desc buffer", &["VkPhysicalDeviceDescriptorBufferFeaturesEXT", "descriptorBuffer"]),
    ("desc heap", &["VkPhysicalDeviceDescriptorHeapFeaturesEXT", "descriptorHeap"]),
    ("robustness2", &["VkPhysicalDeviceRobustness2FeaturesEXT", "robustBufferAccess2"]),
    ("device fault", &["VkPhysicalDeviceFaultFeaturesEXT", "deviceFault"]),
    ("shaderInt64", &["VkPhysicalDeviceFeatures", "shaderInt64"]),
];

/// The caps report as `rtprobe caps` prints it.
pub fn render(caps: &Value) -> String {
    let mut s = String::new();
    render_device(&caps["device"], &mut s);
    render_ray_tracing(caps, &mut s);
    for (name, path) in FEATURE_ROWS {
        let _ = writeln!(s, "  {:<15} {}", name, flag(&caps["features"], path));
    }
    render_extensions(caps, &mut s);
    render_matrix(caps, &mut s);
    if let Some(c) = caps["device_creation"].as_object() {
        let _ = writeln!(
            s,
            "device creation: {} in {} ms",
            if c["ok"].as_bool() == Some(true) { "ok" } else { "FAILED" },
            c["ms"]
        );
    }
    s
}

/// The device line (name, index, type, vendor and ids) and the driver line.
fn render_device(d: &Value, s: &mut String) {
    let _ = writeln!(
        s,
        "{} [device {}, {}, {} {:#06x}:{:#06x}]",
        d["name"].as_str().unwrap_or("?"),
        d["index"],
        d["device_type"].as_str().unwrap_or("?"),
        d["vendor"].as_str().unwrap_or("?"),
        d["vendor_id"].as_u64().unwrap_or(0),
        d["device_id"].as_u64().unwrap_or(0)
    );
    let _ = writeln!(
        s,
        "  driver      {} {} ({}), Vulkan {}",
        d["driver_name"].as_str().unwrap_or("?"),
        d["driver_version"]["decoded"].as_str().unwrap_or("?"),
        d["driver_info"].as_str().unwrap_or(""),
        d["api_version"].as_str().unwrap_or("?")
    );
}

/// Whether the ray tracing pipeline is supported, with its headline limits, or what it misses.
fn render_ray_tracing(caps: &Value, s: &mut String) {
    let rt = &caps["ray_tracing_pipeline"];
    if rt["supported"].as_bool() == Some(true) {
        let p = &caps["limits"]["VkPhysicalDeviceRayTracingPipelinePropertiesKHR"];
        let _ = writeln!(
            s,
            "  RT pipeline yes (handle {} B, recursion {}, dispatch {})",
            p["shaderGroupHandleSize"],
            p["maxRayRecursionDepth"],
            p["maxRayDispatchInvocationCount"]
        );
    } else {
        let _ = writeln!(
            s,
            "  RT pipeline no: missing {}",
            rt["missing"]
                .as_array()
                .map(|a| a.iter().filter_map(|x| x.as_str()).collect::<Vec<_>>().join(", "))
                .unwrap_or_default()
        );
    }
}

/// Per matrix axis, the supported values on one line and each other value, with its status and
/// reason, on a line of its own.
fn render_matrix(caps: &Value, s: &mut String) {
    let _ = writeln!(s, "matrix (what `rtprobe run` can do here):");
    let Some(m) = caps["matrix"].as_object() else {
        return;
    };
    for (axis, values) in m {
        let Some(values) = values.as_object() else {
            continue;
        };
        let mut ok = Vec::new();
        let mut not = Vec::new();
        for (v, sup) in values {
            match sup["status"].as_str() {
                Some("supported") => ok.push(v.clone()),
                Some(st) => not.push(format!(
                    "{v} ({}: {})",
                    st.replace('_', " "),
                    sup["reason"].as_str().unwrap_or("")
                )),
                None => {}
            }
        }
        let _ = writeln!(s, "  {axis:<22} {}", ok.join(" "));
        for n in not {
            let _ = writeln!(s, "  {:<22} ✗ {n}", "");
        }
    }
}
