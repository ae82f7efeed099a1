//! Where a run's time goes: the per-phase sums of its report ([`phases`], in [`PHASES`] order),
//! and the full cell set's time estimated from a `--shard` sample's.
use super::child::Ran;
use crate::model::RunReport;
use serde_json::{json, Value};

/// The per-phase sums of a report, in milliseconds (see `method.phases` in bench.json).
pub fn phases(r: &RunReport) -> serde_json::Map<String, Value> {
    let t = &r.timing;
    let device = t.device_ms_mean * t.workers_started as f64;
    let ready: f64 = r
        .workers
        .iter()
        .filter(|w| {
            w.phase == crate::model::phase::Phase::Setup
                && w.outcome == crate::model::outcome::Outcome::Pass
        })
        .map(|w| w.wall_ms)
        .sum();
    // In PHASES order.
    let values = [
        (ready - device).max(0.0),
        device,
        t.compile_ms,
        t.pipeline_ms,
        t.setup_ms,
        t.trace_ms,
        t.check_ms,
        t.overhead_ms,
    ];
    PHASES.iter().zip(values).map(|(k, v)| (k.to_string(), json!(v))).collect()
}

pub const PHASES: [&str; 8] =
    ["spawn_reference", "device", "compile", "pipeline", "setup", "trace", "check", "overhead"];

/// Phases paid per worker, not per cell: a sample keeps them as they are.
const PER_WORKER: [&str; 2] = ["spawn_reference", "device"];

/// The full cell set's time from a sample's: per-cell phases scaled by `scale`, per-worker
/// phases kept; the wall time grows by the added per-cell time spread over the run's workers.
pub(super) fn estimate(
    r: &Ran,
    ph: &serde_json::Map<String, Value>,
    scale: f64,
) -> (f64, serde_json::Map<String, Value>) {
    let per_cell: f64 = ph
        .iter()
        .filter(|(k, _)| !PER_WORKER.contains(&k.as_str()))
        .map(|(_, v)| v.as_f64().unwrap_or(0.0))
        .sum();
    let jobs = (r.report.options.jobs.unwrap_or(1) as f64).max(1.0);
    let wall = r.wall_s + (scale - 1.0).max(0.0) * per_cell / 1e3 / jobs;
    let m = ph
        .iter()
        .map(|(k, v)| {
            (
                k.clone(),
                json!(
                    v.as_f64().unwrap_or(0.0)
                        * if PER_WORKER.contains(&k.as_str()) { 1.0 } else { scale }
                ),
            )
        })
        .collect();
    (wall, m)
}
