//! `rtprobe merge A.json B.json … -o ALL.json`: join the reports of one matrix run in shards
//! (or re-runs of parts of it) into one. Refuses reports of different rtprobe versions, device
//! identities, scenes or result-changing options unless forced; the same cell in two reports
//! keeps every attempt (its verdict is recomputed from all of them). Sharded reports must make
//! a whole run, forced or not: one shard count, every shard 1…N (issue 22: shards 1/3 and 2/3
//! merged into a `complete` report of 15 of 22 cells, and 1/2 with 2/3 was accepted).
use super::shard::Shard;
use crate::matrix::plan::all_cells;
use crate::model::report::ResultOption;
use crate::model::report::TimingSummary;
use crate::model::Canary;
use crate::model::{CellReport, MutantReport, RunReport, SceneParams};
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
    let file = p.file.as_ref().map_or(String::new(), |f| {
        format!(" --scene {} (content {})", f.path, &f.hash[..f.hash.len().min(12)])
    });
    format!(
        "--seed {} --size {}x{} --instances {} --mesh-detail {}{file}",
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
    /// Shards of different splits: their cells overlap and leave gaps.
    #[error("{first} is shard {first_shard} and {name} is shard {shard}: the shards of one run share their count N")]
    MixedShardCounts { first: String, first_shard: String, name: String, shard: String },
    /// Not every shard 1…N is given: the merged report would lack their cells.
    #[error("shard {} missing (given: {}): merge every shard of the run, or the report lacks their cells", missing.join(", "), given.join(", "))]
    MissingShards { missing: Vec<String>, given: Vec<String> },
    #[error("{name}: its --shard {shard:?} is not I/N")]
    BadShard { name: String, shard: String },
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
        return Err(NotSameRun::Scene(a.scene.params.clone(), b.scene.params.clone()));
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

/// Whether the sharded ones of `reports` make whole runs: one shard count, and every shard of
/// it (a shard may come twice: a re-run). Unsharded reports are re-runs and join freely.
#[allow(clippy::result_large_err)] // as same_run
/// `reports`: each report's file name and `--shard`.
pub fn whole_shards(reports: &[(String, Option<String>)]) -> Result<(), MergeError> {
    let mut first: Option<(&str, Shard)> = None;
    let mut given = std::collections::BTreeSet::new();
    for (name, shard) in reports {
        let Some(label) = shard else { continue };
        let bad = || MergeError::BadShard { name: name.clone(), shard: label.clone() };
        let s = Shard::parse(label).map_err(|_| bad())?;
        match first {
            None => first = Some((name, s)),
            Some((f, fs)) if fs.count != s.count => {
                return Err(MergeError::MixedShardCounts {
                    first: f.into(),
                    first_shard: fs.label(),
                    name: name.clone(),
                    shard: s.label(),
                })
            }
            Some(_) => {}
        }
        given.insert(s.index);
    }
    let Some((_, s)) = first else { return Ok(()) };
    let label = |i: u32| Shard { index: i, count: s.count }.label();
    let missing: Vec<String> = (1..=s.count).filter(|i| !given.contains(i)).map(label).collect();
    if missing.is_empty() {
        return Ok(());
    }
    Err(MergeError::MissingShards { missing, given: given.into_iter().map(label).collect() })
}

/// Merge `reports` (with their file names for messages). `force` merges reports the identity
/// checks refuse, never a partial shard set ([`whole_shards`]); the result is then not
/// `complete`, and `incomplete` says which reports differ in what.
#[allow(clippy::result_large_err)] // as same_run
pub fn merge(reports: Vec<(String, RunReport)>, force: bool) -> Result<RunReport, MergeError> {
    let shards: Vec<(String, Option<String>)> =
        reports.iter().map(|(n, r)| (n.clone(), r.options.shard.clone())).collect();
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
    let mut forced = Vec::new();
    for (name, r) in it {
        if let Err(why) = same_run(&out, &r, ResultOption::MERGED) {
            if !force {
                return Err(MergeError::NotSameRun { name, first: first_name, why });
            }
            forced.push(format!("{name} does not belong with {first_name}: {why}"));
        }
        let id = (r.started.clone(), r.command_line.clone());
        if started.contains(&id) {
            return Err(MergeError::MergedTwice { name, started: r.started });
        }
        started.push(id);
        names.push(name);
        absorb(&mut out, &mut by_id, r);
    }
    whole_shards(&shards)?;
    finish(&mut out, names);
    // Reports of different runs make no one run's report, whatever each says of itself.
    if !forced.is_empty() {
        out.complete = false;
        out.incomplete = Some(format!("merged with --force: {}", forced.join("; ")));
    }
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
    if let Some(m) = r.mutants {
        absorb_mutants(out.mutants.get_or_insert_with(Default::default), m);
    }
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

/// A shard's kill matrix (`run --mutants`) joined into `out`'s: its mutants, entries and round
/// time added, the counts recounted (shards hold other cells, so no entry repeats).
fn absorb_mutants(out: &mut MutantReport, m: MutantReport) {
    for k in m.mutants {
        if !out.mutants.contains(&k) {
            out.mutants.push(k);
        }
    }
    out.mutants.sort();
    out.wall_ms += m.wall_ms;
    out.entries.extend(m.entries);
    out.recount();
}

/// The mean over `n` and `m` items of two means `a` and `b`; `a` where there are none.
fn weighted_mean(a: f64, n: usize, b: f64, m: usize) -> f64 {
    if n + m == 0 {
        return a;
    }
    (a * n as f64 + b * m as f64) / (n + m) as f64
}

/// `r`'s times added to `t`: sums, and the device time's mean over both reports' workers.
fn add_timing(t: &mut TimingSummary, r: &TimingSummary) {
    t.device_ms_mean =
        weighted_mean(t.device_ms_mean, t.workers_started, r.device_ms_mean, r.workers_started);
    t.workers_started += r.workers_started;
    t.as_build_ms_mean =
        weighted_mean(t.as_build_ms_mean, t.as_builds, r.as_build_ms_mean, r.as_builds);
    t.as_builds += r.as_builds;
    t.as_build_ms_max = t.as_build_ms_max.max(r.as_build_ms_max);
    t.wall_ms += r.wall_ms;
    t.compile_ms += r.compile_ms;
    t.pipeline_ms += r.pipeline_ms;
    t.setup_ms += r.setup_ms;
    t.trace_ms += r.trace_ms;
    t.check_ms += r.check_ms;
    t.readback_ms += r.readback_ms;
    t.overhead_ms += r.overhead_ms;
    t.cells_timed += r.cells_timed;
    t.prebuild_ms += r.prebuild_ms;
    t.prebuilt_pipelines += r.prebuilt_pipelines;
    t.overlapped_cells += r.overlapped_cells;
    t.checked_apart += r.checked_apart;
    t.device_create_ms += r.device_create_ms;
    t.pipeline_wait_ms += r.pipeline_wait_ms;
    t.setup_wait_ms += r.setup_wait_ms;
    // The runs' own times add up as their walls do (absent in either: unknown).
    t.own_ms = t.own_ms.zip(r.own_ms).map(|(a, b)| a + b);
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
    if let Some(m) = out.mutants.as_mut() {
        let at: HashMap<&str, usize> =
            out.cells.iter().enumerate().map(|(i, c)| (c.id.as_str(), i)).collect();
        m.entries.sort_by_key(|e| (at.get(e.cell.as_str()).copied(), e.mutant));
    }
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
    use crate::model::{Mutant, MutantEntry, MutantStatus};

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
                    why: None,
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

    #[test]
    fn shards_as_builds_join_as_a_weighted_mean_and_the_slowest() {
        let t = |n, mean, max| TimingSummary {
            workers_started: n,
            as_builds: n,
            as_build_ms_mean: mean,
            as_build_ms_max: max,
            ..Default::default()
        };
        let mut into = t(1, 10.0, 10.0);
        add_timing(&mut into, &t(3, 2.0, 4.0));
        assert_eq!((into.as_builds, into.as_build_ms_mean, into.as_build_ms_max), (4, 4.0, 10.0));
        // A shard without a scene AS (say, compute cells only) leaves the mean alone.
        add_timing(&mut into, &TimingSummary { workers_started: 2, ..Default::default() });
        assert_eq!((into.as_builds, into.as_build_ms_mean), (4, 4.0));
    }

    fn entry(cell: &str, mutant: Mutant, status: MutantStatus) -> MutantEntry {
        MutantEntry {
            cell: cell.into(),
            mutant,
            status,
            why: String::new(),
            outcome: None,
            prediction: None,
            probe_defect: false,
            allowed_by: None,
            wall_ms: 0.0,
        }
    }

    #[test]
    fn shards_kill_matrices_join_and_recount() {
        let mut out = MutantReport {
            mutants: vec![Mutant::ValueBits],
            wall_ms: 1.0,
            entries: vec![entry("a", Mutant::ValueBits, MutantStatus::Killed)],
            ..Default::default()
        };
        out.recount();
        let shard = MutantReport {
            mutants: vec![Mutant::IndexZero, Mutant::ValueBits],
            wall_ms: 2.0,
            entries: vec![
                entry("b", Mutant::IndexZero, MutantStatus::Equivalent),
                entry("b", Mutant::ValueBits, MutantStatus::Killed),
            ],
            ..Default::default()
        };
        absorb_mutants(&mut out, shard);
        assert_eq!(out.mutants, [Mutant::IndexZero, Mutant::ValueBits]);
        assert_eq!((out.wall_ms, out.entries.len()), (3.0, 3));
        assert_eq!((out.counts["value-bits"].killed, out.counts["index-zero"].equivalent), (2, 1));
    }

    fn shard(label: Option<&str>) -> (String, RunReport) {
        let mut r = RunReport::for_tests(vec![]);
        r.options.shard = label.map(String::from);
        (format!("{}.json", label.unwrap_or("all").replace('/', "-of-")), r)
    }

    #[test]
    #[allow(clippy::result_large_err)] // as same_run
    fn shards_must_make_a_whole_run() {
        let all = |labels: &[Option<&str>]| {
            let given: Vec<(String, Option<String>)> =
                labels.iter().map(|l| shard(*l)).map(|(n, r)| (n, r.options.shard)).collect();
            whole_shards(&given)
        };
        all(&[Some("1/3"), Some("3/3"), Some("2/3")]).unwrap();
        all(&[Some("1/2"), Some("2/2"), Some("2/2"), None]).unwrap();
        all(&[None, None]).unwrap();
        let e = all(&[Some("1/3"), Some("2/3")]).unwrap_err().to_string();
        assert!(e.starts_with("shard 3/3 missing (given: 1/3, 2/3)"), "{e}");
        let e = all(&[Some("1/2"), Some("2/3")]).unwrap_err().to_string();
        assert!(e.contains("1-of-2.json is shard 1/2 and 2-of-3.json is shard 2/3"), "{e}");
        assert!(matches!(all(&[Some("4/3")]), Err(MergeError::BadShard { .. })));
        // --force does not make a partial set whole.
        let e = merge(vec![shard(Some("1/2"))], true).unwrap_err().to_string();
        assert!(e.contains("shard 2/2 missing"), "{e}");
    }

    /// `merge --force` of shards with different `--filter`s (or any result-changing option):
    /// their cells are no one run's, so the report is not `complete` and says why.
    #[test]
    fn forced_merges_of_different_runs_are_not_complete() {
        let (mut a, mut b) = (shard(Some("1/2")), shard(Some("2/2")));
        a.1.started = "2026-12-02T06:00:00Z".into();
        b.1.started = "2026-12-02T06:01:00Z".into();
        b.1.options.filters = vec!["model=descriptor_heap".into()];
        let e = merge(vec![a.clone(), b.clone()], false).unwrap_err().to_string();
        assert!(e.contains("--filter"), "{e}");
        let m = merge(vec![a.clone(), b.clone()], true).unwrap();
        assert!(!m.complete);
        let why = m.incomplete.as_deref().unwrap_or_default();
        assert!(why.starts_with("merged with --force: 2-of-2.json does not belong with 1-of-2.json: its --filter differs"), "{why}");
        // The same options: --force changes nothing.
        b.1.options.filters.clear();
        let m = merge(vec![a, b], true).unwrap();
        assert!(m.complete && m.incomplete.is_none());
    }
}
