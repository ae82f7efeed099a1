//! End-to-end tests of `rtprobe devices` and `rtprobe caps` on lavapipe, and of every error path
//! of the foundation (no loader, no driver, unsupported device, bad --device, bad arguments).
mod common;
use common::*;

fn vulkaninfo_summary() -> Option<String> {
    let o = std::process::Command::new("vulkaninfo").arg("--summary").output().ok()?;
    o.status.success().then(|| String::from_utf8_lossy(&o.stdout).into_owned())
}

/// `key = value` from vulkaninfo --summary's first GPU block.
fn summary_value(summary: &str, key: &str) -> Option<String> {
    summary.lines().find_map(|l| {
        let (k, v) = l.split_once('=')?;
        (k.trim() == key).then(|| v.trim().to_string())
    })
}

#[test]
fn caps_json_describes_lavapipe_and_agrees_with_vulkaninfo() {
    let v = json(&run(&["caps", "--json"]));
    assert_eq!(v["schema"], "rtprobe.caps/2");
    assert_eq!(v["ray_tracing_pipeline"]["supported"], true, "{}", v["ray_tracing_pipeline"]);
    let name = v["device"]["name"].as_str().unwrap();
    assert!(name.contains("llvmpipe"), "tests expect lavapipe, got {name}");

    let summary =
        vulkaninfo_summary().expect("vulkaninfo --summary (apt-get install vulkan-tools)");
    assert_eq!(summary_value(&summary, "deviceName").as_deref(), Some(name));
    let api = summary_value(&summary, "apiVersion").unwrap();
    // vulkaninfo prints e.g. "1.4.305" (or "4206897 (1.4.305)" in older versions).
    assert!(
        api.contains(v["device"]["api_version"].as_str().unwrap()),
        "{api} vs {}",
        v["device"]["api_version"]
    );
    let driver = summary_value(&summary, "driverInfo").unwrap();
    assert_eq!(driver, v["device"]["driver_info"].as_str().unwrap());

    // Features and limits come from the driver, keyed by Vulkan struct names.
    let rt = &v["features"]["VkPhysicalDeviceRayTracingPipelineFeaturesKHR"];
    assert_eq!(rt["rayTracingPipeline"], true);
    let lim = &v["limits"]["VkPhysicalDeviceRayTracingPipelinePropertiesKHR"];
    assert!(lim["shaderGroupHandleSize"].as_u64().unwrap() >= 16);
    assert!(lim["maxRayRecursionDepth"].as_u64().unwrap() >= 1);
    assert!(
        v["limits"]["VkPhysicalDeviceAccelerationStructurePropertiesKHR"]["maxInstanceCount"]
            .as_u64()
            .unwrap()
            > 0
    );
    assert!(v["limits"]["VkPhysicalDeviceVulkan12Properties"]
        ["maxPerStageDescriptorUpdateAfterBindStorageBuffers"]
        .as_u64()
        .is_some());

    // The descriptor heap is absent on lavapipe: unsupported, with the reason.
    assert_eq!(v["extensions"]["VK_EXT_descriptor_heap"]["present"], false);
    let heap = &v["matrix"]["descriptor_model"]["descriptor_heap"];
    assert_eq!(heap["status"], "unsupported");
    assert!(heap["reason"].as_str().unwrap().contains("VK_EXT_descriptor_heap"));
    assert_eq!(v["matrix"]["descriptor_model"]["descriptor_indexing"]["status"], "supported");
    assert_eq!(v["matrix"]["stage"]["closest_hit"]["status"], "supported");
    // Lavapipe has ray queries and descriptor buffers; the matrix must say so.
    assert_eq!(v["extensions"]["VK_KHR_ray_query"]["present"], true);
    assert_eq!(v["matrix"]["descriptor_model"]["descriptor_buffer"]["status"], "supported");
    assert_eq!(v["matrix"]["as_access"]["address_patched"]["status"], "supported");

    // The logical device with everything the matrix needs was created.
    assert_eq!(v["device_creation"]["ok"], true, "{}", v["device_creation"]);
}

#[test]
fn caps_matrix_lists_exactly_the_axes_and_values_filter_accepts() {
    let v = json(&run(&["caps", "--json"]));
    let matrix = v["matrix"].as_object().unwrap();
    // The axes `run --filter` names when it refuses one.
    let o = run(&["run", "--list", "--filter", "no_such_axis=x"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let said = stderr(&o);
    let axes: Vec<&str> = said
        .rsplit_once("axes: ")
        .expect("the error lists the axes")
        .1
        .trim()
        .split(", ")
        .collect();
    assert_eq!(matrix.keys().map(String::as_str).collect::<Vec<_>>(), axes);
    for (axis, values) in matrix {
        // Every value caps lists, `run --filter` takes (one term with all of them), and a value
        // caps does not list it refuses, naming the values it takes: the same list.
        let listed: Vec<&str> = values.as_object().unwrap().keys().map(String::as_str).collect();
        let o = run(&["run", "--list", "--filter", &format!("{axis}={}", listed.join("|"))]);
        assert_eq!(o.status.code(), Some(0), "{axis}: {}", stderr(&o));
        let o = run(&["run", "--list", "--filter", &format!("{axis}=no_such_value")]);
        assert_eq!(o.status.code(), Some(2), "{axis}: {}", stderr(&o));
        let taken = stderr(&o)
            .rsplit_once("values: ")
            .expect("the error lists the values")
            .1
            .trim()
            .to_string();
        assert_eq!(taken, listed.join(", "), "{axis}");
    }
    // lavapipe has no SER: the reorder values say why.
    assert_eq!(matrix["reorder"]["reorder"]["status"], "unsupported");
    assert_eq!(matrix["base"]["push_data"]["status"], "supported");
}

/// `name → revision` of every device extension in `vulkaninfo`'s full output.
fn vulkaninfo_device_extensions() -> std::collections::BTreeMap<String, u64> {
    let o = std::process::Command::new("vulkaninfo")
        .output()
        .expect("vulkaninfo (apt-get install vulkan-tools)");
    let text = String::from_utf8_lossy(&o.stdout).into_owned();
    let mut lines = text.lines().skip_while(|l| !l.starts_with("Device Extensions:"));
    lines.next();
    lines
        .take_while(|l| !l.trim().is_empty())
        .filter_map(|l| {
            let (name, rev) = l.split_once(':')?;
            Some((
                name.trim().to_string(),
                rev.trim().trim_start_matches("extension revision").trim().parse().ok()?,
            ))
        })
        .collect()
}

#[test]
fn every_rt_extension_is_listed_and_agrees_with_vulkaninfo() {
    let v = json(&run(&["caps", "--json"]));
    let exts = v["extensions"].as_object().unwrap();
    let vi = vulkaninfo_device_extensions();
    assert!(
        vi.contains_key("VK_KHR_ray_tracing_pipeline"),
        "vulkaninfo's extension list parsed: {vi:?}"
    );
    for name in [
        "VK_NV_ray_tracing_invocation_reorder",
        "VK_EXT_ray_tracing_invocation_reorder",
        "VK_EXT_opacity_micromap",
        "VK_KHR_opacity_micromap",
        "VK_NV_displacement_micromap",
        "VK_NV_cluster_acceleration_structure",
        "VK_NV_partitioned_acceleration_structure",
        "VK_NV_ray_tracing_motion_blur",
        "VK_NV_ray_tracing_linear_swept_spheres",
        "VK_KHR_ray_tracing_position_fetch",
        "VK_KHR_pipeline_library",
        "VK_KHR_ray_query",
        "VK_KHR_ray_tracing_maintenance1",
        "VK_NV_ray_tracing",
        "VK_EXT_pipeline_library_group_handles",
    ] {
        assert!(exts.contains_key(name), "{name} not listed");
    }
    // Present exactly when vulkaninfo lists it, with its revision; a group for the text output.
    for (name, e) in exts {
        assert_eq!(e["present"].as_bool(), Some(vi.contains_key(name)), "{name}: {e}");
        if let Some(rev) = vi.get(name) {
            assert_eq!(e["spec_version"].as_u64(), Some(*rev), "{name}");
        }
        assert!(e["group"].as_str().is_some(), "{name}");
    }
    // Feature structs exist exactly for present extensions: lavapipe has the pipeline library
    // group handles, no invocation reorder.
    let f = &v["features"];
    assert_eq!(
        f["VkPhysicalDevicePipelineLibraryGroupHandlesFeaturesEXT"].is_object(),
        vi.contains_key("VK_EXT_pipeline_library_group_handles")
    );
    assert_eq!(
        f["VkPhysicalDeviceRayTracingInvocationReorderFeaturesNV"].is_object(),
        vi.contains_key("VK_NV_ray_tracing_invocation_reorder")
    );
    assert_eq!(
        f["VkPhysicalDeviceClusterAccelerationStructureFeaturesNV"].is_object(),
        vi.contains_key("VK_NV_cluster_acceleration_structure")
    );
    assert_eq!(
        v["limits"]["VkPhysicalDeviceRayTracingPropertiesNV"].is_object(),
        vi.contains_key("VK_NV_ray_tracing")
    );
    // The text output groups them; the profile export carries present ones and their structs.
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let prof = dir.path().join("p.json");
    let o = run(&["caps", "--profile", prof.to_str().unwrap()]);
    let text = stdout(&o);
    assert!(
        text.contains("invocation reorder")
            && text.contains("micromaps")
            && text.contains("VK_NV_cluster_acceleration_structure"),
        "{text}"
    );
    let p: serde_json::Value = serde_json::from_slice(&std::fs::read(&prof).unwrap()).unwrap();
    let pc = &p["capabilities"]["rtprobe_caps"];
    for (name, e) in exts {
        assert_eq!(
            pc["extensions"].get(name).is_some(),
            e["present"] == true,
            "{name} in the profile"
        );
    }
    assert_eq!(pc["features"], v["features"]);
}

#[test]
fn caps_runs_clean_under_validation() {
    let o = run_env(&["caps", "--json"], &[("RTPROBE_VALIDATE", "1")]);
    let _ = json(&o);
    let err = stderr(&o);
    assert!(!err.contains("ERROR"), "validation errors: {err}");
}

#[test]
fn caps_text_and_profile_export() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let prof = dir.path().join("p.json");
    let out = dir.path().join("caps.json");
    let o = run(&["caps", "--profile", prof.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = stdout(&o);
    assert!(text.contains("RT pipeline yes"), "{text}");
    assert!(text.contains("descriptor_heap"), "{text}");
    let p: serde_json::Value = serde_json::from_slice(&std::fs::read(&prof).unwrap()).unwrap();
    assert!(p["$schema"].as_str().unwrap().contains("profiles"));
    let caps = &p["capabilities"]["rtprobe_caps"];
    assert!(caps["extensions"]["VK_KHR_ray_tracing_pipeline"].as_u64().is_some());
    assert_eq!(
        caps["features"]["VkPhysicalDeviceRayTracingPipelineFeaturesKHR"]["rayTracingPipeline"],
        true
    );
    let saved: serde_json::Value = serde_json::from_slice(&std::fs::read(&out).unwrap()).unwrap();
    assert_eq!(saved["schema"], "rtprobe.caps/2");
}

#[test]
fn devices_lists_lavapipe_as_rt_capable() {
    let o = run(&["devices"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    let line = out.lines().find(|l| l.contains("llvmpipe")).expect("llvmpipe listed");
    assert!(line.starts_with(|c: char| c.is_ascii_digit()), "{line}");
    assert!(line.contains("rt-pipeline: yes"), "{line}");
    assert!(line.contains("driver llvmpipe 25."), "decoded Mesa version: {line}");
    let v = json(&run(&["devices", "--json"]));
    assert!(v.as_array().unwrap().iter().any(|d| d["ray_tracing_pipeline"]["supported"] == true));
}

#[test]
fn missing_loader_is_one_line_exit_3() {
    let o = run_env(&["caps"], &[("RTPROBE_VULKAN_LIB", "/nonexistent/libvulkan.so.1")]);
    assert_one_line_error(&o, 3, "no Vulkan loader");
}

#[test]
fn missing_driver_is_one_line_exit_4() {
    let o = run_env(
        &["caps"],
        &[
            ("VK_DRIVER_FILES", "/nonexistent/icd.json"),
            ("VK_ICD_FILENAMES", "/nonexistent/icd.json"),
        ],
    );
    assert_one_line_error(&o, 4, "no Vulkan driver");
}

#[test]
fn device_without_rt_is_one_line_exit_5() {
    // Lavapipe without its RT extension, as an older driver would be.
    let hide = [("RTPROBE_HIDE_EXTENSIONS", "VK_KHR_ray_tracing_pipeline")];
    let o = run_env(&["caps"], &hide);
    assert_one_line_error(&o, 5, "no device can run ray tracing pipelines");
    assert!(stderr(&o).contains("VK_KHR_ray_tracing_pipeline"), "{}", stderr(&o));
    // Its caps can still be shown when asked for by index, saying what is missing, and the
    // RT stages are unsupported with that reason.
    let v = json(&run_env(&["caps", "--json", "--device", "0"], &hide));
    assert_eq!(v["ray_tracing_pipeline"]["supported"], false);
    assert_eq!(v["ray_tracing_pipeline"]["missing"][0], "VK_KHR_ray_tracing_pipeline");
    assert_eq!(v["matrix"]["stage"]["closest_hit"]["status"], "unsupported");
    assert_eq!(v["matrix"]["stage"]["compute"]["status"], "supported");
    assert_eq!(v["device_creation"]["ok"], true, "the device is still created, without RT");
}

#[test]
fn bad_device_selection_is_one_line_exit_6() {
    assert_one_line_error(&run(&["caps", "--device", "99"]), 6, "matches no device");
    assert_one_line_error(&run(&["caps", "--device", "no-such-gpu"]), 6, "matches no device");
}

#[test]
fn bad_arguments_exit_2_without_panic() {
    let o = run(&["caps", "--no-such-flag"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(!stderr(&o).contains("panicked"));
    let o = run(&["--help"]);
    assert!(o.status.success());
    assert!(stdout(&o).contains("Exit codes:"));
}

#[test]
fn unwritable_output_is_one_line_exit_9() {
    let o = run(&["caps", "-o", "/proc/nope/caps.json"]);
    assert_one_line_error(&o, 9, "/proc/nope/caps.json");
}

#[test]
fn reorder_cells_are_unsupported_on_lavapipe_with_the_reason() {
    let v = json(&run(&["caps", "--json"]));
    let has_ser = v["extensions"]["VK_NV_ray_tracing_invocation_reorder"]["present"] == true;
    for r in ["reorder", "reorder_hint"] {
        let s = &v["matrix"]["reorder"][r];
        assert_eq!(s["status"], if has_ser { "supported" } else { "unsupported" }, "{r}: {s}");
    }
    assert!(!has_ser, "lavapipe grew SER: the cells below would now run");
    // Every planned cell unsupported: the run has nothing to run and fails (exit 5) with the
    // device's reason; --list gives each cell's.
    let filter = "reorder=reorder|reorder_hint,descriptor_model=descriptor_indexing";
    let o = run(&["run", "--filter", filter]);
    assert_one_line_error(&o, 5, "VK_NV_ray_tracing_invocation_reorder");
    let o = run(&["run", "--list", "--filter", filter]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let listed: Vec<String> =
        stdout(&o).lines().filter(|l| !l.starts_with("not generated")).map(String::from).collect();
    let cells: Vec<&String> = listed.iter().filter(|l| l.contains(".reorder")).collect();
    // closest_hit x dynamic: 4 resources x (nonuniform or not) + AS (2 descriptor, 1 address, 2 patched), x 2 values
    assert_eq!(cells.len(), (4 * 2 + 5) * 2, "{listed:?}");
    for c in cells {
        assert!(c.starts_with("unsupported  closest_hit."), "{c}");
        assert!(c.contains("VK_NV_ray_tracing_invocation_reorder"), "{c}");
    }
}
