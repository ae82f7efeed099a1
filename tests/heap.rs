//! Descriptor heap cells. On the host's lavapipe (Mesa 25, no VK_EXT_descriptor_heap) they are
//! planned and `unsupported` with the device's reason. In the Debian sid root made by
//! scripts/setup-sid (lavapipe from Mesa 26 with VK_EXT_descriptor_heap), run through
//! scripts/in-sid with this build's binary, they run and are checked against the CPU reference;
//! those tests skip when the root is missing, unless RTPROBE_REQUIRE_SID=1 (as .ci/run sets).
mod common;
use common::*;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn repo() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// This build's rtprobe, inside the sid root.
fn in_sid(args: &[&str]) -> Output {
    in_sid_env(args, &[])
}

fn in_sid_env(args: &[&str], env: &[(&str, &str)]) -> Output {
    let mut c = Command::new(repo().join("scripts/in-sid"));
    c.arg(env!("CARGO_BIN_EXE_rtprobe"))
        .args(args)
        .env_remove("RUST_LOG")
        .env_remove("RTPROBE_VALIDATE")
        .env_remove("RTPROBE_GLSLANG");
    for (k, v) in env {
        c.env(k, v);
    }
    c.output().expect("spawn scripts/in-sid")
}

/// A report path under target/ (bind-mounted into the root at the same path).
fn report_path(name: &str) -> PathBuf {
    let dir = repo().join("target/heap-tests");
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join(format!("{name}-{}.json", std::process::id()));
    let _ = std::fs::remove_file(&p);
    p
}

/// `rtprobe run --filter FILTER` of heap cells in the root (no confirmation, no workarounds, plus
/// `extra` arguments), and its report.
fn run_in_sid(
    name: &str,
    filter: &str,
    extra: &[&str],
    env: &[(&str, &str)],
) -> (Output, serde_json::Value) {
    let mut args = vec!["--filter", filter, "--no-confirm", "--patches", "none"];
    args.extend_from_slice(extra);
    sid_report(name, &args, env)
}

/// `rtprobe run ARGS -o REPORT` in the root, and its report.
fn sid_report(name: &str, args: &[&str], env: &[(&str, &str)]) -> (Output, serde_json::Value) {
    let path = report_path(name);
    let mut all = vec!["run", "-o", path.to_str().unwrap()];
    all.extend_from_slice(args);
    let o = in_sid_env(&all, env);
    let report = serde_json::from_slice(
        &std::fs::read(&path).unwrap_or_else(|e| panic!("no report ({e}): {}", stderr(&o))),
    )
    .unwrap();
    (o, report)
}

fn list_counts(out: &str) -> (usize, usize, usize) {
    let n = |p: &str| out.lines().filter(|l| l.starts_with(p)).count();
    (n("run "), n("unsupported "), n("not_implemented "))
}

#[test]
fn sid_relative_output_paths_land_in_the_callers_folder() {
    if !have_sid() {
        return;
    }
    // A folder outside the repository: before, the root's shell fell back to `cd /` and the file
    // landed inside the root.
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let o = Command::new(repo().join("scripts/in-sid"))
        .current_dir(dir.path())
        .args([env!("CARGO_BIN_EXE_rtprobe"), "caps", "--no-device-check", "-o", "caps.json"])
        .env_remove("RTPROBE_VALIDATE")
        .output()
        .expect("spawn scripts/in-sid");
    assert!(o.status.success(), "{}", stderr(&o));
    let caps: serde_json::Value = serde_json::from_slice(
        &std::fs::read(dir.path().join("caps.json")).expect("caps.json where the caller is"),
    )
    .unwrap();
    assert_eq!(caps["schema"], "rtprobe.caps/2");
    assert!(!sid_root().join("caps.json").exists(), "nothing written inside the root");
}

#[test]
fn host_lavapipe_plans_heap_cells_as_unsupported_with_the_reason() {
    let o = run(&["run", "--list", "--filter", "descriptor_model=descriptor_heap"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    let (to_run, unsupported, not_implemented) = list_counts(&out);
    if to_run > 0 {
        eprintln!("skipped: this host's driver has VK_EXT_descriptor_heap");
        return;
    }
    assert!(unsupported > 0, "{out}");
    assert_eq!(not_implemented, 0, "the device's reason wins over rtprobe's own gaps: {out}");
    assert!(
        out.lines()
            .filter(|l| l.starts_with("unsupported "))
            .all(|l| l.contains("VK_EXT_descriptor_heap") || l.contains("descriptorHeap")),
        "{out}"
    );
    // Every heap access way is planned, none dropped.
    for way in [
        "mapped_constant_offset",
        "mapped_push_index",
        "mapped_indirect_index",
        "mapped_shader_record_index",
        "direct",
    ] {
        assert!(out.contains(&format!(".descriptor_heap.{way} ")), "{way} missing: {out}");
    }
    assert!(
        out.contains(&format!(
            "{} planned: 0 to run, {unsupported} unsupported, 0 not implemented in rtprobe",
            unsupported
        )),
        "{out}"
    );
}

#[test]
fn sid_plans_every_heap_cell_and_drops_none() {
    if !have_sid() {
        return;
    }
    let o = in_sid(&["run", "--list", "--filter", "descriptor_model=descriptor_heap"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    let (to_run, _, not_implemented) = list_counts(&out);
    assert!(to_run > 0, "lavapipe 26 has VK_EXT_descriptor_heap: {out}");
    // The root's glslang 16.6 compiles the direct way; only the as-to-address rewrite of its
    // untyped-pointer SPIR-V is rtprobe's gap there.
    assert!(not_implemented > 0);
    assert!(
        out.lines()
            .filter(|l| l.starts_with("not_implemented "))
            .all(|l| l.contains(".address_patched.descriptor_heap.direct ")
                && l.contains("as-to-address")),
        "{out}"
    );
    assert!(out.contains("compiler: heap_access=direct shaders by glslangValidator 16."), "{out}");
    for way in [
        "mapped_constant_offset",
        "mapped_push_index",
        "mapped_indirect_index",
        "mapped_shader_record_index",
        "direct",
    ] {
        assert!(
            out.lines()
                .any(|l| l.starts_with("run ") && l.ends_with(&format!(".descriptor_heap.{way}"))),
            "{way} runs: {out}"
        );
    }
    // Without a heap-capable GLSL compiler the direct way is rtprobe's own gap: planned and
    // counted as not_implemented with the reason, never dropped or blamed on the device.
    let o = in_sid_env(
        &["run", "--list", "--filter", "descriptor_model=descriptor_heap"],
        &[("RTPROBE_GLSLANG", "/nonexistent/glslangValidator")],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    let (to_run, unsupported, not_implemented) = list_counts(&out);
    assert!(not_implemented > 0, "{out}");
    assert!(
        out.lines()
            .filter(|l| l.starts_with("not_implemented "))
            .all(|l| l.contains(".descriptor_heap.direct") && l.contains("GL_EXT_descriptor_heap")),
        "{out}"
    );
    assert!(out.lines().filter(|l| l.starts_with("run ")).all(|l| l.contains(".mapped_")), "{out}");
    assert!(
        out.contains(&format!("{} planned: {to_run} to run, {unsupported} unsupported, {not_implemented} not implemented in rtprobe; ", to_run + unsupported + not_implemented)),
        "{out}"
    );
    assert!(
        !out.contains("not implemented in rtprobe:"),
        "nothing is moved to the not-generated list: {out}"
    );
}

#[test]
fn sid_the_pipeline_cache_save_error_is_said_once() {
    if !have_sid() {
        return;
    }
    // Lavapipe 26.2.6 returns a 20-byte vkGetPipelineCacheData: every save fails the same way.
    // The first run says so; later runs do not repeat it (their reports keep it).
    // Under target/ (the same path inside the root), fresh for this test.
    let cache = repo().join(format!("target/heap-tests/cache-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&cache);
    let env = [("RTPROBE_CACHE_DIR", cache.to_str().unwrap())];
    let filter =
        "stage=raygen,resource=storage_buffer,descriptor_model=descriptor_indexing,index=literal";
    let said = "not a valid cache";
    let (o, r) = sid_report("cache-once-1", &["--filter", filter], &env);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains(said), "the first run says it: {}", stdout(&o));
    assert!(r["pipeline_cache"]["save_errors"][0].as_str().unwrap().contains(said));
    let (o, r) = sid_report("cache-once-2", &["--filter", filter], &env);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!stdout(&o).contains(said), "said once: {}", stdout(&o));
    assert!(r["pipeline_cache"]["save_errors"][0].as_str().unwrap().contains(said), "kept");
}

#[test]
fn sid_runs_heap_cells_against_the_reference() {
    if !have_sid() {
        return;
    }
    // Every stage and resource kind, every heap access way, dynamic indices (the original
    // fault's shape, with and without nonuniformEXT). Without a compiler for the direct way
    // (forced here) its cells come out not_implemented, counted in the report and the summary.
    let (o, report) = run_in_sid(
        "heap-run",
        "descriptor_model=descriptor_heap,index=dynamic,base=push_data|none",
        &[],
        &[("RTPROBE_GLSLANG", "/nonexistent/glslangValidator")],
    );
    let cells = report["cells"].as_array().unwrap();
    let count = |f: &dyn Fn(&serde_json::Value) -> bool| cells.iter().filter(|c| f(c)).count();
    let outcome = |c: &serde_json::Value, o: &str| c["outcome"] == o;
    let pass = count(&|c| outcome(c, "pass"));
    let not_impl = count(&|c| outcome(c, "not_implemented"));
    assert_eq!(
        report["plan"]["planned"].as_u64().unwrap() as usize,
        cells.len(),
        "every planned cell is in the report"
    );
    assert_eq!(report["plan"]["not_implemented"].as_u64().unwrap() as usize, not_impl);
    assert!(
        not_impl > 0
            && cells
                .iter()
                .filter(|c| outcome(c, "not_implemented"))
                .all(|c| c["id"].as_str().unwrap().contains(".descriptor_heap.direct"))
    );
    for way in [
        "mapped_constant_offset",
        "mapped_push_index",
        "mapped_indirect_index",
        "mapped_shader_record_index",
    ] {
        let ran: Vec<_> = cells
            .iter()
            .filter(|c| c["id"].as_str().unwrap().ends_with(way) && c["outcome"] != "unsupported")
            .collect();
        assert!(!ran.is_empty(), "{way} cells ran");
    }
    for r in [
        "storage_buffer",
        "uniform_buffer",
        "sampled_image",
        "storage_image",
        "acceleration_structure",
    ] {
        assert!(
            cells.iter().any(|c| c["resource"] == r && outcome(c, "pass")),
            "a {r} heap cell passes"
        );
    }
    // Whatever did not pass is a finding with its reason (lavapipe's heap bugs; see
    // reports/lavapipe-26/FINDINGS.md), never a silent gap: the exit code says so.
    let findings = count(&|c| {
        !["pass", "not_implemented", "unsupported"].contains(&c["outcome"].as_str().unwrap())
    });
    assert!(pass > 0);
    assert_eq!(o.status.code(), Some(if findings > 0 { 1 } else { 0 }), "{}", stderr(&o));
    let summary = stdout(&o);
    assert!(
        !summary.contains("no faults or mismatches\n"),
        "the summary says cells did not run: {summary}"
    );
    assert!(summary.contains("not implemented in rtprobe"), "{summary}");
}

#[test]
fn sid_runs_direct_heap_cells_compiled_by_the_roots_glslang() {
    if !have_sid() {
        return;
    }
    // (Acceleration structures read straight from the heap are a lavapipe 26 finding: not here.)
    let filter = "descriptor_model=descriptor_heap,heap_access=direct,stage=closest_hit|compute,index=dynamic,resource=storage_buffer|uniform_buffer|sampled_image|storage_image,base=push_data|none";
    let (o, report) = run_in_sid("heap-direct", filter, &[], &[]);
    let cells = report["cells"].as_array().unwrap();
    assert_eq!(cells.len(), 20, "2 stages x (3 resources + sampled images with a constant and a dynamic sampler) x nonuniform or not");
    assert!(cells.iter().all(|c| c["outcome"] == "pass"), "{}", stdout(&o));
    // Heap modules declare DescriptorHeapEXT: every read is judged exactly, with or without
    // nonuniformEXT (glslang >= 16.4 omits the decoration on heap accesses on purpose), and the
    // cells without it say why they are exact.
    for c in cells {
        let r = &c["attempts"][0]["result"];
        assert!(r["comparison"]["element_reads"].is_null(), "{}: {r}", c["id"]);
        assert!(c["outside_spec"].is_null(), "{}", c["id"]);
        let exact_note = r["detail"].as_str().is_some_and(|d| d.contains("judged exactly"));
        assert_eq!(exact_note, c["nonuniform"] == false, "{}: {r}", c["id"]);
    }
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
}

/// `patch --glsl` of a source with an extension newer than shaderc's glslang
/// (GL_EXT_shader_invocation_reorder) goes to the root's glslangValidator, with its `-I`, `-D`
/// and `--target-env vulkan1.4` (which that glslang knows: no note).
#[test]
fn sid_patch_glsl_sends_a_newer_extension_to_the_roots_glslang() {
    if !have_sid() {
        return;
    }
    let dir = repo().join(format!("target/heap-tests/ser-{}", std::process::id()));
    std::fs::create_dir_all(dir.join("inc")).unwrap();
    std::fs::write(
        dir.join("inc/bindings.glsl"),
        "layout(binding = 1) buffer B { vec4 v; } bufs[COUNT];\n",
    )
    .unwrap();
    std::fs::write(
        dir.join("ser.rgen"),
        "#version 460\n#extension GL_EXT_ray_tracing : require\n#extension GL_EXT_shader_invocation_reorder : require\n#extension GL_EXT_nonuniform_qualifier : require\n#extension GL_GOOGLE_include_directive : require\n#include \"bindings.glsl\"\nlayout(binding = 0) uniform accelerationStructureEXT tlas;\nlayout(location = 0) rayPayloadEXT vec4 payload;\nlayout(push_constant) uniform P { uint i; } p;\nvoid main() {\n    hitObjectEXT h;\n    hitObjectTraceRayEXT(h, tlas, 0, 0xff, 0, 0, 0, vec3(0), 0.0, vec3(0, 0, 1), 10.0, 0);\n    reorderThreadEXT(h);\n    hitObjectExecuteShaderEXT(h, 0);\n    bufs[p.i].v = payload;\n}\n",
    )
    .unwrap();
    let src = dir.join("ser.rgen");
    let inc = dir.join("inc");
    let out = dir.join("ser.spv");
    let o = in_sid(&[
        "patch",
        src.to_str().unwrap(),
        "--glsl",
        "--stage",
        "rgen",
        "-I",
        inc.to_str().unwrap(),
        "-D",
        "COUNT=4",
        "--target-env",
        "vulkan1.4",
        "--apply",
        "nonuniform",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(!stderr(&o).contains("note:"), "{}", stderr(&o));
    let b = std::fs::read(&out).unwrap();
    assert_eq!(u32::from_le_bytes([b[4], b[5], b[6], b[7]]), 0x0001_0600);
    assert!(stdout(&o).contains("NonUniform"), "{}", stdout(&o));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn sid_runs_the_original_engines_base_sources_and_sampler_indices() {
    if !have_sid() {
        return;
    }
    // Issue 9's variables: the base of `base + gl_InstanceCustomIndexEXT` from push data, the SBT
    // shader record or a per-instance buffer, and a constant or dynamic index into the separate
    // sampler heap, read straight from the heap and through the push-index mapping.
    let filter = "descriptor_model=descriptor_heap,heap_access=direct|mapped_push_index,stage=closest_hit,index=dynamic,nonuniform=true,resource=storage_buffer|sampled_image";
    let (o, report) = run_in_sid("heap-base-sampler", filter, &[], &[]);
    let cells = report["cells"].as_array().unwrap();
    // 3 bases x (direct: SSBO + sampled image with 2 samplers; mapped: SSBO + sampled image)
    assert_eq!(cells.len(), 3 * (3 + 2), "{}", stdout(&o));
    for base in ["shader_record", "buffer"] {
        assert!(cells.iter().any(|c| c["base"] == base), "base={base} planned");
    }
    for sampler in ["constant", "dynamic"] {
        assert!(cells.iter().any(|c| c["sampler"] == sampler), "sampler={sampler} planned");
    }
    assert!(cells.iter().all(|c| c["outcome"] == "pass"), "{}", stdout(&o));
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    // With nonuniformEXT every read is exact, the heap's (no NonUniform needed) and the mapped
    // set/binding one's (its decoration reached the driver).
    for c in cells {
        let r = &c["attempts"][0]["result"];
        assert!(r["comparison"]["element_reads"].is_null(), "{}: {}", c["id"], r);
    }
    // Twin: a wrong value at the probed read of those cells mismatches.
    let (o, report) = run_in_sid(
        "heap-base-sampler-corrupt",
        filter,
        &["--inject-fault", &format!("{filter},base=shader_record|buffer@value")],
        &[],
    );
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    for c in report["cells"].as_array().unwrap() {
        let want = if c["base"].is_string() { "mismatch" } else { "pass" };
        assert_eq!(c["outcome"], want, "{}", c["id"]);
    }
}

/// A heap cell's report records every VkDescriptorSetAndBindingMappingEXT its pipeline's stages
/// got, member by member, for the vendor issue: binding 2 by the cell's way (its set, bindings,
/// strides and sampler members), the records and TLAS at constant offsets. The twin: the other
/// way's cell records another source, so the entries are the cell's, not a fixed text.
#[test]
fn sid_heap_reports_record_the_mapping_structs() {
    if !have_sid() {
        return;
    }
    let (_, report) = run_in_sid(
        "heap-mappings",
        "stage=closest_hit,resource=sampled_image,index=literal,descriptor_model=descriptor_heap,heap_access=mapped_shader_record_index|mapped_constant_offset",
        &[],
        &[],
    );
    let binding2 = |way: &str| {
        let c = report["cells"]
            .as_array()
            .unwrap()
            .iter()
            .find(|c| c["id"].as_str().unwrap().ends_with(way))
            .unwrap();
        let m = &c["attempts"][0]["result"]["comparison"]["heap"]["mappings"];
        assert_eq!(m.as_array().map(|a| a.len()), Some(3), "{way}: {m}");
        assert_eq!(
            (m[0]["first_binding"].as_u64(), m[1]["first_binding"].as_u64()),
            (Some(0), Some(1))
        );
        m[2].clone()
    };
    let record = binding2("mapped_shader_record_index");
    assert_eq!(
        (
            record["descriptor_set"].as_u64(),
            record["first_binding"].as_u64(),
            record["binding_count"].as_u64()
        ),
        (Some(0), Some(2), Some(1))
    );
    assert_eq!(record["source_member"], "shaderRecordIndex");
    let fields = record["fields"].to_string();
    for f in [
        r#"["heapIndexStride","64"]"#,
        r#"["pEmbeddedSampler","NULL"]"#,
        r#"["samplerShaderRecordOffset","0"]"#,
    ] {
        assert!(fields.contains(f), "{f} not in {fields}");
    }
    let constant = binding2("mapped_constant_offset");
    assert_eq!(constant["source"], "VK_DESCRIPTOR_MAPPING_SOURCE_HEAP_WITH_CONSTANT_OFFSET_EXT");
    assert_ne!(constant["fields"], record["fields"]);
}

#[test]
fn sid_heap_cells_are_checked_corrupted_expectations_mismatch() {
    if !have_sid() {
        return;
    }
    // The twin of the run above: with a wrong value injected at the probed read, a passing heap
    // cell must mismatch.
    let filter = "descriptor_model=descriptor_heap,stage=closest_hit,resource=storage_buffer,index=dynamic,nonuniform=true,heap_access=mapped_push_index,base=push_data";
    let inject = format!("{filter}@value");
    let (o, report) = run_in_sid("heap-corrupt", filter, &["--inject-fault", &inject], &[]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let cells = report["cells"].as_array().unwrap();
    assert_eq!(cells.len(), 1);
    assert_eq!(cells[0]["outcome"], "mismatch", "{}", cells[0]);
}

#[test]
fn sid_recommended_patterns_read_the_exact_element_and_layer_in_every_heap_way() {
    if !have_sid() {
        return;
    }
    // Issue 9's recommended patterns (index=dynamic_element: one SSBO at a spec-constant slot
    // read at a dynamic element offset; one texture2DArray sampled at a dynamic layer), in every
    // heap access way, checked exactly against the reference.
    let filter = "descriptor_model=descriptor_heap,index=dynamic_element,stage=closest_hit|compute,base=push_data|none";
    let (o, report) = run_in_sid("heap-patterns", filter, &[], &[]);
    let cells = report["cells"].as_array().unwrap();
    assert_eq!(
        cells.len(),
        2 * (5 + 4) + 2,
        "2 resources x (5 ways in closest-hit, 4 in compute), direct materials with both samplers"
    );
    for c in cells {
        let id = c["id"].as_str().unwrap();
        assert!(
            c["outcome"] != "unsupported" && c["outcome"] != "not_implemented",
            "{id}: {}",
            c["reason"]
        );
        let r = &c["attempts"][0]["result"];
        // (Every pattern cell is exact: a dynamic sampler index from the heap needs no
        // NonUniform.)
        if c["outcome"] == "pass" {
            let d = r["comparison"]["discrimination"].as_f64().unwrap();
            assert!(d >= 0.99, "{id}: every pixel would catch another element or layer ({d})");
        }
    }
    // The geometry pattern passes in every way, and both patterns read straight from the heap.
    let pass = |id: &str| {
        cells.iter().find(|c| c["id"] == id).unwrap_or_else(|| panic!("{id} planned"))["outcome"]
            == "pass"
    };
    assert!(
        cells.iter().filter(|c| c["resource"] == "storage_buffer").all(|c| c["outcome"] == "pass"),
        "{}",
        stdout(&o)
    );
    assert!(
        pass("closest_hit.sampled_image.dynamic_element.descriptor_heap.direct.sampler_constant"),
        "{}",
        stdout(&o)
    );
    assert!(
        pass("closest_hit.sampled_image.dynamic_element.descriptor_heap.direct.sampler_dynamic"),
        "{}",
        stdout(&o)
    );
    // Twin: a wrong value at the pattern's read must mismatch.
    let direct = "descriptor_model=descriptor_heap,heap_access=direct,index=dynamic_element,stage=closest_hit,base=push_data";
    let (o, report) = run_in_sid(
        "heap-patterns-corrupt",
        direct,
        &["--inject-fault", &format!("{direct}@value")],
        &[],
    );
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        report["cells"].as_array().unwrap().iter().all(|c| c["outcome"] == "mismatch"),
        "{}",
        stdout(&o)
    );
}

#[test]
fn sid_a_direct_heap_fault_says_whether_the_recommended_pattern_works() {
    if !have_sid() {
        return;
    }
    // The issue's shape faulting (an injected invalid-address load at the dynamic heap read, as
    // on the NVIDIA driver), with workarounds on: the run schedules each finding's recommended
    // pattern (outside the filter) and says per finding whether it works.
    let filter = "descriptor_model=descriptor_heap,heap_access=direct,stage=closest_hit,index=dynamic,nonuniform=false,resource=storage_buffer|sampled_image,base=push_data,sampler=dynamic|none";
    let (o, report) = sid_report(
        "heap-pattern-finding",
        &["--filter", filter, "--no-confirm", "--inject-fault", &format!("{filter}@device")],
        &[],
    );
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let cells = report["cells"].as_array().unwrap();
    for (id, pattern) in [
        ("closest_hit.storage_buffer.dynamic.descriptor_heap.direct", "geometry"),
        ("closest_hit.sampled_image.dynamic.descriptor_heap.direct.sampler_dynamic", "materials"),
    ] {
        let f = cells.iter().find(|c| c["id"] == id).unwrap();
        assert_eq!(f["outcome"], "crash", "{}", f["reason"]);
        let p = &f["recommended"];
        assert_eq!(
            (p["pattern"].as_str(), p["status"].as_str()),
            (Some(pattern), Some("passes")),
            "{p}"
        );
        assert!(stdout(&o).contains(&format!("recommended pattern {pattern} (")), "{}", stdout(&o));
    }
}

#[test]
fn sid_gpu_av_reruns_heap_findings_with_a_control() {
    if !have_sid() {
        return;
    }
    // The root's layers (1.4.363) know VK_EXT_descriptor_heap: heap findings run under GPU-AV with
    // their literal-index control. Whatever GPU-AV does is recorded (reports/lavapipe-26/FINDINGS.md
    // #4: it crashes closest-hit heap pipelines), never hidden and never mixed into the cell's verdict.
    let filter = "descriptor_model=descriptor_heap,heap_access=direct,stage=closest_hit|compute,resource=storage_buffer,index=dynamic|literal,nonuniform=false";
    let (o, report) = run_in_sid(
        "heap-gpu-av",
        filter,
        &["--validate=gpu-av", "--inject-fault", "index=dynamic@device"],
        &[],
    );
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let cells = report["cells"].as_array().unwrap();
    for stage in ["closest_hit", "compute"] {
        let f = cells
            .iter()
            .find(|c| c["id"] == format!("{stage}.storage_buffer.dynamic.descriptor_heap.direct"))
            .unwrap();
        assert_eq!(f["attempts"].as_array().unwrap().len(), 1);
        let v = &f["gpu_av"];
        let control =
            v["control"].as_array().unwrap_or_else(|| panic!("{stage}: a control ran: {v}"));
        let control_faulted =
            !["pass", "unsupported", "not_implemented"].contains(&control[1].as_str().unwrap());
        let verdict = v["verdict"].as_str().unwrap();
        assert!(
            ["masked", "inconclusive", "still_faults", "gpu_av_failed"].contains(&verdict),
            "{stage}: {v}"
        );
        if !["masked", "inconclusive"].contains(&verdict) {
            assert_eq!(verdict == "gpu_av_failed", control_faulted, "{stage}: {v}");
        }
        assert!(stdout(&o).contains("GPU-AV: "), "{}", stdout(&o));
    }
}

/// `module` with the descriptor index of its first access into the probed array (the resource
/// heap, or set 0 binding 2) replaced by a 32-bit integer constant 0 of the module's own (valid SPIR-V: what a
/// driver reading element 0 for every lane would do).
fn first_probed_index_zeroed(module: &[u32]) -> Vec<u32> {
    let mut w = module.to_vec();
    let insts = |w: &[u32]| {
        let mut at = Vec::new();
        let mut i = 5;
        while i < w.len() && w[i] >> 16 != 0 {
            at.push(i);
            i += (w[i] >> 16) as usize;
        }
        at
    };
    let at = insts(&w);
    let op = |i: usize| w[i] & 0xffff;
    // OpDecorate %x BuiltIn ResourceHeapEXT, or OpDecorate %x Binding 2
    let base = at
        .iter()
        .find(|&&i| op(i) == 71 && (w[i + 2..i + 4] == [11, 5123] || w[i + 2..i + 4] == [33, 2]))
        .map(|&i| w[i + 1])
        .expect("the probed array");
    let ints: Vec<u32> =
        at.iter().filter(|&&i| op(i) == 21 && w[i + 2] == 32).map(|&i| w[i + 1]).collect();
    let zero = at
        .iter()
        .find(|&&i| op(i) == 43 && ints.contains(&w[i + 1]) && w[i + 3] == 0)
        .map(|&i| w[i + 2])
        .expect("a 32-bit integer constant 0");
    let chain = at
        .iter()
        .find_map(|&i| match op(i) {
            65 | 66 if w[i + 3] == base => Some(i + 4),
            4419 | 4420 if w[i + 4] == base => Some(i + 5),
            _ => None,
        })
        .expect("an access into the probed array");
    w[chain] = zero;
    w
}

/// Issue 21, item 1: a direct heap read whose heap index the driver replaced by 0 (the bundle's
/// closest-hit SPIR-V edited so) is a mismatch, as its descriptor-indexing twin is; before, the
/// heap cell was judged as an undefined read and passed (exit 0).
#[test]
fn sid_a_direct_heap_read_of_index_zero_is_a_mismatch() {
    if !have_sid() {
        return;
    }
    for (model, id) in [
        (
            "descriptor_heap,heap_access=direct",
            "closest_hit.storage_buffer.dynamic.nonuniform.descriptor_heap.direct",
        ),
        (
            "descriptor_indexing",
            "closest_hit.storage_buffer.dynamic.nonuniform.descriptor_indexing",
        ),
    ] {
        let filter = format!("descriptor_model={model},stage=closest_hit,resource=storage_buffer,index=dynamic,nonuniform=true,base=push_data");
        let name = model.split(',').next().unwrap();
        let (o, _) = run_in_sid(&format!("zero-{name}"), &filter, &[], &[]);
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        // (the report run_in_sid wrote: report_path would remove it)
        let from = repo()
            .join("target/heap-tests")
            .join(format!("zero-{name}-{}.json", std::process::id()));
        let bundle = from.with_extension("bundle");
        let o = in_sid(&[
            "repro",
            "--force",
            "--from",
            from.to_str().unwrap(),
            id,
            "-o",
            bundle.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        for file in ["closest_hit_triangles.rchit.spv", "closest_hit_procedural.rchit.spv"] {
            let p = bundle.join("shaders").join(file);
            let words: Vec<u32> = std::fs::read(&p)
                .unwrap()
                .chunks_exact(4)
                .map(|c| u32::from_le_bytes(c.try_into().unwrap()))
                .collect();
            let zeroed: Vec<u8> =
                first_probed_index_zeroed(&words).iter().flat_map(|x| x.to_le_bytes()).collect();
            std::fs::write(&p, zeroed).unwrap();
        }
        let out = report_path(&format!("zero-{name}-rerun"));
        let spec = bundle.join("cell.json");
        let o = in_sid(&[
            "run",
            "--cell-spec",
            spec.to_str().unwrap(),
            "--no-confirm",
            "-o",
            out.to_str().unwrap(),
        ]);
        assert_eq!(o.status.code(), Some(1), "{id}: {}{}", stdout(&o), stderr(&o));
        let report: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
        let c = &report["cells"][0];
        assert_eq!(c["outcome"], "mismatch", "{id}: {}", c["attempts"][0]["result"]);
        let cmp = &c["attempts"][0]["result"]["comparison"];
        assert!(cmp["element_reads"].is_null(), "{id}: judged exactly: {cmp}");
        assert!(cmp["by_field"]["value"].as_u64().unwrap() > 1000, "{id}: {cmp}");
    }
}

/// `args` run in the sid root with `-o` a report named `name`: the report, the exit code 0
/// asserted.
fn sid_shader_report(name: &str, args: &[&str]) -> serde_json::Value {
    let path = report_path(name);
    let mut all = args.to_vec();
    all.extend(["-o", path.to_str().unwrap()]);
    let o = in_sid(&all);
    let r: serde_json::Value = serde_json::from_slice(
        &std::fs::read(&path).unwrap_or_else(|e| panic!("no report ({e}): {}", stderr(&o))),
    )
    .unwrap();
    assert_eq!(o.status.code(), Some(0), "{}{}", stdout(&o), stderr(&o));
    r
}

/// Issue #24: a heap closest-hit like the original fault (a `layout(descriptor_heap)` SSBO
/// array indexed by a push-data base plus gl_InstanceCustomIndexEXT) run with `--shader` on
/// lavapipe 26 under `--validate`: the heap model chosen, no validation message, no fault, and
/// every patched variant's outputs those of the unpatched pipeline.
#[test]
fn sid_a_heap_closest_hit_runs_clean_with_shader() {
    if !have_sid() {
        return;
    }
    let shader = repo().join("tests/shaders/user/heap.rchit");
    let args = ["run", "--validate", "--repeat", "2", "--shader", shader.to_str().unwrap()];
    let r = sid_shader_report("shader-heap", &args);
    assert_eq!(r["options"]["descriptor_model"], "descriptor_heap");
    let variants = r["variants"].as_array().unwrap();
    let reference = &variants[0]["attempts"][0]["outputs"];
    assert!(reference.as_array().is_some_and(|a| !a.is_empty()), "{reference}");
    for v in variants {
        assert_eq!(v["outcome"], "pass", "{v}");
        let attempts = v["attempts"].as_array().unwrap();
        assert_eq!(attempts.len(), 2);
        for a in attempts {
            assert_eq!(a["outcome"], "pass", "{a}");
            assert_eq!(a["validation_messages"], 0, "{a}");
            assert_eq!(&a["outputs"], reference, "{}", v["name"]);
        }
    }
    // The heap's data reaches the outputs: the index shifted by one reads other descriptors,
    // each with data of its own, so the outputs differ; the same ranges given as a
    // --heap-layout file change nothing.
    let run = |name: &str, extra: &[&str]| {
        let mut all = vec!["run", "--repeat", "1", "--shader", shader.to_str().unwrap()];
        all.extend_from_slice(extra);
        sid_shader_report(name, &all)["variants"][0]["attempts"][0]["outputs"].clone()
    };
    let shifted = run("shader-heap-shift", &["-D", "MATERIAL_SHIFT=1"]);
    assert_ne!(&shifted, reference, "another index, other descriptors");
    let layout = repo().join("target/heap-tests/layout.json");
    std::fs::write(
        &layout,
        r#"{"resource": [{"kind": "storage_buffer", "first": 0, "count": 128}]}"#,
    )
    .unwrap();
    let given = run("shader-heap-layout", &["--heap-layout", layout.to_str().unwrap()]);
    assert_eq!(&given, reference, "the inferred layout, given as a file");
    // The twin: one attempt's output flipped is a difference the report shows.
    let path = report_path("shader-heap-flip");
    let mut all = args.to_vec();
    all.extend(["-o", path.to_str().unwrap()]);
    let o = in_sid_env(&all, &[("RTPROBE_SHADER_FAULT", "flip:unpatched:2")]);
    let r: serde_json::Value = serde_json::from_slice(
        &std::fs::read(&path).unwrap_or_else(|e| panic!("no report ({e}): {}", stderr(&o))),
    )
    .unwrap();
    assert_ne!(o.status.code(), Some(0), "{}", stdout(&o));
    assert!(r["variants"][0]["attempts"][1]["differs"].is_string(), "{}", r["variants"][0]);
}
