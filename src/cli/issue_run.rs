//! What `rtprobe report` measures on the report's device before it writes the issue: the
//! failing cell re-run once alone under VK_LAYER_KHRONOS_validation (unless the run validated
//! already or `--no-validation-run`), and the device's SBT properties. Both need the device on
//! this machine; where it is not, the issue says why instead. Where the validation run's worker
//! fails in its setup, before the cell's turn, a control cell (one the run passed) is re-run the
//! same way, and the issue says what it did; a fault in the cell's own steps needs no control.
use super::commands::Globals;
use super::shared::{report_device, supervisor_options, SupervisorOracle};
use crate::bisect::scope::ReportOptions;
use crate::model::{Cell, RunReport};
use crate::report::issue::{ControlRun, SbtProps, ValidationRun};
use crate::runner::oracle::{Event, Mode, Oracle};
use crate::vk::driver_version::format_api_version;

/// The validation run and the SBT properties (`validate`: make the run; `cells`: the failing cell
/// and a control cell that passed in the run).
pub(super) fn measure(
    g: &Globals,
    r: &RunReport,
    ro: &ReportOptions,
    (cell, control): (Option<Cell>, Option<Cell>),
    validate: bool,
) -> (ValidationRun, Option<SbtProps>) {
    let (inst, info, _) = match report_device(g, r) {
        Ok(d) => d,
        Err(_) => {
            let why = format!(
                "the report's device, {} with driver {}, is not on the machine writing the issue",
                r.device["name"].as_str().unwrap_or("?"),
                r.device["driver_version"]["decoded"].as_str().unwrap_or("?")
            );
            return (ValidationRun::NotRun(why), None);
        }
    };
    let sbt = info.properties.rt_pipeline.map(|p| SbtProps {
        handle_size: p.shader_group_handle_size,
        handle_alignment: p.shader_group_handle_alignment,
        base_alignment: p.shader_group_base_alignment,
        max_recursion_depth: p.max_ray_recursion_depth,
    });
    let run = match (validate, cell, inst.validation_layer_version()) {
        (false, _, _) => ValidationRun::NotRun("--no-validation-run".into()),
        (_, None, _) => ValidationRun::NotRun("the failing cell is not a cell id".into()),
        (_, _, None) => ValidationRun::NotRun(
            "VK_LAYER_KHRONOS_validation is not installed on the machine writing the issue".into(),
        ),
        (true, Some(c), Some(v)) => {
            let layer = format!("VK_LAYER_KHRONOS_validation {}", format_api_version(v));
            match run_validated(r, ro, info.index, c) {
                Some(a) => {
                    // only where the cell never ran: a fault in its own steps is the cell's
                    let never_ran =
                        a.result.is_none() && !a.phase.is_some_and(crate::model::Phase::in_cell);
                    let control = control.filter(|_| never_ran).and_then(|k| {
                        let attempt = Box::new(run_validated(r, ro, info.index, k)?);
                        Some(ControlRun { cell: k.id(), attempt })
                    });
                    ValidationRun::Ran { layer, attempt: Box::new(a), control }
                }
                None => ValidationRun::NotRun(format!(
                    "the validation run of {} recorded no attempt (its worker could not start)",
                    c.id()
                )),
            }
        }
    };
    (run, sbt)
}

/// Run `cell` once alone with the validation layer, with the report's scene, timeout,
/// injections, binding stages, lane evidence and `--pipelines`: its attempt, if it recorded one.
fn run_validated(
    r: &RunReport,
    ro: &ReportOptions,
    device: usize,
    cell: Cell,
) -> Option<crate::model::Attempt> {
    let mut opts = supervisor_options(
        device,
        r.scene.params.clone(),
        1,
        ro.isolation,
        ro.timeout_s,
        true,
        ro.inject.clone(),
    );
    super::shared::as_the_report_ran(&mut opts, &r.options);
    let mut oracle = SupervisorOracle::for_run(opts);
    let mut got = None;
    oracle.run(&[cell], Mode::Alone, &mut |ev| {
        if let Event::Attempt { attempt, .. } = ev {
            got = Some(attempt);
        }
    });
    got
}
