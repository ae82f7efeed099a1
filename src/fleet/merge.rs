//! `rtprobe merge A.json B.json … -o ALL.json`: join the reports of one matrix run in shards
//! (or re-runs of parts of it) into one. Refuses reports of different rtprobe versions, device
//! identities, scenes or result-changing options unless forced; the same cell in two reports
//! keeps every attempt (its verdict is recomputed from all of them).
use crate::matrix::plan::all_cells;
use crate::model::report::ResultOption;
use crate::model::report::TimingSummary;
use crate::model::Canary;
use crate::model::{CellReport, RunReport, SceneParams};
use serde_json::Value;
use std::collections::HashMap;

/// How two reports are not of the same run ([`same_run`]).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum NotSameRun {
    #[error("rtprobe versions differ ({} and {})", human(.0), human(.1))]
    Version(Value, Value),
    /// `key`: the [`DEVICE_KEYS`] entry that differs.
    #[error("it was made on another device ({key} {} here, {} there)", human(.here), human(.there))]
    Device { key: &'static str, here: Value, there: Value },
    #[error("its scene differs ({} here, {} there)", scene(.0), scene(.1))]
    Scene(SceneParams, SceneParams),
    /// `flag`: the option's command-line flag.
    #[error("its {flag} differs ({} here, {} there)", human(.here), human(.there))]
    Option { flag: &'static str, here: Value, there: Value },
}

/// A report value as a person reads it: text without quotes, a list joined by `; `, a decoded
/// version (`driver_version`'s `decoded`), `none` for nothing.
pub fn human(v: &Value) -> String {
    match v {
        Value::Null => "none".into(),
        Value::String(s) => s.clone(),
        Value::Array(a) if a.is_empty() => "none".into(),
        Value::Array(a) => a.iter().map(human).collect::<Vec<_>>().join("; "),
        Value::Object(o) => match o.get("decoded") {
            Some(d) => human(d),
            None => v.to_string(),
        },
        other => other.to_string(),
    }
}

/// A scene as `run`'s flags give it.
fn scene(p: &SceneParams) -> String {
    format!(
        "--seed {} --size {}x{} --instances {} --mesh-detail {}",
        p.seed, p.width, p.height, p.instances, p.mesh_detail
    )
}

/// Why reports do not merge.
#[derive(Debug, thiserror::Error)]
pub enum MergeError {
    #[error("merge needs at least one report")]
    NoReports,
    #[error("{name} does not belong with {first}: {why} (--force merges anyway)")]
    NotSameRun { name: String, first: String, why: NotSameRun },
    /// The same run (start stamp and command line) given twice.
    #[error("{name} is a run already merged (started {started}, same command line): merging it twice would double its attempts")]
    MergedTwice { name: String, started: String },
}

/// Device identity: a report continues, merges with or is compared like-for-like with another
/// only when all of these agree.
pub const DEVICE_KEYS: &[&str] =
    &["name", "driver_version", "api_version", "driver_uuid", "device_uuid"];

/// Whether `b` describes the same device, scene and result-changing options as `a`; says what
/// differs. `options` limits which option keys are compared.
// A refusal is made once per merge and says both sides in full: no need to box it.
#[allow(clippy::result_large_err)]
pub fn same_run(a: &RunReport, b: &RunReport, options: &[ResultOption]) -> Result<(), NotSameRun> {
    if a.tool["version"] != b.tool["version"] {
        return Err(NotSameRun::Version(a.tool["version"].clone(), b.tool["version"].clone()));
    }
    for key in DEVICE_KEYS {
        if a.device[key] != b.device[key] {
            return Err(NotSameRun::Device {
                key,
                here: a.device[key].clone(),
                there: b.device[key].clone(),
            });
        }
    }
    if a.scene.params != b.scene.params {
        return Err(NotSameRun::Scene(a.scene.params, b.scene.params));
    }
    for key in options {
        let (va, vb) = (key.value(&a.options), key.value(&b.options));
        if va != vb {
            return Err(NotSameRun::Option { flag: key.flag(), here: va, there: vb });
        }
    }
    Ok(())
}

/// The baseline checks of the reports merged, joined: what `merge` carries when every report was
/// checked against the same baseline (`None`: none was checked; `Err`: they differ, or only some
/// were checked, and the merge needs `--baseline`).
pub fn carried_check(
    checks: &[Option<&crate::model::BaselineCheck>],
) -> Result<Option<crate::model::BaselineCheck>, String> {
    if checks.iter().all(Option::is_none) {
        return Ok(None);
    }
    let sources: Vec<&str> =
        checks.iter().map(|c| c.map_or("none", |c| c.source.as_str())).collect();
    if checks.iter().any(Option::is_none) || sources.iter().any(|s| *s != sources[0]) {
        return Err(format!(
            "the reports were held to different baselines ({}), or only some to one",
            sources.join(", ")
        ));
    }
    let all: Vec<&crate::model::BaselineCheck> = checks.iter().flatten().copied().collect();
    let mut out = crate::model::BaselineCheck { source: sources[0].into(), ..Default::default() };
    for c in &all {
        for x in &c.cells {
            out.cells.retain(|y| y.cell != x.cell);
            out.cells.push(x.clone());
        }
        out.expected += c.expected;
        out.known_flakes += c.known_flakes;
        out.performance.extend(c.performance.iter().cloned());
        out.worker_faults.extend(c.worker_faults.iter().cloned());
        out.expected_worker_faults += c.expected_worker_faults;
    }
    // An entry none of them ran (each report lists those it did not run).
    out.not_run_cells = all[0]
        .not_run_cells
        .iter()
        .filter(|e| all.iter().all(|c| c.not_run_cells.contains(e)))
        .cloned()
        .collect();
    out.not_run = if all.iter().all(|c| c.not_run_cells.len() == c.not_run) {
        out.not_run_cells.len()
    } else {
        all.iter().map(|c| c.not_run).min().unwrap_or(0)
    };
    Ok(Some(out))
}

/// Plan order of every cell id the matrix can hold (workaround variants sort after their cell).
fn order() -> HashMap<String, usize> {
    let (cells, _) = all_cells();
    let mut m: HashMap<String, usize> =
        cells.iter().enumerate().map(|(i, c)| (c.id(), i)).collect();
    for (k, c) in Canary::ALL.iter().enumerate() {
        m.insert(crate::model::Cell::canary(*c).id(), cells.len() + k);
    }
    m
}

/// Merge `reports` (with their file names for messages). `force` skips the identity checks.
#[allow(clippy::result_large_err)] // as same_run
pub fn merge(reports: Vec<(String, RunReport)>, force: bool) -> Result<RunReport, MergeError> {
    let mut it = reports.into_iter();
    let (first_name, mut out) = it.next().ok_or(MergeError::NoReports)?;
    let mut names = vec![first_name.clone()];
    // A run is known by its start stamp and command line (shards started in the same second
    // differ in `--shard`).
    let mut started = vec![(out.started.clone(), out.command_line.clone())];
    // Baseline checks describe one report's cells; the merged report is checked anew.
    out.baseline = None;
    let mut by_id: HashMap<String, usize> =
        out.cells.iter().enumerate().map(|(i, c)| (c.id.clone(), i)).collect();
    for (name, r) in it {
        if !force {
            same_run(&out, &r, ResultOption::MERGED).map_err(|why| MergeError::NotSameRun {
                name: name.clone(),
                first: first_name.clone(),
                why,
            })?;
        }
        let id = (r.started.clone(), r.command_line.clone());
        if started.contains(&id) {
            return Err(MergeError::MergedTwice { name, started: r.started });
        }
        started.push(id);
        names.push(name);
        absorb(&mut out, &mut by_id, r);
    }
    finish(&mut out, names);
    Ok(out)
}

/// Add `r`'s workers, times and attempts to `out`; `by_id` says where each cell of `out` is.
fn absorb(out: &mut RunReport, by_id: &mut HashMap<String, usize>, r: RunReport) {
    out.complete &= r.complete;
    // Worker numbers restart in every report: keep them apart.
    let offset = out.workers.iter().map(|w| w.worker).max().unwrap_or(0);
    out.workers.extend(r.workers.iter().cloned().map(|mut w| {
        w.worker += offset;
        w
    }));
    add_timing(&mut out.timing, &r.timing);
    for mut c in r.cells {
        for a in c.attempts.iter_mut() {
            a.worker += offset;
        }
        match by_id.get(&c.id) {
            Some(&i) => join(&mut out.cells[i], c),
            None => {
                by_id.insert(c.id.clone(), out.cells.len());
                out.cells.push(c);
            }
        }
    }
}

/// `r`'s times added to `t`: sums, and the device time's mean over both reports' workers.
fn add_timing(t: &mut TimingSummary, r: &TimingSummary) {
    let workers = t.workers_started + r.workers_started;
    if workers > 0 {
        t.device_ms_mean = (t.device_ms_mean * t.workers_started as f64
            + r.device_ms_mean * r.workers_started as f64)
            / workers as f64;
    }
    t.workers_started = workers;
    t.wall_ms += r.wall_ms;
    t.compile_ms += r.compile_ms;
    t.pipeline_ms += r.pipeline_ms;
    t.setup_ms += r.setup_ms;
    t.trace_ms += r.trace_ms;
    t.check_ms += r.check_ms;
    t.overhead_ms += r.overhead_ms;
    t.cells_timed += r.cells_timed;
    t.prebuild_ms += r.prebuild_ms;
    t.prebuilt_pipelines += r.prebuilt_pipelines;
}

/// The merged report made whole: cells in plan order, the plan and tallies recounted, shard
/// options cleared, the reports it came from (`names`) listed, and the findings annotated.
fn finish(out: &mut RunReport, names: Vec<String>) {
    let order = order();
    out.cells.sort_by_key(|c| {
        (
            order.get(&c.cell.base().id()).copied().unwrap_or(usize::MAX),
            c.cell.patch.map(|p| 1 + p as usize).unwrap_or(0),
        )
    });
    // Retries (workaround variants unless --patches all planned them, recommended patterns a
    // round added) are no planned cells.
    let patches = out.options.patches;
    let planned: Vec<&CellReport> = out.cells.iter().filter(|c| !c.is_retry(patches)).collect();
    let unsupported = planned.iter().filter(|c| c.attempts.is_empty()).count();
    out.plan.planned = planned.len();
    out.plan.unsupported = unsupported;
    out.plan.to_run = planned.len() - unsupported;
    out.plan.sharded_out = 0;
    out.options.shard = None;
    out.options.merged_from = names;
    out.recount();
    crate::report::writer::annotate_findings(out);
}

/// The same cell from two reports: every attempt kept, the verdict recomputed. A cell one shard
/// planned is planned, even where another shard's round ran it as a retry (a recommended pattern
/// of a finding whose pattern cell fell to the other shard).
fn join(into: &mut CellReport, other: CellReport) {
    let retry = into.retry && other.retry;
    if into.attempts.is_empty() {
        *into = other;
    } else if !other.attempts.is_empty() {
        into.attempts.extend(other.attempts);
        into.refresh();
    }
    into.retry = retry;
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{BaselineCheck, CellCheck, Outcome, Status};

    #[test]
    fn a_cell_one_shard_planned_stays_planned() {
        use crate::model::{Attempt, Cell, DescriptorModel, IndexSource, Resource, Stage};
        let c = Cell::new(
            Stage::ClosestHit,
            Resource::StorageBuffer,
            IndexSource::DynamicElement,
            DescriptorModel::DescriptorIndexing,
        );
        let mut retried = CellReport::new(&c, Attempt::for_tests(Outcome::Pass, true));
        retried.retry = true;
        let planned = CellReport::new(&c, Attempt::for_tests(Outcome::Pass, false));
        for (a, b) in [(retried.clone(), planned.clone()), (planned, retried.clone())] {
            let mut into = a;
            join(&mut into, b);
            assert!(!into.retry && into.attempts.len() == 2);
        }
        let mut both = retried.clone();
        join(&mut both, retried);
        assert!(both.retry, "a retry in every shard stays one");
    }

    #[test]
    fn values_read_as_words_not_json() {
        let v = serde_json::json!({ "value": 136, "decoded": "25.0.7" });
        assert_eq!(human(&v), "25.0.7");
        assert_eq!(
            human(&serde_json::json!(["stage=raygen", "index=dynamic"])),
            "stage=raygen; index=dynamic"
        );
        assert_eq!(human(&serde_json::json!([])), "none");
        let e = NotSameRun::Device {
            key: "driver_version",
            here: v.clone(),
            there: serde_json::json!({ "value": 137, "decoded": "26.2.6" }),
        };
        assert_eq!(
            e.to_string(),
            "it was made on another device (driver_version 25.0.7 here, 26.2.6 there)"
        );
    }

    fn check(cells: &[&str], not_run: &[&str]) -> BaselineCheck {
        BaselineCheck {
            source: "b.json".into(),
            cells: cells
                .iter()
                .map(|c| CellCheck {
                    cell: c.to_string(),
                    status: Status::Regression,
                    expected: Outcome::Pass,
                    actual: Outcome::Crash,
                })
                .collect(),
            expected: 3,
            not_run: not_run.len(),
            not_run_cells: not_run.iter().map(|c| c.to_string()).collect(),
            ..Default::default()
        }
    }

    #[test]
    fn shards_checked_against_one_baseline_carry_it_joined() {
        let (a, b) = (check(&["x"], &["p", "q"]), check(&["y"], &["q", "x2"]));
        let m = carried_check(&[Some(&a), Some(&b)]).unwrap().unwrap();
        assert_eq!(m.regressions().count(), 2);
        assert_eq!(m.expected, 6);
        assert_eq!(
            (m.not_run, m.not_run_cells.clone()),
            (1, vec!["q".to_string()]),
            "only q ran nowhere"
        );
        assert_eq!(carried_check(&[None, None]).unwrap(), None);
        // Another baseline, or none on one shard: no verdict to carry.
        let other = BaselineCheck { source: "c.json".into(), ..a.clone() };
        assert!(carried_check(&[Some(&a), Some(&other)]).unwrap_err().contains("b.json, c.json"));
        assert!(carried_check(&[Some(&a), None]).is_err());
    }
}
