//! The patch corpus (`tests/fixtures/patch-corpus/`): engine-like shaders written for these tests —
//! GLSL with includes (a Latin-1 header, a function-like `-D`, unbounded bindless arrays), and DXC-, Slang- and older-DXC
//! (SPV_NV_ray_tracing) modules as SPIR-V assembly — each case patched by `rtprobe patch`, and
//! every result checked here, independently of the command's own checks:
//! - valid under the newest spirv-val with the options its input needs (`invalid` otherwise);
//! - one push-constant address per descriptor the patch removed, none shared (`merged`
//!   otherwise), read from the host contract against the descriptors each module lost;
//! - where lavapipe runs the pipeline, `--verify`: the patched pipeline, fed as the contract says,
//!   renders the unpatched pipeline's image texel for texel, with distinct data per descriptor.
//!
//! Refusals must be one line naming the reason. The table of counts is printed; 0 invalid and 0
//! merged are required.
mod common;
use common::*;
use rtprobe::harness::reflect::{self, BindingKind};
use rtprobe::model::contract::HostContract;
use rtprobe::tools::spirv::{self as tools, Validation};
use std::collections::BTreeSet;
use std::os::unix::process::ExitStatusExt;
use std::path::{Path, PathBuf};

fn corpus() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/patch-corpus")
}

/// What a case must come to.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Expect {
    /// Patched, valid, and identical on lavapipe (`--verify`).
    Verified,
    /// Patched and valid; not run on the host's lavapipe, for this reason.
    Valid(&'static str),
    /// Refused with one line containing this.
    Refused(&'static str),
}

struct Case {
    name: &'static str,
    inputs: &'static [&'static str],
    patches: &'static str,
    extra: &'static [&'static str],
    expect: Expect,
}

const SCENE: &[&str] = &["scene/raygen.rgen", "scene/hit.rchit", "common/miss.rmiss"];
const PUSH: &[&str] = &["push/raygen.rgen", "push/hit.rchit", "push/miss.rmiss"];
const BINDLESS: &[&str] = &["common/raygen.rgen", "bindless/hit.rchit", "common/miss.rmiss"];
const DXC: &[&str] = &["dxc/raygen.spvasm", "dxc/closesthit.spvasm", "dxc/miss.spvasm"];

/// Integers read from a buffer and from push constants index other arrays (review item 1).
const INDEXED: Case = Case {
    name: "index buffer indexes the vertex buffer",
    inputs: &["common/raygen.rgen", "indexed/hit.rchit", "common/miss.rmiss"],
    patches: "ssbo-to-address",
    extra: &[],
    expect: Expect::Verified,
};
const PUSH_INDEX: Case = Case {
    name: "material index in push constants",
    inputs: &["common/raygen.rgen", "pushidx/hit.rchit", "common/miss.rmiss"],
    patches: "ssbo-to-address",
    extra: &[],
    expect: Expect::Verified,
};

/// Runtime arrays indexed per pixel (review item 3).
const PER_PIXEL: Case = Case {
    name: "per-pixel runtime arrays",
    inputs: &["perpixel/raygen.rgen", "perpixel/hit.rchit", "common/miss.rmiss"],
    patches: "ssbo-to-address",
    extra: &[],
    expect: Expect::Verified,
};

/// An atomic append queue beside the image (review item 6).
const APPEND: Case = Case {
    name: "atomic append queue",
    inputs: &["append/raygen.rgen", "common/hit.rchit", "common/miss.rmiss"],
    patches: "as-to-address",
    extra: &[],
    expect: Expect::Verified,
};

const CASES: &[Case] = &[
    INDEXED,
    APPEND,
    PER_PIXEL,
    PUSH_INDEX,
    Case { name: "two TLASes, one address each", inputs: SCENE, patches: "as-to-address", extra: &[], expect: Expect::Verified },
    Case { name: "three SSBO arrays, one table each", inputs: SCENE, patches: "ssbo-to-address", extra: &[], expect: Expect::Verified },
    Case { name: "both address patches together", inputs: SCENE, patches: "as-to-address,ssbo-to-address", extra: &[], expect: Expect::Verified },
    Case { name: "set=3 picks the shadow TLAS only", inputs: SCENE, patches: "as-to-address", extra: &["--option", "set=3"], expect: Expect::Verified },
    Case { name: "unbounded arrays indexed by custom index", inputs: BINDLESS, patches: "ssbo-to-address", extra: &[], expect: Expect::Verified },
    Case { name: "mixed int/uint indices pinned", inputs: &["scene/hit.rchit"], patches: "pin-index", extra: &[], expect: Expect::Valid("pin-index changes the index by design") },
    Case { name: "overlapping push ranges", inputs: PUSH, patches: "as-to-address", extra: &[], expect: Expect::Verified },
    Case { name: "nonuniform on a forgotten nonuniformEXT", inputs: PUSH, patches: "nonuniform", extra: &[], expect: Expect::Verified },
    Case { name: "nested 36-byte push struct", inputs: &["nested/raygen.rgen", "common/hit.rchit", "common/miss.rmiss"], patches: "as-to-address", extra: &[], expect: Expect::Verified },
    Case { name: "layout(scalar) blocks", inputs: &["common/raygen.rgen", "scalar/hit.rchit", "common/miss.rmiss"], patches: "ssbo-to-address", extra: &[], expect: Expect::Verified },
    Case { name: "uint64 declared after the push block", inputs: &["late64/raygen.rgen", "common/hit.rchit", "common/miss.rmiss"], patches: "as-to-address", extra: &[], expect: Expect::Verified },
    Case { name: "Latin-1 header", inputs: &["latin1/raygen.rgen", "common/hit.rchit", "common/miss.rmiss"], patches: "as-to-address", extra: &[], expect: Expect::Verified },
    Case { name: "function-like -D", inputs: &["defines/tonemap.rgen", "common/hit.rchit", "common/miss.rmiss"], patches: "as-to-address", extra: &["-D", "TONEMAP(c)=c/(c+1.0)"], expect: Expect::Verified },
    Case { name: "DXC pipeline", inputs: DXC, patches: "as-to-address,ssbo-to-address", extra: &[], expect: Expect::Verified },
    Case { name: "DXC closest-hit, nonuniform stripped", inputs: DXC, patches: "nonuniform", extra: &["--option", "strip=true"], expect: Expect::Verified },
    Case { name: "Slang closest-hit", inputs: &["common/raygen.rgen", "slang/closesthit.spvasm", "common/miss.rmiss"], patches: "ssbo-to-address", extra: &[], expect: Expect::Valid("the host's validation layer predates Slang's source tag: verified in the sid root (slang_pipeline_verifies_in_the_sid_root)") },
    Case { name: "SPV_NV_ray_tracing raygen (older DXC)", inputs: &["nv/raygen.spvasm"], patches: "as-to-address", extra: &[], expect: Expect::Valid("lavapipe has no VK_NV_ray_tracing") },
    Case { name: "SER raygen (GL_EXT_shader_invocation_reorder)", inputs: &["ser/raygen.rgen"], patches: "as-to-address", extra: &[], expect: Expect::Valid("no lavapipe has VK_EXT_ray_tracing_invocation_reorder (25 and the sid root's 26: `rtprobe caps` says absent)") },
    Case { name: "store into an SSBO array", inputs: &["bad/store.rchit"], patches: "ssbo-to-address", extra: &[], expect: Expect::Refused("only loads are rewritten") },
    Case { name: "push range past 128 bytes", inputs: &["bad/full_push.rchit"], patches: "as-to-address", extra: &[], expect: Expect::Refused("maxPushConstantsSize 128") },
    Case { name: "no acceleration structure", inputs: &["common/miss.rmiss"], patches: "as-to-address", extra: &[], expect: Expect::Refused("nothing to patch") },
    Case { name: "GLSL without #version", inputs: &["bad/noversion.rgen"], patches: "as-to-address", extra: &[], expect: Expect::Refused("no #version line") },
];

/// The input files of a case, ready for `rtprobe patch`: GLSL as is, assembly assembled (by the
/// newest spirv-as) into `dir`.
fn prepare(inputs: &[&str], dir: &Path) -> Vec<PathBuf> {
    inputs
        .iter()
        .map(|i| {
            let src = corpus().join(i);
            if !i.ends_with(".spvasm") {
                return src;
            }
            let out = dir.join(i.replace('/', "_").replace(".spvasm", ".spv"));
            let env = if i.starts_with("nv/") { "vulkan1.1" } else { "vulkan1.2" };
            tools::assemble(&src, &out, env).unwrap_or_else(|e| panic!("{i}: {e}"));
            out
        })
        .collect()
}

fn words(p: &Path) -> Vec<u32> {
    let b = std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    b.chunks_exact(4).map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect()
}

/// The descriptors (set, binding) of a module that an address patch may replace: acceleration
/// structures and storage-buffer arrays.
fn addressable(w: &[u32]) -> BTreeSet<(u32, u32)> {
    let m = rtprobe::patches::load(&tools::bytes(w)).expect("loads");
    reflect::reflect(&m)
        .expect("reflects")
        .bindings
        .iter()
        .filter(|b| {
            b.kind == BindingKind::AccelerationStructure
                || matches!(b.kind, BindingKind::StorageBuffer(_))
        })
        .map(|b| (b.set, b.binding))
        .collect()
}

/// What one case came to.
#[derive(Default)]
struct Tally {
    compiled: usize,
    ok: usize,
    verified: usize,
    refused_right: usize,
    invalid: usize,
    merged: usize,
    /// Cases whose modules read an address where the contract does not put it (or past 128).
    offsets: usize,
    wrong: Vec<String>,
}

/// The outputs of a case: each input's patched module and the input as compiled.
fn outputs(inputs: &[PathBuf], dir: &Path) -> Vec<(PathBuf, PathBuf)> {
    inputs
        .iter()
        .map(|i| {
            let f = i.file_name().unwrap().to_string_lossy().into_owned();
            let stem = f.strip_suffix(".spv").unwrap_or(&f).to_string();
            (dir.join(format!("{stem}.patched.spv")), dir.join(format!("{stem}.unpatched.spv")))
        })
        .collect()
}

/// The offsets of the 8-byte members (64-bit integers, PhysicalStorageBuffer pointers) of a
/// module's push-constant block, read here with rspirv independently of the patches' code.
fn push_addresses(w: &[u32]) -> BTreeSet<u32> {
    use rspirv::dr::Operand;
    use rspirv::spirv::{Decoration, Op, StorageClass};
    let m = rtprobe::patches::load(&tools::bytes(w)).expect("loads");
    let def = |id: u32| m.types_global_values.iter().find(|i| i.result_id == Some(id));
    let id = |o: &Operand| match o {
        Operand::IdRef(x) => Some(*x),
        _ => None,
    };
    let mut out = BTreeSet::new();
    for v in m.types_global_values.iter().filter(|i| i.class.opcode == Op::Variable) {
        if v.operands.first() != Some(&Operand::StorageClass(StorageClass::PushConstant)) {
            continue;
        }
        let st = def(v.result_type.unwrap()).and_then(|p| id(&p.operands[1])).unwrap();
        let members = &def(st).expect("the push block").operands;
        for (k, o) in members.iter().enumerate() {
            let ty = def(id(o).unwrap()).unwrap();
            let eight = match ty.class.opcode {
                Op::TypeInt => ty.operands[0] == Operand::LiteralBit32(64),
                Op::TypePointer => {
                    ty.operands[0] == Operand::StorageClass(StorageClass::PhysicalStorageBuffer)
                }
                _ => false,
            };
            let offset = m.annotations.iter().find_map(|a| {
                let hit = a.class.opcode == Op::MemberDecorate
                    && a.operands[0] == Operand::IdRef(st)
                    && a.operands[1] == Operand::LiteralBit32(k as u32)
                    && a.operands[2] == Operand::Decoration(Decoration::Offset);
                hit.then(|| match a.operands[3] {
                    Operand::LiteralBit32(x) => x,
                    _ => u32::MAX,
                })
            });
            if eight {
                out.insert(offset.expect("push members have offsets"));
            }
        }
    }
    out
}

/// The push-constant offsets each stage's patched modules read addresses at (the 8-byte push
/// members the patch added) against the contract's: equal per stage, each inside the
/// `maxPushConstantsSize` 128 every device has, like the contract's range.
fn check_offsets(case: &Case, pairs: &[(PathBuf, PathBuf)], c: &HostContract, t: &mut Tally) {
    let mut found: std::collections::BTreeMap<String, BTreeSet<u32>> = Default::default();
    for (patched, unpatched) in pairs {
        let w = words(patched);
        let m = rtprobe::patches::load(&tools::bytes(&w)).expect("loads");
        let stage = reflect::reflect(&m).expect("reflects").stage;
        let added: BTreeSet<u32> =
            push_addresses(&w).difference(&push_addresses(&words(unpatched))).copied().collect();
        found.entry(stage).or_default().extend(added);
    }
    let mut wanted: std::collections::BTreeMap<String, BTreeSet<u32>> = Default::default();
    for a in &c.addresses {
        for st in &a.stages {
            wanted.entry(st.clone()).or_default().insert(a.offset);
        }
    }
    found.retain(|_, v| !v.is_empty());
    let range_end = c.push_range.as_ref().map_or(0, |r| r.offset + r.size);
    let past = found.values().flatten().any(|o| o + 8 > 128) || range_end > 128 || c.push_end > 128;
    let covered = c.addresses.iter().all(|a| {
        c.push_range.as_ref().is_some_and(|r| a.offset >= r.offset && a.offset + 8 <= range_end)
    });
    if found != wanted || past || !covered {
        t.offsets += 1;
        t.wrong.push(format!(
            "{}: the modules read addresses at {found:?}, the contract says {wanted:?} (range {:?}, push end {})",
            case.name, c.push_range, c.push_end
        ));
    }
}

/// Check a patched case: validity per module, one address per removed descriptor, each where
/// the contract says.
fn check_patched(
    case: &Case,
    pairs: &[(PathBuf, PathBuf)],
    contract: Option<HostContract>,
    t: &mut Tally,
) {
    let mut removed = BTreeSet::new();
    for (patched, unpatched) in pairs {
        let (input, output) = (words(unpatched), words(patched));
        t.compiled += 1;
        let (v, opts) = tools::validate_input(&input);
        assert_eq!(v, Validation::Valid, "{}: the input must validate", case.name);
        match tools::validate(&output, &opts) {
            Validation::Valid => {}
            other => {
                t.invalid += 1;
                t.wrong.push(format!("{}: {} invalid: {other:?}", case.name, patched.display()));
            }
        }
        removed.extend(addressable(&input).difference(&addressable(&output)).copied());
    }
    if let Some(c) = &contract {
        check_offsets(case, pairs, c, t);
    }
    let addresses = contract.map(|c| c.addresses).unwrap_or_default();
    let offsets: BTreeSet<u32> = addresses.iter().map(|a| a.offset).collect();
    let listed: Vec<(u32, u32)> = addresses.iter().map(|a| (a.set, a.binding)).collect();
    let each_once = removed.iter().all(|d| listed.iter().filter(|l| *l == d).count() == 1);
    if offsets.len() != addresses.len() || !each_once || listed.len() != removed.len() {
        t.merged += 1;
        t.wrong.push(format!(
            "{}: descriptors {removed:?} but addresses {listed:?} at {offsets:?}",
            case.name
        ));
    }
}

fn run_case(case: &Case, t: &mut Tally) {
    let d = rtprobe::tempdir::tempdir().unwrap();
    let inputs = prepare(case.inputs, d.path());
    let out = d.path().join("out");
    let unpatched = d.path().join("out");
    let mut args: Vec<String> = vec!["patch".into()];
    args.extend(inputs.iter().map(|p| p.to_string_lossy().into_owned()));
    let inc = corpus().join("include");
    args.extend(["-I", inc.to_str().unwrap(), "-a", case.patches].map(String::from));
    args.extend(case.extra.iter().map(|s| s.to_string()));
    let (o_flag, contract) = if inputs.len() > 1 {
        (out.clone(), out.join("pipeline.contract.json"))
    } else {
        let f = inputs[0].file_name().unwrap().to_string_lossy().into_owned();
        let stem = f.strip_suffix(".spv").unwrap_or(&f).to_string();
        (out.join(format!("{stem}.patched.spv")), out.join(format!("{stem}.patched.contract.json")))
    };
    std::fs::create_dir_all(&out).unwrap();
    args.extend(["-o".to_string(), o_flag.to_string_lossy().into_owned()]);
    let emit =
        if inputs.len() > 1 { unpatched.clone() } else { outputs(&inputs, &out)[0].1.clone() };
    args.extend(["--emit-unpatched".to_string(), emit.to_string_lossy().into_owned()]);
    if case.expect == Expect::Verified {
        args.push("--verify".into());
    }
    let refs: Vec<&str> = args.iter().map(String::as_str).collect();
    let o = run(&refs);
    match case.expect {
        Expect::Refused(needle) => {
            assert_one_line_error(&o, 9, needle);
            assert!(
                std::fs::read_dir(&out).unwrap().next().is_none(),
                "{}: nothing written",
                case.name
            );
            t.refused_right += 1;
        }
        Expect::Verified | Expect::Valid(_) => {
            assert!(o.status.success(), "{}: {}", case.name, stderr(&o));
            let c = std::fs::read(&contract)
                .ok()
                .map(|b| serde_json::from_slice(&b).expect("contract JSON"));
            check_patched(case, &outputs(&inputs, &out), c, t);
            t.ok += 1;
            if case.expect == Expect::Verified {
                let s = stdout(&o);
                assert!(
                    s.contains("verified on") && s.contains("texels identical"),
                    "{}: {s}",
                    case.name
                );
                t.verified += 1;
            }
        }
    }
}

#[test]
fn the_corpus_patches_validly_without_merging_and_renders_identically() {
    let mut t = Tally::default();
    for case in CASES {
        run_case(case, &mut t);
    }
    let md = table(&t);
    println!("{md}");
    assert!(t.wrong.is_empty(), "{:#?}", t.wrong);
    assert_eq!((t.invalid, t.merged, t.offsets), (0, 0, 0));
    assert_eq!(t.ok + t.refused_right, CASES.len());
    // The committed table (reports/patch/corpus.md) is this test's: it fails when they differ;
    // RTPROBE_UPDATE_REPORTS=1 rewrites it.
    let committed = Path::new(env!("CARGO_MANIFEST_DIR")).join("reports/patch/corpus.md");
    if std::env::var("RTPROBE_UPDATE_REPORTS").is_ok_and(|v| v == "1") {
        std::fs::create_dir_all(committed.parent().unwrap()).unwrap();
        std::fs::write(&committed, &md).unwrap();
    }
    let old = std::fs::read_to_string(&committed).unwrap_or_default();
    assert_eq!(old, md, "reports/patch/corpus.md is stale: re-run with RTPROBE_UPDATE_REPORTS=1");
}

/// Review item 1: buffers used to hold float bits in every word, so an index read from an index
/// buffer or from push constants was ~0x3F80xxxx: the patched pipeline (through addresses)
/// crashed, or the unpatched one did. Integer words now hold small indices: both verify.
#[test]
fn indices_read_from_buffers_and_push_constants_verify() {
    let mut t = Tally::default();
    for case in [&INDEXED, &PUSH_INDEX] {
        run_case(case, &mut t);
    }
    assert_eq!(t.verified, 2, "{:#?}", t.wrong);
}

/// Review item 3: a block's runtime array had 256 elements while a per-pixel index reaches
/// 64 × 64 − 1: the patched hit shader read past the history buffers through addresses (the
/// descriptor path read zeros) and a correct patch failed. Now every runtime array covers every
/// pixel, and the per-pixel accumulation buffer is compared whole.
#[test]
fn per_pixel_runtime_arrays_cover_the_trace() {
    let d = rtprobe::tempdir::tempdir().unwrap();
    let inputs = prepare(PER_PIXEL.inputs, d.path());
    let out = d.path().join("out");
    let mut args: Vec<String> = vec!["patch".into()];
    args.extend(inputs.iter().map(|p| p.to_string_lossy().into_owned()));
    let inc = corpus().join("include");
    let o = out.to_string_lossy().into_owned();
    args.extend(
        ["-I", inc.to_str().unwrap(), "-a", "ssbo-to-address", "-o", &o, "--verify"]
            .map(String::from),
    );
    let refs: Vec<&str> = args.iter().map(String::as_str).collect();
    let r = run(&refs);
    assert!(r.status.success(), "{}", stderr(&r));
    let s = stdout(&r);
    assert!(s.contains("storage buffer set 0 binding 3[0]: 16384 4-byte words"), "{s}");
}

/// `rtprobe patch INPUTS -a PATCHES -o OUT --verify` (and `extra`) on corpus files, with `env`.
fn verify_cli(
    inputs: &[&str],
    patches: &str,
    extra: &[&str],
    env: &[(&str, &str)],
) -> (std::process::Output, rtprobe::tempdir::TempDir) {
    let d = rtprobe::tempdir::tempdir().unwrap();
    let inputs = prepare(inputs, d.path());
    let out = d.path().join("out");
    std::fs::create_dir_all(&out).unwrap();
    let mut args: Vec<String> = vec!["patch".into()];
    args.extend(inputs.iter().map(|p| p.to_string_lossy().into_owned()));
    let inc = corpus().join("include");
    let o = out.to_string_lossy().into_owned();
    args.extend(
        ["-I", inc.to_str().unwrap(), "-a", patches, "-o", &o, "--verify"].map(String::from),
    );
    args.extend(extra.iter().map(|s| s.to_string()));
    let refs: Vec<&str> = args.iter().map(String::as_str).collect();
    (run_env(&refs, env), d)
}

/// Review item 5: a writable buffer the trace never writes compared "identical" (its initial
/// fill) and verify passed comparing nothing. Now it is "not written", and with nothing else
/// written the pipeline is unfit: exit 9, nothing written.
#[test]
fn a_pipeline_that_never_writes_its_buffer_is_unfit() {
    let inputs = ["unwritten/raygen.rgen", "common/hit.rchit", "common/miss.rmiss"];
    let (o, d) = verify_cli(&inputs, "as-to-address", &[], &[]);
    assert_one_line_error(&o, 9, "writable buffers were not written by the trace");
    assert!(std::fs::read_dir(d.path().join("out")).unwrap().next().is_none(), "nothing written");
}

/// Review item 6: an atomic append queue's record order is the driver's scheduling (lavapipe
/// with 8 threads reorders it run to run), so a correct patch failed at random. Words that differ
/// between two unpatched runs are left out (and counted); a reordered queue is no difference.
/// Three runs, each with 8 llvmpipe threads.
#[test]
fn an_append_queue_verifies_every_time() {
    for i in 0..3 {
        let (o, _d) = verify_cli(APPEND.inputs, APPEND.patches, &[], &[("LP_NUM_THREADS", "8")]);
        assert!(o.status.success(), "run {i}: {}", stderr(&o));
        let s = stdout(&o);
        // The queue in the unpatched order is compared; in another order it is said and not
        // counted (the image decides): never a failure for the driver's scheduling.
        assert!(
            s.contains("storage buffer set 0 binding 4[0]: 16388 4-byte words identical")
                || s.contains(
                    "storage buffer set 0 binding 4[0]: the same records in another order"
                ),
            "run {i}: {s}"
        );
        assert!(s.contains("texels identical"), "run {i}: {s}");
        println!("run {i}: {}", s.lines().find(|l| l.contains("binding 4")).unwrap_or_default());
    }
}

/// Review item 7: end to end, a wrong patch (the child swaps the contract's two table addresses,
/// `RTPROBE_VERIFY_FAULT=swap`) makes `rtprobe patch --verify` exit 1 and write nothing.
#[test]
fn a_wrong_patch_exits_1_and_writes_nothing() {
    let d = rtprobe::tempdir::tempdir().unwrap();
    let (args, out) = bindless_args(d.path(), &["--verify"]);
    let refs: Vec<&str> = args.iter().map(String::as_str).collect();
    let o = run_env(&refs, &[("RTPROBE_VERIFY_FAULT", "swap")]);
    assert_one_line_error(&o, 1, "differs from the unpatched one's");
    assert!(std::fs::read_dir(&out).unwrap().next().is_none(), "nothing written");
}

/// Review item 8: pin-index changes the index by design, so `--verify` would always fail it:
/// refused up front (exit 2, one line saying why), nothing written.
#[test]
fn verify_refuses_pin_index_up_front() {
    let (o, d) = verify_cli(SCENE, "pin-index", &[], &[]);
    assert_one_line_error(&o, 2, "--verify cannot check pin-index");
    assert!(std::fs::read_dir(d.path().join("out")).unwrap().next().is_none(), "nothing written");
}

/// Review item 9: `--verify-timeout` took any u64 and `max(1) * 1000` overflowed; now 1..=3600.
#[test]
fn verify_timeout_out_of_range_is_a_usage_error() {
    for t in ["0", "3601", "18446744073709551615"] {
        let (o, d) = verify_cli(
            &["common/raygen.rgen", "common/hit.rchit", "common/miss.rmiss"],
            "as-to-address",
            &["--verify-timeout", t],
            &[],
        );
        assert_eq!(o.status.code(), Some(2), "{t}: {}", stderr(&o));
        assert!(stderr(&o).contains("--verify-timeout"), "{t}: {}", stderr(&o));
        assert!(std::fs::read_dir(d.path().join("out")).unwrap().next().is_none(), "{t}");
    }
}

/// The corpus table (reports/patch/corpus.md): the counts, then each case.
fn table(t: &Tally) -> String {
    let mut md = String::from("# The patch corpus\n\n");
    md.push_str(
        "Written by `RTPROBE_UPDATE_REPORTS=1 cargo test --release --test patch_corpus \
        the_corpus_patches_validly_without_merging_and_renders_identically` (the test fails when \
        this file differs from what it measures). The shaders are engine-like ones written for the \
        tests (`tests/fixtures/patch-corpus/`); each case is `rtprobe patch` on its inputs as one \
        pipeline, checked independently: spirv-val (the newest, with the input's options), one \
        address per removed descriptor (`merged` otherwise), each patched module's push members \
        at the contract's offsets within 128 bytes (`offset ≠ contract` otherwise), and \
        `--verify` on lavapipe 25 (images texel for texel, writable buffers byte for byte).\n\n",
    );
    md.push_str("| cases | modules compiled (patched cases) | ok (patched, valid) | ran identical on lavapipe | refused right | invalid | merged | offset ≠ contract |\n");
    md.push_str("|---|---|---|---|---|---|---|---|\n");
    md.push_str(&format!(
        "| {} | {} | {} | {} | {} | {} | {} | {} |\n\n",
        CASES.len(),
        t.compiled,
        t.ok,
        t.verified,
        t.refused_right,
        t.invalid,
        t.merged,
        t.offsets
    ));
    md.push_str("| case | inputs | patches | result |\n|---|---|---|---|\n");
    for case in CASES {
        let how = match case.expect {
            Expect::Verified => "patched, valid, identical on lavapipe".to_string(),
            Expect::Valid(why) => format!("patched, valid; not run: {why}"),
            Expect::Refused(why) => format!("refused: {why}"),
        };
        let mut patches = case.patches.to_string();
        if !case.extra.is_empty() {
            patches = format!("{patches} `{}`", case.extra.join(" "));
        }
        md.push_str(&format!(
            "| {} | {} | {patches} | {how} |\n",
            case.name,
            case.inputs.join(" ")
        ));
    }
    md
}

/// The two-TLAS case patched (no --verify): its directory, inputs, outputs and contract path.
fn two_tlas_case() -> (rtprobe::tempdir::TempDir, Vec<(PathBuf, PathBuf)>, PathBuf) {
    let d = rtprobe::tempdir::tempdir().unwrap();
    let inputs = prepare(SCENE, d.path());
    let out = d.path().join("out");
    let mut args: Vec<String> = vec!["patch".into()];
    args.extend(inputs.iter().map(|p| p.to_string_lossy().into_owned()));
    let inc = corpus().join("include");
    let o = out.to_string_lossy().into_owned();
    args.extend(
        ["-I", inc.to_str().unwrap(), "-a", "as-to-address", "-o", &o, "--emit-unpatched", &o]
            .map(String::from),
    );
    let refs: Vec<&str> = args.iter().map(String::as_str).collect();
    let r = run(&refs);
    assert!(r.status.success(), "{}", stderr(&r));
    let pairs = outputs(&inputs, &out);
    (d, pairs, out.join("pipeline.contract.json"))
}

/// Twin of the corpus checks: a contract giving two descriptors one address is counted merged,
/// one placing an address where no module reads it (or past 128 bytes) a wrong offset, a broken
/// output invalid.
#[test]
fn the_checks_catch_a_shared_address_and_an_invalid_module() {
    let (_d, pairs, contract) = two_tlas_case();
    let case = &CASES[0];
    let mut c: HostContract = serde_json::from_slice(&std::fs::read(&contract).unwrap()).unwrap();
    let mut t = Tally::default();
    check_patched(case, &pairs, Some(c.clone()), &mut t);
    assert_eq!((t.invalid, t.merged, t.offsets), (0, 0, 0), "{:?}", t.wrong);
    assert_eq!(c.addresses.len(), 2, "set 2 and set 3 binding 0");
    let good = c.clone();
    // One address for both descriptors, as `binding=0` gave before: merged.
    c.addresses[1].offset = c.addresses[0].offset;
    let mut t = Tally::default();
    check_patched(case, &pairs, Some(c.clone()), &mut t);
    assert_eq!(t.merged, 1);
    // An address planted at an offset no module reads it at (the modules read 0 and 8):
    // a wrong offset, as is a range past maxPushConstantsSize 128.
    let mut planted = good.clone();
    planted.addresses[1].offset = 64;
    planted.push_range.as_mut().unwrap().size = 72;
    let mut t = Tally::default();
    check_patched(case, &pairs, Some(planted), &mut t);
    assert_eq!((t.offsets, t.merged), (1, 0), "{:?}", t.wrong);
    let mut past = good.clone();
    past.push_range.as_mut().unwrap().size = 200;
    let mut t = Tally::default();
    check_patched(case, &pairs, Some(past), &mut t);
    assert_eq!(t.offsets, 1, "{:?}", t.wrong);
    // One descriptor left out of the contract: merged too.
    c.addresses.pop();
    let mut t = Tally::default();
    check_patched(case, &pairs, Some(c), &mut t);
    assert_eq!(t.merged, 1);
    // An output that uses 64-bit integers without declaring Int64: invalid.
    let mut w = words(&pairs[0].0);
    let at = w.windows(2).position(|p| p == [0x0002_0011, 11]).expect("OpCapability Int64");
    w.drain(at..at + 2);
    std::fs::write(&pairs[0].0, tools::bytes(&w)).unwrap();
    let mut t = Tally::default();
    check_patched(
        case,
        &pairs,
        Some(serde_json::from_slice(&std::fs::read(&contract).unwrap()).unwrap()),
        &mut t,
    );
    assert_eq!(t.invalid, 1, "{:?}", t.wrong);
}

/// A device for the harness, in this process.
fn gpu() -> rtprobe::vk::Gpu {
    let inst =
        std::sync::Arc::new(rtprobe::vk::Instance::new(&Default::default()).expect("instance"));
    let all = rtprobe::vk::features::query_all(&inst).expect("devices");
    let info = rtprobe::vk::features::select(&all, None).expect("a device").clone();
    rtprobe::vk::Gpu::new(inst, info, rtprobe::harness::requirements(false)).expect("device")
}

/// Twin of `--verify`: fed against the contract — the two TLAS addresses swapped — the patched
/// pipeline renders something else, so identical images mean each descriptor got its own data.
#[test]
fn verify_sees_two_tlases_swapped() {
    use rtprobe::harness::{self, UserModule};
    let (_d, pairs, contract) = two_tlas_case();
    let mut c: HostContract = serde_json::from_slice(&std::fs::read(&contract).unwrap()).unwrap();
    let module = |p: &Path| UserModule::new(&p.display().to_string(), &words(p)).unwrap();
    let before: Vec<UserModule> = pairs.iter().map(|p| module(&p.1)).collect();
    let after: Vec<UserModule> = pairs.iter().map(|p| module(&p.0)).collect();
    let (_, same) = harness::verify(gpu(), &before, &after, &c).unwrap();
    assert!(same.iter().all(|x| x.differing == 0 && x.distinct > 1000), "{same:?}");
    let (a, b) = (c.addresses[0].offset, c.addresses[1].offset);
    c.addresses[0].offset = b;
    c.addresses[1].offset = a;
    let (_, swapped) = harness::verify(gpu(), &before, &after, &c).unwrap();
    assert!(swapped[0].differing > 100, "{swapped:?}");
}

/// The Slang closest-hit under the sid root's lavapipe 26 and validation layers 1.4.363 (the
/// host's layers predate Slang's source tag): patched, verified identical, no validation message.
#[test]
fn slang_pipeline_verifies_in_the_sid_root() {
    let root = std::env::var_os("RTPROBE_SID_ROOT")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("/var/lib/rtprobe/sid-root"));
    if !root.join("etc/rtprobe-sid.stamp").exists() || unsafe { libc::geteuid() } != 0 {
        if std::env::var("RTPROBE_REQUIRE_SID").is_ok_and(|v| v == "1") {
            panic!(
                "RTPROBE_REQUIRE_SID=1 but no sid root at {} (or no root rights)",
                root.display()
            );
        }
        eprintln!(
            "skipped: no sid root at {} (scripts/setup-sid), or no root rights",
            root.display()
        );
        return;
    }
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = repo.join(format!("target/patch-corpus-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let inputs =
        prepare(&["common/raygen.rgen", "slang/closesthit.spvasm", "common/miss.rmiss"], &dir);
    let inc = corpus().join("include");
    let out = dir.join("out");
    let mut c = std::process::Command::new(repo.join("scripts/in-sid"));
    c.arg(env!("CARGO_BIN_EXE_rtprobe")).args(["--validate", "patch"]).args(&inputs);
    c.args([
        "-I",
        inc.to_str().unwrap(),
        "-a",
        "ssbo-to-address",
        "--verify",
        "-o",
        out.to_str().unwrap(),
    ]);
    let o = c.env_remove("RTPROBE_VALIDATE").output().expect("scripts/in-sid");
    let _ = std::fs::remove_dir_all(&dir);
    assert!(o.status.success(), "{}", stderr(&o));
    let s = stdout(&o);
    assert!(s.contains("verified on llvmpipe") && s.contains("texels identical"), "{s}");
    assert!(!stderr(&o).contains("Validation Error"), "{}", stderr(&o));
}

/// The bindless pipeline (unbounded SSBO arrays indexed by `gl_InstanceCustomIndexEXT`, a
/// writable hit log) patched with ssbo-to-address, and `patch`'s other arguments after it.
fn bindless_args(dir: &Path, extra: &[&str]) -> (Vec<String>, PathBuf) {
    let inputs = prepare(BINDLESS, dir);
    let out = dir.join("out");
    std::fs::create_dir_all(&out).unwrap();
    let mut args: Vec<String> = vec!["patch".into()];
    args.extend(inputs.iter().map(|p| p.to_string_lossy().into_owned()));
    let inc = corpus().join("include");
    let o = out.to_string_lossy().into_owned();
    args.extend(["-I", inc.to_str().unwrap(), "-a", "ssbo-to-address", "-o", &o].map(String::from));
    args.extend(extra.iter().map(|s| s.to_string()));
    (args, out)
}

/// Item 1 of the review: runtime arrays indexed by the custom index used to get 4 descriptors
/// while the scene's custom indices reach 2^24, and the in-process trace took rtprobe down with
/// a SIGSEGV. Now every index the scene produces is in bounds, and the writable log is compared.
#[test]
fn verify_runs_unbounded_arrays_indexed_by_the_custom_index() {
    let d = rtprobe::tempdir::tempdir().unwrap();
    let (args, _) = bindless_args(d.path(), &["--verify"]);
    let refs: Vec<&str> = args.iter().map(String::as_str).collect();
    let o = run(&refs);
    assert!(o.status.success(), "{:?}: {}", o.status, stderr(&o));
    let s = stdout(&o);
    assert!(s.contains("set 0 binding 1[0]: 4096 texels identical"), "{s}");
    assert!(s.contains("storage buffer set 0 binding 2[0]: 16384 4-byte words identical"), "{s}");
}

/// Twin: a driver that crashes or hangs while verifying is the verification's one-line outcome
/// (exit 8, nothing written), never a crash of rtprobe itself.
#[test]
fn a_crashing_or_hanging_verify_child_is_one_line_and_nothing_written() {
    for (fault, needle) in [
        ("crash", "died of signal 11 (SIGSEGV) at `trace patched`"),
        ("hang", "was silent for 12s and was killed at `trace patched`"),
    ] {
        let d = rtprobe::tempdir::tempdir().unwrap();
        let (args, out) = bindless_args(d.path(), &["--verify", "--verify-timeout", "1"]);
        let refs: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = run_env(&refs, &[("RTPROBE_VERIFY_FAULT", fault)]);
        assert_eq!(o.status.signal(), None, "{fault}: rtprobe itself died: {}", stderr(&o));
        assert_one_line_error(&o, 8, needle);
        assert!(std::fs::read_dir(&out).unwrap().next().is_none(), "{fault}: nothing written");
        if fault == "crash" {
            let e = stderr(&o);
            assert!(e.contains("the patched pipeline faulted where the unpatched one ran"), "{e}");
            assert!(!e.contains("driver crashed"), "{e}");
        }
    }
}

/// Review item 2: a crash while tracing the *unpatched* pipeline says nothing about the patch
/// or the driver's handling of it: the harness cannot run this input (exit 9), never "the driver
/// crashed".
#[test]
fn a_crash_of_the_unpatched_pipeline_is_unrunnable_input() {
    let d = rtprobe::tempdir::tempdir().unwrap();
    let (args, out) = bindless_args(d.path(), &["--verify"]);
    let refs: Vec<&str> = args.iter().map(String::as_str).collect();
    let o = run_env(&refs, &[("RTPROBE_VERIFY_FAULT", "crash-unpatched")]);
    assert_one_line_error(&o, 9, "at `trace unpatched`: the harness cannot run this input");
    assert!(!stderr(&o).contains("driver crashed"), "{}", stderr(&o));
    assert!(stderr(&o).contains("`rtprobe run --shader` runs the same patches"), "{}", stderr(&o));
    assert!(std::fs::read_dir(&out).unwrap().next().is_none(), "nothing written");
}

/// Ctrl-C while `patch --verify`'s child runs (here hung by the test hook): the child is killed,
/// the work folder `rtprobe-verify-<pid>-…` goes with its job file, the message says nothing was
/// written (not `run`'s `--resume`), and the output folder stays empty. Twin: without the
/// handler the folder stayed in TMPDIR.
#[test]
fn ctrl_c_during_verify_kills_its_child_and_leaves_nothing() {
    let d = rtprobe::tempdir::tempdir().unwrap();
    let (args, out) = bindless_args(d.path(), &["--verify"]);
    let tmp = d.path().join("tmp");
    std::fs::create_dir(&tmp).unwrap();
    let mut c = bin();
    c.args(&args).env("TMPDIR", &tmp).env("RTPROBE_VERIFY_FAULT", "hang");
    let (status, err) = interrupt_once_children_run(c, (&tmp, "__verify"), libc::SIGINT, |_| {});
    assert_eq!(status.code(), Some(130), "{status:?} {err}");
    assert!(err.contains("interrupted (SIGINT)") && err.contains("nothing was written"), "{err}");
    assert!(!err.contains("--resume"), "{err}");
    assert_eq!(entries(&tmp), Vec::<String>::new(), "the work folder and its job file");
    assert_eq!(entries(&out), Vec::<String>::new(), "nothing written");
}

/// Item 2 of the review: verify compares every writable storage buffer too. The patched hit
/// shader fed the materials' table where the lights' belongs writes other lights into its log
/// while the image (from the materials) stays identical: verify must fail on the buffer.
#[test]
fn verify_fails_when_only_a_writable_buffer_differs() {
    use rtprobe::harness::{self, judge, PartKind, UserModule, Verdict};
    let d = rtprobe::tempdir::tempdir().unwrap();
    let (args, out) = bindless_args(d.path(), &["--emit-unpatched"]);
    let mut args = args;
    args.push(out.to_string_lossy().into_owned());
    let refs: Vec<&str> = args.iter().map(String::as_str).collect();
    let r = run(&refs);
    assert!(r.status.success(), "{}", stderr(&r));
    let pairs = outputs(&prepare(BINDLESS, d.path()), &out);
    let c: HostContract =
        serde_json::from_slice(&std::fs::read(out.join("pipeline.contract.json")).unwrap())
            .unwrap();
    let module = |p: &Path| UserModule::new(&p.display().to_string(), &words(p)).unwrap();
    let before: Vec<UserModule> = pairs.iter().map(|p| module(&p.1)).collect();
    let after: Vec<UserModule> = pairs.iter().map(|p| module(&p.0)).collect();
    let (dev, same) = harness::verify(gpu(), &before, &after, &c).unwrap();
    assert!(matches!(judge(&dev, &same), Verdict::Identical(_)), "{same:?}");
    assert!(same.iter().any(|x| x.kind == PartKind::Buffer), "{same:?}");
    let mut wrong = c.clone();
    let lights = wrong.addresses.iter_mut().find(|a| a.binding == 1).expect("the lights' table");
    lights.binding = 0;
    let (dev, swapped) = harness::verify(gpu(), &before, &after, &wrong).unwrap();
    let image = swapped.iter().find(|x| x.kind == PartKind::Image).unwrap();
    assert_eq!(image.differing, 0, "the image does not read the lights: {swapped:?}");
    match judge(&dev, &swapped) {
        Verdict::Differs(l) => assert!(l.contains("storage buffer set 0 binding 2[0]"), "{l}"),
        v => panic!("{v:?}"),
    }
}

/// Issue #24 item 3: a closest-hit given alone runs in the harness with a supplied raygen and
/// miss; every payload word the raygen writes (64×64 pixels × 10 words, at the binding after the
/// user's) is compared, unpatched against patched. Twin: a payload holding a pointer cannot be
/// mirrored: one line naming it, exit 9, nothing written.
#[test]
fn a_closest_hit_alone_verifies_with_supplied_stages() {
    let verify = |file: &str| {
        let d = rtprobe::tempdir::tempdir().unwrap();
        let (src, out) = (corpus().join(file), d.path().join("out.spv"));
        let args = ["patch", src.to_str().unwrap(), "-a", "ssbo-to-address", "-o"];
        let o = run(&[&args[..], &[out.to_str().unwrap(), "--verify"]].concat());
        (o, d)
    };
    let (o, _d) = verify("alone/shade.rchit");
    assert!(o.status.success(), "{}", stderr(&o));
    let s = stdout(&o);
    assert!(s.contains("storage buffer set 0 binding 2[0]: 40960 4-byte words identical"), "{s}");
    let (o, d) = verify("alone/node.rchit");
    assert_one_line_error(&o, 9, "payload `visit` cannot be mirrored");
    assert!(stderr(&o).contains("payload.node, a pointer"), "{}", stderr(&o));
    assert!(std::fs::read_dir(d.path()).unwrap().next().is_none(), "nothing written");
}
