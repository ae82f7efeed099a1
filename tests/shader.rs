//! End-to-end tests of `rtprobe run --shader` on lavapipe: engine-like pipelines written for
//! these tests (`tests/shaders/user/`, with an `#include` of a common file) run under
//! `--validate` with no message, no fault and the same outputs in every attempt and every
//! patched variant; their twins (the child crashing in one attempt, one attempt's output
//! flipped) fail with the attempts recorded; bad input is one line, a non-zero exit and no
//! report.
mod common;
use common::*;
use serde_json::Value;
use std::path::{Path, PathBuf};

fn user() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/shaders/user")
}

/// `run --validate --shader F…` with `extra` and `env`; the output and the report, if written.
fn shader_run(
    files: &[&str],
    extra: &[&str],
    env: &[(&str, &str)],
) -> (std::process::Output, Option<Value>, rtprobe::tempdir::TempDir) {
    let d = rtprobe::tempdir::tempdir().unwrap();
    let (o, report) = run_user_shaders(files, &d.path().join("report.json"), extra, env);
    (o, report, d)
}

fn variants(r: &Value) -> &Vec<Value> {
    r["variants"].as_array().unwrap()
}

fn attempts(v: &Value) -> &Vec<Value> {
    v["attempts"].as_array().unwrap()
}

/// Every attempt of every variant: passed, no validation message, the outputs of the unpatched
/// pipeline's first attempt; at least `min_variants` variants, `repeat` attempts each.
fn assert_clean(o: &std::process::Output, r: &Value, min_variants: usize, repeat: usize) {
    assert_eq!(o.status.code(), Some(0), "{}{}", stdout(o), stderr(o));
    assert_eq!(r["schema"], "rtprobe.shader-run/1");
    assert!(r["cell"].as_str().unwrap().starts_with("shader:raygen.rgen@"), "{}", r["cell"]);
    let v = variants(r);
    assert!(v.len() >= min_variants, "{}", stdout(o));
    assert_eq!(v[0]["name"], "unpatched");
    let reference = &attempts(&v[0])[0]["outputs"];
    assert!(!reference.as_array().unwrap().is_empty(), "outputs were hashed");
    for variant in v {
        assert_eq!(variant["outcome"], "pass", "{variant}");
        assert_eq!(attempts(variant).len(), repeat);
        for a in attempts(variant) {
            assert_eq!(a["outcome"], "pass");
            assert_eq!(a["validation_messages"], 0, "{a}");
            assert_eq!(&a["outputs"], reference, "{}", variant["name"]);
        }
    }
    assert!(stdout(o).lines().last().unwrap().starts_with("verdict: PASS"), "{}", stdout(o));
}

/// (a) A raygen with its own payload, a miss, and a bindless closest-hit indexing an SSBO array
/// and a storage-image array by a push-constant base plus gl_InstanceCustomIndexEXT: clean
/// unpatched and under as-to-address and ssbo-to-address, with the colour target dumped.
#[test]
fn a_bindless_closest_hit_runs_clean_in_every_variant() {
    let dump = rtprobe::tempdir::tempdir().unwrap();
    let dir = dump.path().to_str().unwrap();
    let (o, r, _d) = shader_run(
        &["raygen.rgen", "miss.rmiss", "bindless.rchit"],
        &["--repeat", "2", "--dump", dir],
        &[],
    );
    let r = r.unwrap_or_else(|| panic!("no report: {}", stderr(&o)));
    assert_clean(&o, &r, 3, 2);
    let names: Vec<&str> = variants(&r).iter().map(|v| v["name"].as_str().unwrap()).collect();
    assert!(names.contains(&"ssbo-to-address") && names.contains(&"as-to-address"), "{names:?}");
    let png = dump.path().join("unpatched-1-set-0-binding-1-0.png");
    assert!(std::fs::read(&png).is_ok_and(|b| b.starts_with(b"\x89PNG")), "{}", png.display());
}

/// Issue #24 (textures): bindless closest-hits indexing an SSBO array and a texture array by a
/// push-constant base plus gl_InstanceCustomIndexEXT, `nonuniformEXT` — combined image samplers,
/// and separate `texture2D[]` with a `sampler` — clean in every variant: no validation message,
/// no fault, the same outputs.
#[test]
fn bindless_textured_closest_hits_run_clean_in_every_variant() {
    for hit in ["textured.rchit", "textured_split.rchit"] {
        let (o, r, _d) = shader_run(&["raygen.rgen", "miss.rmiss", hit], &["--repeat", "2"], &[]);
        let r = r.unwrap_or_else(|| panic!("{hit}: no report: {}", stderr(&o)));
        assert_clean(&o, &r, 2, 2);
    }
}

/// Issue #24 (textures): a glTF-style closest-hit — a scene-description SSBO of buffer-reference
/// addresses and per-mesh offsets, the base colour from `textureSamplers[nonuniformEXT(txtId)]`
/// — clean in every variant.
#[test]
fn a_gltf_closest_hit_with_textures_runs_clean_in_every_variant() {
    let (o, r, _d) =
        shader_run(&["raygen.rgen", "miss.rmiss", "gltf.rchit"], &["--repeat", "2"], &[]);
    let r = r.unwrap_or_else(|| panic!("no report: {}", stderr(&o)));
    assert_clean(&o, &r, 2, 2);
}

/// `--array-size` and `--sink-size` reach the children: a texture array of 128 elements and a
/// 64 KiB sink run clean, recorded in the report's options; out of their bounds, one line.
#[test]
fn array_and_sink_sizes_are_taken_and_checked() {
    let files = ["raygen.rgen", "miss.rmiss", "gltf.rchit"];
    let sized = ["--repeat", "1", "--array-size", "128", "--sink-size", "65536"];
    let (o, r, _d) = shader_run(&files, &sized, &[]);
    let r = r.unwrap_or_else(|| panic!("no report: {}", stderr(&o)));
    assert_clean(&o, &r, 2, 1);
    assert_eq!(
        (&r["options"]["array_size"], &r["options"]["sink_size"]),
        (&128.into(), &65536.into())
    );
    for (flag, value, needle) in [
        ("--array-size", "0", "--array-size 0: give 1 to 65536 elements"),
        ("--array-size", "65537", "--array-size 65537: give 1 to 65536"),
        ("--sink-size", "8", "--sink-size 8: give 16 to 1073741824 bytes"),
        ("--sink-size", "2000000000", "--sink-size 2000000000: give 16"),
    ] {
        let (o, r, _d) = shader_run(&files, &[flag, value], &[]);
        assert_one_line_error(&o, 2, needle);
        assert!(r.is_none(), "no report for {flag} {value}");
    }
}

/// (f) The bindless closest-hit given alone: rtprobe supplies a raygen sending its payload type
/// and a miss; clean in every variant, the supplied raygen's payload words among the outputs.
#[test]
fn a_closest_hit_alone_runs_with_supplied_stages() {
    let (o, r, _d) = shader_run(&["bindless.rchit"], &["--repeat", "2"], &[]);
    let r = r.unwrap_or_else(|| panic!("no report: {}", stderr(&o)));
    assert_eq!(o.status.code(), Some(0), "{}{}", stdout(&o), stderr(&o));
    assert!(r["cell"].as_str().unwrap().starts_with("shader:bindless.rchit@"), "{}", r["cell"]);
    let v = variants(&r);
    let reference = &attempts(&v[0])[0]["outputs"];
    // the colour target and the supplied raygen's payload words: more than one output
    assert!(reference.as_array().unwrap().len() >= 2, "{reference}");
    for variant in v {
        assert_eq!(variant["outcome"], "pass", "{variant}");
        for a in attempts(variant) {
            assert_eq!(a["validation_messages"], 0, "{a}");
            assert_eq!(&a["outputs"], reference, "{}", variant["name"]);
        }
    }
}

/// A closest-hit alone passing in every variant, no validation message, the same outputs.
fn assert_alone_clean(file: &str) {
    let (o, r, _d) = shader_run(&[file], &["--repeat", "2"], &[]);
    let r = r.unwrap_or_else(|| panic!("no report: {}", stderr(&o)));
    assert_eq!(o.status.code(), Some(0), "{}{}", stdout(&o), stderr(&o));
    let v = variants(&r);
    let reference = &attempts(&v[0])[0]["outputs"];
    for variant in v {
        assert_eq!(variant["outcome"], "pass", "{variant}");
        for a in attempts(variant) {
            assert_eq!(a["validation_messages"], 0, "{a}");
            assert_eq!(&a["outputs"], reference, "{}", variant["name"]);
        }
    }
}

/// (g) Issue #24: an "ObjDesc" closest-hit dereferencing the `uint64_t` vertex and index
/// addresses its SSBO holds: the harness fills them with its sink buffer's address, so the
/// child reads zeros instead of crashing on a small integer taken for a pointer.
#[test]
fn an_objdesc_closest_hit_dereferences_the_sink() {
    assert_alone_clean("objdesc.rchit");
}

/// (h) Two blocks aliased at one set/binding are one binding of the larger size: clean.
#[test]
fn aliased_blocks_at_one_binding_run_clean() {
    assert_alone_clean("aliased.rchit");
}

/// (h) Twin: a storage and a uniform buffer at one binding cannot be one descriptor: refused
/// before any child, one line, exit 9, no report.
#[test]
fn incompatible_kinds_at_one_binding_are_refused_at_plan_time() {
    let d = rtprobe::tempdir::tempdir().unwrap();
    let f = d.path().join("clash.rchit");
    std::fs::write(&f, "#version 460\n#extension GL_EXT_ray_tracing : require\nlayout(set = 1, binding = 0) readonly buffer S { vec4 s[]; } sb;\nlayout(set = 1, binding = 0) uniform U { vec4 u; } ub;\nlayout(location = 0) rayPayloadInEXT vec4 p;\nvoid main() { p = sb.s[1] + ub.u; }\n").unwrap();
    let (o, r, _d2) = shader_run(&[f.to_str().unwrap()], &[], &[]);
    assert_one_line_error(
        &o,
        9,
        "set 1 binding 0 is declared as a storage buffer and as a uniform buffer",
    );
    assert!(r.is_none(), "no report");
}

/// (b) An any-hit alpha test beside a plain closest-hit.
#[test]
fn an_any_hit_alpha_test_runs_clean() {
    let (o, r, _d) = shader_run(
        &["raygen.rgen", "miss.rmiss", "plain.rchit", "alpha.rahit"],
        &["--repeat", "2"],
        &[],
    );
    assert_clean(&o, &r.expect("report"), 2, 2);
}

/// (c) An intersection shader with its hit attributes, read by the sphere's closest-hit.
#[test]
fn an_intersection_shader_with_hit_attributes_runs_clean() {
    let files = ["raygen.rgen", "miss.rmiss", "plain.rchit", "sphere.rint", "sphere.rchit"];
    let (o, r, _d) = shader_run(&files, &["--repeat", "2"], &[]);
    let r = r.expect("report");
    assert_clean(&o, &r, 2, 2);
    let stages: Vec<&str> =
        r["inputs"].as_array().unwrap().iter().map(|i| i["stage"].as_str().unwrap()).collect();
    assert_eq!(stages, ["raygen", "miss", "closest_hit", "intersection", "closest_hit"]);
}

/// (e) Twin: the child crashes in the unpatched pipeline's second attempt. The crash is a
/// finding with its incidence, attempts 1 and 3 ran in other children, rtprobe exits 1.
#[test]
fn a_child_crash_is_a_finding_with_its_attempts() {
    let env = [("RTPROBE_SHADER_FAULT", "crash:unpatched:2")];
    let (o, r, _d) = shader_run(&["raygen.rgen", "miss.rmiss", "plain.rchit"], &[], &env);
    assert_eq!(o.status.code(), Some(1), "{}{}", stdout(&o), stderr(&o));
    let r = r.expect("the report is written");
    let u = &variants(&r)[0];
    let outcomes: Vec<&str> = attempts(u).iter().map(|a| a["outcome"].as_str().unwrap()).collect();
    assert_eq!(outcomes, ["pass", "crash", "pass"]);
    assert_eq!((u["outcome"].as_str(), u["judgement"].as_str()), (Some("crash"), Some("fault")));
    assert_eq!(
        (&u["incidence"]["faulted"], &u["incidence"]["attempts"]),
        (&Value::from(1), &Value::from(3))
    );
    assert!(attempts(u)[1]["detail"].as_str().unwrap().contains("signal 11"), "{u}");
    assert_eq!(r["outcome"], "crash");
    assert!(stdout(&o).contains("verdict: FAIL"), "{}", stdout(&o));
}

/// (e) Twins of the differential checks: one unpatched attempt's output flipped is `unstable`;
/// a patched variant's flipped is a mismatch naming the patch and the output.
#[test]
fn differing_outputs_are_unstable_or_the_patchs() {
    let files = ["raygen.rgen", "miss.rmiss", "plain.rchit"];
    let (o, r, _d) =
        shader_run(&files, &["--repeat", "2"], &[("RTPROBE_SHADER_FAULT", "flip:unpatched:2")]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let u = &variants(r.as_ref().unwrap())[0];
    assert_eq!(
        (u["outcome"].as_str(), u["judgement"].as_str()),
        (Some("mismatch"), Some("unstable"))
    );
    assert!(
        u["detail"].as_str().unwrap().contains("attempt 2's set 0 binding 1[0] differs"),
        "{u}"
    );
    let (o, r, _d) =
        shader_run(&files, &["--repeat", "2"], &[("RTPROBE_SHADER_FAULT", "flip:as-to-address")]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let r = r.unwrap();
    let v: Vec<&Value> = variants(&r).iter().filter(|v| v["name"] == "as-to-address").collect();
    assert_eq!(
        (v[0]["outcome"].as_str(), v[0]["judgement"].as_str()),
        (Some("mismatch"), Some("patch_differs"))
    );
    assert!(
        v[0]["detail"].as_str().unwrap().starts_with("as-to-address: the patched pipeline's"),
        "{}",
        v[0]
    );
    assert_eq!(variants(&r)[0]["outcome"], "pass");
}

/// (d) Bad input: one line naming the thing, a non-zero exit, no report.
#[test]
fn bad_input_is_one_line_and_no_report() {
    let cases: &[(&[&str], &[&str], i32, &str)] = &[
        (&["raygen.rgen", "missing.rmiss"], &[], 9, "missing.rmiss"),
        (&["raygen.rgen", "miss.rmiss", "bad.rchit"], &[], 9, "bad.rchit"),
        (&["raygen.rgen", "common.glsl"], &[], 2, "cannot tell the stage"),
        (
            &["raygen.rgen", "miss.rmiss"],
            &["--filter", "stage=raygen"],
            2,
            "--filter cannot be used with --shader",
        ),
        (&["raygen.rgen", "miss.rmiss"], &["--repeat", "0"], 2, "--repeat 0"),
        (
            &["raygen.rgen", "miss.rmiss"],
            &["--inject-fault", "descriptor_model=descriptor_heap"],
            2,
            "takes stage, resource, index",
        ),
        (
            &["raygen.rgen", "miss.rmiss"],
            &["--inject-fault", "stage=raygen@value:0.5"],
            2,
            "needs a CPU reference",
        ),
    ];
    for (files, extra, code, needle) in cases {
        let (o, r, _d) = shader_run(files, extra, &[]);
        assert_one_line_error(&o, *code, needle);
        assert!(r.is_none(), "no report for {files:?} {extra:?}");
    }
    // A closest-hit alone whose payload holds a pointer: no raygen can be generated for it.
    let node =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/patch-corpus/alone/node.rchit");
    let (o, r, _d) = shader_run(&[node.to_str().unwrap()], &[], &[]);
    assert_one_line_error(&o, 9, "give your raygen with --shader");
    assert!(r.is_none(), "no report for node.rchit");
    // Textures the harness does not make (a 3D one, a cube map): one line naming the set and
    // binding.
    let d = rtprobe::tempdir::tempdir().unwrap();
    for (decl, read, what) in [
        ("uniform sampler3D volume", "textureLod(volume, vec3(0.5), 0.0)", "a 3D texture"),
        ("uniform samplerCube sky", "textureLod(sky, vec3(0, 0, 1), 0.0)", "a cube texture"),
    ] {
        let tex = d.path().join("tex.rchit");
        std::fs::write(&tex, format!("#version 460\n#extension GL_EXT_ray_tracing : require\n#extension GL_EXT_shader_image_load_formatted : require\nlayout(set = 1, binding = 3) {decl};\nlayout(location = 0) rayPayloadInEXT vec4 p;\nvoid main() {{ p = {read}; }}\n")).unwrap();
        let (o, r, _d2) =
            shader_run(&["raygen.rgen", "miss.rmiss", tex.to_str().unwrap()], &[], &[]);
        assert_one_line_error(&o, 9, &format!("set 1 binding 3: {what}"));
        assert!(r.is_none());
    }
    // A storage image without a format (HLSL's `RWTexture2D<float4>`, GLSL's formatted load) is
    // made RGBA32F, read with the feature its capability asks for: 0 validation messages.
    let raw = d.path().join("raw.rchit");
    std::fs::write(&raw, "#version 460\n#extension GL_EXT_ray_tracing : require\n#extension GL_EXT_shader_image_load_formatted : require\nlayout(set = 1, binding = 3) uniform readonly image2D raw;\nlayout(location = 0) rayPayloadInEXT vec4 p;\nvoid main() { p = imageLoad(raw, ivec2(gl_LaunchIDEXT.xy) % 4); }\n").unwrap();
    let (o, r, _d2) = shader_run(&[raw.to_str().unwrap()], &[], &[]);
    assert_eq!(o.status.code(), Some(0), "{}{}", stdout(&o), stderr(&o));
    let r = r.unwrap();
    assert_eq!(r["outcome"], "pass", "{}", stdout(&o));
    assert!(variants(&r).iter().all(|v| v["attempts"]
        .as_array()
        .unwrap()
        .iter()
        .all(|a| a["validation_messages"] == 0)));
    // A stage the harness does not run, and a raygen without its capability (spirv-val fails).
    let frag = "OpCapability Shader\nOpMemoryModel Logical GLSL450\nOpEntryPoint Fragment %main \"main\"\nOpExecutionMode %main OriginUpperLeft\n";
    let rgen = "OpCapability Shader\nOpMemoryModel Logical GLSL450\nOpEntryPoint RayGenerationKHR %main \"main\"\n";
    let body = "%void = OpTypeVoid\n%fn = OpTypeFunction %void\n%main = OpFunction %void None %fn\n%l = OpLabel\nOpReturn\nOpFunctionEnd\n";
    for (name, head, needle) in
        [("frag.spv", frag, "fragment"), ("nocap.spv", rgen, "fails spirv-val")]
    {
        let spv = d.path().join(name);
        let asm = d.path().join(format!("{name}asm"));
        std::fs::write(&asm, format!("{head}{body}")).unwrap();
        let a = std::process::Command::new("spirv-as")
            .args([asm.to_str().unwrap(), "-o", spv.to_str().unwrap()])
            .output()
            .expect("spirv-as");
        assert!(a.status.success(), "{}", String::from_utf8_lossy(&a.stderr));
        let (o, r, _d3) =
            shader_run(&["raygen.rgen", "miss.rmiss", spv.to_str().unwrap()], &[], &[]);
        assert_one_line_error(&o, 9, needle);
        assert!(stderr(&o).contains(name), "{}", stderr(&o));
        assert!(r.is_none());
    }
}

/// Issue 24 (B2, B4, B5): refused in one line before any device work — `-o` naming a folder, `--dump` naming a file, `--entry` naming no entry point of a module, and a
/// GLSL file with many errors (its first error and how many more, not every one).
#[test]
fn refusals_before_the_device_are_one_short_line() {
    let d = rtprobe::tempdir::tempdir().unwrap();
    let f = |n: &str| user().join(n).to_string_lossy().into_owned();
    let (rgen, miss) = (f("raygen.rgen"), f("miss.rmiss"));
    let report = d.path().join("r.json").to_string_lossy().into_owned();
    let file = d.path().join("a-file");
    std::fs::write(&file, "x").unwrap();
    let (dir, file) = (d.path().to_str().unwrap(), file.to_str().unwrap());
    let many = d.path().join("many.rchit");
    let body: String = (0..60).map(|k| format!("    p.x += undeclared{k};\n")).collect();
    std::fs::write(&many, format!("#version 460\n#extension GL_EXT_ray_tracing : require\nlayout(location = 0) rayPayloadInEXT vec4 p;\nvoid main() {{\n{body}}}\n")).unwrap();
    let many = many.to_string_lossy().into_owned();
    let cases: &[(&[&str], i32, &str)] = &[
        (&["-o", dir], 2, "is a folder"),
        (&["-o", &report, "--dump", file], 2, "is a file"),
        (&["-o", &report, "--entry", "nope"], 9, "has no entry point \"nope\""),
    ];
    for (extra, code, needle) in cases {
        let mut args = vec!["run", "--shader", &rgen, "--shader", &miss];
        args.extend_from_slice(extra);
        let o = run_env(&args, &[]);
        assert_one_line_error(&o, *code, needle);
        assert!(!Path::new(&report).exists(), "no report for {extra:?}");
    }
    let o = run_env(
        &["run", "--shader", &rgen, "--shader", &miss, "--shader", &many, "-o", &report],
        &[],
    );
    assert_one_line_error(&o, 9, "(and 59 more errors)");
    assert!(stderr(&o).len() < 1000, "{}", stderr(&o));
}

/// Issue 24 (B1, B3): every unpatched attempt crashes, so patched variants are compared among
/// their own attempts and never called identical; a child that crashes after its last output
/// is a teardown line in the report and the summary.
#[test]
fn uncompared_variants_and_teardown_faults_are_said() {
    let files = ["raygen.rgen", "miss.rmiss", "plain.rchit"];
    let (o, r, _d) =
        shader_run(&files, &["--repeat", "2"], &[("RTPROBE_SHADER_FAULT", "crash:unpatched")]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let r = r.unwrap();
    let v = &variants(&r)[1];
    assert!(v["uncompared"].as_str().unwrap().contains("produced no outputs"), "{v}");
    assert!(!stdout(&o).contains("identical"), "{}", stdout(&o));
    let (o, r, _d) =
        shader_run(&files, &["--repeat", "2"], &[("RTPROBE_SHADER_FAULT", "teardown:unpatched")]);
    let r = r.unwrap_or_else(|| panic!("{}", stderr(&o)));
    let t = variants(&r)[0]["teardown"].as_str().unwrap_or_else(|| panic!("{r}"));
    assert!(t.contains("signal 11") && t.contains("teardown"), "{t}");
    assert!(stdout(&o).contains("after its last attempt"), "{}", stdout(&o));
}

/// Issue 24: DXC-style SPIR-V end to end — the HLSL pipeline of the patch corpus as DXC writes it
/// (`tests/fixtures/patch-corpus/dxc/*.spvasm`: entry points `RayGen`, `ClosestHit`, `Miss`,
/// HLSL type names, `StructuredBuffer` arrays in set 1, an `Rgba32f` RWTexture2D, a payload
/// variable without a Location, every global in the interface), assembled for Vulkan 1.2 and run
/// as given: clean in every variant, its closest-hit's SSBO arrays bound as reflected.
#[test]
fn dxc_style_spirv_runs_clean_in_every_variant() {
    let d = rtprobe::tempdir::tempdir().unwrap();
    let corpus = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/patch-corpus/dxc");
    let mut files = Vec::new();
    for stage in ["raygen", "closesthit", "miss"] {
        let spv = d.path().join(format!("{stage}.spv"));
        rtprobe::tools::spirv::assemble(&corpus.join(format!("{stage}.spvasm")), &spv, "vulkan1.2")
            .unwrap_or_else(|e| panic!("{stage}: {e}"));
        files.push(spv.to_string_lossy().into_owned());
    }
    let names: Vec<&str> = files.iter().map(String::as_str).collect();
    let (o, r, _d) = shader_run(&names, &["--repeat", "2"], &[]);
    let r = r.unwrap_or_else(|| panic!("no report: {}{}", stdout(&o), stderr(&o)));
    assert_eq!(o.status.code(), Some(0), "{}{}", stdout(&o), stderr(&o));
    assert!(r["cell"].as_str().unwrap().starts_with("shader:raygen.spv@"), "{}", r["cell"]);
    let v = variants(&r);
    let names: Vec<&str> = v.iter().map(|v| v["name"].as_str().unwrap()).collect();
    assert!(names.contains(&"ssbo-to-address"), "the StructuredBuffer arrays were seen: {names:?}");
    let reference = &attempts(&v[0])[0]["outputs"];
    assert!(!reference.as_array().unwrap().is_empty(), "the RWTexture2D was read back");
    for variant in v {
        assert_eq!(variant["outcome"], "pass", "{variant}");
        for a in attempts(variant) {
            assert_eq!(a["validation_messages"], 0, "{a}");
            assert_eq!(&a["outputs"], reference, "{}", variant["name"]);
        }
    }
}

/// The DXC raygen and miss of the patch corpus, and `closest_hit` (SPIR-V assembly text), each
/// assembled for Vulkan 1.2 into `dir`: the `--shader` paths.
fn dxc_pipeline(dir: &Path, closest_hit: &str) -> Vec<String> {
    let corpus = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/patch-corpus/dxc");
    let hit = dir.join("closesthit.spvasm");
    std::fs::write(&hit, closest_hit).unwrap();
    let sources = [corpus.join("raygen.spvasm"), corpus.join("miss.spvasm"), hit];
    let mut files = Vec::new();
    for (k, src) in sources.iter().enumerate() {
        let spv = dir.join(format!("{k}.spv"));
        rtprobe::tools::spirv::assemble(src, &spv, "vulkan1.2")
            .unwrap_or_else(|e| panic!("{}: {e}", src.display()));
        files.push(spv.to_string_lossy().into_owned());
    }
    files
}

/// Issue 24: a DXC `-fspv-reflect` closest-hit (`reflect.rchit.spvasm`: UserSemantic strings,
/// UserTypeGOOGLE, OpDecorateId CounterBuffer) runs with the VK_GOOGLE extensions its
/// SPV_GOOGLE extensions need: without SPV_GOOGLE_user_type (lavapipe 25 lacks its device
/// extension) clean under `--validate` in every variant; with it, clean where the device has
/// VK_GOOGLE_user_type and refused in one line naming it (exit 5, no report) where not. Twin:
/// the device extension hidden, the same module is refused before any run.
#[test]
fn dxc_reflect_modules_get_their_google_extensions() {
    let d = rtprobe::tempdir::tempdir().unwrap();
    let full = std::fs::read_to_string(user().join("reflect.rchit.spvasm")).unwrap();
    let no_user_type: String = full
        .lines()
        .filter(|l| !l.contains("user_type") && !l.contains("UserTypeGOOGLE"))
        .map(|l| format!("{l}\n"))
        .collect();
    assert!(no_user_type.contains("CounterBuffer") && no_user_type.contains("UserSemantic"));
    let files = dxc_pipeline(d.path(), &no_user_type);
    let names: Vec<&str> = files.iter().map(String::as_str).collect();
    let (o, r, _d) = shader_run(&names, &["--repeat", "1"], &[]);
    let r = r.unwrap_or_else(|| panic!("no report: {}{}", stdout(&o), stderr(&o)));
    assert_eq!(o.status.code(), Some(0), "{}{}", stdout(&o), stderr(&o));
    assert!(variants(&r).len() >= 2);
    for v in variants(&r) {
        assert_eq!(v["outcome"], "pass", "{v}");
        assert!(attempts(v).iter().all(|a| a["validation_messages"] == 0), "{v}");
    }
    let hide = [("RTPROBE_HIDE_EXTENSIONS", "VK_GOOGLE_hlsl_functionality1")];
    let (o, r, _d) = shader_run(&names, &["--repeat", "1"], &hide);
    assert_one_line_error(
        &o,
        5,
        "missing VK_GOOGLE_hlsl_functionality1 (the modules declare SPV_GOOGLE_hlsl_functionality1",
    );
    assert!(stderr(&o).contains("without -fspv-reflect"), "{}", stderr(&o));
    assert!(r.is_none(), "no report");
    let d2 = rtprobe::tempdir::tempdir().unwrap();
    let files = dxc_pipeline(d2.path(), &full);
    let names: Vec<&str> = files.iter().map(String::as_str).collect();
    let (o, r, _d) = shader_run(&names, &["--repeat", "1"], &[]);
    match o.status.code() {
        Some(0) => {
            let r = r.expect("a report");
            for v in variants(&r) {
                assert!(attempts(v).iter().all(|a| a["validation_messages"] == 0), "{v}");
            }
        }
        _ => {
            assert_one_line_error(&o, 5, "missing VK_GOOGLE_user_type");
            assert!(r.is_none(), "no report");
        }
    }
}

/// The unpatched pipeline's first attempt's output hashes of a clean `--repeat 1` run.
fn first_outputs(files: &[&str], extra: &[&str]) -> Value {
    let mut args = vec!["--repeat", "1"];
    args.extend_from_slice(extra);
    let (o, r, _d) = shader_run(files, &args, &[]);
    let r = r.unwrap_or_else(|| panic!("no report: {}", stderr(&o)));
    assert_eq!(o.status.code(), Some(0), "{}{}", stdout(&o), stderr(&o));
    for variant in variants(&r) {
        assert_eq!(variant["outcome"], "pass", "{variant}");
        for a in attempts(variant) {
            assert_eq!(a["validation_messages"], 0, "{a}");
        }
    }
    let specs: Vec<&str> = extra.windows(2).filter(|w| w[0] == "--spec").map(|w| w[1]).collect();
    assert_eq!(r["options"]["spec"], serde_json::json!(specs));
    let models: Vec<&str> =
        extra.windows(2).filter(|w| w[0] == "--descriptor-model").map(|w| w[1]).collect();
    let model = models.first().copied().unwrap_or("descriptor_indexing");
    assert_eq!(r["options"]["descriptor_model"], model);
    attempts(&variants(&r)[0])[0]["outputs"].clone()
}

/// `--spec`: a closest-hit whose colour a spec constant sets gives other outputs with another
/// value (the twin: the declared default given explicitly gives the default's outputs).
#[test]
fn a_spec_constant_reaches_the_pipeline() {
    let default = first_outputs(&["tinted.rchit"], &[]);
    let zero = first_outputs(&["tinted.rchit"], &["--spec", "1=0"]);
    let five = first_outputs(&["tinted.rchit"], &["--spec", "1=5"]);
    let gain = first_outputs(&["tinted.rchit"], &["--spec", "1=5", "--spec", "2=0.5"]);
    assert_eq!(default, zero, "the declared default given explicitly changes nothing");
    assert_ne!(zero, five, "TINT=5 colours the hits differently");
    assert_ne!(five, gain, "GAIN=0.5 darkens them");
}

/// Bad `--spec` and `--descriptor-model` values: one line each, exit 2, no report.
#[test]
fn bad_spec_and_descriptor_models_are_one_line() {
    let d = rtprobe::tempdir::tempdir().unwrap();
    let report = d.path().join("r.json").to_string_lossy().into_owned();
    let f = |n: &str| user().join(n).to_string_lossy().into_owned();
    let (tinted, bindless) = (f("tinted.rchit"), f("bindless.rchit"));
    let cases: &[(&str, &[&str], &str)] = &[
        (
            &tinted,
            &["--spec", "9=1"],
            "no stage declares SpecId 9; give one of the declared IDs: 1, 2",
        ),
        (&tinted, &["--spec", "1=-4"], "SpecId 1 is a 32-bit uint"),
        (&tinted, &["--spec", "2=bright"], "SpecId 2 is a 32-bit float"),
        (&tinted, &["--spec", "TINT"], "give ID=VALUE"),
        (&bindless, &["--descriptor-model", "descriptor_heap"], "not through a heap"),
        (&bindless, &["--descriptor-model", "sets"], "invalid value 'sets'"),
        (&bindless, &["--heap-layout", "heap.json"], "the descriptor_indexing model has no heap"),
    ];
    for (file, extra, needle) in cases {
        let mut args = vec!["run", "--shader", file, "-o", &report];
        args.extend_from_slice(extra);
        let o = run_env(&args, &[]);
        assert_one_line_error(&o, 2, needle);
        assert!(!Path::new(&report).exists(), "no report for {extra:?}");
    }
}

/// A heap closest-hit on lavapipe 25 (no VK_EXT_descriptor_heap): the device's unsupported
/// exit naming the feature; a set/binding model for it is refused before the device.
#[test]
fn a_heap_shader_on_a_device_without_heaps_is_unsupported() {
    let d = rtprobe::tempdir::tempdir().unwrap();
    let report = d.path().join("r.json").to_string_lossy().into_owned();
    let heap = user().join("heap.rchit").to_string_lossy().into_owned();
    let o = run_env(&["run", "--shader", &heap, "-o", &report], &[]);
    if stderr(&o).contains("glslang") {
        return eprintln!("skipped: no glslang with GL_EXT_descriptor_heap here: {}", stderr(&o));
    }
    assert_one_line_error(&o, 5, "descriptorHeap (VK_EXT_descriptor_heap)");
    let args =
        ["run", "--shader", &heap, "-o", &report, "--descriptor-model", "descriptor_indexing"];
    assert_one_line_error(&run_env(&args, &[]), 2, "only the descriptor_heap model binds");
    assert!(!Path::new(&report).exists());
}

/// `--descriptor-model descriptor_buffer` (VK_EXT_descriptor_buffer, which lavapipe 25 has): the
/// bindless pipeline's hashed outputs are those of descriptor sets, in every variant (the
/// twin: `--spec` above shows a changed pipeline changes the hashes).
#[test]
fn descriptor_buffers_give_the_outputs_of_descriptor_sets() {
    let files = ["raygen.rgen", "miss.rmiss", "bindless.rchit"];
    let sets = first_outputs(&files, &[]);
    let buffers = first_outputs(&files, &["--descriptor-model", "descriptor_buffer"]);
    assert!(sets.as_array().is_some_and(|a| a.len() >= 2), "{sets}");
    assert_eq!(sets, buffers);
}

/// (name, count) pairs.
type Counts = Vec<(String, u64)>;

/// The report's injection: what each module matched (by file name), and each variant's faults.
fn injected(r: &Value) -> (Counts, Counts) {
    let inj = &r["injection"];
    let name = |f: &Value| f.as_str().unwrap().rsplit('/').next().unwrap().to_string();
    let modules = inj["modules"].as_array().unwrap();
    let variants = inj["variants"].as_array().unwrap();
    (
        modules.iter().map(|m| (name(&m["file"]), m["matched"].as_u64().unwrap())).collect(),
        variants.iter().map(|v| (name(&v["name"]), v["faults"].as_u64().unwrap())).collect(),
    )
}

/// Issue 24 (`--inject-fault` into user shaders): a `device` fault injected after the bindless
/// closest-hit's dynamically indexed material read crashes lavapipe in every attempt of every
/// variant (the patches rewrite the injected module and keep the fault); the report records the
/// injection, one access matched in the closest-hit and none elsewhere; exit 1, as for findings.
#[test]
fn an_injected_device_fault_is_a_crash_finding_with_its_attempts() {
    let files = ["raygen.rgen", "miss.rmiss", "bindless.rchit"];
    let pred = "stage=closest_hit,resource=storage_buffer,index=dynamic@device";
    let (o, r, _d) = shader_run(&files, &["--repeat", "2", "--inject-fault", pred], &[]);
    assert_eq!(o.status.code(), Some(1), "{}{}", stdout(&o), stderr(&o));
    let r = r.expect("the report is written");
    assert_eq!(
        (r["injection"]["spec"].as_str(), r["injection"]["fault"].as_str()),
        (Some(pred), Some("device"))
    );
    let (modules, faults) = injected(&r);
    let matched = |f: &str| modules.iter().find(|m| m.0 == f).map(|m| m.1);
    assert_eq!(
        (matched("raygen.rgen"), matched("miss.rmiss"), matched("bindless.rchit")),
        (Some(0), Some(0), Some(1)),
        "{modules:?}"
    );
    let v = variants(&r);
    assert!(v.len() >= 2, "{}", stdout(&o));
    assert_eq!(faults.len(), v.len());
    for (variant, (name, n)) in v.iter().zip(&faults) {
        assert_eq!((variant["name"].as_str().unwrap(), *n), (name.as_str(), 1), "{faults:?}");
        assert_eq!(
            (variant["outcome"].as_str(), variant["judgement"].as_str()),
            (Some("crash"), Some("fault")),
            "{variant}"
        );
        let outcomes: Vec<&str> =
            attempts(variant).iter().map(|a| a["outcome"].as_str().unwrap()).collect();
        assert_eq!(outcomes, ["crash", "crash"], "{variant}");
        assert_eq!(
            (&variant["incidence"]["faulted"], &variant["incidence"]["attempts"]),
            (&Value::from(2), &Value::from(2))
        );
    }
    assert_eq!(r["outcome"], "crash");
    assert!(stdout(&o).contains("note: injected device fault"), "{}", stdout(&o));
    assert!(stdout(&o).lines().last().unwrap().starts_with("verdict: FAIL"), "{}", stdout(&o));
}

/// Twin: a predicate on a resource the pipeline does not read (no uniform buffer anywhere)
/// injects nothing: the run is clean, and the report and the summary say the injection matched
/// no access.
#[test]
fn an_injection_matching_no_access_runs_clean_and_says_so() {
    let files = ["raygen.rgen", "miss.rmiss", "bindless.rchit"];
    let (o, r, _d) = shader_run(
        &files,
        &["--repeat", "2", "--inject-fault", "resource=uniform_buffer@device"],
        &[],
    );
    let r = r.unwrap_or_else(|| panic!("no report: {}", stderr(&o)));
    assert_clean(&o, &r, 3, 2);
    let (modules, faults) = injected(&r);
    assert!(modules.len() == 3 && modules.iter().all(|m| m.1 == 0), "{modules:?}");
    assert!(faults.iter().all(|f| f.1 == 0), "{faults:?}");
    let said = "the injection matched no access";
    let notes = r["notes"].as_array().unwrap();
    assert!(notes.iter().any(|n| n.as_str().unwrap().starts_with(said)), "{notes:?}");
    assert!(stdout(&o).contains(&format!("note: {said}")), "{}", stdout(&o));
}

/// An injected `hang` after every closest-hit access: each variant's one attempt passes its
/// fence deadline (`--timeout 3`) and is a timeout finding; exit 1.
#[test]
fn an_injected_hang_is_a_timeout_finding() {
    let (o, r, _d) = shader_run(
        &["bindless.rchit"],
        &["--repeat", "1", "--timeout", "3", "--inject-fault", "stage=closest_hit@hang"],
        &[],
    );
    assert_eq!(o.status.code(), Some(1), "{}{}", stdout(&o), stderr(&o));
    let r = r.expect("the report is written");
    let (modules, _) = injected(&r);
    // The material read and the texture read.
    assert_eq!(modules, [("bindless.rchit".to_string(), 2)]);
    for variant in variants(&r) {
        assert_eq!(
            (variant["outcome"].as_str(), variant["judgement"].as_str()),
            (Some("timeout"), Some("fault")),
            "{variant}"
        );
        let a = &attempts(variant)[0];
        assert_eq!(a["outcome"], "timeout");
        assert!(a["detail"].as_str().unwrap().contains("within 3s"), "{a}");
    }
    assert_eq!(r["outcome"], "timeout");
}

/// Review of issue 24: the harness scene was opaque, so a given any-hit never ran and a fault in
/// it passed. With an any-hit in the pipeline every instance is FORCE_NO_OPAQUE: a device fault
/// injected after the alpha test's uniform read is a crash finding (the twin of
/// `an_any_hit_alpha_test_runs_clean`, whose outputs are identical without it).
#[test]
fn a_fault_in_a_given_any_hit_is_found() {
    let (o, r, _d) = shader_run(
        &["raygen.rgen", "miss.rmiss", "plain.rchit", "alpha.rahit"],
        &["--repeat", "1", "--inject-fault", "stage=any_hit@device"],
        &[],
    );
    let r = r.unwrap_or_else(|| panic!("no report: {}", stderr(&o)));
    assert_eq!(o.status.code(), Some(1), "{}{}", stdout(&o), stderr(&o));
    for v in variants(&r) {
        assert_eq!(v["outcome"], "crash", "{v}");
    }
}

/// FNV-1a 128 of `bytes` after their length, as the report hashes an output.
fn output_hash(bytes: &[u8]) -> String {
    let mut h: u128 = 0x6c62_272e_07bb_0142_62b8_2175_6295_c58d;
    let prime: u128 = 0x0000_0000_0100_0000_0000_0000_0000_013b;
    for b in (bytes.len() as u64).to_le_bytes().iter().chain(bytes) {
        h ^= *b as u128;
        h = h.wrapping_mul(prime);
    }
    format!("{h:032x}")
}

/// The `filled.rchit` run with `extra` (`--repeat 1` unless it has a `--repeat`): the hash of its
/// `seen` buffer in every attempt of every variant (asserted to be one), and the report.
fn seen_hash(extra: &[&str]) -> (String, Value) {
    let mut args = if extra.contains(&"--repeat") { vec![] } else { vec!["--repeat", "1"] };
    args.extend_from_slice(extra);
    let (o, r, _d) = shader_run(&["filled.rchit"], &args, &[]);
    let r = r.unwrap_or_else(|| panic!("no report: {}", stderr(&o)));
    assert_eq!(o.status.code(), Some(0), "{}{}", stdout(&o), stderr(&o));
    let mut hashes = std::collections::BTreeSet::new();
    for variant in variants(&r) {
        assert_eq!(variant["outcome"], "pass", "{variant}");
        for a in attempts(variant) {
            assert_eq!(a["validation_messages"], 0, "{a}");
            let seen = a["outputs"].as_array().unwrap().iter().find(|p| {
                p["label"].as_str().unwrap().starts_with("storage buffer set 0 binding 1[")
            });
            hashes.insert(
                seen.unwrap_or_else(|| panic!("{a}"))["hash"].as_str().unwrap().to_string(),
            );
        }
    }
    assert_eq!(hashes.len(), 1, "{hashes:?}");
    (hashes.into_iter().next().unwrap(), r)
}

/// The bytes the closest-hit writes when it reads `material`, `light` and `texture`.
fn seen_bytes(material: u32, light: u32, texture: u32) -> Vec<u8> {
    [material, light, texture, 0xC0FFEE].iter().flat_map(|w| w.to_le_bytes()).collect()
}

/// `--fill` from files: the closest-hit reads the files' values from its buffer binding, its
/// push constants and its shader record, and writes them; `zero` gives zeros. The twin: without
/// the fills it reads the harness's data, so the written bytes differ. The options are in the
/// report and the cell id (the plain run's has no options hash).
#[test]
fn fills_put_a_files_bytes_in_buffers_push_constants_and_records() {
    let d = rtprobe::tempdir::tempdir().unwrap();
    let file = |name: &str, bytes: &[u8]| {
        let p = d.path().join(name);
        std::fs::write(&p, bytes).unwrap();
        p.to_string_lossy().into_owned()
    };
    let mat = file("mat.bin", &[0, 0, 0, 0, 0x44, 0x33, 0x22, 0x11]);
    let light = file("light.bin", &0x0BAD_F00D_u32.to_le_bytes());
    let tex = file("tex.bin", &0x5EED_1234_u32.to_le_bytes());
    let (a, b, c) = (format!("0.0={mat}"), format!("push.4={light}"), format!("record.4={tex}"));
    // Three attempts: the bytes are the same in each (one pixel writes them; a racing write from
    // every hit once made this unstable on lavapipe).
    let (filled, r) = seen_hash(&["--repeat", "3", "--fill", &a, "--fill", &b, "--fill", &c]);
    assert_eq!(filled, output_hash(&seen_bytes(0x1122_3344, 0x0BAD_F00D, 0x5EED_1234)));
    let fills = r["options"]["fill"].as_array().unwrap();
    assert_eq!(fills.len(), 3);
    assert!(fills[0].as_str().unwrap().starts_with("0.0=file:"), "{fills:?}");
    let cell = r["cell"].as_str().unwrap();
    assert!(cell.starts_with("shader:filled.rchit@") && cell.contains('#'), "{cell}");
    let zero = ["--fill", "0.0=zero", "--fill", "push.4=zero", "--fill", "record.4=zero"];
    assert_eq!(seen_hash(&zero).0, output_hash(&seen_bytes(0, 0, 0)));
    let (plain, r) = seen_hash(&[]);
    assert_ne!(plain, filled, "without --fill the harness's data is read");
    assert_ne!(plain, output_hash(&seen_bytes(0, 0, 0)));
    assert!(!r["cell"].as_str().unwrap().contains('#'), "{}", r["cell"]);
}

/// Bad `--fill`: a target the modules lack, a binding that is no buffer, an element or offset
/// out of range, a scene source, a missing or too large file, two fills that overlap: one line,
/// exit 2 or 9, no report.
#[test]
fn bad_fills_are_one_line_and_no_report() {
    let d = rtprobe::tempdir::tempdir().unwrap();
    let report = d.path().join("r.json").to_string_lossy().into_owned();
    let big = d.path().join("big.bin");
    std::fs::write(&big, [7u8; 17]).unwrap();
    let big = format!("0.0={}", big.display());
    let f = |n: &str| user().join(n).to_string_lossy().into_owned();
    let (filled, textured) = (f("filled.rchit"), f("textured.rchit"));
    let cases: &[(&str, &str, i32, &str)] = &[
        (&filled, "9.9=zero", 2, "no module binds set 9 binding 9 (bound: 0.0, 0.1)"),
        (&filled, "0.0[1]=zero", 2, "has 1 element(s)"),
        (&filled, "push.8=zero", 2, "past the end of the push constants (8 bytes)"),
        (&filled, "record.8=zero", 2, "past the end of the shader record block (8 bytes)"),
        (&filled, "0.0=scene.positions", 2, "scene.positions needs --scene FILE"),
        (&filled, "0.0=random:x", 2, "random:42"),
        (&filled, "0.0", 2, "give TARGET=SOURCE"),
        (&filled, "0.0=/nonexistent/fill.bin", 9, "give a readable regular file"),
        (&filled, "0.0=/dev/zero", 9, "not a regular file"),
        (&filled, &big, 9, "holds 17 bytes, more than the 16"),
        (
            &textured,
            "1.1=zero",
            2,
            "set 1 binding 1 is a texture (combined image sampler), not a buffer",
        ),
    ];
    for (file, fill, code, needle) in cases {
        let args = ["run", "--shader", file, "-o", &report, "--fill", fill];
        let o = run_env(&args, &[]);
        assert_one_line_error(&o, *code, needle);
        assert!(!Path::new(&report).exists(), "no report for {fill}");
    }
    // Two fills that overlap (push bytes 4..8 both write): one line, exit 2, no report.
    let args = [
        "run",
        "--shader",
        &filled,
        "-o",
        &report,
        "--fill",
        "push.0=zero",
        "--fill",
        "push.4=random:1",
    ];
    assert_one_line_error(&run_env(&args, &[]), 2, "push.4=random:1: overlaps --fill push.0=zero");
    assert!(!Path::new(&report).exists(), "no report for overlapping fills");
}

/// A Vulkan Profiles JSON written for a test: `features` as `"VkStruct": {"member": true}`.
fn profile_file(dir: &Path, name: &str, features: Value) -> String {
    let p = dir.join(name);
    let json =
        serde_json::json!({"capabilities": {"engine": {"features": features}}, "profiles": {}});
    std::fs::write(&p, serde_json::to_vec(&json).unwrap()).unwrap();
    p.to_string_lossy().into_owned()
}

/// Issue 24 (`--profile`): an engine's profile enabling robustBufferAccess2 and partially bound,
/// update-after-bind and variable-count bindings (by the pre-1.2 struct names an engine may
/// use): the bindless pipeline runs clean under `--validate` with those flags on its set
/// layouts, and the report records what was enabled and bound and the profile's hash.
#[test]
fn a_profile_with_robustness_and_binding_flags_runs_clean() {
    let d = rtprobe::tempdir::tempdir().unwrap();
    let features = serde_json::json!({
        "VkPhysicalDeviceRobustness2FeaturesKHR": {"robustBufferAccess2": true, "nullDescriptor": false},
        "VkPhysicalDeviceDescriptorIndexingFeatures": {
            "descriptorBindingPartiallyBound": true,
            "descriptorBindingStorageBufferUpdateAfterBind": true,
            "descriptorBindingStorageImageUpdateAfterBind": true,
            "descriptorBindingVariableDescriptorCount": true,
            "runtimeDescriptorArray": true
        }
    });
    let file = profile_file(d.path(), "engine.json", features);
    let (o, r, _d) = shader_run(
        &["raygen.rgen", "miss.rmiss", "bindless.rchit"],
        &["--repeat", "2", "--profile", &file],
        &[],
    );
    let r = r.unwrap_or_else(|| panic!("no report: {}", stderr(&o)));
    assert_clean(&o, &r, 3, 2);
    let p = &r["profile"];
    let enabled: Vec<&str> =
        p["enabled"].as_array().unwrap().iter().map(|v| v.as_str().unwrap()).collect();
    for want in [
        "VkPhysicalDeviceRobustness2FeaturesEXT.robustBufferAccess2",
        "VkPhysicalDeviceVulkan12Features.descriptorBindingPartiallyBound",
        "VkPhysicalDeviceVulkan12Features.descriptorBindingVariableDescriptorCount",
    ] {
        assert!(enabled.contains(&want), "{want} not in {enabled:?}");
    }
    // false enables nothing.
    assert!(!enabled.iter().any(|e| e.ends_with("nullDescriptor")), "{enabled:?}");
    assert_eq!(
        p["binding_flags"],
        serde_json::json!([
            "partially_bound",
            "update_after_bind(storage_buffer, storage_image)",
            "variable_descriptor_count"
        ])
    );
    // robustBufferAccess2 without robustBufferAccess: the harness adds it, with the VUID.
    let implied = p["implied"][0].as_str().unwrap_or_default();
    assert!(implied.contains("robustBufferAccess2-04000"), "{p}");
    assert_eq!(r["options"]["profile"], p["hash"]);
    assert_eq!(p["hash"].as_str().map(str::len), Some(32));
    assert_variable_count(p, "set 1 binding 1", 64);
}

/// The report's variable-sized binding `at`: allocated `allocated` (`--array-size`) under a
/// layout bound larger than that (the device's limits less the other bindings).
fn assert_variable_count(profile: &Value, at: &str, allocated: u64) {
    let counts = profile["variable_counts"].as_array().unwrap_or_else(|| panic!("{profile}"));
    assert_eq!(counts.len(), 1, "{profile}");
    let line = counts[0].as_str().unwrap();
    let (binding, rest) = line.split_once(": layout ").unwrap_or_else(|| panic!("{line}"));
    let (layout, alloc) = rest.split_once(", allocated ").unwrap_or_else(|| panic!("{line}"));
    let (layout, alloc): (u64, u64) = (layout.parse().unwrap(), alloc.parse().unwrap());
    assert_eq!((binding, alloc), (at, allocated), "{line}");
    assert!(layout > alloc, "the layout's maximum is the device's bound, not the count: {line}");
}

/// The cell id of a clean `--repeat 1` run of `files` with `extra`, and its report.
fn clean_cell(files: &[&str], extra: &[&str]) -> (String, Value) {
    let mut args = vec!["--repeat", "1"];
    args.extend_from_slice(extra);
    let (o, r, _d) = shader_run(files, &args, &[]);
    let r = r.unwrap_or_else(|| panic!("no report: {}{}", stdout(&o), stderr(&o)));
    assert_eq!(o.status.code(), Some(0), "{}{}", stdout(&o), stderr(&o));
    for v in variants(&r) {
        assert!(attempts(v).iter().all(|a| a["validation_messages"] == 0), "{v}");
    }
    (r["cell"].as_str().unwrap().to_string(), r)
}

/// Issue 24: `--profile` is in the cell id by what it turns on, not by its file: the same
/// features in another file at another path, written in another order, are the same cell; one
/// feature more is another; no profile is another again. The variable-count profile allocates
/// the 64 textures (`--array-size`'s default) under a layout bound at the device's limit, clean
/// under `--validate`.
#[test]
fn the_profile_is_in_the_cell_id_by_what_it_turns_on() {
    let d = rtprobe::tempdir::tempdir().unwrap();
    let files = ["raygen.rgen", "miss.rmiss", "textured.rchit"];
    let partially = serde_json::json!({
        "VkPhysicalDeviceDescriptorIndexingFeatures": {"descriptorBindingPartiallyBound": true}
    });
    let a = profile_file(d.path(), "a.json", partially);
    std::fs::create_dir(d.path().join("other")).unwrap();
    let b = d.path().join("other/engine.json");
    std::fs::write(
        &b,
        r#"{"profiles": {}, "capabilities": {"x": {"features": {"VkPhysicalDeviceVulkan12Features": {"shaderInt8": false, "descriptorBindingPartiallyBound": true}}}}}"#,
    )
    .unwrap();
    let variable = profile_file(
        d.path(),
        "variable.json",
        serde_json::json!({"VkPhysicalDeviceDescriptorIndexingFeatures": {
            "descriptorBindingPartiallyBound": true,
            "descriptorBindingVariableDescriptorCount": true
        }}),
    );
    let (id_a, ra) = clean_cell(&files, &["--profile", &a]);
    let (id_b, _) = clean_cell(&files, &["--profile", b.to_str().unwrap()]);
    let (id_var, rv) = clean_cell(&files, &["--profile", &variable]);
    let (id_none, _) = clean_cell(&files, &[]);
    assert_eq!(id_a, id_b, "the same features in another file");
    assert!(id_a.starts_with(&format!("{id_none}#")), "{id_a}");
    assert_eq!(ra["cell_options"]["profile"], serde_json::json!(["partially_bound"]));
    assert_ne!(id_var, id_a, "one feature more is another cell");
    assert_variable_count(&rv["profile"], "set 1 binding 1", 64);
}

/// Issue 24: `--spec` is in the cell id in a normal form: the order given and the spelling of a
/// value (`05`, `0.50`) do not change the id; another value does. The report's options keep
/// the values as given.
#[test]
fn spec_values_are_one_cell_in_any_order_and_spelling() {
    let files = ["tinted.rchit"];
    let (id, r) = clean_cell(&files, &["--spec", "2=0.5", "--spec", "1=5"]);
    let (same, r2) = clean_cell(&files, &["--spec", "1=05", "--spec", "2=0.50"]);
    let (other, _) = clean_cell(&files, &["--spec", "1=6", "--spec", "2=0.5"]);
    assert_eq!(id, same);
    assert_ne!(id, other);
    assert_eq!(r["cell_options"]["spec"], serde_json::json!(["1=5", "2=0.5"]));
    assert_eq!(r2["options"]["spec"], serde_json::json!(["1=05", "2=0.50"]));
}

/// Twins: a profile naming a feature lavapipe lacks (VK_NV_ray_tracing_motion_blur's) is
/// refused before any run in one line naming it (exit 5), a feature that is not a boolean and
/// a file that is not JSON in one line each (exit 9); no report in any case.
#[test]
fn a_profile_the_device_cannot_meet_or_that_is_malformed_is_one_line() {
    let d = rtprobe::tempdir::tempdir().unwrap();
    let lacks = profile_file(
        d.path(),
        "lacks.json",
        serde_json::json!({
            "VkPhysicalDeviceRayTracingMotionBlurFeaturesNV": {"rayTracingMotionBlur": true},
            "VkPhysicalDeviceRobustness2FeaturesEXT": {"robustBufferAccess2": true}
        }),
    );
    let not_bool = profile_file(
        d.path(),
        "not_bool.json",
        serde_json::json!({"VkPhysicalDeviceFeatures": {"robustBufferAccess": "yes"}}),
    );
    let broken = d.path().join("broken.json");
    std::fs::write(&broken, "{\"capabilities\": ").unwrap();
    let broken = broken.to_string_lossy().into_owned();
    let cases = [
        (
            lacks.as_str(),
            5,
            "lacks VkPhysicalDeviceRayTracingMotionBlurFeaturesNV.rayTracingMotionBlur",
        ),
        (not_bool.as_str(), 9, "robustBufferAccess: not true or false"),
        (broken.as_str(), 9, "not JSON"),
    ];
    for (file, code, says) in cases {
        let (o, r, _d) = shader_run(&["bindless.rchit"], &["--profile", file], &[]);
        assert_eq!(o.status.code(), Some(code), "{file}: {}{}", stdout(&o), stderr(&o));
        let err = stderr(&o);
        assert_eq!(err.trim_end().lines().count(), 1, "{err}");
        assert!(err.contains(says), "{err}");
        assert!(r.is_none(), "{file}: a report was written");
    }
}

/// Issue 24 (GPU-AV re-runs): an injected `device` fault under `--validate=gpu-av` — each
/// faulting variant is re-run under GPU-AV with as many attempts, kept apart in `gpu_av`. The
/// injected load reads an address no buffer holds through a value the shader computes, which
/// bookworm's layer (1.3.239) does not instrument as an invalid access: no invalid-access
/// report, every attempt still crashes, so the judgement is pinned to `still_faults` (the
/// variant stays a crash finding, no control and no more attempts run: those are for passes).
/// Its twins: the out-of-range index below (`reports`, an `error`), and the judge's unit tests
/// (`model::shader_gpu_av`: a control that does not fault, a setup message alone).
#[test]
fn an_injected_fault_still_faults_under_gpu_av() {
    let files = ["raygen.rgen", "miss.rmiss", "bindless.rchit"];
    let pred = "stage=closest_hit,resource=storage_buffer,index=dynamic@device";
    let (o, r, _d) =
        shader_run(&files, &["--validate=gpu-av", "--repeat", "2", "--inject-fault", pred], &[]);
    assert_eq!(o.status.code(), Some(1), "{}{}", stdout(&o), stderr(&o));
    let r = r.expect("the report is written");
    assert_eq!(r["options"]["gpu_av"], true);
    for v in variants(&r) {
        let own: Vec<&str> = attempts(v).iter().map(|a| a["outcome"].as_str().unwrap()).collect();
        assert_eq!(own, ["crash", "crash"], "{v}");
        let g = &v["gpu_av"];
        let tries = g["attempts"].as_array().unwrap_or_else(|| panic!("no gpu_av: {v}"));
        let under: Vec<&str> = tries.iter().map(|a| a["outcome"].as_str().unwrap()).collect();
        assert_eq!(under, ["crash", "crash"], "{g}");
        assert_eq!(g["messages"]["invalid_access"], 0, "{g}");
        assert_eq!(
            (g["judgement"].as_str(), v["outcome"].as_str(), v["judgement"].as_str()),
            (Some("still_faults"), Some("crash"), Some("fault")),
            "{v}"
        );
        assert!(g.get("control").is_none() && g.get("miss_probability").is_none(), "{g}");
        let line = g["line"].as_str().unwrap();
        assert!(line.starts_with("still faults under GPU-AV (2 of 2 attempts)"), "{line}");
        assert!(stdout(&o).contains(line), "{}", stdout(&o));
    }
}

/// Issue 24: an out-of-range descriptor index (`--array-size 2` under a shader indexing up to
/// 63) crashes lavapipe; under GPU-AV the layer reports it, so the variant is the shader's
/// `error` (judgement `validation`), not a driver finding. Twin: without GPU-AV the same run is
/// a crash finding with no `gpu_av`. (The index check refuses the run first, exit 9; here it is
/// skipped, `--no-index-check`, as where it cannot see: heap arrays, an injected fault.)
#[test]
fn an_index_gpu_av_reports_out_of_range_is_an_error_not_a_finding() {
    let files = ["raygen.rgen", "miss.rmiss", "bindless.rchit"];
    let (o, r, _d) = shader_run(&files, &["--repeat", "1", "--array-size", "2"], &[]);
    assert_one_line_error(&o, 9, "(2 descriptors, as --array-size gave)");
    assert!(r.is_none());
    let args = ["--repeat", "1", "--array-size", "2", "--no-index-check"];
    let (o, r, _d) = shader_run(&files, &args, &[]);
    let r = r.unwrap_or_else(|| panic!("no report: {}", stderr(&o)));
    let v = &variants(&r)[0];
    assert_eq!(
        (v["outcome"].as_str(), v["judgement"].as_str()),
        (Some("crash"), Some("fault")),
        "{v}"
    );
    assert!(v.get("gpu_av").is_none(), "{v}");
    let with: Vec<&str> = ["--validate=gpu-av"].into_iter().chain(args).collect();
    let (o, r, _d) = shader_run(&files, &with, &[]);
    assert_eq!(o.status.code(), Some(1), "{}{}", stdout(&o), stderr(&o));
    let r = r.expect("the report is written");
    let v = &variants(&r)[0];
    assert_eq!(v["gpu_av"]["judgement"], "reports", "{v}");
    assert_eq!(
        (v["outcome"].as_str(), v["judgement"].as_str()),
        (Some("error"), Some("validation"))
    );
    let first = v["gpu_av"]["attempts"][0]["validation"][0].as_str().unwrap();
    assert!(first.contains("out of bounds"), "{first}");
    // Counted as an invalid access: that, not any message, makes the `error`.
    assert!(v["gpu_av"]["attempts"][0]["invalid_access"].as_u64().is_some_and(|n| n > 0), "{v}");
    assert!(v["gpu_av"]["messages"]["invalid_access"].as_u64().is_some_and(|n| n > 0), "{v}");
    let detail = v["detail"].as_str().unwrap();
    assert!(detail.starts_with("GPU-AV reports the harness's own fault: "), "{detail}");
    assert!(detail.contains("not a driver finding"), "{v}");
}

/// The two words of `shadow.rchit`'s counter buffer in `variant`'s embedded outputs, less their
/// initial values: (shadowed hits, lit hits).
fn shadow_counts(variant: &Value) -> (u32, u32) {
    let data = variant["data"].as_array().unwrap();
    let d =
        data.iter().find(|d| d["label"].as_str().unwrap().contains("set 0 binding 1[")).unwrap();
    let word = |b: &[u8], k: usize| u32::from_le_bytes(b[4 * k..4 * k + 4].try_into().unwrap());
    let (now, then) = (unb64(d["bytes"].as_str().unwrap()), unb64(d["initial"].as_str().unwrap()));
    (word(&now, 0).wrapping_sub(word(&then, 0)), word(&now, 1).wrapping_sub(word(&then, 1)))
}

/// A closest-hit shading with a shadow ray (miss index 1, a `bool` payload at location 1,
/// closest-hits skipped) runs clean: the harness supplies a miss at each index, the shadow one
/// clearing the bool, so hits are counted both shadowed and lit. The twin: the shadow ray
/// without the skip flag would run the closest-hit with a `bool` payload — refused in one line,
/// exit 9, no report.
#[test]
fn a_shadow_ray_gets_a_miss_of_its_own_and_its_payload_is_held() {
    let (o, r, _d) = shader_run(&["shadow.rchit"], &["--repeat", "2"], &[]);
    let r = r.unwrap_or_else(|| panic!("no report: {}", stderr(&o)));
    assert_eq!(o.status.code(), Some(0), "{}{}", stdout(&o), stderr(&o));
    for v in variants(&r) {
        assert_eq!(v["outcome"], "pass", "{v}");
        for a in attempts(v) {
            assert_eq!(a["validation_messages"], 0, "{a}");
        }
    }
    let (shadowed, lit) = shadow_counts(&variants(&r)[0]);
    assert!(shadowed > 0 && lit > 0, "shadowed {shadowed}, lit {lit}");
    let (o, r, _d) = shader_run(&["shadow.rchit"], &["-D", "SHADOW_RUNS_CLOSEST_HIT"], &[]);
    assert_eq!(o.status.code(), Some(9), "{}{}", stdout(&o), stderr(&o));
    assert!(r.is_none());
    let e = stderr(&o);
    assert_eq!(e.trim_end().lines().count(), 1, "{e}");
    assert!(e.contains("payload `shadowed`") && e.contains("(closest_hit)"), "{e}");
}
