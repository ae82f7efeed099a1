//! `bisect`, `report` and `repro` on lavapipe, with injected faults as ground truth: single-axis,
//! two-axis and value-set predicates come back exactly; a flaky one comes back with repeats and
//! its miss probability; a fault no conjunction separates is reported as such; the issue has every
//! section; a repro bundle re-runs its cell with the same verdict.
mod common;
use common::*;
use rtprobe::model::stats;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// Small scopes: lavapipe runs take seconds, and the machine is shared.
const SCOPE: &str = "stage=raygen|closest_hit,resource=storage_buffer|uniform_buffer,descriptor_model=descriptor_indexing,scene_layout=none";

fn json_file(p: &Path) -> Value {
    serde_json::from_slice(&std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display())))
        .expect("JSON")
}

/// `run` over `filter` with `inject` (each an --inject-fault); the report's path.
fn run_report(dir: &Path, name: &str, filter: &str, inject: &[&str], extra: &[&str]) -> PathBuf {
    let out = dir.join(name);
    let mut args = vec![
        "run",
        "--patches",
        "none",
        "--timeout",
        "5",
        "--filter",
        filter,
        "-o",
        out.to_str().unwrap(),
    ];
    for i in inject {
        args.push("--inject-fault");
        args.push(i);
    }
    args.extend_from_slice(extra);
    let o = run(&args);
    assert!(matches!(o.status.code(), Some(0 | 1)), "run failed: {}\n{}", stdout(&o), stderr(&o));
    out
}

/// `bisect REPORT --json FILE extra…`: stdout and the JSON.
fn bisect(report: &Path, extra: &[&str]) -> (String, Value) {
    let json = report.with_extension("bisect.json");
    let mut args = vec!["bisect", report.to_str().unwrap(), "--json", json.to_str().unwrap()];
    args.extend_from_slice(extra);
    let o = run(&args);
    assert_eq!(o.status.code(), Some(0), "bisect failed: {}\n{}", stdout(&o), stderr(&o));
    (stdout(&o), json_file(&json))
}

fn last_line(s: &str) -> &str {
    s.trim_end().lines().last().unwrap_or("")
}

/// One report shared by the report and repro tests: a two-axis injected predicate.
fn shared() -> &'static (PathBuf, PathBuf) {
    static S: OnceLock<(PathBuf, PathBuf)> = OnceLock::new();
    S.get_or_init(|| {
        let dir = tempdir_until_exit();
        let r = run_report(&dir, "two-axis.json", SCOPE, &["stage=closest_hit,index=dynamic"], &[]);
        (dir, r)
    })
}

/// `bisect` of [`shared`]'s report with no options: its stdout and JSON, made once for the
/// predicate test and the issue test (each asserted what it reads from the same bisection).
fn shared_bisect() -> &'static (String, Value) {
    static B: OnceLock<(String, Value)> = OnceLock::new();
    B.get_or_init(|| bisect(&shared().1, &[]))
}

/// `bisect` of [`shared`]'s report with `--max-attempts 2` (too few to conclude on a pass): its
/// output and JSON, made once for the threshold test and the same-card twin of the other-card test.
fn shared_capped() -> &'static (std::process::Output, Value) {
    static C: OnceLock<(std::process::Output, Value)> = OnceLock::new();
    C.get_or_init(|| {
        let report = &shared().1;
        let json = report.with_extension("capped.bisect.json");
        let o = run(&[
            "bisect",
            report.to_str().unwrap(),
            "--max-attempts",
            "2",
            "--json",
            json.to_str().unwrap(),
        ]);
        assert_eq!(o.status.code(), Some(0), "{}\n{}", stdout(&o), stderr(&o));
        let j = json_file(&json);
        (o, j)
    })
}

#[test]
fn single_axis_two_axis_and_value_set_predicates_come_back_exactly() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let cases = [
        // Not `index=dynamic`: its cells without nonuniformEXT are no evidence (undefined reads), so
        // the trusted faults are exactly the nonuniform=true ones and `nonuniform=true` separates
        // them as well as `index=dynamic` does.
        (
            "index=push_constant",
            run_report(dir.path(), "one.json", SCOPE, &["index=push_constant"], &[]),
        ),
        ("stage=closest_hit,index=dynamic", shared().1.clone()),
        (
            "resource=uniform_buffer,index=literal|spec_constant",
            run_report(
                dir.path(),
                "set.json",
                SCOPE,
                &["resource=uniform_buffer,index=literal|spec_constant"],
                &[],
            ),
        ),
    ];
    for (p, report) in &cases {
        let (text, j) =
            if *report == shared().1 { shared_bisect().clone() } else { bisect(report, &[]) };
        assert_eq!(last_line(&text), format!("minimal: {p}"), "{text}");
        assert_eq!(j["minimal"], *p);
        assert_eq!(j["separable"], true);
        assert_eq!(j["schema"], "rtprobe.bisect/1");
        // Runs against the matrix, and the isolation list in plain words with k/N.
        assert!(
            text.contains("made by bisect")
                && text.contains("cells in scope")
                && text.contains("full matrix "),
            "{text}"
        );
        // Piped stdout is plain text: the words without their marks (the JSON keeps them).
        assert!(text.contains(": crash (") && text.contains(": passes ("), "{text}");
        assert!(!text.contains('❌') && !text.contains('✅'), "{text}");
        assert!(j["text"].as_str().unwrap().contains(": ❌ crash ("));
        let iso = j["isolation"].as_array().unwrap();
        assert_eq!(iso[0]["cell"], j["representative"]);
        assert!(iso[0]["line"].as_str().unwrap().contains(" reading "), "{}", iso[0]["line"]);
        // Every verdict used carries k of N. The deterministic fault faulted every time, so its
        // bound is alpha^(1/N); each pass is held to it: (1 - bound)^attempts below 1%.
        for l in iso {
            assert!(l["attempts"].as_u64().unwrap() >= 1, "{l}");
        }
        let n = iso[0]["attempts"].as_u64().unwrap() as u32;
        assert_eq!(iso[0]["agreeing"].as_u64().unwrap() as u32, n, "{}", iso[0]);
        let bound = stats::rate_bound(n, n);
        assert!((j["fault_rate_bound"].as_f64().unwrap() - bound).abs() < 1e-12, "{j}");
        assert!(text.contains(&format!("({n} of {n}, p ≥ {bound:.2} at 95%)")), "{text}");
        let need = stats::attempts_needed(bound, 0.01, 50);
        assert_eq!(j["attempts_per_pass"].as_u64().unwrap() as u32, need);
        // The fault was repeated until it had as many attempts as a pass then needs.
        assert!(n >= need, "{n} attempts of the fault, {need} per pass");
        // (a suspect pass — an undefined read whose other-lane reads a faulting sibling may
        // explain — is listed but not used, so not repeated either)
        for l in iso.iter().filter(|l| l["verdict"] == "pass" && l["suspect"].is_null()) {
            assert_eq!(l["attempts"].as_u64().unwrap() as u32, need, "{l}");
            assert!(l["miss_probability"].as_f64().unwrap() < 0.01 && l["settled"] == true, "{l}");
            assert!(
                l["line"].as_str().unwrap().contains(&format!("({need} of {need}; miss ≤ ")),
                "{l}"
            );
        }
        assert!(j["unsettled"].as_array().unwrap().is_empty());
        assert!(!text.contains("NOT CONCLUDED"), "{text}");
    }
}

#[test]
fn a_flaky_injection_is_recovered_with_repeats_and_its_miss_probability() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let scope = "stage=raygen|closest_hit,resource=storage_buffer,index=literal|dynamic,descriptor_model=descriptor_indexing";
    // The run itself may miss both injected cells (1 in 4: each fires with probability 1/2 and
    // `--repeat` repeats only cells that faulted); run again until it has a finding (8 misses in
    // a row: 1.5e-5).
    let report = (0..8)
        .map(|i| {
            run_report(
                dir.path(),
                &format!("flaky-{i}.json"),
                scope,
                &["stage=raygen,index=dynamic@flaky:0.5"],
                &["--repeat", "4"],
            )
        })
        // (the injected cell with nonuniformEXT: its twin without it reads undefined, and bisect
        // uses no evidence of such a cell)
        .find(|r| {
            json_file(r)["cells"].as_array().unwrap().iter().any(|c| {
                c["nonuniform"] == true
                    && !matches!(
                        c["outcome"].as_str(),
                        Some("pass" | "unsupported" | "not_implemented")
                    )
            })
        })
        .expect("one of 8 runs saw the rate-0.5 fault");
    // An injected cell the run missed (probability 1/2 each) must show up in bisect's repeats: a
    // pass is held to the fault's 95% lower bound, so with --max-miss 0.001 it misses a rate-0.5
    // fault only where that bound overshoots 0.5 (5%) and the shorter run still misses.
    // The minimal cell faults in all of its N attempts with probability 2^-N (1/128 at N = 7):
    // bisect again then, so the k < N claim below holds with probability 1 - 2^-3N.
    let (text, j) = (0..3)
        .map(|_| bisect(&report, &["--max-miss", "0.001"]))
        .find(|(_, j)| {
            let r = &j["isolation"][0];
            r["agreeing"].as_u64() < r["attempts"].as_u64()
        })
        .expect("a rate-0.5 fault missed some attempts in one of 3 bisections");
    assert_eq!(last_line(&text), "minimal: stage=raygen,index=dynamic", "{text}");
    assert!(text.contains("worst miss probability"), "{text}");
    let worst = j["worst_miss_probability"].as_f64().unwrap();
    assert!(worst < 0.001, "{worst}");
    // The family-wise figure: the sum over passes, at least the worst one, at most 1.
    let union = j["union_miss_probability"].as_f64().unwrap();
    assert!(union <= 1.0, "{union}");
    // Several passes relied on, each with a miss probability of its own: the union bound sums
    // them, so it lies strictly above the worst one.
    assert!(j["passes_relied_on"].as_u64().unwrap() >= 2, "{}", j["passes_relied_on"]);
    assert!(union > worst, "{union} vs {worst}");
    assert!(text.contains("that any of them missed (union bound)"), "{text}");
    assert!(j["unsettled"].as_array().unwrap().is_empty(), "{}", j["unsettled"]);
    // The minimal failing cell did not fault every time; its bound is its own k of N.
    let rep = &j["isolation"][0];
    let (k, n) =
        (rep["agreeing"].as_u64().unwrap() as u32, rep["attempts"].as_u64().unwrap() as u32);
    assert!(k < n, "a rate-0.5 fault missed some of {n} attempts: {rep}");
    let bound = stats::rate_bound(k, n);
    assert!((j["fault_rate_bound"].as_f64().unwrap() - bound).abs() < 1e-12);
    assert!(
        rep["line"].as_str().unwrap().contains(&format!("({k} of {n}, p ≥ {bound:.2} at 95%)")),
        "{rep}"
    );
    // Passes were repeated to the attempts the bound asks for, and print their miss probability.
    let need = stats::attempts_needed(bound, 0.001, 50);
    assert_eq!(j["attempts_per_pass"].as_u64().unwrap() as u32, need);
    assert!(n >= need, "the fault was repeated first: {n} < {need}");
    for l in j["isolation"].as_array().unwrap().iter().filter(|l| l["verdict"] == "pass") {
        assert!(l["attempts"].as_u64().unwrap() as u32 >= need, "{l}");
        assert!(
            l["line"].as_str().unwrap().contains("; miss ≤ ")
                && l["line"].as_str().unwrap().contains(&format!("for p ≥ {bound:.2})")),
            "{l}"
        );
    }
}

#[test]
fn a_fault_no_conjunction_separates_is_said_so_with_a_disjunction() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let scope =
        "stage=raygen|closest_hit,resource=storage_buffer,descriptor_model=descriptor_indexing";
    let report = run_report(
        dir.path(),
        "two.json",
        scope,
        &["stage=raygen,index=literal", "stage=closest_hit,index=dynamic"],
        &[],
    );
    let (text, j) = bisect(&report, &[]);
    assert!(text.contains("NO single conjunction separates"), "{text}");
    assert_eq!(j["separable"], false);
    assert_eq!(
        last_line(&text),
        "minimal: stage=raygen,index=literal;stage=closest_hit,index=dynamic",
        "{text}"
    );
    assert_eq!(j["conjunctions"].as_array().unwrap().len(), 2);
}

#[test]
fn the_issue_has_every_section() {
    let (dir, report) = shared();
    let (_, j) = shared_bisect();
    let bis = report.with_extension("bisect.json");
    let md = dir.join("issue.md");
    let o = run(&[
        "report",
        report.to_str().unwrap(),
        "--bisect",
        bis.to_str().unwrap(),
        "-o",
        md.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let text = std::fs::read_to_string(&md).unwrap();
    let title = text.lines().next().unwrap();
    assert!(
        title.starts_with(
            "# [injected, not a driver bug] Driver crash: closest_hit reading storage_buffer"
        ) && title.contains("llvmpipe")
            && title.contains("Vulkan 1."),
        "{title}"
    );
    // One screen of facts (`common::run` holds it to the line budget), then collapsed sections.
    for section in [
        "**Driver** llvmpipe",
        "**OS** ",
        "**What happens**: crash",
        "**Expected vs actual** ",
        "**The probed read** (`closest_hit_triangles.rchit`",
        "```glsl",
        "- **Descriptors**: ",
        "- **Index**: ",
        "- **SBT**: ",
        "- **Device fault**: ",
        "- **Validation**: ",
        "**Isolation**: minimal description",
        "**Reproduce** (",
        "**Workarounds**: ",
        "<details><summary>Isolation list with statistics",
        "<details><summary>Environment</summary>",
        "| Kernel |",
        "```diff\n--- passing/",
        "<details><summary>Not tested</summary>",
    ] {
        assert!(text.contains(section), "{section} missing:\n{text}");
    }
    assert!(
        text.contains(&format!("minimal description: `{}`", j["minimal"].as_str().unwrap())),
        "{text}"
    );
    assert!(text.contains(" attempts faulted"), "{text}");
    assert!(
        text.contains("rtprobe run --filter 'stage=closest_hit,")
            && text.contains("--inject-fault 'stage=closest_hit,index=dynamic@device'"),
        "{text}"
    );
    assert!(text.contains("rtprobe run --cell-spec"), "{text}");
    // Issue 9: whether the engines' recommended pattern nearest the finding works on this driver.
    assert!(text.contains("; recommended pattern geometry (one storage buffer at a spec-constant slot, dynamic element offset; closest_hit.storage_buffer.dynamic_element."), "{text}");
    let dis = Path::new("/usr/bin/spirv-dis").exists();
    assert_eq!(text.contains("; SPIR-V"), dis, "disassembly present iff spirv-dis is installed");
    // JSON: the same content as data; without --bisect, the report's own verdicts are bisected.
    let o = run(&["report", report.to_str().unwrap(), "--format", "json"]);
    let v = json(&o);
    assert_eq!(v["schema"], "rtprobe.issue/2");
    assert_eq!(v["minimal"], j["minimal"]);
    for key in [
        "title",
        "environment",
        "summary",
        "incidence",
        "expected",
        "actual",
        "isolation",
        "shader",
        "device_fault",
        "validation",
        "reproduce",
        "workarounds",
        "recommended_pattern",
        "not_tested",
        "attempts",
        "facts",
        "reproducer",
        "isolation_summary",
    ] {
        assert!(!v[key].is_null(), "{key}");
    }
    // Bad input and unwritable output: one line, exit 9, no file.
    assert_one_line_error(&run(&["report", "/nonexistent/r.json"]), 9, "cannot read");
    let bad = dir.join("no/such/dir");
    std::fs::write(dir.join("no"), b"a file").unwrap();
    assert_one_line_error(
        &run(&["report", report.to_str().unwrap(), "-o", bad.join("i.md").to_str().unwrap()]),
        9,
        "cannot write",
    );
    assert_one_line_error(
        &run(&["report", report.to_str().unwrap(), "--bisect", report.to_str().unwrap()]),
        9,
        "not an rtprobe bisection",
    );
}

#[test]
fn a_repro_bundle_reruns_its_cell_with_the_same_verdict() {
    let (dir, report) = shared();
    let r = json_file(report);
    for id in [
        "closest_hit.uniform_buffer.dynamic.nonuniform.descriptor_indexing",
        "closest_hit.storage_buffer.literal.descriptor_indexing",
    ] {
        let want = r["cells"].as_array().unwrap().iter().find(|c| c["id"] == id).unwrap()
            ["outcome"]
            .clone();
        let b = dir.join(format!("repro-{id}"));
        let o = run(&["repro", id, "--from", report.to_str().unwrap(), "-o", b.to_str().unwrap()]);
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        for f in [
            "cell.json",
            "caps.json",
            "README.txt",
            "shaders/closest_hit_triangles.rchit.glsl",
            "shaders/closest_hit_triangles.rchit.spv",
            "shaders/raygen.rgen.glsl",
        ] {
            assert!(b.join(f).exists(), "{id}: {f}");
        }
        let spec = json_file(&b.join("cell.json"));
        assert_eq!(spec["id"], id);
        assert_eq!(json_file(&b.join("caps.json"))["schema"], "rtprobe.caps/2");
        let out = b.join("rerun.json");
        let o = run(&[
            "run",
            "--cell-spec",
            b.join("cell.json").to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ]);
        let again = json_file(&out);
        let cells = again["cells"].as_array().unwrap();
        assert_eq!(cells.len(), 1, "exactly that cell: {cells:?}");
        assert_eq!(cells[0]["id"], id);
        assert_eq!(cells[0]["outcome"], want, "{id}: {}", stderr(&o));
        // The cell's own compile: the persisted pipeline cache is never loaded by a repro.
        assert!(again["options"]["pipeline_cache"].is_null(), "{}", again["options"]);
        assert!(again["pipeline_cache"].is_null(), "{}", again["pipeline_cache"]);
    }
    assert_one_line_error(
        &run(&["repro", "raygen.nope", "--from", report.to_str().unwrap(), "-o", "/tmp/x"]),
        9,
        "not a cell id",
    );
    assert_one_line_error(
        &run(&["run", "--cell-spec", report.to_str().unwrap()]),
        9,
        "not an rtprobe cell spec",
    );
    let o = run(&["run", "--cell-spec", "x.json", "--filter", "stage=raygen"]);
    assert_eq!(o.status.code(), Some(2), "--cell-spec replaces --filter");
}

#[test]
fn nothing_to_bisect_and_a_wrong_cell_are_one_line_errors() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let report = run_report(
        dir.path(),
        "clean.json",
        "stage=raygen,resource=storage_buffer,index=literal,descriptor_model=descriptor_indexing",
        &[],
        &[],
    );
    assert_one_line_error(&run(&["bisect", report.to_str().unwrap()]), 9, "nothing to bisect");
    let (_, shared_report) = shared();
    assert_one_line_error(
        &run(&[
            "bisect",
            shared_report.to_str().unwrap(),
            "--offline",
            "--cell",
            "raygen.storage_buffer.literal.descriptor_indexing",
        ]),
        9,
        "not a faulting cell",
    );
    assert_one_line_error(
        &run(&["bisect", shared_report.to_str().unwrap(), "--max-miss", "2"]),
        2,
        "--max-miss",
    );
}

#[test]
fn passes_below_the_threshold_are_not_concluded_on() {
    // Two attempts at most: a fault seen 2 of 2 is only p >= 0.05^(1/2) at 95%, and two passing
    // attempts would miss such a fault with probability (1 - 0.05^(1/2))^2, far above 1%.
    let (o, j) = shared_capped();
    let text = stdout(o);
    let miss = stats::miss(stats::rate_bound(2, 2), 2);
    assert!(miss >= 0.01);
    assert!(text.contains("NOT CONCLUDED"), "{text}");
    let passes: Vec<&Value> =
        j["isolation"].as_array().unwrap().iter().filter(|l| l["verdict"] == "pass").collect();
    assert!(!passes.is_empty(), "{text}");
    for l in passes {
        assert_eq!(l["settled"], false, "{l}");
        assert!(
            l["line"].as_str().unwrap().contains("too little evidence, not concluded on"),
            "{l}"
        );
        assert!(j["unsettled"].as_array().unwrap().contains(&l["cell"]), "{l}");
    }
}

#[test]
fn a_bundle_is_replaced_whole_runs_its_own_spirv_and_has_an_amber_script_where_it_fits() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let filter = "stage=compute|closest_hit,resource=storage_buffer,index=literal|push_constant|spec_constant,descriptor_model=descriptor_indexing";
    let report = run_report(dir.path(), "mixed.json", filter, &[], &[]);
    let b = dir.path().join("bundle");
    let repro = |id: &str, force: bool| {
        let mut args =
            vec!["repro", id, "--from", report.to_str().unwrap(), "-o", b.to_str().unwrap()];
        if force {
            args.push("--force");
        }
        run(&args)
    };
    // A compute buffer cell: an Amber script with its SPIR-V, buffers and expected records.
    let o = repro("compute.storage_buffer.push_constant.descriptor_indexing", false);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let amber = std::fs::read_to_string(b.join("cell.amber")).expect("cell.amber");
    assert!(
        amber.starts_with("#!amber\n")
            && amber.contains("SHADER compute probe SPIRV-HEX\n03 02 23 07 "),
        "{}",
        &amber[..600]
    );
    assert!(
        amber.contains("BIND BUFFER_ARRAY slot0 ")
            && amber.contains("\nRUN probe_pipeline ")
            && amber.contains("\nEXPECT records IDX 0 TOLERANCE 0.001 EQ ")
    );
    assert!(amber.contains("# Run: amber -d -v 1.2 cell.amber"), "says how to run it");
    let spec = json_file(&b.join("cell.json"));
    let modules = spec["modules"].as_array().unwrap();
    assert_eq!(modules.len(), 1);
    assert!(modules[0]["compiler"].as_str().unwrap().starts_with("shaderc-rs "), "{spec}");
    let readme = std::fs::read_to_string(b.join("README.txt")).unwrap();
    assert!(readme.contains("The SPIR-V was compiled by shaderc-rs "), "{readme}");
    // A second bundle into the same folder: refused without --force, the first one left whole.
    assert_one_line_error(
        &repro("closest_hit.storage_buffer.literal.descriptor_indexing", false),
        9,
        "--force",
    );
    assert!(b.join("cell.amber").exists());
    // With --force: the old bundle's files are gone (a ray tracing cell whose slot is a
    // specialization constant has no Amber script) and nothing is left beside it.
    let o = repro("closest_hit.storage_buffer.spec_constant.descriptor_indexing", true);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(!b.join("cell.amber").exists(), "stale cell.amber kept");
    assert!(!b.join("shaders/probe.comp.spv").exists(), "stale shader kept");
    assert_eq!(
        json_file(&b.join("cell.json"))["id"],
        "closest_hit.storage_buffer.spec_constant.descriptor_indexing"
    );
    let readme = std::fs::read_to_string(b.join("README.txt")).unwrap();
    assert!(
        readme.contains("no cell.amber: AmberScript cannot specialize ray tracing shaders"),
        "{readme}"
    );
    let leftovers: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with('.'))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
    // --cell-spec runs the bundle's SPIR-V: garbage there is what the worker loads.
    let spv = b.join("shaders/closest_hit_triangles.rchit.spv");
    std::fs::write(&spv, b"not spir-v").unwrap();
    let out = b.join("rerun.json");
    let o = run(&[
        "run",
        "--cell-spec",
        b.join("cell.json").to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(stderr(&o).contains("running the bundle's SPIR-V"), "{}", stderr(&o));
    let cell = &json_file(&out)["cells"][0];
    assert_eq!(cell["outcome"], "error", "{cell}");
    assert!(cell.to_string().contains("is not SPIR-V"), "{cell}");
    // A listed module that is missing: one line, before any GPU work.
    std::fs::remove_file(&spv).unwrap();
    assert_one_line_error(
        &run(&["run", "--cell-spec", b.join("cell.json").to_str().unwrap()]),
        9,
        "is missing",
    );
}

#[test]
fn force_replaces_only_a_bundle_and_never_the_folder_of_the_report_or_the_current_directory() {
    let (_, report) = shared();
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let cell = "raygen.storage_buffer.literal.descriptor_indexing";
    let repro = |out: &Path, from: &Path| {
        run(&[
            "repro",
            cell,
            "--from",
            from.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--force",
        ])
    };
    // A folder that is not a bundle: refused, every file left.
    let plain = dir.path().join("plain");
    std::fs::create_dir(&plain).unwrap();
    std::fs::write(plain.join("notes.txt"), b"mine").unwrap();
    assert_one_line_error(&repro(&plain, report), 9, "is not a repro bundle (no cell.json)");
    assert_eq!(std::fs::read(plain.join("notes.txt")).unwrap(), b"mine");
    // A bundle-looking folder that holds the --from report: refused, the report left.
    let holder = dir.path().join("holder");
    std::fs::create_dir(&holder).unwrap();
    std::fs::write(holder.join("cell.json"), b"{}").unwrap();
    let inner = holder.join("r.json");
    std::fs::copy(report, &inner).unwrap();
    assert_one_line_error(&repro(&holder, &inner), 9, "holds the --from report");
    assert!(inner.exists());
    // The current directory (and `/`, `.`): refused before anything is created.
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_rtprobe"))
        .args([
            "repro",
            cell,
            "--from",
            inner.to_str().unwrap(),
            "-o",
            holder.to_str().unwrap(),
            "--force",
        ])
        .current_dir(&holder)
        .output()
        .unwrap();
    assert_one_line_error(&o, 9, "holds the current directory");
    assert_one_line_error(&repro(Path::new("/"), report), 9, "does not name a folder");
    let names = |d: &Path| {
        std::fs::read_dir(d).unwrap().flatten().map(|e| e.file_name()).collect::<Vec<_>>()
    };
    assert_eq!(names(&holder).len(), 2, "{:?}", names(&holder));
    assert!(
        names(dir.path()).iter().all(|n| !n.to_string_lossy().starts_with('.')),
        "{:?}",
        names(dir.path())
    );
}

#[test]
fn another_card_of_the_same_driver_bisects_and_another_driver_build_is_refused() {
    let (dir, shared_report) = shared();
    let mut r = json_file(shared_report);
    r["device"]["device_uuid"] = Value::from("00000000000000000000000000000000");
    let other_card = dir.join("other-card.json");
    std::fs::write(&other_card, serde_json::to_vec(&r).unwrap()).unwrap();
    let json = dir.join("other-card.bisect.json");
    let o = run(&[
        "bisect",
        other_card.to_str().unwrap(),
        "--max-attempts",
        "2",
        "--json",
        json.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}\n{}", stdout(&o), stderr(&o));
    // Said, not silent: a warning on stderr, the card in the bisection file and in the issue.
    let warning = stderr(&o);
    assert!(
        warning.contains(
            "the report's card (UUID 00000000000000000000000000000000) is not here; re-running on "
        ),
        "{warning}"
    );
    assert!(warning.contains("of the same driver build"), "{warning}");
    let here =
        json_file(&json)["device_uuid_rerun"].as_str().expect("device_uuid_rerun").to_string();
    assert!(warning.contains(&format!("UUID {here} of the same driver build")), "{warning}");
    let issue = run(&["report", other_card.to_str().unwrap(), "--bisect", json.to_str().unwrap()]);
    assert!(
        stdout(&issue).contains(&format!(
            "re-ran cells on another card of the same driver build, UUID {here}"
        )),
        "{}\n{}",
        stdout(&issue),
        stderr(&issue)
    );
    // Twin: the report's own card (the same bisection, `--max-attempts 2`) gives no warning and
    // no device_uuid_rerun.
    let (o, same) = shared_capped();
    assert!(!stderr(o).contains("is not here"), "{}", stderr(o));
    assert!(same.get("device_uuid_rerun").is_none(), "{same}");
    // Twin: a different driver build is not the device the fault was seen on.
    r["device"]["driver_uuid"] = Value::from("00000000000000000000000000000000");
    let other_driver = dir.join("other-driver.json");
    std::fs::write(&other_driver, serde_json::to_vec(&r).unwrap()).unwrap();
    assert_one_line_error(
        &run(&["bisect", other_driver.to_str().unwrap()]),
        6,
        "not on this machine",
    );
}

/// Issue 21, item 7: a bundle whose SPIR-V does not fit its cell's interface (here a sampled-image
/// cell's bundle carrying a storage-buffer cell's compute module) is the cell's `error` naming
/// binding 2, found before any pipeline is made — never a driver finding (on lavapipe such a
/// pipeline crashed and was reported as a `crash`).
#[test]
fn a_bundle_whose_spirv_does_not_fit_its_cell_is_an_error_naming_the_binding() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let filter = "stage=compute,resource=storage_buffer|sampled_image,index=literal,descriptor_model=descriptor_indexing";
    let report = run_report(dir.path(), "two.json", filter, &[], &[]);
    let bundle = |id: &str, name: &str| {
        let b = dir.path().join(name);
        let o = run(&["repro", id, "--from", report.to_str().unwrap(), "-o", b.to_str().unwrap()]);
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        b
    };
    let ssbo = bundle("compute.storage_buffer.literal.descriptor_indexing", "ssbo");
    let image = bundle("compute.sampled_image.literal.descriptor_indexing", "image");
    std::fs::copy(ssbo.join("shaders/probe.comp.spv"), image.join("shaders/probe.comp.spv"))
        .unwrap();
    let out = dir.path().join("rerun.json");
    let spec = image.join("cell.json");
    let o = run(&["run", "--cell-spec", spec.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    let cell = &json_file(&out)["cells"][0];
    assert_eq!(cell["outcome"], "error", "{cell}");
    let detail = cell["attempts"][0]["result"]["detail"].as_str().unwrap_or_default();
    assert!(
        detail.contains("set 0 binding 2")
            && detail.contains(
                "declares a storage buffer, the pipeline provides a combined image sampler"
            ),
        "{detail}"
    );
    assert!(stdout(&o).contains("error"), "{}", stdout(&o));
}
