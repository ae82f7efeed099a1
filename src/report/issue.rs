//! The vendor issue (`rtprobe report`): from a run report and its bisection, the text a driver
//! team asks for (Mesa's and NVIDIA's bug templates): title with symptom, GPU, driver and API
//! version; OS and kernel; summary; incidence; expected vs actual; the isolation list; the minimal
//! failing shader next to its closest passing sibling (GLSL and SPIR-V, as a diff);
//! VK_EXT_device_fault details; validation status; the exact reproduce command; verified
//! workarounds; what was not tested. [`Issue`] is the data (`--format json`), [`Issue::markdown`]
//! the text.
use crate::bisect::isolation::{describe, percent};
use crate::bisect::scope::cell_by_id;
use crate::model::inject::for_cell;
use crate::model::BisectFile;
use crate::model::Cell;
use crate::model::Injection;
use crate::model::IsolationLine;
use crate::model::Outcome;
use crate::model::{CellReport, RunReport};
use crate::report::shaders::{cell_shaders, lanes_in, probed_role, spirv_dis, ShaderError};
use serde::{Deserialize, Serialize};
use serde_json::Value;

/// What `rtprobe report` writes (`--format`'s names are in `cli::values`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    Md,
    Json,
}

pub const SCHEMA: &str = "rtprobe.issue/1";

/// What writing the issue, or its shader comparison, fails with.
#[derive(Debug, thiserror::Error)]
pub enum IssueError {
    /// The bisection's representative cell id does not parse.
    #[error("the bisection's minimal failing cell {0:?} is not a cell id")]
    NotACell(String),
    /// A compared cell's shaders could not be made (`cell`: its id).
    #[error("{cell}: {err}")]
    Shaders { cell: String, err: ShaderError },
    /// The cell's shaders lack the one that does the probed read (`cell`: its id).
    #[error("{cell}: no probed shader")]
    NoProbedShader { cell: String },
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Environment {
    pub gpu: String,
    pub vendor: String,
    pub device_id: String,
    pub driver: String,
    pub driver_version: String,
    pub api_version: String,
    pub conformance_version: String,
    pub os: String,
    pub kernel: String,
    pub rtprobe: String,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ShaderComparison {
    pub failing_cell: String,
    pub passing_cell: Option<String>,
    pub file: String,
    pub glsl: String,
    /// `- ` lines only in the failing shader, `+ ` lines only in the passing one.
    pub glsl_diff: Option<String>,
    /// `spirv-dis` output, or why there is none.
    pub spirv: String,
    pub spirv_diff: Option<String>,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Issue {
    pub schema: String,
    pub title: String,
    /// Set when the fault was injected with `--inject-fault`: not a driver bug.
    pub injected: Option<String>,
    pub environment: Environment,
    pub summary: String,
    pub incidence: String,
    pub expected: String,
    pub actual: String,
    pub minimal: String,
    pub separable: bool,
    pub isolation: Vec<String>,
    pub shader: Option<ShaderComparison>,
    pub shader_error: Option<String>,
    pub device_fault: String,
    pub validation: String,
    pub reproduce: Vec<String>,
    pub workarounds: Vec<String>,
    /// Whether the engines' recommended pattern nearest the minimal failing cell works on this
    /// driver (`report::recommended`): "recommended pattern X (…): passes (k/N)" / fails / not run.
    #[serde(default)]
    pub recommended_pattern: String,
    /// How the minimal failing cell's mismatching pixels split by their subgroup lane evidence,
    /// or why there is none (`model::lanes`).
    #[serde(default)]
    pub lanes: String,
    /// For a descriptor-heap cell: binding 2's mapping, the shader record bytes and where the
    /// probed descriptors sit in the heap.
    #[serde(default)]
    pub heap: String,
    pub not_tested: Vec<String>,
}

fn s(v: &Value) -> String {
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

fn symptom(o: Outcome) -> &'static str {
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
const EXPECTED: &str = "The trace completes and every pixel's record matches rtprobe's CPU reference (f64): hit kind, instance custom index, primitive id and probed slot exactly, t within 1e-3 relative, barycentrics within 1e-3, and the value read from the probed resource exactly (for a dynamic index without nonuniformEXT, some element of the array).";

/// Build the issue for `report` and its bisection.
pub fn build(
    report: &RunReport,
    report_path: &str,
    b: &BisectFile,
    inject: &[Injection],
) -> Result<Issue, IssueError> {
    let bi = &b.bisection;
    let d = &report.device;
    let environment = environment(report, b);
    let rep = cell_by_id(&bi.representative)
        .ok_or_else(|| IssueError::NotACell(bi.representative.clone()))?;
    let rep_line = bi.isolation.first();
    let rep_report: Option<&CellReport> = report.cells.iter().find(|c| c.id == bi.representative);
    let outcome = representative_outcome(rep_report, rep_line);
    let injection = for_cell(inject, &rep);
    let injected = injection.map(|i| format!("This fault was injected on purpose with `--inject-fault '{}'`: rtprobe made the shader misbehave to prove its own detection. It is not a driver bug; do not file it.", i.spec));
    let title = format!(
        "{}{}: {} on {} ({} {}, Vulkan {})",
        if injected.is_some() { "[injected, not a driver bug] " } else { "" },
        symptom(outcome),
        describe(&rep),
        environment.gpu,
        s(&d["driver_name"]),
        environment.driver_version,
        environment.api_version
    );
    // The bisection's count includes the report's attempts and its own.
    let (agree, n) = rep_line.map(|l| (l.agreeing, l.attempts)).unwrap_or((0, 0));
    let incidence = incidence_text(bi, rep_report, agree, n);
    let summary = summary_text(
        &environment,
        &s(&d["driver_name"]),
        &rep,
        outcome,
        (agree, n),
        bi,
        injection.is_none(),
    );
    let (shader, shader_error) = match shader_comparison(report, &rep, bi, inject) {
        Ok(sc) => (Some(sc), None),
        Err(e) => (None, Some(e.to_string())),
    };
    Ok(Issue {
        schema: SCHEMA.into(),
        title,
        injected,
        environment,
        summary,
        incidence,
        expected: EXPECTED.to_string(),
        actual: actual_text(rep_report, outcome),
        minimal: bi.minimal.clone(),
        separable: bi.separable,
        isolation: bi.isolation.iter().map(|l| l.line.clone()).collect(),
        shader,
        shader_error,
        device_fault: device_fault_text(rep_report, outcome),
        validation: validation_text(report, rep_report),
        reproduce: reproduce_commands(report, report_path, &rep, injection),
        workarounds: workaround_lines(bi),
        recommended_pattern: crate::report::recommended::result(report, &rep).line(),
        lanes: lanes_text(report, &rep, rep_report),
        heap: heap_text(&rep, rep_report),
        not_tested: not_tested(report, b),
    })
}

/// The representative's outcome: its verdict in the report, else the one its isolation line
/// names, else `error`.
fn representative_outcome(
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

/// The bisection's workaround lines, or a line saying none applies.
fn workaround_lines(bi: &crate::model::Bisection) -> Vec<String> {
    if bi.workarounds.is_empty() {
        vec!["No workaround patch applies to this cell.".into()]
    } else {
        bi.workarounds.iter().map(|w| w.line.clone()).collect()
    }
}

/// The device, driver and machine the issue is about.
fn environment(report: &RunReport, b: &BisectFile) -> Environment {
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
    }
}

/// How often the minimal failing cell faulted (`agree` of `n` attempts), alone too, and the
/// bisection's fault-rate bound.
fn incidence_text(
    bi: &crate::model::Bisection,
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

/// The issue's summary paragraph; `(agree, n)`: attempts of the minimal failing cell that
/// faulted; `real`: not an injected fault (only then do verified workarounds count).
fn summary_text(
    env: &Environment,
    driver_name: &str,
    rep: &Cell,
    outcome: Outcome,
    (agree, n): (u32, u32),
    bi: &crate::model::Bisection,
    real: bool,
) -> String {
    let verified: Vec<&IsolationLine> =
        bi.workarounds.iter().filter(|w| w.verdict == "pass" && w.settled() && real).collect();
    format!(
        "On {} with {} {} (Vulkan {}), a {} {} ({}). Bisecting {} cells of rtprobe's shader matrix ({} extra runs beyond the report) narrows the failing configurations down to `{}`{}. {}",
        env.gpu,
        driver_name,
        env.driver_version,
        env.api_version,
        describe(rep).replacen(" reading ", " shader reading ", 1),
        what_happens(outcome),
        if n > 0 { format!("{agree} of {n} attempts") } else { "attempts unknown".into() },
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
fn device_fault_text(rep_report: Option<&CellReport>, outcome: Outcome) -> String {
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
            _ => format!("Not applicable: the outcome is {} (VK_EXT_device_fault is queried after a device loss).", outcome.as_str()),
        },
    }
}

/// The comparisons of the cell's attempts, latest first.
fn comparisons(rep: Option<&CellReport>) -> impl Iterator<Item = &crate::model::Comparison> {
    rep.into_iter()
        .flat_map(|c| c.attempts.iter().rev())
        .filter_map(|a| a.result.as_ref()?.comparison.as_ref())
}

/// How the minimal failing cell's mismatches split by lane evidence, or why there is none.
fn lanes_text(report: &RunReport, rep: &Cell, rep_report: Option<&CellReport>) -> String {
    if let Some(split) = comparisons(rep_report).find_map(|c| c.lanes.as_ref()) {
        return format!(
            "Lane evidence of its latest mismatching attempt (`docs/lane-evidence.md`): {}.",
            split.sentence()
        );
    }
    let recorded = comparisons(rep_report).any(|c| c.lane_evidence.recorded());
    match (recorded, crate::model::lanes::device_ballot(&report.device, rep.stage)) {
        (true, _) => "Its records carry lane evidence, but no attempt with a comparison mismatched.".into(),
        (false, true) => "No lane evidence in the run report (the run was made with --lane-evidence off, or by an older rtprobe).".into(),
        (false, false) => format!("No lane evidence: the device does not list subgroup ballot in {} shaders ({}); `rtprobe run --lane-evidence force` records it anyway, as a diagnosis outside the spec.", rep.stage.as_str(), crate::model::lanes::SUBGROUP_STAGE_VUID),
    }
}

/// A heap cell's binding 2 mapping, shader record bytes and descriptor offsets (empty for other
/// models).
fn heap_text(rep: &Cell, rep_report: Option<&CellReport>) -> String {
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
    format!(
        "Binding 2 (set 0) is mapped {}; {record}. The probed array's element 0 sits at byte {} of the resource heap with stride {}, so slot s is read from byte {} + s × {}: {read}.",
        h.mapping, h.probe_offset, h.probe_stride, h.probe_offset, h.probe_stride
    )
}

fn actual_text(rep: Option<&CellReport>, outcome: Outcome) -> String {
    let Some(c) = rep else {
        return format!(
            "{} (the cell ran during bisection; see the bisection file)",
            outcome.as_str()
        );
    };
    let worst = c.attempts.iter().max_by_key(|a| a.outcome.severity());
    let mut t = format!(
        "{} (in the run report): {}",
        outcome.as_str(),
        c.reason.clone().unwrap_or_else(|| outcome.as_str().into())
    );
    if let Some(a) = worst {
        if let Some(cmp) =
            a.result.as_ref().and_then(|r| r.comparison.as_ref()).filter(|c| !c.passed())
        {
            let fields: Vec<String> = cmp
                .by_field
                .iter()
                .filter(|(_, n)| **n > 0)
                .map(|(f, n)| format!("{f} {n}"))
                .collect();
            t += &format!(
                ". {} of {} compared pixels differ (by field: {}).",
                cmp.mismatched_pixels,
                cmp.compared,
                fields.join(", ")
            );
        }
        if let Some(x) = &a.worker_exit {
            if let Some(sig) = x.signal.filter(|_| !t.contains("signal")) {
                t += &format!(
                    " The process was killed by signal {sig} ({}).",
                    crate::model::signal_name(sig)
                );
            }
            if !x.stderr_tail.trim().is_empty() {
                let tail: Vec<&str> = x
                    .stderr_tail
                    .trim()
                    .lines()
                    .rev()
                    .take(3)
                    .collect::<Vec<_>>()
                    .into_iter()
                    .rev()
                    .collect();
                t += &format!(" Last stderr lines: `{}`", tail.join(" | "));
            }
        }
    }
    t
}

fn validation_text(report: &RunReport, rep: Option<&CellReport>) -> String {
    let on = report.options.validate;
    let errors: u64 = rep
        .map(|c| {
            c.attempts.iter().filter_map(|a| a.result.as_ref()).map(|r| r.validation_errors).sum()
        })
        .unwrap_or(0);
    let ran_to_end =
        rep.map(|c| c.attempts.iter().filter(|a| a.result.is_some()).count()).unwrap_or(0);
    let mut t = if !on {
        "The run did not enable VK_LAYER_KHRONOS_validation (`--validate`): API usage was not checked for this report.".to_string()
    } else if errors > 0 {
        format!("{errors} validation error(s) while the cell ran: rtprobe itself misused the API, so this outcome is not evidence about the driver until they are fixed.")
    } else {
        format!("Clean under VK_LAYER_KHRONOS_validation: no validation error in the {ran_to_end} attempt(s) that reported back (an attempt whose process died reports nothing).")
    };
    match rep.and_then(|c| c.gpu_av.as_ref()) {
        Some(v) => t += &format!(" Re-run alone under GPU-assisted validation (`--validate=gpu-av`): {}.", v.line()),
        None => t += " GPU-assisted validation (GPU-AV) was not run (`rtprobe run --validate=gpu-av`): whether it masks or reports the fault is untested.",
    }
    t
}

fn reproduce_commands(
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
    // A switch of the original run that changes results is part of the command.
    let env = report
        .options
        .binding_stages
        .as_deref()
        .map(|v| format!("RTPROBE_BINDING_STAGES={v} "))
        .unwrap_or_default();
    vec![
        format!("{env}{run}"),
        format!("rtprobe repro {} --from {report_path} -o repro && rtprobe run --cell-spec repro/cell.json", rep.id()),
        format!("{env}rtprobe bisect {report_path}"),
    ]
}

fn not_tested(report: &RunReport, b: &BisectFile) -> Vec<String> {
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
    v.push(format!("One scene only (seed {}, {}x{}, {} instances, mesh detail {}); other scene sizes were not tried.", p.seed, p.width, p.height, p.instances, p.mesh_detail));
    v.push("Other drivers and GPUs; GPU-assisted validation.".into());
    v
}

/// The probed shader of the failing cell and of its closest passing sibling (preferring a
/// sibling that differs in the index, then the resource, then the other axes in registry order).
fn shader_comparison(
    report: &RunReport,
    rep: &Cell,
    bi: &crate::model::Bisection,
    inject: &[Injection],
) -> Result<ShaderComparison, IssueError> {
    const FIRST: [&str; 3] = ["index", "nonuniform", "resource"];
    let order: Vec<&str> = FIRST
        .into_iter()
        .chain(crate::model::registry::names().filter(|a| !FIRST.contains(a)))
        .collect();
    let sibling = order
        .iter()
        .find_map(|ax| {
            bi.isolation.iter().find(|l| l.varied.as_deref() == Some(*ax) && l.verdict == "pass")
        })
        .and_then(|l| cell_by_id(&l.cell));
    let role = probed_role(rep.stage);
    let pick = |c: &Cell| -> Result<(String, Vec<u32>), IssueError> {
        let fault = for_cell(inject, c).map(|i| i.fault);
        let shaders = cell_shaders(c, fault, lanes_in(report, c))
            .map_err(|err| IssueError::Shaders { cell: c.id(), err })?;
        let sh = shaders
            .into_iter()
            .find(|s| s.role == probed_role(c.stage))
            .ok_or_else(|| IssueError::NoProbedShader { cell: c.id() })?;
        Ok((sh.glsl, sh.spirv))
    };
    let (glsl, spirv) = pick(rep)?;
    let dis = spirv_dis(&spirv);
    let (glsl_diff, spirv_diff) = match &sibling {
        Some(sib) => {
            let (g2, s2) = pick(sib)?;
            let sd = match (&dis, spirv_dis(&s2)) {
                (Some(a), Some(b)) => Some(crate::patches::diff(a, &b)),
                _ => None,
            };
            (Some(crate::patches::diff(&glsl, &g2)), sd)
        }
        None => (None, None),
    };
    Ok(ShaderComparison {
        failing_cell: rep.id(),
        passing_cell: sibling.map(|c| c.id()),
        file: role.file_name().to_string(),
        glsl,
        glsl_diff,
        spirv: dis.unwrap_or_else(|| "spirv-dis is not installed (SPIRV-Tools): no disassembly; `rtprobe repro` writes the .spv files".into()),
        spirv_diff,
    })
}

impl Issue {
    pub fn markdown(&self) -> String {
        let mut m = format!("# {}\n\n", self.title);
        if let Some(i) = &self.injected {
            m += &format!("> **Note:** {i}\n\n");
        }
        let e = &self.environment;
        m += "## Environment\n\n";
        m += &format!(
            "| | |\n|---|---|\n| GPU | {} |\n| Vendor / device id | {} / {} |\n| Driver | {} |\n| Driver version | {} |\n| Vulkan API version | {} |\n| Conformance version | {} |\n| OS | {} |\n| Kernel | {} |\n| rtprobe | {} |\n\n",
            e.gpu, e.vendor, e.device_id, e.driver, e.driver_version, e.api_version, e.conformance_version, e.os, e.kernel, e.rtprobe
        );
        m += &format!("## Summary\n\n{}\n\n", self.summary);
        m += &format!("## Incidence\n\n{}\n\n", self.incidence);
        m += &format!("## Expected\n\n{}\n\n## Actual\n\n{}\n\n", self.expected, self.actual);
        m += "## Isolation\n\nThe minimal failing cell first, then its closest siblings, one axis changed at a time (k/N: attempts that agree with the verdict, of all attempts):\n\n";
        for l in &self.isolation {
            m += &format!("- {l}\n");
        }
        m += &format!(
            "\nMinimal description{}: `{}`\n\n",
            if self.separable {
                ""
            } else {
                " (no single conjunction separates the cells; a disjunction, `;`-separated)"
            },
            self.minimal
        );
        m += "## Minimal failing shader\n\n";
        match (&self.shader, &self.shader_error) {
            (Some(sc), _) => {
                m += &format!(
                    "`{}` of `{}` (GLSL as rtprobe generates it):\n\n```glsl\n{}```\n\n",
                    sc.file, sc.failing_cell, sc.glsl
                );
                match (&sc.passing_cell, &sc.glsl_diff) {
                    (Some(p), Some(d)) => m += &format!("Against its closest passing sibling `{p}` (`-` only in the failing shader, `+` only in the passing one):\n\n```diff\n{d}```\n\n"),
                    _ => m += "No passing sibling was found to compare with.\n\n",
                }
                m += &format!(
                    "SPIR-V disassembly of the failing shader:\n\n```\n{}```\n\n",
                    sc.spirv
                );
                if let Some(d) = &sc.spirv_diff {
                    m +=
                        &format!("SPIR-V diff against the passing sibling:\n\n```diff\n{d}```\n\n");
                }
            }
            (None, Some(err)) => m += &format!("The shaders could not be rebuilt: {err}\n\n"),
            (None, None) => {}
        }
        if !self.lanes.is_empty() {
            m += &format!("## Lane evidence\n\n{}\n\n", self.lanes);
        }
        if !self.heap.is_empty() {
            m += &format!("## Descriptor heap\n\n{}\n\n", self.heap);
        }
        m += &format!("## VK_EXT_device_fault\n\n{}\n\n", self.device_fault);
        m += &format!("## Validation\n\n{}\n\n", self.validation);
        m += "## Reproduce\n\n```sh\n";
        for r in &self.reproduce {
            m += &format!("{r}\n");
        }
        m += "```\n\n## Workarounds\n\n";
        for w in &self.workarounds {
            m += &format!("- {w}\n");
        }
        m += &format!("- {}\n", self.recommended_pattern);
        m += "\n## Not tested\n\n";
        for n in &self.not_tested {
            m += &format!("- {n}\n");
        }
        m
    }
}
