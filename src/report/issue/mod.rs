//! The vendor issue (`rtprobe report`): from a run report and its bisection, the text a driver
//! engineer accepts as is. One screen first ([`markdown::ONE_SCREEN_LINES`] lines before the
//! first `<details>`): a one-line diagnosis where the evidence supports one, driver version and `driverInfo`, compiler, OS, the one-line reproducer and
//! what it prints, expected against actual values, the probed read and its declarations, the
//! descriptor layout (binding flags, array size; a heap's mapping and byte offsets), the index
//! values and whether they are in bounds, the SBT layout and recursion depth, the lane evidence,
//! the validation run, the device-fault report, the isolation list (one attempt count per cell,
//! statistics only where a fault is flaky) and the workarounds. Below it, collapsed: the full
//! isolation list with its statistics, the environment table, the full shaders, real unified
//! diffs against the closest passing sibling, the other reproduce commands and what was not
//! tested. [`Issue`] is the data (`--format json`), [`Issue::markdown`] the text.
mod diagnosis;
mod diff;
mod facts;
mod markdown;
mod shaders;
mod text;
mod types;

pub use diff::{unified, Match};
pub use markdown::{one_screen_lines, ONE_SCREEN_LINES};
pub use types::{
    ControlRun, Environment, Extras, Facts, Format, Issue, IssueError, Reproducer, SbtProps,
    ShaderComparison, ValidationRun, SCHEMA,
};

use crate::bisect::isolation::describe;
use crate::bisect::scope::cell_by_id;
use crate::model::inject::for_cell;
use crate::model::BisectFile;
use crate::model::Injection;
use crate::model::RunReport;
use types::Representative;

fn representative<'a>(
    report: &'a RunReport,
    b: &BisectFile,
    inject: &'a [Injection],
) -> Result<Representative<'a>, IssueError> {
    let bi = &b.bisection;
    let cell = cell_by_id(&bi.representative)
        .ok_or_else(|| IssueError::NotACell(bi.representative.clone()))?;
    let line = bi.isolation.first();
    let entry = report.cells.iter().find(|c| c.id == bi.representative);
    let outcome = text::representative_outcome(entry, line);
    // The bisection's count includes the report's attempts and its own.
    let (agree, n) = match (line, entry.and_then(|c| c.incidence.as_ref())) {
        (Some(l), _) => (l.agreeing, l.attempts),
        (None, Some(i)) => (i.faulted, i.attempts),
        (None, None) => (0, 0),
    };
    Ok(Representative { cell, entry, outcome, injection: for_cell(inject, &cell), agree, n })
}

/// Build the issue for `report` and its bisection, with what `rtprobe report` adds (`extras`).
pub fn build(
    report: &RunReport,
    report_path: &str,
    b: &BisectFile,
    inject: &[Injection],
    extras: &Extras,
) -> Result<Issue, IssueError> {
    let bi = &b.bisection;
    let rep = representative(report, b, inject)?;
    let (shader, shader_error) = match shaders::comparison(report, &rep.cell, bi, inject) {
        Ok(sc) => (Some(sc), None),
        Err(e) => (None, Some(e.to_string())),
    };
    let environment = text::environment(report, b, shader.as_ref().map(|s| s.glsl.as_str()));
    let injected = rep.injection.map(|i| format!("This fault was injected on purpose with `--inject-fault '{}'`: rtprobe made the shader misbehave to prove its own detection. It is not a driver bug; do not file it.", i.spec));
    let title = format!(
        "{}{}: {} on {} ({} {}, Vulkan {})",
        if injected.is_some() { "[injected, not a driver bug] " } else { "" },
        text::symptom(rep.outcome),
        describe(&rep.cell),
        environment.gpu,
        text::s(&report.device["driver_name"]),
        environment.driver_version,
        environment.api_version
    );
    Ok(Issue {
        schema: SCHEMA.into(),
        title,
        injected,
        diagnosis: diagnosis::of(&rep.cell, rep.entry, report.scene.params.instances, bi),
        summary: text::summary_text(&environment, report, &rep, bi),
        environment,
        incidence: text::incidence_text(bi, rep.entry, rep.agree, rep.n),
        attempts: text::attempts_text(rep.agree, rep.n),
        expected: text::EXPECTED.to_string(),
        actual: text::actual_text(rep.entry, rep.outcome),
        facts: facts::of(report, &rep.cell, rep.entry, extras.sbt),
        reproducer: text::reproducer(report, report_path, &rep),
        minimal: bi.minimal.clone(),
        separable: bi.separable,
        isolation: bi.isolation.iter().map(|l| l.line.clone()).collect(),
        isolation_summary: text::isolation_summary(bi),
        shader,
        shader_error,
        device_fault: text::device_fault_text(rep.entry, rep.outcome),
        validation: text::validation_text(report, rep.entry, &extras.validation),
        reproduce: text::reproduce_commands(report, report_path, &rep.cell, rep.injection),
        workarounds: text::workaround_lines(bi),
        workaround_details: bi.workarounds.iter().map(|w| w.line.clone()).collect(),
        recommended_pattern: crate::report::recommended::result(report, &rep.cell).line(),
        lanes: text::lanes_text(report, &rep.cell, rep.entry, extras.lanes),
        heap: text::heap_text(&rep.cell, rep.entry),
        not_tested: text::not_tested(report, b),
    })
}

#[cfg(test)]
mod tests;
