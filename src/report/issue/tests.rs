use super::*;
use crate::model::{BisectFile, RunReport};
use std::path::Path;

const RUN: &str = "reports/lavapipe-26/run.json";
const BISECT: &str = "reports/lavapipe-26/bisect-shader-record.json";
const LANES: &str = "reports/lavapipe-26/lanes-forced.json";

fn lavapipe_26() -> (RunReport, BisectFile, RunReport) {
    (
        RunReport::load(Path::new(RUN)).unwrap(),
        BisectFile::load(Path::new(BISECT)).unwrap(),
        RunReport::load(Path::new(LANES)).unwrap(),
    )
}

fn screen(md: &str) -> &str {
    let n: usize = md.lines().take(one_screen_lines(md)).map(|l| l.len() + 1).sum();
    &md[..n.min(md.len())]
}

#[test]
fn one_screen_counts_the_lines_before_the_first_details() {
    let short = "# t\n\na\n<details><summary>x</summary>\n\nmore\n</details>\n";
    assert_eq!(one_screen_lines(short), 3);
    // The twin: a page without <details> is all screen, and 61 lines are too many.
    let long: String = (0..61).map(|k| format!("line {k}\n")).collect();
    assert_eq!(one_screen_lines(&long), 61);
    assert!(one_screen_lines(&long) > ONE_SCREEN_LINES);
}

/// Issue 30's reading of the lavapipe 26 shader-record issue as a Mesa developer would, held on
/// the issue the committed report, bisection and lane-evidence run make: one screen, with the
/// facts that say what the driver does wrong.
#[test]
fn the_lavapipe_26_shader_record_issue_fits_one_screen_with_every_fact() {
    let (r, b, lanes) = lavapipe_26();
    let sbt = SbtProps {
        handle_size: 32,
        handle_alignment: 32,
        base_alignment: 64,
        max_recursion_depth: 31,
    };
    let run = ValidationRun::NotRun("a unit test".into());
    let extras = Extras { lanes: Some(&lanes), validation: run, sbt: Some(sbt) };
    let issue = build(&r, RUN, &b, &[], &extras).unwrap();
    let md = issue.markdown();
    assert!(
        one_screen_lines(&md) <= ONE_SCREEN_LINES,
        "{} lines:\n{}",
        one_screen_lines(&md),
        screen(&md)
    );
    let top = screen(&md);
    assert!(top.starts_with("# Wrong results: closest_hit reading sampled_image"), "{top}");
    // The diagnosis right under the title, from the decode and the one-axis siblings.
    assert_eq!(
        md.lines().nth(2),
        Some("**Diagnosis**: Reads the descriptor 192 bytes (3 descriptors) before the right one, at the right element, in all 8 decoded example pixels of 926 that differ (16 examples from the run report's 2 failing attempts); fails in closest_hit/any_hit/miss, passes in raygen/intersection/callable; fails with heap_access=mapped_shader_record_index, passes with heap_access=mapped_constant_offset|mapped_push_index|mapped_indirect_index, one axis changed at a time."),
        "{top}"
    );
    // Only the 9 pixels named by a lone record are garbage (a random leader word gives that).
    assert_eq!(top.matches("garbage lane data").count(), 1, "{top}");
    assert!(top.contains("(garbage lane data, left out above) 9 of 9 pixels"), "{top}");
    for fact in [
        // The stored debug-form detail in words, from the comparison.
        "**What happens**: mismatch: 926 of 4087 compared pixels differ (value 926); 6 of 6",
        // This run's rtprobe recorded binding 2's summary but not the mapping structs.
        "the run's rtprobe did not record the VkDescriptorSetAndBindingMappingEXT entries",
        "`driverInfo` Mesa 26.2.6-1 (LLVM 22.1.8)",
        "**SPIR-V by** shaderc",
        "6 of 6 attempts faulted, every one",
        // Expected against actual, with the slots and heap bytes they come from.
        "expected `[4.0, 33.0, 1014.0, 2.25]` = slot 3 element 2, heap byte 384, got `[1.0, 33.0, 1002.0, 2.25]` = slot 0 element 2, heap byte 192. The descriptor read is 3 × 64 = 192 bytes before the expected one.",
        "uniform sampler2D probeTex[]",
        "textureLod(probeTex[3u]",
        "HEAP_WITH_SHADER_RECORD_INDEX { heapOffset 0, shaderRecordOffset 0, heapIndexStride 64, heapArrayStride 64 }",
        "`03 00 00 00 02 00 00 00`",
        "slot = literal 3 in the GLSL: slots 3..=3 of the 19 bound (in bounds)",
        "each record a 32-byte handle + 8 bytes of data",
        "maxPipelineRayRecursionDepth 1 (device maximum 31)",
        // every call without lane 0 has a leader word outside the call: shown as what was
        // observed (how many named pixels' own records say lane 0, more than one pixel named),
        // never called garbage, and under forced evidence never a check the driver failed
        "mismatches by lane 0 of the subgroup: in calls without lane 0 whose leader word names a pixel outside the call (more than one pixel in all; the named pixel's own record says lane 0 for 57 of them) (in a valid shader the leader must be the lowest active lane, subgroupBroadcastFirst = OpGroupNonUniformBroadcastFirst), 915 of 915 pixels mismatched — consistent with a value taken from lane 0 while it is not in the call; in the calls their leaders ran in (left out with them) 0 of 21; where the lane words hold, where it was inactive in the call 0 of 0 pixels, where active 0 of 1806",
        "(forced lane evidence, a diagnosis only: VUID-RuntimeSpirv-None-06343 (Vulkan 1.4.360): \"Group operations with subgroup scope must not be used if the shader stage is not in subgroupSupportedStages\"; this device's subgroupSupportedStages does not include closest_hit",
        "--lane-evidence force",
        "**Validation**: Not checked",
        "**Device fault**: Not applicable",
        "**stage**: ❌ any_hit 2/2 mismatch, miss 2/2 mismatch · ✅ raygen 5/5",
        "rtprobe repro closest_hit.sampled_image.literal.descriptor_heap.mapped_shader_record_index --from",
        "No Amber script for this cell: Amber has no VK_EXT_descriptor_heap; no standalone program either",
        "**Workarounds**",
    ] {
        assert!(top.contains(fact), "{fact:?} not on the first screen:\n{top}");
    }
    // One attempt count for the failing cell, stated once; no statistics for a fault seen every
    // time; the cells whose read the spec leaves undefined are not on the screen.
    assert_eq!(top.matches("6 of 6").count(), 1, "{top}");
    assert!(!top.contains("p ≥") && !top.contains("miss ≤"), "{top}");
    assert!(!top.contains("base_shader_record") && !top.contains("— not used:"), "{top}");
    assert!(!top.contains("{\"value\""), "no debug-form detail: {top}");
    assert!(!top.contains("handed") && !top.contains("check they fail"), "{top}");
    // The full list and real unified diffs are collapsed below.
    let rest = &md[top.len()..];
    assert!(
        rest.contains("❌ mismatch (6 of 6, p ≥ 0.61 at 95%)") && rest.contains("— not used:"),
        "{rest}"
    );
    let glsl = issue.shader.as_ref().unwrap().glsl_diff.as_ref().unwrap();
    assert!(
        glsl.starts_with("--- passing/closest_hit_triangles.rchit (") && glsl.contains("\n@@ -"),
        "{glsl}"
    );
}

#[test]
fn the_excerpt_is_the_probed_array_and_the_read() {
    let cell = crate::model::Cell::parse_id(
        "closest_hit.storage_buffer.dynamic.nonuniform.descriptor_indexing",
    )
    .unwrap();
    let glsl = &crate::shadergen::generate(&cell)
        .shaders
        .iter()
        .find(|s| s.role == crate::shadergen::Role::ClosestHitTriangles)
        .unwrap()
        .glsl
        .clone();
    let e = shaders::excerpt(glsl);
    assert!(e.contains("layout(set = 0, binding = 2, std430) readonly buffer ProbeBuffer"), "{e}");
    assert!(
        e.contains(
            "uint probeSlot = (pc.dynBase + (uint(gl_InstanceCustomIndexEXT) & pc.dynMask));"
        ),
        "{e}"
    );
    assert!(e.contains("probeBuf[nonuniformEXT("), "{e}");
    assert!(!e.contains("rayPayloadInEXT") && !e.contains("pl.custom"), "{e}");
    assert!(e.lines().count() <= 10, "{e}");
    assert_eq!(shaders::excerpt("no probe here"), "");
}

#[test]
fn the_attempt_count_carries_a_rate_bound_only_when_flaky() {
    let every = text::attempts_text(6, 6);
    assert_eq!(every, "6 of 6 attempts faulted, every one");
    let flaky = text::attempts_text(3, 10);
    assert!(flaky.starts_with("3 of 10 attempts faulted: flaky, fault rate p ≥ 0.0"), "{flaky}");
}

#[test]
fn an_index_is_named_with_its_range_and_bounds() {
    let cell =
        crate::model::Cell::parse_id("closest_hit.storage_buffer.dynamic.descriptor_indexing")
            .unwrap();
    let r = RunReport::load(Path::new(RUN)).unwrap();
    assert_eq!(r.scene.params.instances, 16);
    let f = facts::of(&r, &cell, None, None);
    assert!(
        f.index
            .contains("base + (gl_InstanceCustomIndexEXT & 0xf), base = push constant dynBase = 3"),
        "{}",
        f.index
    );
    assert!(
        f.index.contains("without nonuniformEXT on a non-uniform index: the read is undefined"),
        "{}",
        f.index
    );
    assert!(f.index.contains("slots 3..=18 of the 19 bound (in bounds)"), "{}", f.index);
    assert!(
        f.layout.contains("19 × STORAGE_BUFFER") && f.layout.contains("PARTIALLY_BOUND"),
        "{}",
        f.layout
    );
    assert!(f.sbt.contains("stride align(handle + 0, shaderGroupHandleAlignment)"), "{}", f.sbt);
    assert!(f.values.starts_with("No attempt of this cell"), "{}", f.values);
}

/// The injected H100 demo's bisection: workarounds and siblings on the screen with one count
/// each and no statistics (those stay in the collapsed list), no stand-in `none` values.
#[test]
fn workarounds_and_siblings_are_one_count_each() {
    let b = BisectFile::load(Path::new("reports/nvidia-h100/bisect-demo.bisect.json")).unwrap();
    let w = text::workaround_lines(&b.bisection);
    assert!(w.iter().any(|l| l == "patch `nonuniform`: ❌ mismatch 1/1 (the injected fault survives the patch: nothing about the driver)"), "{w:?}");
    assert!(w.iter().all(|l| !l.contains("p ≥")), "{w:?}");
    assert!(b.bisection.workarounds.iter().any(|l| l.line.contains("p ≥ 0.05")));
    let iso = text::isolation_summary(&b.bisection);
    assert!(iso.contains(&"**stage**: ✅ raygen 5/5, miss 5/5".to_string()), "{iso:?}");
    assert!(iso.iter().all(|l| !l.contains("+none")), "{iso:?}");
}

fn lavapipe_26_issue(r: &RunReport, b: &BisectFile) -> Issue {
    build(r, RUN, b, &[], &Extras::default()).unwrap()
}

/// The representative's report entry, to change what the issue is built from.
fn rep_entry<'a>(r: &'a mut RunReport, b: &BisectFile) -> &'a mut crate::model::CellReport {
    r.cells.iter_mut().find(|c| c.id == b.bisection.representative).unwrap()
}

/// The twins of the diagnosis: the isolation list that shows the fault depends on the stage
/// gives the stage clause, as the list shows it (fails in, passes in; never "only"); a stage
/// sibling that no longer passes (no split on the stage) drops it; without a decode (no example
/// pixel to tell which descriptor was read) there is none; the decode rests on every failing
/// attempt's examples, says their number, and says when the element read differs.
#[test]
fn the_diagnosis_says_only_what_the_evidence_holds() {
    let (r, b, _) = lavapipe_26();
    let d = lavapipe_26_issue(&r, &b).diagnosis;
    assert!(
        d.contains("; fails in closest_hit/any_hit/miss, passes in raygen/intersection/callable;"),
        "{d}"
    );
    assert!(d.contains("in all 8 decoded example pixels of 926 that differ"), "{d}");
    assert!(d.ends_with(", one axis changed at a time.") && !d.contains("only"), "{d}");
    // Every pure stage sibling faults: the stage is not where the fault is.
    let mut every_stage = b.clone();
    for l in
        every_stage.bisection.isolation.iter_mut().filter(|l| l.varied.as_deref() == Some("stage"))
    {
        l.verdict = "mismatch".into();
    }
    let d = lavapipe_26_issue(&r, &every_stage).diagnosis;
    assert!(d.starts_with("Reads the descriptor 192 bytes") && !d.contains("fails in"), "{d}");
    // No decode: no diagnosis, and no line for it on the screen.
    let mut no_decode = r.clone();
    for a in rep_entry(&mut no_decode, &b).attempts.iter_mut() {
        if let Some(c) = a.result.as_mut().and_then(|x| x.comparison.as_mut()) {
            c.examples.clear();
        }
    }
    let issue = lavapipe_26_issue(&no_decode, &b);
    assert_eq!(issue.diagnosis, "");
    assert!(!issue.markdown().contains("**Diagnosis**"));
    // Examples that disagree on the descriptor read: none either.
    let mut mixed = r.clone();
    for a in rep_entry(&mut mixed, &b).attempts.iter_mut() {
        if let Some(c) = a.result.as_mut().and_then(|x| x.comparison.as_mut()) {
            c.examples[1].actual = c.examples[1].expected.clone();
        }
    }
    assert_eq!(lavapipe_26_issue(&mixed, &b).diagnosis, "");
    // One example of the oldest failing attempt disagrees: every attempt's examples count.
    let mut oldest = r.clone();
    let first = rep_entry(&mut oldest, &b)
        .attempts
        .iter_mut()
        .find_map(|a| a.result.as_mut()?.comparison.as_mut())
        .unwrap();
    first.examples[0].actual = first.examples[0].expected.clone();
    assert_eq!(lavapipe_26_issue(&oldest, &b).diagnosis, "");
}

/// The decode requires the element to match; the twin reads the right slot shift at another
/// element in one example per attempt, and says so with the count.
#[test]
fn the_diagnosis_says_when_the_element_differs() {
    let (r, b, _) = lavapipe_26();
    let cell = crate::model::Cell::parse_id(&b.bisection.representative).unwrap();
    let slots = crate::probe::slot_count(cell.resource, r.scene.params.instances);
    let mut other = r.clone();
    for a in rep_entry(&mut other, &b).attempts.iter_mut() {
        if let Some(c) = a.result.as_mut().and_then(|x| x.comparison.as_mut()) {
            let m = &mut c.examples[0];
            let (s, e) =
                facts::whose(cell.resource, slots, facts::parse_value(&m.expected).unwrap())
                    .unwrap();
            let v = crate::probe::resource_value(cell.resource, s - 3, (e + 1) % 4);
            m.actual = format!("{v:?}");
        }
    }
    let d = lavapipe_26_issue(&other, &b).diagnosis;
    assert!(d.contains("before the right one, at another element in 2 of 16, in all 8"), "{d}");
    assert!(lavapipe_26_issue(&r, &b).diagnosis.contains("at the right element"));
}

/// A heap cell whose run recorded its VkDescriptorSetAndBindingMappingEXT entries shows binding
/// 2's set, bindings and sampler members on the screen and every entry in the collapsed section;
/// the twin, the committed run from before they were recorded, says so instead.
#[test]
fn recorded_mapping_entries_are_on_the_screen_and_in_full_below() {
    let (r, b, _) = lavapipe_26();
    let mut recorded = r.clone();
    let l = crate::exec::heap::HeapLayout::new(64, 64, 19, false);
    let entries = crate::exec::heap::PipelineMapping::new(
        crate::model::HeapAccess::MappedShaderRecordIndex,
        &l,
    )
    .entries();
    for a in rep_entry(&mut recorded, &b).attempts.iter_mut() {
        if let Some(h) = a.result.as_mut().and_then(|x| x.comparison.as_mut()?.heap.as_mut()) {
            h.mappings = entries.clone();
        }
    }
    let md = lavapipe_26_issue(&recorded, &b).markdown();
    let top = screen(&md);
    assert!(top.contains("its VkDescriptorSetAndBindingMappingEXT: descriptorSet 0, firstBinding 2, bindingCount 1, resourceMask VK_SPIRV_RESOURCE_TYPE_ALL_EXT, sampler members pEmbeddedSampler NULL, useCombinedImageSamplerIndex VK_FALSE, samplerHeapOffset 0, samplerShaderRecordOffset 0, samplerHeapIndexStride 0, samplerHeapArrayStride 0; binding 0 constantOffset heapOffset 0, binding 1 constantOffset heapOffset 64"), "{top}");
    assert!(one_screen_lines(&md) <= ONE_SCREEN_LINES);
    assert!(md.contains("- `{ descriptorSet 0, firstBinding 2, bindingCount 1, resourceMask VK_SPIRV_RESOURCE_TYPE_ALL_EXT, source VK_DESCRIPTOR_MAPPING_SOURCE_HEAP_WITH_SHADER_RECORD_INDEX_EXT, sourceData.shaderRecordIndex { heapOffset 0,"), "{md}");
    let old = lavapipe_26_issue(&r, &b).markdown();
    assert!(
        !old.contains("firstBinding 2")
            && old.contains("did not record the VkDescriptorSetAndBindingMappingEXT entries"),
        "{old}"
    );
}

/// The validation run whose worker crashed in setup before the cell's turn (issue 21's re-run:
/// SIGSEGV in setup, twice): the issue says who ended how in which step, that the layer checked
/// nothing of the cell, and what a control cell under the same layer did, as observed (one
/// attempt of one cell that differs in its stage), never as a conclusion about the fault.
#[test]
fn a_validation_run_that_never_reached_the_cell_says_who_crashed_where() {
    use crate::model::{Attempt, CellResult, Outcome, Phase};
    let (r, b, _) = lavapipe_26();
    let rep = r.cells.iter().find(|c| c.id == b.bisection.representative);
    let detail = "not run: two workers in a row failed before running a cell; the last: crash in setup: worker killed by signal 11 (SIGSEGV) in setup (acceleration structures and resources)";
    let crashed = || {
        Attempt::new(Outcome::Crash, true).with_worker(2, Phase::Setup, vec![]).with_detail(detail)
    };
    let layer = "VK_LAYER_KHRONOS_validation 1.4.363".to_string();
    let control = |attempt: Attempt| {
        Some(ControlRun {
            cell: "raygen.sampled_image.literal.descriptor_heap.mapped_shader_record_index".into(),
            attempt: Box::new(attempt),
        })
    };
    let text = |control| {
        let run =
            ValidationRun::Ran { layer: layer.clone(), attempt: Box::new(crashed()), control };
        text::validation_text(&r, rep, &run)
    };
    let same = text(control(crashed()));
    for fact in [
        "Not obtained: re-run alone under VK_LAYER_KHRONOS_validation 1.4.363, the failing cell never ran.",
        "rtprobe's worker process (the layer and the driver loaded in it) crashed in its setup step, before the cell's turn",
        "signal 11 (SIGSEGV) in setup (acceleration structures and resources)",
        "so the layer checked nothing of the cell",
        "A control cell, `raygen.sampled_image.literal.descriptor_heap.mapped_shader_record_index` (it differs in stage raygen; passed in the run), re-run once alone under the same layer, crashed in its setup step",
    ] {
        assert!(same.contains(fact), "{fact:?} not in {same}");
    }
    assert!(!same.contains("the cell crash ") && !same.contains("the fault comes with"), "{same}");
    let result = CellResult {
        outcome: Outcome::Pass,
        detail: None,
        timings: Default::default(),
        comparison: None,
        fault: None,
        validation_errors: 0,
    };
    let ran = Attempt::new(Outcome::Pass, true).with_result(result);
    let own = text(control(ran));
    assert!(
        own.contains("re-run once alone under the same layer, set up and ran (`pass`, 0 validation message(s)).")
            && !own.contains("own setup"),
        "{own}"
    );
    assert!(text(None).contains("No control cell was re-run under the layer"));
}

/// The README tour's validation run: the worker crashed in the cell's trace step (the injected
/// fault, as in the run). The cell ran under the layer up to its trace, so it is no "never ran":
/// the cell ended the same way in the same step under the layer, with the layer's messages from the stderr tail. The
/// twins: a run that recorded another fault says so; no message in the tail says that.
#[test]
fn a_validation_run_that_crashed_mid_cell_reproduced_the_finding() {
    use crate::model::{Attempt, Outcome, Phase, WorkerExit};
    let (r, b, _) = lavapipe_26();
    let detail = "worker killed by signal 11 (SIGSEGV) mid-cell, in trace";
    let tail = "ERROR Validation Error: [ VUID-vkCmdTraceRaysKHR-None-08114 ] a message\n";
    let crashed = |tail: &str| {
        Attempt::new(Outcome::Crash, true)
            .with_worker(1, Phase::Trace, vec![])
            .with_detail(detail)
            .with_exit(WorkerExit {
                signal: Some(11),
                stderr_tail: tail.into(),
                ..Default::default()
            })
    };
    let layer = "VK_LAYER_KHRONOS_validation 1.4.363".to_string();
    let mut entry = r.cells.iter().find(|c| c.id == b.bisection.representative).unwrap().clone();
    let text = |entry: &crate::model::CellReport, tail: &str| {
        let run = ValidationRun::Ran {
            layer: layer.clone(),
            attempt: Box::new(crashed(tail)),
            control: None,
        };
        text::validation_text(&r, Some(entry), &run)
    };
    let mismatch = text(&entry, tail);
    entry.attempts = vec![crashed("")];
    let same = text(&entry, tail);
    for t in [&same, &mismatch] {
        assert!(
            t.contains("the failing cell ran its steps up to trace and crashed there (`worker killed by signal 11 (SIGSEGV) mid-cell, in trace`)"),
            "{t}"
        );
        assert!(
            !t.contains("never ran")
                && !t.contains("before the cell's turn")
                && !t.contains("control"),
            "{t}"
        );
        assert!(t.contains("1 validation message(s) in the worker's stderr before it"), "{t}");
    }
    assert!(
        same.contains(": the cell ended the same way in the same step under the layer"),
        "{same}"
    );
    assert!(mismatch.contains("not the fault the run recorded (mismatch"), "{mismatch}");
    assert!(text(&entry, "").contains("No validation message in the worker's stderr before it."));
}

/// A crash whose worker wrote its native backtrace: the issue quotes where it faulted (the
/// driver's frame first), not the last stderr lines (the process's start on a deep stack). The twin without a
/// backtrace keeps the last lines.
#[test]
fn a_crash_with_a_native_backtrace_quotes_where_it_faulted() {
    use crate::model::{Attempt, CellReport, Outcome, Phase, WorkerExit};
    let (r, _, _) = lavapipe_26();
    let tail = "rtprobe worker: fatal signal 11 (fault address 0x10); native backtrace:\n\
                /proc/self/exe(+0x525f7a)[0x55ccc2235f7a]\n\
                /lib/x86_64-linux-gnu/libc.so.6(+0x3c050)[0x7fa0ea37a050]\n\
                /usr/lib/x86_64-linux-gnu/libnvidia-glcore.so.580.159.04(+0x1a2b3c)[0x7f0]\n\
                /lib/x86_64-linux-gnu/libc.so.6(__libc_start_main+0x85)[0x7fa0ea365305]\n";
    let with = |tail: &str| {
        let a = Attempt::new(Outcome::Crash, false)
            .with_worker(1, Phase::Trace, vec![])
            .with_detail("worker killed by signal 11 (SIGSEGV) mid-cell, in trace")
            .with_exit(WorkerExit {
                signal: Some(11),
                stderr_tail: tail.into(),
                ..Default::default()
            });
        let mut c: CellReport = r.cells[0].clone();
        c.outcome = Outcome::Crash;
        c.attempts = vec![a];
        text::actual_text(Some(&c), Outcome::Crash)
    };
    let t = with(tail);
    assert!(
        t.contains("where it faulted (innermost first): `rtprobe worker: fatal signal 11"),
        "{t}"
    );
    assert!(t.contains("libnvidia-glcore.so.580.159.04(+0x1a2b3c)"), "{t}");
    // (the handler's own frame and the signal trampoline are left out: the driver's frame first)
    assert!(t.contains("native backtrace: | /usr/lib/x86_64-linux-gnu/libnvidia-glcore"), "{t}");
    assert!(!t.contains("+0x525f7a") && !t.contains("last stderr lines"), "{t}");
    let plain = with("lavapipe: boom\n");
    assert!(plain.contains("last stderr lines: `lavapipe: boom`"), "{plain}");
}
