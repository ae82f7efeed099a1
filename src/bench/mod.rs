//! `rtprobe bench`: run time against error. It measures rtprobe by running it: every point is
//! a child `rtprobe run` (this executable, `runner::self_exe`) with `-o` into a temporary
//! directory, whose report is read back and deleted. That keeps each point exactly the command a
//! user would type (recorded per point), runs the whole product (supervisor, workers, report),
//! and lets the run-argument sweep be a list of plain arguments.
//!
//! Four parts, each in a file of its own beside `child` (the child runs), `options`, `timing`
//! (the per-phase split, and a sample's time scaled to the full cell set), `stats` and `plots`:
//! 1. **Size against detection** (`size`): for each image size, the matrix's time (wall and
//!    per-phase sums; at large sizes a deterministic `--shard 1/k` sample, scaled up), and the
//!    share of cells caught with a wrong value on a fraction f of the records
//!    (`--inject-fault 'F@value:f:SEED'`: each cell draws its own records from SEED and its id),
//!    against `1 - (1 - f)^n` with n the cell's `comparison.probe_checked`.
//! 2. **Repeats against flaky faults** (`flaky`): rounds of `--inject-fault 'F@flaky:P'`, each a
//!    fresh run (fresh workers, fresh dice); per cell, whether its first r attempts showed the
//!    fault, against `1 - (1 - P)^r`, and the repeats 95% / 99% need.
//! 3. **Where the time goes** (`sweep`): the per-phase time of each entry of a list of extra run
//!    arguments ([`DEFAULT_SWEEP`]); entries naming a flag this binary's `run` does not know are
//!    recorded as skipped.
//! 4. **Detection with mutants** (`mutants`): at each of its sizes, `run --mutants` on its filter's
//!    cells: per mutant (an emulated driver bug) the applicable pairs killed, the survivors, and
//!    the round's time per mutant attempt.
//!
//!
//! With `--cells`, only **time against distinct cells** runs (`cells`): `run --cells-scale N`
//! for each N, first and again, with a fitted line each.
//!
//! Nothing is written until every point ran: then `bench.json` and the SVG plots, atomically.
pub mod plots;
pub mod stats;

mod cells;
mod child;
mod flaky;
mod mutants;
mod options;
mod size;
mod sweep;
mod timing;

pub use child::{Bench, BenchError};
pub use mutants::counts_of as mutant_counts;
pub use options::{BenchOptions, BASE_ARGS, DEFAULT_SWEEP};
pub use size::trials_of;
pub use sweep::skip_reason;
pub use timing::{phases, PHASES};

use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use std::time::Instant;

pub const SCHEMA: &str = "rtprobe.bench/1";

/// How `--cells` points are made (bench.json's `method.cells`).
const CELLS_METHOD: &str = "each point is `rtprobe run --cells-scale N`: the matrix's first N cells, or all of them and then copies (`.copy-k`), each copy with a constant of its own in its first stage, so shaders and a pipeline of its own; run twice in a row, `first` (with --cells-cold in new, empty cache folders) and `again`; wall = the child process's; fit = least squares over the points";

/// The output folder cannot take bench's files ([`check_out_dir`]).
#[derive(Debug, thiserror::Error)]
pub enum OutDirError {
    #[error("cannot create {}: {err}", .dir.display())]
    Create { dir: PathBuf, err: std::io::Error },
    #[error("cannot write in {}: {err}", .dir.display())]
    NotWritable { dir: PathBuf, err: std::io::Error },
}

impl Bench<'_> {
    /// Every part's points, then the bench.json value: the device, the options, the method and
    /// each part's results.
    pub fn run_all(&mut self) -> Result<Value, BenchError> {
        let started = crate::report::time::now_unix();
        let t = Instant::now();
        let mut device = Value::Null;
        if !self.opts.cells.is_empty() {
            let cells = self.cells(&mut device)?;
            return Ok(json!({
                "schema": SCHEMA,
                "tool": { "name": "rtprobe", "version": env!("CARGO_PKG_VERSION") },
                "command_line": std::env::args().collect::<Vec<_>>(),
                "started": format!("{} ({started})", crate::report::time::stamp(started)),
                "wall_s": t.elapsed().as_secs_f64(),
                "device": device,
                "options": self.opts,
                "method": { "cells": CELLS_METHOD, "base_args": BASE_ARGS },
                "cells": cells,
            }));
        }
        let size_time = self.size_time(&mut device)?;
        let detection = self.detection()?;
        let sweep = self.sweep()?;
        let mutants =
            if self.opts.mutants_sizes.is_empty() { Value::Null } else { self.mutants()? };
        // Last: its injected fault reads an invalid address, which leaves some GPUs hung for
        // every later process (NVIDIA 580 on the H100); `--no-flaky` leaves it out.
        let flaky = self.flaky()?;
        let default = default_statement(self.opts, &size_time, &detection);
        Ok(json!({
            "schema": SCHEMA,
            "tool": { "name": "rtprobe", "version": env!("CARGO_PKG_VERSION") },
            "command_line": std::env::args().collect::<Vec<_>>(),
            "started": format!("{} ({started})", crate::report::time::stamp(started)),
            "wall_s": t.elapsed().as_secs_f64(),
            "device": device,
            "driver": {
                "name": device["driver_name"], "info": device["driver_info"], "version": device["driver_version"]["decoded"], "api_version": device["api_version"],
            },
            "options": self.opts,
            "method": {
                "points": "each point is a child `rtprobe run` (this binary) with the arguments in its `command` and `-o` a temporary file; its report is read back and deleted",
                "base_args": BASE_ARGS,
                "n": "records a wrong value can be caught on, per cell: comparison.probe_checked (non-ambiguous pixels where the probed stage must run)",
                "prediction": "1 - (1 - f)^n per cell, averaged over a point's cells; flaky: 1 - (1 - P)^r",
                "flaky_measured": "measured: share of all windows of r consecutive attempts (every cell, every start) with a fault; measured_first: share of cells with a fault in their first r attempts (fewer samples)",
                "phases": "spawn_reference: worker process start to ready minus device (includes the CPU reference); device: instance, device, scene AS and resources; compile, pipeline, setup (per-cell resources), trace, check (readback and compare); overhead: supervisor-observed time beyond the worker's split",
                "mutants": "each point is `rtprobe run --mutants` on the mutants filter at one size; kill_rate = killed / (killed + probe defects): survivors the cell's own rule allows (undefined reads) are left out, faults are never kills",
                "sampling": "with sample_large, a size of p pixels runs `--shard 1/k` of the cells (k = p / default pixels for time, p / (2·default)² for detection, where only the first seed runs); estimated: per-cell phases scaled to the full cell count, per-worker phases (spawn_reference, device) kept, wall + the added per-cell time / jobs",
            },
            "default": default,
            "size_time": size_time,
            "detection": detection,
            "flaky": flaky,
            "sweep": sweep,
            "mutants": mutants,
        }))
    }
}

/// Where the default size sits: its time and its pooled detection per fraction.
fn default_statement(o: &BenchOptions, size_time: &Value, detection: &Value) -> Value {
    let s = o.default_size;
    let time = size_time["points"]
        .as_array()
        .and_then(|p| p.iter().find(|x| x["size"] == s))
        .map(|x| x["estimated"]["wall_s"].clone());
    let det: Vec<Value> = detection["pooled"]
        .as_array()
        .map(|p| p.iter().filter(|x| x["size"] == s).map(|x| json!({ "fraction": x["fraction"], "measured": x["detection"]["measured"], "predicted": x["detection"]["predicted"], "n_mean": x["detection"]["n_mean"] })).collect())
        .unwrap_or_default();
    json!({ "size": s, "matrix_wall_s": time, "detection": det })
}

/// Check that `dir` can take the output (created if missing) before any run: a probe file is
/// written and removed.
pub fn check_out_dir(dir: &Path) -> Result<(), OutDirError> {
    std::fs::create_dir_all(dir).map_err(|err| OutDirError::Create { dir: dir.into(), err })?;
    crate::atomic::can_write_in(dir)
        .map_err(|err| OutDirError::NotWritable { dir: dir.into(), err })
}
