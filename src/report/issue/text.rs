//! The sentences: environment, summary, the one attempt count, the fault-rate
//! statistics, actual outcome, device fault, lane evidence, validation (the report's and the
//! validation run's), reproducers, workarounds, the isolation list on one screen, and what was
//! not tested.
use super::types::{ControlRun, Environment, Representative, Reproducer, ValidationRun};
use crate::bisect::isolation::{describe, percent};
use crate::bisect::scope::cell_by_id;
use crate::model::{BisectFile, Comparison};
use crate::model::{Bisection, Cell, CellReport, Injection, IsolationLine, Outcome, RunReport};
use serde_json::Value;

pub(super) fn s(v: &Value) -> String {
    match v {
        Value::String(x) => x.clone(),
        Value::Null => "unknown".into(),
        other => other.to_string(),
    }
}

/// `uname -srvm` and the OS's PRETTY_NAME, of the machine writing the issue.
fn os_and_kernel() -> (String, String) {
    let os = std::fs::read_to_string("/etc/os-release")
        .ok()
        .and_then(|t| {
            t.lines().find_map(|l| {
                l.strip_prefix("PRETTY_NAME=").map(|v| v.trim_matches('"').to_string())
            })
        })
        .unwrap_or_else(|| "unknown".into());
    let mut u: libc::utsname = unsafe { std::mem::zeroed() };
    let kernel = if unsafe { libc::uname(&mut u) } == 0 {
        let f = |b: &[std::ffi::c_char]| {
            unsafe { std::ffi::CStr::from_ptr(b.as_ptr()) }.to_string_lossy().into_owned()
        };
        format!("{} {} {} {}", f(&u.sysname), f(&u.release), f(&u.version), f(&u.machine))
    } else {
        "unknown".into()
    };
    (os, kernel)
}

pub(super) fn symptom(o: Outcome) -> &'static str {
    match o {
        Outcome::DeviceLost => "VK_ERROR_DEVICE_LOST",
        Outcome::Crash => "Driver crash",
        Outcome::Timeout => "GPU hang",
        Outcome::Mismatch => "Wrong results",
        Outcome::Error => "Error",
        Outcome::Pass | Outcome::Unsupported | Outcome::NotImplemented => "No fault",
    }
}

fn what_happens(o: Outcome) -> &'static str {
    match o {
        Outcome::DeviceLost => "loses the device",
        Outcome::Crash => "kills the process inside the driver",
        Outcome::Timeout => "never finishes (the submission hangs past the deadline)",
        Outcome::Mismatch => "returns wrong values",
        Outcome::Error => "fails with a Vulkan error",
        Outcome::Pass | Outcome::Unsupported | Outcome::NotImplemented => "works",
    }
}

/// What the issue says a correct run does.
pub(super) const EXPECTED: &str = "The trace completes and every pixel's record matches rtprobe's CPU reference (f64): hit kind, instance custom index, primitive id and probed slot exactly, t within 1e-3 relative, barycentrics within 1e-3, and the value read from the probed resource exactly (for a dynamic index without nonuniformEXT, some element of the array).";

/// The representative's outcome: its verdict in the report, else the one its isolation line
/// names, else `error`.
pub(super) fn representative_outcome(
    rep_report: Option<&CellReport>,
    rep_line: Option<&IsolationLine>,
) -> Outcome {
    rep_report
        .map(|c| c.outcome)
        .or_else(|| {
            rep_line.and_then(|l| Outcome::ALL.iter().copied().find(|o| o.as_str() == l.verdict))
        })
        .unwrap_or(Outcome::Error)
}

/// The bisection's workarounds, one count each (their full lines are in the isolation list's
/// section), or a line saying none applies.
pub(super) fn workaround_lines(bi: &Bisection) -> Vec<String> {
    if bi.workarounds.is_empty() {
        return vec!["No workaround patch applies to this cell.".into()];
    }
    bi.workarounds
        .iter()
        .map(|w| {
            let patch = cell_by_id(&w.cell)
                .and_then(|c| c.patch)
                .map(|p| p.as_str().to_string())
                .unwrap_or_else(|| w.cell.clone());
            let verdict = match w.verdict.as_str() {
                "pass" => format!("✅ passes {}/{}", w.agreeing, w.attempts),
                v => format!("❌ {v} {}/{}", w.agreeing, w.attempts),
            };
            let injected = if w.injected.is_some() && w.verdict != "pass" {
                " (the injected fault survives the patch: nothing about the driver)"
            } else {
                ""
            };
            format!("patch `{patch}`: {verdict}{injected}")
        })
        .collect()
}

/// The device, driver and machine the issue is about; `glsl`: the failing shader's, for the
/// compiler that made its SPIR-V.
pub(super) fn environment(report: &RunReport, b: &BisectFile, glsl: Option<&str>) -> Environment {
    let d = &report.device;
    let (os, kernel) = os_and_kernel();
    Environment {
        gpu: match &b.device_uuid_rerun {
            Some(uuid) => format!("{} (the bisection re-ran cells on another card of the same driver build, UUID {uuid}, not the report's UUID {})", s(&d["name"]), s(&d["device_uuid"])),
            None => s(&d["name"]),
        },
        vendor: format!("{} ({:#06x})", s(&d["vendor"]), d["vendor_id"].as_u64().unwrap_or(0)),
        device_id: format!("{:#06x}", d["device_id"].as_u64().unwrap_or(0)),
        driver: format!("{} ({})", s(&d["driver_name"]), s(&d["driver_info"])),
        driver_version: s(&d["driver_version"]["decoded"]),
        api_version: s(&d["api_version"]),
        conformance_version: s(&d["conformance_version"]),
        os: format!("{os} (of the machine that wrote this issue; the run report does not record it)"),
        kernel,
        rtprobe: s(&report.tool["version"]),
        driver_info: s(&d["driver_info"]),
        compiler: glsl
            .map(crate::shadergen::compile::compiler_for)
            .unwrap_or_else(|| "unknown (the shaders could not be rebuilt)".into()),
    }
}

/// The minimal failing cell's attempts, once: `6 of 6 attempts faulted, every one`, with the
/// fault-rate bound only where the fault is flaky.
pub(super) fn attempts_text(agree: u32, n: u32) -> String {
    if n == 0 {
        return "attempts unknown (the cell ran only during bisection)".into();
    }
    if agree == n {
        return format!("{agree} of {n} attempts faulted, every one");
    }
    format!(
        "{agree} of {n} attempts faulted: flaky, fault rate p ≥ {:.2} at 95% (one-sided Clopper–Pearson)",
        crate::model::stats::rate_bound(agree, n)
    )
}

/// Whether the representative's run alone reproduced it, and the bisection's fault-rate bound
/// and miss probabilities (the statistics behind the isolation list).
pub(super) fn incidence_text(
    bi: &Bisection,
    rep_report: Option<&CellReport>,
    agree: u32,
    n: u32,
) -> String {
    let alone = match rep_report.and_then(|c| c.incidence.as_ref()).and_then(|i| i.reproduced_alone)
    {
        Some(true) => " It also faulted when run alone in a fresh process.",
        Some(false) => " It did NOT fault when run alone in a fresh process.",
        None => "",
    };
    format!(
        "{agree} of {n} attempts of the minimal failing cell faulted.{alone} {} of {} cells in the bisected scope fault{}.",
        bi.faulting_cells,
        bi.scope_cells,
        match bi.fault_rate_bound {
            Some(p) => format!(
                "; its fault rate is p ≥ {p:.2} at {:.0}% (one-sided Clopper–Pearson), and each of the {} passes relied on would have missed a fault of that rate with probability at most {} (at most {} that any of them did, by the union bound, if that rate bound holds)",
                100.0 * bi.confidence,
                bi.passes_relied_on,
                percent(bi.worst_miss_probability),
                percent(bi.union_miss_probability)
            ),
            None => String::new(),
        }
    )
}

/// The summary paragraph (no attempt count: [`attempts_text`] says it once).
pub(super) fn summary_text(
    env: &Environment,
    report: &RunReport,
    rep: &Representative,
    bi: &Bisection,
) -> String {
    let real = rep.injection.is_none();
    let verified: Vec<&IsolationLine> =
        bi.workarounds.iter().filter(|w| w.verdict == "pass" && w.settled() && real).collect();
    format!(
        "On {} with {} {} (Vulkan {}), a {} {}. Bisecting {} cells of rtprobe's shader matrix ({} extra runs beyond the report) narrows the failing configurations down to `{}`{}. {}",
        env.gpu,
        s(&report.device["driver_name"]),
        env.driver_version,
        env.api_version,
        describe(&rep.cell).replacen(" reading ", " shader reading ", 1),
        what_happens(rep.outcome),
        bi.scope_cells,
        bi.runs,
        bi.minimal,
        if bi.separable { ": every cell matching it faults and every other one passes" } else { " (a disjunction: no single conjunction of axis values separates the failing cells from the passing ones)" },
        match verified.len() {
            0 => "No workaround patch was verified to avoid it.".to_string(),
            _ => format!("Verified workaround(s): {}.", verified.iter().map(|w| w.cell.rsplit("patch-").next().unwrap_or(&w.cell).to_string()).collect::<Vec<_>>().join(", ")),
        }
    )
}

/// The first VK_EXT_device_fault report of the cell's attempts, or why there is none.
pub(super) fn device_fault_text(rep_report: Option<&CellReport>, outcome: Outcome) -> String {
    let faults: Vec<_> = rep_report
        .map(|c| {
            c.attempts
                .iter()
                .filter_map(|a| a.result.as_ref().and_then(|r| r.fault.clone()))
                .collect()
        })
        .unwrap_or_default();
    match faults.first() {
        Some(f) => format!(
            "{}; addresses: {}; vendor info: {}; vendor binary: {} bytes",
            f.description,
            if f.addresses.is_empty() { "none".into() } else { f.addresses.iter().map(|a| format!("{} {} (±{})", a.kind, a.address, a.precision)).collect::<Vec<_>>().join(", ") },
            if f.vendor.is_empty() { "none".into() } else { f.vendor.iter().map(|v| format!("{} (code {:#x}, data {:#x})", v.description, v.code, v.data)).collect::<Vec<_>>().join(", ") },
            f.vendor_binary_bytes
        ),
        None => match outcome {
            Outcome::DeviceLost => "The device was lost but no VK_EXT_device_fault report was obtained (the driver does not expose the extension, or the query failed).".into(),
            Outcome::Crash => "None: the process died inside the driver (no device loss to query VK_EXT_device_fault after; the signal and the worker's last phase are under Actual).".into(),
            _ => format!("Not applicable: the outcome is {} (VK_EXT_device_fault is queried after a device loss).", outcome.as_str()),
        },
    }
}

/// The comparisons of the cell's attempts, latest first.
pub(super) fn comparisons(rep: Option<&CellReport>) -> impl Iterator<Item = &Comparison> {
    rep.into_iter()
        .flat_map(|c| c.attempts.iter().rev())
        .filter_map(|a| a.result.as_ref()?.comparison.as_ref())
}

/// How the minimal failing cell's mismatches split by lane evidence — from the run report, else
/// from `forced` (a `--lane-evidence force` report of the same device) — or why there is none.
pub(super) fn lanes_text(
    report: &RunReport,
    rep: &Cell,
    rep_report: Option<&CellReport>,
    forced: Option<&RunReport>,
) -> String {
    if let Some(split) = comparisons(rep_report).find_map(|c| c.lanes.as_ref()) {
        return format!("{} (`docs/lane-evidence.md`).", split.sentence(rep.stage.as_str()));
    }
    let id = rep.id();
    let other = forced.and_then(|f| f.cells.iter().find(|c| c.id == id));
    if let Some(split) = comparisons(other).find_map(|c| c.lanes.as_ref()) {
        return format!(
            "{}; from a separate run with `--lane-evidence force`, whose verdict is not used (`docs/lane-evidence.md`).",
            split.sentence(rep.stage.as_str())
        );
    }
    let recorded = comparisons(rep_report).any(|c| c.lane_evidence.recorded());
    // A report from before the device's ballot stages were recorded says nothing about them.
    let listed = report.device.get(crate::model::lanes::DEVICE_BALLOT_STAGES).is_some();
    match (recorded, crate::model::lanes::device_ballot(&report.device, rep.stage) || !listed) {
        (true, _) => "Its records carry lane evidence, but no attempt with a comparison mismatched.".into(),
        (false, true) => "No lane evidence in the run report (the run was made with --lane-evidence off, or by an older rtprobe).".into(),
        (false, false) => format!("No lane evidence: {}, and this device's subgroupSupportedStages does not include {}, so rtprobe records none there; `rtprobe run --lane-evidence force` records it anyway, breaking that rule, as a diagnosis only (`rtprobe report --lanes` reads that report).", crate::model::lanes::rule_quote(), rep.stage.as_str()),
    }
}

/// A heap cell's binding 2 mapping, shader record data and descriptor offsets (empty for other
/// models).
pub(super) fn heap_text(rep: &Cell, rep_report: Option<&CellReport>) -> String {
    let Some(h) = comparisons(rep_report).find_map(|c| c.heap.as_ref()) else {
        return String::new();
    };
    let slot = crate::probe::spec::ProbeSpec::of(rep).slot.fixed();
    let read = match slot {
        Some(s) => {
            format!("this cell reads slot {s}, at byte {}", h.probe_offset + s * h.probe_stride)
        }
        None => "this cell reads the slot each lane computes (the record's `slot`)".into(),
    };
    let record = if h.shader_record.is_empty() {
        "no shader record data".to_string()
    } else {
        format!("the shader record data after each hit group's handle is `{}` (the heap index, then the base, little-endian u32s)", h.shader_record)
    };
    let entries = match h.mappings.len() {
        0 => "The run's rtprobe did not record the VkDescriptorSetAndBindingMappingEXT entries; a re-run of the cell (`rtprobe repro`, then `rtprobe run --cell-spec`) records them.".to_string(),
        n => format!(
            "The VkShaderDescriptorSetAndBindingMappingInfoEXT chained to every stage holds {n} VkDescriptorSetAndBindingMappingEXT, as the driver got them:\n\n{}",
            h.mappings.iter().map(|m| format!("- `{}`", m.text())).collect::<Vec<_>>().join("\n")
        ),
    };
    format!(
        "Binding 2 (set 0) is mapped {}; {record}. The probed array's element 0 sits at byte {} of the resource heap with stride {}, so slot s is read from byte {} + s × {}: {read}.\n\n{entries}",
        h.mapping, h.probe_offset, h.probe_stride, h.probe_offset, h.probe_stride
    )
}

/// The attempt that decided the cell's verdict (its worst).
pub(super) fn worst(c: &CellReport) -> Option<&crate::model::Attempt> {
    c.attempts.iter().max_by_key(|a| a.outcome.severity())
}

/// An attempt's detail, its mismatch counts in words from its comparison
/// (`model::comparison::detail_in_words`: older reports stored them in debug form).
pub(super) fn detail_in_words(a: &crate::model::Attempt) -> Option<String> {
    let d = a.detail.as_deref()?;
    Some(match a.result.as_ref().and_then(|r| r.comparison.as_ref()) {
        Some(cmp) => crate::model::comparison::detail_in_words(d, cmp),
        None => d.to_string(),
    })
}

/// What happened, from the worst attempt (no attempt count: [`attempts_text`] says it once).
pub(super) fn actual_text(rep: Option<&CellReport>, outcome: Outcome) -> String {
    let Some(a) = rep.and_then(worst) else {
        return format!(
            "{} (the cell ran during bisection; see the bisection file)",
            outcome.as_str()
        );
    };
    let detail = detail_in_words(a).unwrap_or_else(|| outcome.as_str().into());
    let mut t = format!("{}: {detail}", outcome.as_str());
    if let Some(x) = &a.worker_exit {
        if let Some(sig) = x.signal.filter(|_| !t.contains("signal")) {
            t += &format!(
                "; the process was killed by signal {sig} ({})",
                crate::model::signal_name(sig)
            );
        }
        let tail: Vec<&str> = x.stderr_tail.trim().lines().rev().take(3).collect();
        if let Some(frames) = crate::model::native_backtrace::top(&x.stderr_tail, 6) {
            t += &format!("; where it faulted (innermost first): `{frames}`");
        } else if !tail.is_empty() {
            let tail: Vec<&str> = tail.into_iter().rev().collect();
            t += &format!("; last stderr lines: `{}`", tail.join(" | "));
        }
    }
    t
}

/// The report's own validation, then the validation run's.
pub(super) fn validation_text(
    report: &RunReport,
    rep: Option<&CellReport>,
    run: &ValidationRun,
) -> String {
    let errors: u64 = rep
        .map(|c| {
            c.attempts.iter().filter_map(|a| a.result.as_ref()).map(|r| r.validation_errors).sum()
        })
        .unwrap_or(0);
    let mut t = match (report.options.validate, errors) {
        (false, _) => match run {
            ValidationRun::Ran { layer, attempt, control } => {
                validation_run_text(layer, rep, attempt, control.as_ref())
            }
            ValidationRun::NotRun(why) => format!("Not checked: the run did not enable VK_LAYER_KHRONOS_validation, and no validation run was made ({why})."),
        },
        (true, 0) => format!("Clean under VK_LAYER_KHRONOS_validation in the run: no validation error in the {} attempt(s) that reported back (an attempt whose process died reports nothing).", rep.map(|c| c.attempts.iter().filter(|a| a.result.is_some()).count()).unwrap_or(0)),
        (true, n) => format!("{n} validation error(s) while the cell ran: rtprobe itself misused the API, so this outcome is not evidence about the driver until they are fixed."),
    };
    match rep.and_then(|c| c.gpu_av.as_ref()) {
        Some(v) => t += &format!(" GPU-assisted validation: {}.", v.line()),
        None => t += " GPU-AV not run (`rtprobe run --validate=gpu-av`).",
    }
    t
}

/// What the validation run of `rtprobe report` found (`rep`: the failing cell's report entry,
/// for the fault the run recorded).
fn validation_run_text(
    layer: &str,
    rep: Option<&CellReport>,
    a: &crate::model::Attempt,
    control: Option<&ControlRun>,
) -> String {
    match &a.result {
        Some(r) if r.validation_errors == 0 => format!(
            "Clean: the failing cell re-run alone under {layer} reported no validation message, and still {} (`{}`).",
            a.outcome.as_str(),
            a.detail.as_deref().unwrap_or("")
        ),
        Some(r) => format!(
            "{} validation error(s) when the failing cell re-ran alone under {layer} (outcome {}): rtprobe itself may misuse the API; check them before filing (`rtprobe run --validate`, the worker's stderr).",
            r.validation_errors,
            a.outcome.as_str()
        ),
        None if a.phase.is_some_and(crate::model::Phase::in_cell) => mid_cell(layer, rep, a),
        None => format!(
            "Not obtained: re-run alone under {layer}, the failing cell never ran. {} {}",
            never_ran(a, "rtprobe's worker process (the layer and the driver loaded in it)"),
            control_text(rep, control)
        ),
    }
}

/// A validation run whose worker died or hung in one of the cell's own steps: the cell ran under
/// the layer up to that step, and faulted there, as the run recorded it or otherwise; the
/// validation messages its worker printed before that, if any.
fn mid_cell(layer: &str, rep: Option<&CellReport>, a: &crate::model::Attempt) -> String {
    let phase = a.phase.map_or("an unknown", crate::model::Phase::as_str);
    let run = rep.and_then(worst);
    let same = run.is_some_and(|r| r.outcome == a.outcome && r.phase == a.phase);
    let how = match (same, run) {
        (true, _) => "the cell ended the same way in the same step under the layer".to_string(),
        (false, Some(r)) => format!(
            "not the fault the run recorded ({}{})",
            r.outcome.as_str(),
            r.phase.map(|p| format!(" in {p}")).unwrap_or_default()
        ),
        (false, None) => "the run recorded no attempt to compare it with".to_string(),
    };
    format!(
        "Re-run alone under {layer}, the failing cell ran its steps up to {phase} and {} there (`{}`): {how}; the layer saw the cell's steps up to it, and the worker died before reporting its count of validation messages. {}",
        past(a.outcome),
        a.detail.as_deref().unwrap_or("no detail"),
        messages_before(a)
    )
}

/// The validation layer's messages in a dead worker's stderr tail (its count went with it).
fn messages_before(a: &crate::model::Attempt) -> String {
    let tail = a.worker_exit.as_ref().map(|x| x.stderr_tail.as_str()).unwrap_or("");
    let msgs: Vec<&str> = tail
        .lines()
        .map(str::trim)
        .filter(|l| l.contains("Validation Error") || l.contains("VUID-"))
        .collect();
    match msgs.as_slice() {
        [] => "No validation message in the worker's stderr before it.".into(),
        [first, ..] => format!(
            "{} validation message(s) in the worker's stderr before it (its last lines only), the first: `{first}`.",
            msgs.len()
        ),
    }
}

/// Who ended how, in which step, for an attempt whose worker failed before the cell's turn: `who`
/// ended with the attempt's outcome in its phase (the runner's detail quoted).
fn never_ran(a: &crate::model::Attempt, who: &str) -> String {
    let phase = a.phase.map_or("an unknown", crate::model::Phase::as_str);
    let how = past(a.outcome);
    format!(
        "{who} {how} in its {phase} step, before the cell's turn (`{}`), so the layer checked nothing of the cell; which of the layer, the driver and rtprobe faulted takes a stack trace to say.",
        a.detail.as_deref().unwrap_or("no detail")
    )
}

/// What the control cell re-run under the layer did, as observed: one attempt of one cell, which
/// may differ from the failing cell in more than the axis that makes it fail, so no conclusion.
fn control_text(rep: Option<&CellReport>, control: Option<&ControlRun>) -> String {
    let Some(c) = control else {
        return "No control cell was re-run under the layer (the bisection lists no passing cell)."
            .into();
    };
    let a = &c.attempt;
    let who = format!(
        "A control cell, `{}` ({}passed in the run), re-run once alone under the same layer,",
        c.cell,
        differs(rep.map(|r| r.id.as_str()), &c.cell)
    );
    match &a.result {
        None => format!(
            "{who} {} in its {} step (`{}`).",
            past(a.outcome),
            a.phase.map_or("an unknown", crate::model::Phase::as_str),
            a.detail.as_deref().unwrap_or("no detail")
        ),
        Some(r) => format!(
            "{who} set up and ran (`{}`, {} validation message(s)).",
            a.outcome.as_str(),
            r.validation_errors
        ),
    }
}

/// The axes where cell `other` differs from `cell` ("it differs in stage (raygen); "), empty
/// where either is no cell id.
fn differs(cell: Option<&str>, other: &str) -> String {
    let (Some(a), Ok(b)) = (cell.and_then(|c| Cell::parse_id(c).ok()), Cell::parse_id(other))
    else {
        return String::new();
    };
    let axes: Vec<String> = crate::model::registry::names()
        .filter(|x| a.axis_value(x) != b.axis_value(x))
        .map(|x| format!("{x} {}", b.axis_value(x).unwrap_or_else(|| "none".into())))
        .collect();
    match axes.is_empty() {
        true => String::new(),
        false => format!("it differs in {}; ", axes.join(", ")),
    }
}

/// An outcome of a worker that reported nothing, as a verb in the past.
fn past(o: Outcome) -> &'static str {
    match o {
        Outcome::Crash => "crashed",
        Outcome::Timeout => "hung",
        Outcome::DeviceLost => "lost the device",
        Outcome::Pass
        | Outcome::Mismatch
        | Outcome::Unsupported
        | Outcome::NotImplemented
        | Outcome::Error => "ended without a result",
    }
}

/// A switch of the original run that changes results, as the environment variable it is.
fn binding_stages_env(report: &RunReport) -> String {
    report
        .options
        .binding_stages
        .as_deref()
        .map(|v| format!("RTPROBE_BINDING_STAGES={v} "))
        .unwrap_or_default()
}

pub(super) fn reproduce_commands(
    report: &RunReport,
    report_path: &str,
    rep: &Cell,
    injection: Option<&Injection>,
) -> Vec<String> {
    let p = &report.scene.params;
    let patches = if rep.patch.is_some() { "all" } else { "none" };
    let mut run = format!(
        "rtprobe run --filter '{}' --patches {patches} --seed {} --size {}x{} --instances {} --mesh-detail {} --repeat 5",
        crate::model::registry::exact_filter(rep),
        p.seed,
        p.width,
        p.height,
        p.instances,
        p.mesh_detail
    );
    if let Some(i) = injection {
        run += &format!(" --inject-fault '{}'", i.spec);
    }
    let env = binding_stages_env(report);
    vec![
        format!("{env}{run}"),
        format!("rtprobe repro {} --from {report_path} -o repro && rtprobe run --cell-spec repro/cell.json", rep.id()),
        format!("{env}rtprobe bisect {report_path}"),
    ]
}

/// The one-line reproducer, what it prints, and the reproducer without rtprobe.
pub(super) fn reproducer(
    report: &RunReport,
    report_path: &str,
    rep: &Representative,
) -> Reproducer {
    let id = rep.cell.id();
    let detail = rep.entry.and_then(worst).and_then(detail_in_words).unwrap_or_default();
    let without_rtprobe = match crate::report::amber::fits(&rep.cell, rep.injection) {
        Ok(()) => "`amber -d -v 1.2 repro/cell.amber` runs the same SPIR-V on the same scene and checks the same records without rtprobe (Amber is built from source: docs/bisect-report-repro.md#amber-the-reproducer-without-rtprobe).".to_string(),
        Err(why) => format!(
            "No Amber script for this cell: {why}; {}.",
            crate::report::amber::NO_STANDALONE
        ),
    };
    Reproducer {
        command: format!(
            "{}rtprobe repro {id} --from {report_path} -o repro && rtprobe run --cell-spec repro/cell.json",
            binding_stages_env(report)
        ),
        prints: format!("exits 1 (a finding); the cell's verdict: `{}`: {detail}", rep.outcome.as_str()),
        without_rtprobe,
    }
}

/// The isolation list on one screen: per varied axis, each sibling's values where it differs
/// from the minimal failing cell, its verdict and its attempts (one count each); siblings whose
/// read the spec leaves undefined are left to the full list.
pub(super) fn isolation_summary(bi: &Bisection) -> Vec<String> {
    let Some(rep) = cell_by_id(&bi.representative) else { return vec![] };
    let doubtful = |id: &str| bi.doubtful.iter().any(|d| d.starts_with(&format!("{id} (")));
    let mut axes: Vec<(String, Vec<String>, Vec<String>)> = Vec::new();
    for l in bi.isolation.iter().filter(|l| l.varied.is_some() && !doubtful(&l.cell)) {
        let Some(c) = cell_by_id(&l.cell) else { continue };
        let axis = l.varied.clone().unwrap_or_default();
        // The sibling's values where it differs: the varied axes', and any other axis's but a
        // stand-in `none` (an axis that does not apply to the sibling).
        let varied = |a: &str| axis.split(", ").any(|v| v == a);
        let values: Vec<String> = crate::model::registry::names()
            .filter(|a| c.axis_value(a) != rep.axis_value(a))
            .filter_map(|a| c.axis_value(a).filter(|v| varied(a) || v != "none"))
            .collect();
        let entry = format!("{} {}/{}", values.join("+"), l.agreeing, l.attempts);
        let at = match axes.iter().position(|(a, _, _)| *a == axis) {
            Some(k) => k,
            None => {
                axes.push((axis, vec![], vec![]));
                axes.len() - 1
            }
        };
        match l.verdict.as_str() {
            "pass" => axes[at].2.push(entry),
            v => axes[at].1.push(format!("{entry} {v}")),
        }
    }
    axes.into_iter()
        .map(|(axis, bad, good)| {
            let mut parts = vec![];
            if !bad.is_empty() {
                parts.push(format!("❌ {}", bad.join(", ")));
            }
            if !good.is_empty() {
                parts.push(format!("✅ {}", good.join(", ")));
            }
            format!("**{axis}**: {}", parts.join(" · "))
        })
        .collect()
}

pub(super) fn not_tested(report: &RunReport, b: &BisectFile) -> Vec<String> {
    let bi = &b.bisection;
    let mut v = Vec::new();
    if !b.scope.is_empty() {
        v.push(format!(
            "Only cells matching `{}` were in the bisected scope ({} cells of a {}-cell matrix).",
            b.scope.join("` and `"),
            bi.scope_cells,
            b.full_matrix
        ));
    }
    if !bi.not_varied.is_empty() {
        v.push(format!(
            "Axes with a single value in the scope, so the result says nothing about them: {}.",
            bi.not_varied.join(", ")
        ));
    }
    if bi.not_run > 0 {
        v.push(format!(
            "{} cells of the scope never ran (bisection did not need them).",
            bi.not_run
        ));
    }
    if !bi.doubtful.is_empty() {
        v.push(format!(
            "{} cells of the scope are evidence rtprobe doubts, so they count neither way: {}.",
            bi.doubtful.len(),
            bi.doubtful.join(", ")
        ));
    }
    if !bi.errored.is_empty() {
        v.push(format!("{} cells of the scope could not be run by rtprobe (`error`), so they count neither way: {}.", bi.errored.len(), bi.errored.join(", ")));
    }
    if !bi.unsettled.is_empty() {
        v.push(format!("Not concluded: {} passing cells relied on have fewer attempts than a miss probability below {} needs: {}.", bi.unsettled.len(), percent(bi.max_miss), bi.unsettled.join(", ")));
    }
    let mut reasons: std::collections::BTreeMap<String, usize> = Default::default();
    for c in report.cells.iter().filter(|c| c.outcome == Outcome::Unsupported) {
        *reasons.entry(c.reason.clone().unwrap_or_default()).or_default() += 1;
    }
    for (r, n) in reasons {
        v.push(format!("{n} cells unsupported on this device: {r}."));
    }
    for ng in &report.plan.not_generated {
        v.push(format!("Not generated ({} combinations): {}.", ng.count, ng.rule));
    }
    let p = &report.scene.params;
    v.push(format!("One scene only (seed {}, {}x{}, {} instances, mesh detail {}); other scene sizes were not tested.", p.seed, p.width, p.height, p.instances, p.mesh_detail));
    v.push("Other drivers and GPUs.".into());
    v
}
