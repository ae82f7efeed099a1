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

pub fn render(caps: &Value) -> String {
    let d = &caps["device"];
    let f = &caps["features"];
    let l = &caps["limits"];
    let mut s = String::new();
    let _ = writeln!(s, "{} [device {}, {}, {} {:#06x}:{:#06x}]", d["name"].as_str().unwrap_or("?"), d["index"], d["device_type"].as_str().unwrap_or("?"),
        d["vendor"].as_str().unwrap_or("?"), d["vendor_id"].as_u64().unwrap_or(0), d["device_id"].as_u64().unwrap_or(0));
    let _ = writeln!(s, "  driver      {} {} ({}), Vulkan {}", d["driver_name"].as_str().unwrap_or("?"), d["driver_version"]["decoded"].as_str().unwrap_or("?"),
        d["driver_info"].as_str().unwrap_or(""), d["api_version"].as_str().unwrap_or("?"));
    let rt = &caps["ray_tracing_pipeline"];
    if rt["supported"].as_bool() == Some(true) {
        let p = &l["VkPhysicalDeviceRayTracingPipelinePropertiesKHR"];
        let _ = writeln!(s, "  RT pipeline yes (handle {} B, recursion {}, dispatch {})", p["shaderGroupHandleSize"], p["maxRayRecursionDepth"], p["maxRayDispatchInvocationCount"]);
    } else {
        let _ = writeln!(s, "  RT pipeline no: missing {}", rt["missing"].as_array().map(|a| a.iter().filter_map(|x| x.as_str()).collect::<Vec<_>>().join(", ")).unwrap_or_default());
    }
    let rows: &[(&str, &[&str])] = &[
        ("accel struct", &["VkPhysicalDeviceAccelerationStructureFeaturesKHR", "accelerationStructure"]),
        ("ray query", &["VkPhysicalDeviceRayQueryFeaturesKHR", "rayQuery"]),
        ("position fetch", &["VkPhysicalDeviceRayTracingPositionFetchFeaturesKHR", "rayTracingPositionFetch"]),
        ("buffer address", &["VkPhysicalDeviceVulkan12Features", "bufferDeviceAddress"]),
        ("desc indexing", &["VkPhysicalDeviceVulkan12Features", "descriptorIndexing"]),
        ("desc buffer", &["VkPhysicalDeviceDescriptorBufferFeaturesEXT", "descriptorBuffer"]),
        ("desc heap", &["VkPhysicalDeviceDescriptorHeapFeaturesEXT", "descriptorHeap"]),
        ("robustness2", &["VkPhysicalDeviceRobustness2FeaturesEXT", "robustBufferAccess2"]),
        ("device fault", &["VkPhysicalDeviceFaultFeaturesEXT", "deviceFault"]),
        ("shaderInt64", &["VkPhysicalDeviceFeatures", "shaderInt64"]),
    ];
    for (name, path) in rows {
        let _ = writeln!(s, "  {:<15} {}", name, flag(f, path));
    }
    let _ = writeln!(s, "matrix (what `rtprobe run` can do here):");
    if let Some(m) = caps["matrix"].as_object() {
        for (axis, values) in m {
            let Some(values) = values.as_object() else { continue };
            let mut ok = Vec::new();
            let mut not = Vec::new();
            for (v, sup) in values {
                match sup["status"].as_str() {
                    Some("supported") => ok.push(v.clone()),
                    Some(st) => not.push(format!("{v} ({}: {})", st.replace('_', " "), sup["reason"].as_str().unwrap_or(""))),
                    None => {}
                }
            }
            let _ = writeln!(s, "  {axis:<22} {}", ok.join(" "));
            for n in not {
                let _ = writeln!(s, "  {:<22} ✗ {n}", "");
            }
        }
    }
    if let Some(c) = caps["device_creation"].as_object() {
        let _ = writeln!(s, "device creation: {} in {} ms", if c["ok"].as_bool() == Some(true) { "ok" } else { "FAILED" }, c["ms"]);
    }
    s
}
