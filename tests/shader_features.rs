//! `run --shader` enables what the user's modules' capabilities need (issue 24, review
//! finding): a half-precision closest-hit with 16-bit storage and a closest-hit with a
//! ray-query shadow test run under `--validate` with no message where the device has the
//! features (else they are refused in one line naming the feature), and an old DXC module
//! with `SPV_NV_ray_tracing` is refused in one line before any device work.
mod common;
use common::*;
use serde_json::Value;
use std::path::{Path, PathBuf};

fn user() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/shaders/user")
}

/// `run --validate --shader FILE -o DIR/report.json`: the output and the report, if written.
fn run_one(file: &Path) -> (std::process::Output, Option<Value>) {
    let d = rtprobe::tempdir::tempdir().unwrap();
    let out = d.path().join("report.json");
    let o = run(&[
        "run",
        "--validate",
        "--shader",
        file.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    let report = std::fs::read(&out).ok().map(|b| serde_json::from_slice(&b).unwrap());
    (o, report)
}

/// The device's feature `member` of `strukt`, as `caps --json` reports it.
fn device_has(caps: &Value, strukt: &str, member: &str) -> bool {
    caps["features"][strukt][member].as_bool().unwrap_or(false)
}

/// Every attempt passed with no validation message; the verdict is PASS.
fn assert_clean(o: &std::process::Output, r: &Value) {
    assert_eq!(o.status.code(), Some(0), "{}{}", stdout(o), stderr(o));
    for variant in r["variants"].as_array().unwrap() {
        assert_eq!(variant["outcome"], "pass", "{variant}");
        for a in variant["attempts"].as_array().unwrap() {
            assert_eq!(a["validation_messages"], 0, "{a}");
        }
    }
    assert!(stdout(o).lines().last().unwrap().starts_with("verdict: PASS"), "{}", stdout(o));
}

/// A closest-hit in float16 over a 16-bit storage buffer: where the device has shaderFloat16
/// and storageBuffer16BitAccess, clean under `--validate` (without the enabling it fails with
/// VUID-VkShaderModuleCreateInfo-pCode-08740); else one line naming the missing feature.
#[test]
fn a_half_precision_closest_hit_gets_its_features() {
    let caps = json(&run(&["caps", "--json"]));
    let has = device_has(&caps, "VkPhysicalDeviceVulkan12Features", "shaderFloat16")
        && device_has(&caps, "VkPhysicalDeviceVulkan11Features", "storageBuffer16BitAccess");
    let (o, r) = run_one(&user().join("half.rchit"));
    if has {
        let r = r.unwrap_or_else(|| panic!("no report: {}", stderr(&o)));
        assert_clean(&o, &r);
    } else {
        assert!(r.is_none(), "no report on a device without 16-bit floats");
        assert_one_line_error(&o, 5, "shaderFloat16");
    }
}

/// A closest-hit testing its shadow with a ray query: clean under `--validate` where the device
/// reports rayQuery (VK_KHR_ray_query enabled from the module's RayQueryKHR); else, and on the
/// device with VK_KHR_ray_query hidden, refused in one line naming it.
#[test]
fn a_ray_query_shadow_in_a_closest_hit_gets_ray_query() {
    let caps = json(&run(&["caps", "--json"]));
    let has = device_has(&caps, "VkPhysicalDeviceRayQueryFeaturesKHR", "rayQuery");
    let (o, r) = run_one(&user().join("rayquery_shadow.rchit"));
    if has {
        let r = r.unwrap_or_else(|| panic!("no report: {}", stderr(&o)));
        assert_clean(&o, &r);
    } else {
        assert!(r.is_none());
        assert_one_line_error(&o, 5, "rayQuery (VK_KHR_ray_query)");
    }
    // Twin: the device without VK_KHR_ray_query (hidden) is refused, naming it; no report.
    let d = rtprobe::tempdir::tempdir().unwrap();
    let out = d.path().join("report.json");
    let hit = user().join("rayquery_shadow.rchit");
    let args = ["run", "--shader", hit.to_str().unwrap(), "-o", out.to_str().unwrap()];
    let o = run_env(&args, &[("RTPROBE_HIDE_EXTENSIONS", "VK_KHR_ray_query")]);
    assert_one_line_error(&o, 5, "rayQuery (VK_KHR_ray_query)");
    assert!(!out.exists(), "no report");
}

/// An old DXC closest-hit (RayTracingNV, SPV_NV_ray_tracing) is refused before any device
/// work in one line saying how to recompile it; no report. Its twin, the same closest-hit
/// assembled as SPV_KHR_ray_tracing, is not refused for its capabilities.
#[test]
fn an_nv_ray_tracing_module_is_refused_in_one_line() {
    let d = rtprobe::tempdir::tempdir().unwrap();
    let src = std::fs::read_to_string(user().join("nv_closest.rchit.spvasm")).unwrap();
    let assemble = |text: &str, name: &str| {
        let (asm, spv) = (d.path().join(format!("{name}.spvasm")), d.path().join(name));
        std::fs::write(&asm, text).unwrap();
        rtprobe::tools::spirv::assemble(&asm, &spv, "vulkan1.2").unwrap();
        spv
    };
    let (o, r) = run_one(&assemble(&src, "nv.rchit.spv"));
    assert!(r.is_none(), "no report");
    assert_one_line_error(
        &o,
        9,
        "recompile with `-fspv-target-env=vulkan1.2` (SPV_KHR_ray_tracing)",
    );
    assert!(stderr(&o).contains("SPV_NV_ray_tracing"), "{}", stderr(&o));
    let khr = src
        .replace("OpCapability RayTracingNV", "OpCapability RayTracingKHR")
        .replace("SPV_NV_ray_tracing", "SPV_KHR_ray_tracing");
    let (o, _r) = run_one(&assemble(&khr, "khr.rchit.spv"));
    assert!(!stderr(&o).contains("SPV_NV_ray_tracing"), "{}", stderr(&o));
    assert_eq!(o.status.code(), Some(0), "{}{}", stdout(&o), stderr(&o));
}
