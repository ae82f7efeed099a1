//! End-to-end tests of `rtprobe patch`: SPIR-V assembly in (spirv-as), disassembly out
//! (spirv-dis), spirv-val clean; engine-like GLSL shaders patched; bad and random input refused
//! with one line and no output file.
mod common;
use common::*;
use std::path::{Path, PathBuf};
use std::process::Command;

fn tool(name: &str, args: &[&str]) -> std::process::Output {
    Command::new(name)
        .args(args)
        .output()
        .unwrap_or_else(|e| panic!("{name}: {e} (apt-get install spirv-tools)"))
}

fn assemble(src: &Path, out: &Path) {
    let o = tool(
        "spirv-as",
        &["--target-env", "vulkan1.2", src.to_str().unwrap(), "-o", out.to_str().unwrap()],
    );
    assert!(o.status.success(), "spirv-as: {}", String::from_utf8_lossy(&o.stderr));
}

fn dis(p: &Path) -> String {
    let o = tool("spirv-dis", &["--raw-id", p.to_str().unwrap()]);
    assert!(o.status.success());
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn val(p: &Path) {
    let o = tool("spirv-val", &["--target-env", "vulkan1.2", p.to_str().unwrap()]);
    assert!(
        o.status.success(),
        "spirv-val {}: {}",
        p.display(),
        String::from_utf8_lossy(&o.stderr)
    );
}

fn shaders() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/shaders")
}

#[test]
fn as_to_address_rewrites_hand_written_spirv() {
    let d = rtprobe::tempdir::tempdir().unwrap();
    let input = d.path().join("in.spv");
    let out = d.path().join("out.spv");
    assemble(&shaders().join("as_array.spvasm"), &input);
    val(&input);
    let o = run(&[
        "patch",
        input.to_str().unwrap(),
        "--apply",
        "as-to-address",
        "-o",
        out.to_str().unwrap(),
        "--disassemble",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    val(&out);
    let text = dis(&out);
    // The descriptor array is gone; the handle comes from an address in a table whose address is
    // appended to the existing push-constant block at the first free 8-aligned offset (8).
    assert!(
        !text.lines().any(|l| l.contains("OpVariable") && l.contains("UniformConstant")),
        "{text}"
    );
    assert!(!text.contains("DescriptorSet"), "{text}");
    assert!(text.contains("OpMemoryModel PhysicalStorageBuffer64 GLSL450"), "{text}");
    assert!(text.contains("OpMemberDecorate %") && text.contains(" 1 Offset 8"), "{text}");
    assert!(text.contains("OpConvertUToPtr"), "{text}");
    assert!(text.contains("Aligned 8"), "{text}");
    assert!(text.contains("OpConvertUToAccelerationStructureKHR"), "{text}");
    // The diff printed on request shows the load being replaced.
    let diff = stdout(&o);
    assert!(
        diff.lines().any(|l| l.starts_with("- ") && l.contains("OpLoad") && l.contains("%chain")
            || l.starts_with("- ") && l.contains("OpAccessChain")),
        "{diff}"
    );
    assert!(diff.contains("+ ") && diff.contains("OpConvertUToAccelerationStructureKHR"), "{diff}");
}

#[test]
fn nonuniform_and_pin_index_rewrite_hand_written_spirv() {
    let d = rtprobe::tempdir::tempdir().unwrap();
    let input = d.path().join("in.spv");
    assemble(&shaders().join("as_array.spvasm"), &input);
    // nonuniform: the push-constant index, the chain into the AS array and the loaded handle.
    let nu = d.path().join("nu.spv");
    let o = run(&[
        "patch",
        input.to_str().unwrap(),
        "--apply",
        "nonuniform",
        "-o",
        nu.to_str().unwrap(),
        "--disassemble",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("3 objects decorated NonUniform"), "{}", stdout(&o));
    let diff = stdout(&o);
    assert_eq!(
        diff.lines().filter(|l| l.starts_with("+ ") && l.ends_with(" NonUniform")).count(),
        3,
        "{diff}"
    );
    assert!(diff.contains("+ OpCapability ShaderNonUniform"), "{diff}");
    val(&nu);
    // pin-index: the chain indexes with a new spec constant (SpecId 0, default 2).
    let pin = d.path().join("pin.spv");
    let o = run(&[
        "patch",
        input.to_str().unwrap(),
        "--apply",
        "pin-index",
        "--option",
        "value=2",
        "-o",
        pin.to_str().unwrap(),
        "--disassemble",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let diff = stdout(&o);
    assert!(
        diff.lines()
            .any(|l| l.starts_with("+ ") && l.contains("OpSpecConstant") && l.ends_with(" 2")),
        "{diff}"
    );
    assert!(diff.lines().any(|l| l.starts_with("+ ") && l.contains("SpecId 0")), "{diff}");
    assert!(diff.lines().any(|l| l.starts_with("- ") && l.contains("OpAccessChain")), "{diff}");
    val(&pin);
    // the spec id is refused when already used
    let again = d.path().join("again.spv");
    assert_one_line_error(
        &run(&[
            "patch",
            pin.to_str().unwrap(),
            "--apply",
            "pin-index",
            "--option",
            "spec-id=0",
            "-o",
            again.to_str().unwrap(),
        ]),
        9,
        "",
    );
}

#[test]
fn engine_shaders_are_patched_from_glsl() {
    let d = rtprobe::tempdir::tempdir().unwrap();
    let chit = shaders().join("engine_closest_hit.rchit");
    let rgen = shaders().join("engine_raygen.rgen");
    // nonuniform: the mesh and material indices become NonUniform (the engine forgot nonuniformEXT).
    let out = d.path().join("chit_nu.spv");
    let o = run(&[
        "patch",
        chit.to_str().unwrap(),
        "--glsl",
        "--stage",
        "rchit",
        "--apply",
        "nonuniform",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = dis(&out);
    assert!(text.contains("OpCapability ShaderNonUniform"));
    assert!(text.contains("OpCapability StorageBufferArrayNonUniformIndexing"));
    assert!(text.contains("OpCapability SampledImageArrayNonUniformIndexing"));
    assert!(text.matches("NonUniform\n").count() >= 4, "{text}");
    val(&out);
    // then strip it again
    let back = d.path().join("chit_strip.spv");
    let o = run(&[
        "patch",
        out.to_str().unwrap(),
        "--apply",
        "nonuniform",
        "--option",
        "strip=true",
        "-o",
        back.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!dis(&back).contains("OpDecorate %") || !dis(&back).contains(" NonUniform\n"));
    // pin-index: the material texture index (binding 1 of set 1) becomes a spec constant.
    let pinned = d.path().join("chit_pin.spv");
    let o = run(&[
        "patch",
        chit.to_str().unwrap(),
        "--glsl",
        "--stage",
        "rchit",
        "--apply",
        "pin-index",
        "--option",
        "binding=1",
        "--option",
        "value=3",
        "-o",
        pinned.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = dis(&pinned);
    assert!(
        text.contains("SpecId 0")
            && text.lines().any(|l| l.contains("OpSpecConstant") && l.ends_with(" 3")),
        "{text}"
    );
    val(&pinned);
    // as-to-address on the raygen: its TLAS array is reached through an address table.
    let raddr = d.path().join("rgen_addr.spv");
    let o = run(&[
        "patch",
        rgen.to_str().unwrap(),
        "--glsl",
        "--stage",
        "rgen",
        "--apply",
        "as-to-address",
        "-o",
        raddr.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("address at push-constant offset 8"), "{}", stdout(&o));
    let text = dis(&raddr);
    assert!(
        text.contains("OpConvertUToAccelerationStructureKHR") && !text.contains("%tlas"),
        "{text}"
    );
    val(&raddr);
}

#[test]
fn as_to_address_sizes_an_engine_camera_push_block() {
    // Matrices (column- and row-major), 8/16/64-bit members and a struct array in the push block:
    // the table address goes right after it without --option offset, and an offset inside it is
    // refused. The block is 193 bytes: past the 128 every device has, refused unless the device
    // has more (--max-push-constants 256, as NVIDIA's).
    let d = rtprobe::tempdir::tempdir().unwrap();
    let rgen = shaders().join("engine_camera.rgen");
    let out = d.path().join("camera_addr.spv");
    let patch = |extra: &[&str]| {
        let mut a = vec!["patch", rgen.to_str().unwrap(), "--apply", "as-to-address", "-o"];
        a.push(out.to_str().unwrap());
        a.extend_from_slice(extra);
        run(&a)
    };
    assert_one_line_error(&patch(&[]), 9, "past maxPushConstantsSize 128");
    let o = patch(&["--max-push-constants", "256"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("address at push-constant offset 200"), "{}", stdout(&o));
    let text = dis(&out);
    assert!(text.contains(" Offset 200"), "{text}");
    val(&out);
    let outs = d.path().join("overlap.spv");
    assert_one_line_error(
        &run(&[
            "patch",
            rgen.to_str().unwrap(),
            "--glsl",
            "--stage",
            "rgen",
            "--apply",
            "as-to-address",
            "--option",
            "offset=184",
            "-o",
            outs.to_str().unwrap(),
        ]),
        9,
        "overlaps",
    );
    assert!(!outs.exists());
}

#[test]
fn ssbo_to_address_turns_the_mesh_array_into_address_loads() {
    let d = rtprobe::tempdir::tempdir().unwrap();
    let chit = shaders().join("engine_closest_hit.rchit");
    let out = d.path().join("chit_addr.spv");
    let o = run(&[
        "patch",
        chit.to_str().unwrap(),
        "--glsl",
        "--stage",
        "rchit",
        "--apply",
        "ssbo-to-address",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("3 loads now read through buffer addresses"), "{}", stdout(&o));
    val(&out);
    let text = dis(&out);
    assert!(text.contains("OpMemoryModel PhysicalStorageBuffer64"), "{text}");
    // the per-mesh array is gone; the single material buffer (not an array) is untouched
    assert!(!text.contains("\"meshVertices\""), "{text}");
    assert!(text.contains("\"materials\""), "{text}");
    assert!(text.matches("OpConvertUToPtr").count() >= 6, "{text}");
    // A store into an SSBO array is a shape the patch refuses, naming the instruction.
    let w = d.path().join("w.comp");
    std::fs::write(&w, "#version 460\n#extension GL_EXT_nonuniform_qualifier : require\nlayout(local_size_x = 1) in;\nlayout(set = 0, binding = 0) buffer B { uint v[]; } bufs[];\nlayout(push_constant) uniform P { uint i; } p;\nvoid main() { bufs[p.i].v[0] = 1u; }\n").unwrap();
    let o = run(&[
        "patch",
        w.to_str().unwrap(),
        "--glsl",
        "--stage",
        "comp",
        "--apply",
        "ssbo-to-address",
        "-o",
        d.path().join("w.spv").to_str().unwrap(),
    ]);
    assert_one_line_error(&o, 9, "only loads are rewritten");
}

#[test]
fn bad_input_is_refused_with_one_line_and_no_output() {
    let d = rtprobe::tempdir::tempdir().unwrap();
    let out = d.path().join("out.spv");
    let outs = out.to_str().unwrap();
    let junk = d.path().join("junk.spv");
    std::fs::write(&junk, b"this is not spir-v at all!!").unwrap();
    assert_one_line_error(
        &run(&["patch", junk.to_str().unwrap(), "-a", "nonuniform", "-o", outs]),
        9,
        "not a SPIR-V module",
    );
    // truncated valid module
    let good = d.path().join("good.spv");
    assemble(&shaders().join("as_array.spvasm"), &good);
    let bytes = std::fs::read(&good).unwrap();
    let trunc = d.path().join("trunc.spv");
    std::fs::write(&trunc, &bytes[..bytes.len() / 2 / 4 * 4]).unwrap();
    assert_one_line_error(
        &run(&["patch", trunc.to_str().unwrap(), "-a", "as-to-address", "-o", outs]),
        9,
        "not a SPIR-V module",
    );
    // a patch that changes nothing: no acceleration structure in a closest-hit shader
    let chit = shaders().join("engine_closest_hit.rchit");
    assert_one_line_error(
        &run(&[
            "patch",
            chit.to_str().unwrap(),
            "--glsl",
            "--stage",
            "rchit",
            "-a",
            "as-to-address",
            "-o",
            outs,
        ]),
        9,
        "nothing to patch",
    );
    assert_one_line_error(
        &run(&[
            "patch",
            chit.to_str().unwrap(),
            "--glsl",
            "--stage",
            "rchit",
            "-a",
            "pin-index",
            "--option",
            "binding=7",
            "-o",
            outs,
        ]),
        9,
        "binding 7",
    );
    assert_one_line_error(
        &run(&[
            "patch",
            good.to_str().unwrap(),
            "-a",
            "nonuniform",
            "--option",
            "strip=true",
            "-o",
            outs,
        ]),
        9,
        "nothing to patch",
    );
    // options that belong to no applied patch, unknown patches, overlapping offsets
    assert_one_line_error(
        &run(&[
            "patch",
            good.to_str().unwrap(),
            "-a",
            "nonuniform",
            "--option",
            "offset=8",
            "-o",
            outs,
        ]),
        9,
        "offset",
    );
    assert_one_line_error(
        &run(&["patch", good.to_str().unwrap(), "-a", "make-it-fast", "-o", outs]),
        2,
        "unknown patch",
    );
    assert_one_line_error(
        &run(&[
            "patch",
            good.to_str().unwrap(),
            "-a",
            "as-to-address",
            "--option",
            "offset=0",
            "-o",
            outs,
        ]),
        9,
        "overlaps",
    );
    assert!(!out.exists(), "no output file after a refusal");
    let o = run(&["patch", "--list"]);
    assert!(stdout(&o).contains("as-to-address") && stdout(&o).contains("pin-index"));
}

#[test]
fn random_and_truncated_modules_never_panic() {
    let d = rtprobe::tempdir::tempdir().unwrap();
    let good = d.path().join("good.spv");
    assemble(&shaders().join("as_array.spvasm"), &good);
    let bytes = std::fs::read(&good).unwrap();
    let out = d.path().join("o.spv");
    let mut seed = 0x1234_5678_u64;
    let mut rnd = || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        seed
    };
    for i in 0..24 {
        // corrupt a few words of a valid module, or cut it
        let mut b = bytes.clone();
        if i % 2 == 0 {
            for _ in 0..4 {
                let at = (rnd() as usize % (b.len() / 4 - 5) + 5) * 4;
                b[at..at + 4].copy_from_slice(&(rnd() as u32).to_le_bytes());
            }
        } else {
            b.truncate((rnd() as usize % b.len()) / 4 * 4);
        }
        let p = d.path().join(format!("case{i}.spv"));
        std::fs::write(&p, &b).unwrap();
        let o = run(&[
            "patch",
            p.to_str().unwrap(),
            "-a",
            "as-to-address,nonuniform",
            "-o",
            out.to_str().unwrap(),
        ]);
        let err = stderr(&o);
        assert!(!err.contains("panicked"), "case {i}: {err}");
        assert!(matches!(o.status.code(), Some(0) | Some(9)), "case {i}: {:?} {err}", o.status);
    }
}

/// `--glsl` on a shader tree: `#include <...>` through `-I`, `#include "..."` next to the
/// including file and through the search path, `-D` with and without a value, `--target-env`.
#[test]
fn glsl_shader_tree_with_includes_and_defines_is_patched() {
    let d = rtprobe::tempdir::tempdir().unwrap();
    let tree = shaders().join("tree");
    let chit = tree.join("shaders/gbuffer.rchit");
    let inc = tree.join("engine/include");
    let compile = |extra: &[&str], out: &Path| {
        let mut args = vec![
            "patch",
            chit.to_str().unwrap(),
            "--glsl",
            "--stage",
            "rchit",
            "-I",
            inc.to_str().unwrap(),
            "--apply",
            "nonuniform",
            "-o",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        run(&args)
    };
    let out8 = d.path().join("m8.spv");
    let o = compile(&["-D", "MAX_MATERIALS=8"], &out8);
    assert!(o.status.success(), "{}", stderr(&o));
    val(&out8);
    let text = dis(&out8);
    assert!(text.contains("OpCapability StorageBufferArrayNonUniformIndexing"), "{text}");
    assert!(text.contains("OpCapability SampledImageArrayNonUniformIndexing"), "{text}");
    // The define reaches the included header: the material table is 8 long.
    assert!(
        text.lines().any(|l| l.contains("OpTypeArray"))
            && text.lines().any(|l| l.contains("OpConstant") && l.ends_with(" 8")),
        "{text}"
    );
    // A value-less define switches the local helper's branch: no texture read is left.
    let dbg = d.path().join("dbg.spv");
    let o = compile(&["-D", "MAX_MATERIALS=4", "-D", "DEBUG_UV"], &dbg);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!dis(&dbg).contains("OpImageSampleExplicitLod"), "DEBUG_UV not applied");
    assert!(text.contains("OpImageSampleExplicitLod"));
    // Target environments: SPIR-V 1.5 for vulkan1.2 (default), 1.6 for vulkan1.3 and vulkan1.4.
    let version = |p: &Path| {
        let b = std::fs::read(p).unwrap();
        u32::from_le_bytes([b[4], b[5], b[6], b[7]])
    };
    assert_eq!(version(&out8), 0x0001_0500);
    for env in ["vulkan1.3", "vulkan1.4"] {
        let p = d.path().join(format!("{env}.spv"));
        let o = compile(&["-D", "MAX_MATERIALS=8", "--target-env", env], &p);
        assert!(o.status.success(), "{env}: {}", stderr(&o));
        assert_eq!(version(&p), 0x0001_0600, "{env}");
        // The system shaderc predates Vulkan 1.4: rtprobe asks it for 1.3 and says so.
        let noted =
            stderr(&o).contains("rtprobe: note: --target-env vulkan1.4: compiled for vulkan1.3");
        assert_eq!(
            noted,
            env == "vulkan1.4" && cfg!(shaderc_without_vulkan_1_4),
            "{env}: {}",
            stderr(&o)
        );
    }
}

/// A compute shader at SPIR-V 1.6: glslang 12 (the system shaderc's) writes its workgroup size as
/// `OpExecutionModeId ... LocalSizeId`, which the patcher must load and write back.
#[test]
fn glsl_compute_at_spirv_1_6_is_patched() {
    let d = rtprobe::tempdir::tempdir().unwrap();
    let src = d.path().join("d.comp");
    std::fs::write(&src, "#version 460\n#extension GL_EXT_nonuniform_qualifier : require\nlayout(local_size_x = 8) in;\nlayout(binding = 0) buffer B { uint x; } b[4];\nlayout(push_constant) uniform P { uint i; } p;\nvoid main() { b[p.i].x = 1u; }\n").unwrap();
    for env in ["vulkan1.2", "vulkan1.3", "vulkan1.4"] {
        let out = d.path().join(format!("{env}.spv"));
        let o = run(&[
            "patch",
            src.to_str().unwrap(),
            "--glsl",
            "--stage",
            "comp",
            "--target-env",
            env,
            "--apply",
            "nonuniform",
            "-o",
            out.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{env}: {}", stderr(&o));
        let text = dis(&out);
        assert!(text.contains("NonUniform"), "{env}: {text}");
        assert!(text.contains("LocalSize"), "{env}: {text}");
    }
}

/// GLSL enabling an extension newer than shaderc's glslang goes to the external glslangValidator
/// (tests/heap.rs compiles it in the sid root); without one, one line names the extension.
#[test]
fn glsl_with_a_newer_extension_needs_the_external_glslang() {
    let d = rtprobe::tempdir::tempdir().unwrap();
    let src = d.path().join("ser.rgen");
    std::fs::write(&src, "#version 460\n#extension GL_EXT_ray_tracing : require\n#extension GL_EXT_shader_invocation_reorder : require\nvoid main() {}\n").unwrap();
    let out = d.path().join("out.spv");
    let o = run_env(
        &[
            "patch",
            src.to_str().unwrap(),
            "--glsl",
            "--stage",
            "rgen",
            "--apply",
            "nonuniform",
            "-o",
            out.to_str().unwrap(),
        ],
        &[
            ("RTPROBE_GLSLANG", "/nonexistent/glslangValidator"),
            ("RTPROBE_SID_ROOT", "/nonexistent"),
        ],
    );
    assert_one_line_error(&o, 9, "no GLSL compiler with GL_EXT_shader_invocation_reorder");
    assert!(!out.exists());
}

#[test]
fn glsl_include_errors_are_one_line_naming_the_file_and_chain() {
    let d = rtprobe::tempdir::tempdir().unwrap();
    let out = d.path().join("out.spv");
    let tree = shaders().join("tree");
    let chit = tree.join("shaders/gbuffer.rchit");
    let inc = tree.join("engine/include");
    let patch = |input: &Path, stage: &str, extra: &[&str]| {
        let mut args = vec![
            "patch",
            input.to_str().unwrap(),
            "--glsl",
            "--stage",
            stage,
            "--apply",
            "nonuniform",
            "-o",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        run(&args)
    };
    // A header includes a file that does not exist: the missing name, the header and its line.
    let o = patch(&tree.join("broken/main.rgen"), "rgen", &[]);
    assert_one_line_error(&o, 9, "missing/constants.glsl");
    let err = stderr(&o);
    assert!(err.contains("helpers.glsl:3"), "{err}");
    assert!(err.contains("broken/main.rgen:5"), "the chain names the root's include line: {err}");
    // A compile error inside an included file: that file and line, then who included it.
    let o = patch(&tree.join("broken/typo.rgen"), "rgen", &[]);
    assert_one_line_error(&o, 9, "typo.glsl:3");
    let err = stderr(&o);
    assert!(
        err.contains("undeclaredThing")
            && err.contains("(included from")
            && err.contains("typo.rgen:4"),
        "{err}"
    );
    // Without -I the engine header is not found; the message says where it looked.
    let o = patch(&chit, "rchit", &["-D", "MAX_MATERIALS=8"]);
    assert_one_line_error(&o, 9, "render/bindings.glsl");
    assert!(stderr(&o).contains("searched"), "{}", stderr(&o));
    // An #error in a nested header (define forgotten) names the header and the chain.
    let o = patch(&chit, "rchit", &["-I", inc.to_str().unwrap()]);
    assert_one_line_error(&o, 9, "MAX_MATERIALS must be defined");
    assert!(stderr(&o).contains("render/bindings.glsl:"), "{}", stderr(&o));
    // An include cycle ends with one line instead of a hang.
    std::fs::write(d.path().join("cycle.comp"), "#version 460\n#extension GL_GOOGLE_include_directive : require\n#include \"a.glsl\"\nlayout(local_size_x = 1) in;\nvoid main() {}\n").unwrap();
    std::fs::write(d.path().join("a.glsl"), "#include \"b.glsl\"\n").unwrap();
    std::fs::write(d.path().join("b.glsl"), "#include \"a.glsl\"\n").unwrap();
    let o = patch(&d.path().join("cycle.comp"), "comp", &[]);
    assert_one_line_error(&o, 9, "include cycle");
    // Bad flags are usage errors.
    assert_one_line_error(&patch(&chit, "rchit", &["-D", "1BAD=2"]), 2, "GLSL identifier");
    // (a folder of the test's own that is not there: a fixed path could exist on the machine)
    let missing = d.path().join("no-such-dir");
    assert_one_line_error(
        &patch(&chit, "rchit", &["-I", missing.to_str().unwrap()]),
        2,
        "not a directory",
    );
    assert!(!out.exists(), "nothing written");
}

fn corpus() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/patch-corpus")
}

/// Inputs are SPIR-V or GLSL by content, stages come from names (`--stage` overrides), `-o` is
/// optional (beside the input), `-o -` writes the module to stdout, `--emit-unpatched` keeps the
/// compiled input.
#[test]
fn inputs_stages_and_outputs_need_no_flags() {
    let d = rtprobe::tempdir::tempdir().unwrap();
    let rgen = d.path().join("camera.rgen");
    std::fs::copy(corpus().join("nested/raygen.rgen"), &rgen).unwrap();
    let inc = corpus().join("include");
    let inc = inc.to_str().unwrap();
    let o = run(&["patch", rgen.to_str().unwrap(), "-I", inc, "-a", "as-to-address"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = d.path().join("camera.rgen.patched.spv");
    val(&out);
    assert!(stdout(&o).contains(&format!("wrote {}", out.display())), "{}", stdout(&o));
    let contract: serde_json::Value = serde_json::from_slice(
        &std::fs::read(d.path().join("camera.rgen.patched.contract.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(contract["schema"], "rtprobe.patch-contract/1");
    assert_eq!(contract["addresses"][0]["offset"], 48, "past the nested struct's padding");
    assert_eq!(contract["modules"][0]["stage"], "raygen");
    // The patched module is SPIR-V: patched again, it is read as such (stage from its entry point).
    let again = run(&["patch", out.to_str().unwrap(), "-a", "nonuniform", "-o", "-"]);
    assert_one_line_error(&again, 9, "nothing to patch");
    // -o -: the module on stdout, the lines on stderr; --emit-unpatched: the compiled input.
    let unpatched = d.path().join("u.spv");
    let o = run(&[
        "patch",
        rgen.to_str().unwrap(),
        "-I",
        inc,
        "-a",
        "as-to-address",
        "-o",
        "-",
        "--emit-unpatched",
        unpatched.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(o.stdout[..4], 0x0723_0203u32.to_le_bytes(), "SPIR-V on stdout");
    assert!(stderr(&o).contains("as-to-address: 1 loads rewritten"), "{}", stderr(&o));
    val(&unpatched);
    assert!(
        dis(&unpatched).contains("OpTypeAccelerationStructureKHR")
            && dis(&unpatched).contains("DescriptorSet")
    );
    // A name that says no stage needs --stage; NAME.rgen.glsl says it.
    let plain = d.path().join("shader.glsl");
    std::fs::copy(&rgen, &plain).unwrap();
    let o = run(&["patch", plain.to_str().unwrap(), "-I", inc, "-a", "as-to-address", "-o", "-"]);
    assert_one_line_error(&o, 2, "cannot tell the stage");
    let o = run(&[
        "patch",
        plain.to_str().unwrap(),
        "-I",
        inc,
        "-a",
        "as-to-address",
        "--stage",
        "rgen",
        "-o",
        "-",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let named = d.path().join("camera.rgen.glsl");
    std::fs::copy(&rgen, &named).unwrap();
    let o = run(&["patch", named.to_str().unwrap(), "-I", inc, "-a", "as-to-address", "-o", "-"]);
    assert!(o.status.success(), "{}", stderr(&o));
    // Several inputs write to a folder; one module cannot go to stdout with others.
    let o = run(&[
        "patch",
        rgen.to_str().unwrap(),
        named.to_str().unwrap(),
        "-I",
        inc,
        "-a",
        "as-to-address",
        "-o",
        "-",
    ]);
    assert_one_line_error(&o, 2, "give one input");
}

/// A stage patched alone that had no push block gets one at byte 0, with a warning; patched with
/// its pipeline, its address goes past the other stages' push data and nobody warns.
#[test]
fn a_lone_stage_without_push_constants_is_warned_about() {
    let d = rtprobe::tempdir::tempdir().unwrap();
    let inc = corpus().join("include");
    let rgen = corpus().join("push/raygen.rgen");
    let o = run(&[
        "patch",
        rgen.to_str().unwrap(),
        "-I",
        inc.to_str().unwrap(),
        "-a",
        "as-to-address",
        "-o",
        d.path().join("a.spv").to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("warning:") && stderr(&o).contains("had no push-constant block"),
        "{}",
        stderr(&o)
    );
    assert!(stdout(&o).contains("offset 0"), "{}", stdout(&o));
    let (hit, miss) = (corpus().join("push/hit.rchit"), corpus().join("push/miss.rmiss"));
    let o = run(&[
        "patch",
        rgen.to_str().unwrap(),
        hit.to_str().unwrap(),
        miss.to_str().unwrap(),
        "-I",
        inc.to_str().unwrap(),
        "-a",
        "as-to-address",
        "-o",
        d.path().to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!stderr(&o).contains("warning"), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("push/raygen.rgen: as-to-address") && stdout(&o).contains("offset 24"),
        "{}",
        stdout(&o)
    );
    assert!(
        stdout(&o).contains("bytes 24..32 for VK_SHADER_STAGE_RAYGEN_BIT_KHR"),
        "{}",
        stdout(&o)
    );
}

/// An input that fails spirv-val is said to be invalid before any patch — never the patch's fault.
#[test]
fn an_invalid_input_is_blamed_on_the_input() {
    let d = rtprobe::tempdir::tempdir().unwrap();
    let good = d.path().join("good.spv");
    assemble(&shaders().join("as_array.spvasm"), &good);
    let b = std::fs::read(&good).unwrap();
    let mut w: Vec<u32> =
        b.chunks_exact(4).map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
    // Drop `OpCapability RayTracingKHR`: still loads, no longer valid.
    let at =
        w.windows(2).position(|p| p == [0x0002_0011, 4479]).expect("OpCapability RayTracingKHR");
    w.drain(at..at + 2);
    let bad = d.path().join("bad.spv");
    std::fs::write(&bad, w.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>()).unwrap();
    let out = d.path().join("o.spv");
    let o =
        run(&["patch", bad.to_str().unwrap(), "-a", "as-to-address", "-o", out.to_str().unwrap()]);
    assert_one_line_error(&o, 9, "fails spirv-val before any patch");
    assert!(stderr(&o).contains("the input itself is invalid"), "{}", stderr(&o));
    assert!(!stderr(&o).contains("patched"), "{}", stderr(&o));
    assert!(!out.exists());
    // --no-spirv-val patches it anyway (the output is not checked either).
    let o = run(&[
        "patch",
        bad.to_str().unwrap(),
        "-a",
        "as-to-address",
        "-o",
        out.to_str().unwrap(),
        "--no-spirv-val",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
}

/// Slang's SPIR-V carries its own source-language tag, which SPIRV-Tools 2023.1 (Debian 12's)
/// rejects: that validator is named too old for it, not the patch. The sid root's 2026.x
/// validates it. (Assembling the Slang module needs a spirv-as that knows the tag: the sid
/// root's.)
#[test]
fn a_validator_too_old_for_a_module_is_named_not_blamed() {
    let Some(root) = rtprobe::tools::sid_root() else {
        eprintln!("skipped: no sid root (scripts/setup-sid) to assemble Slang's module");
        return;
    };
    let d = rtprobe::tempdir::tempdir().unwrap();
    let spv = d.path().join("slang.spv");
    rtprobe::tools::spirv::assemble(&corpus().join("slang/closesthit.spvasm"), &spv, "vulkan1.2")
        .unwrap();
    let out = d.path().join("o.spv");
    let args =
        ["patch", spv.to_str().unwrap(), "-a", "ssbo-to-address", "-o", out.to_str().unwrap()];
    let o = run(&args);
    assert!(o.status.success(), "with {}: {}", root.display(), stderr(&o));
    let host = run_env(&args, &[("RTPROBE_SID_ROOT", "/nonexistent")]);
    let host_val = std::process::Command::new("spirv-val").arg("--version").output();
    let old = host_val.is_ok_and(|v| String::from_utf8_lossy(&v.stdout).contains("v2023."));
    if old {
        assert_one_line_error(&host, 9, "too old for the module's OpSource language Slang (11)");
        assert!(stderr(&host).contains("--no-spirv-val") && !stderr(&host).contains("patched"));
    } else {
        assert!(host.status.success(), "{}", stderr(&host));
    }
}

/// The bundled compiler predates GL_EXT_shader_invocation_reorder, the host's glslang 12 too; the
/// sid root's glslang 16.6 compiles the SER raygen, and without it the error says so in one line.
#[test]
fn a_ser_raygen_compiles_with_the_sid_roots_glslang_or_says_why_not() {
    let d = rtprobe::tempdir::tempdir().unwrap();
    let rgen = corpus().join("ser/raygen.rgen");
    let inc = corpus().join("include");
    let out = d.path().join("o.spv");
    let args = [
        "patch",
        rgen.to_str().unwrap(),
        "-I",
        inc.to_str().unwrap(),
        "-a",
        "as-to-address",
        "-o",
        out.to_str().unwrap(),
    ];
    let o = run_env(
        &args,
        &[
            ("RTPROBE_SID_ROOT", "/nonexistent"),
            ("RTPROBE_GLSLANG", "/nonexistent/glslangValidator"),
        ],
    );
    assert_one_line_error(&o, 9, "no GLSL compiler with GL_EXT_shader_invocation_reorder");
    assert!(
        stderr(&o).contains("no sid root here") && stderr(&o).contains("scripts/setup-sid"),
        "{}",
        stderr(&o)
    );
    if rtprobe::tools::sid_root().is_some() {
        let o = run(&args);
        assert!(o.status.success(), "{}", stderr(&o));
        // The newest spirv-dis: the host's does not know the SER capability either.
        let b = std::fs::read(&out).unwrap();
        let w: Vec<u32> =
            b.chunks_exact(4).map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
        let text = rtprobe::tools::spirv::disassemble(&w, false).unwrap();
        assert!(text.contains("OpCapability ShaderInvocationReorderEXT"), "{text}");
        assert!(text.contains("OpConvertUToAccelerationStructureKHR"), "{text}");
    }
}

/// GLSL without #version: one error line, nothing on stdout (glslang would print its thousands of
/// built-in declarations there); `-D` takes function-like macros, and refuses what is not one.
#[test]
fn glsl_front_end_errors_are_one_line() {
    let o = run(&[
        "patch",
        corpus().join("bad/noversion.rgen").to_str().unwrap(),
        "-a",
        "as-to-address",
        "-o",
        "-",
    ]);
    assert_one_line_error(&o, 9, "no #version line");
    assert!(o.stdout.is_empty(), "{} bytes on stdout", o.stdout.len());
    let rgen = corpus().join("defines/tonemap.rgen");
    let inc = corpus().join("include");
    let o = run(&[
        "patch",
        rgen.to_str().unwrap(),
        "-I",
        inc.to_str().unwrap(),
        "-D",
        "TONEMAP(c)=c/(c+1.0)",
        "-a",
        "as-to-address",
        "-o",
        "-",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = run(&[
        "patch",
        rgen.to_str().unwrap(),
        "-I",
        inc.to_str().unwrap(),
        "-D",
        "TONEMAP(1c)=c",
        "-a",
        "as-to-address",
        "-o",
        "-",
    ]);
    assert_one_line_error(&o, 2, "function-like macro");
    let help = stdout(&run(&["patch", "--help"]));
    for p in ["as-to-address", "nonuniform", "pin-index", "ssbo-to-address"] {
        assert!(help.contains(p), "{p} missing from --help: {help}");
    }
}
