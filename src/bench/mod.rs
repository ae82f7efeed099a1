//! `rtprobe bench`: run time against error. It measures rtprobe by running it: every point is
//! a child `rtprobe run` (this executable, `std::env::current_exe()`) with `-o` into a temporary
//! directory, whose report is read back and deleted. That keeps each point exactly the command a
//! user would type (recorded per point), runs the whole product (supervisor, workers, report),
//! and lets the run-argument sweep be a list of plain arguments.
//!
//! Three parts:
//! 1. **Size against detection** (`size_time`, `detection`): for each image size, the matrix's
//!    time (wall and per-phase sums; at large sizes a deterministic `--shard 1/k` sample, scaled
//!    up), and the share of cells caught with a wrong value on a fraction f of the records
//!    (`--inject-fault 'F@value:f:SEED'`: each cell draws its own records from SEED and its id),
//!    against `1 - (1 - f)^n` with n the cell's `comparison.probe_checked`.
//! 2. **Repeats against flaky faults** (`flaky`): rounds of `--inject-fault 'F@flaky:P'`, each a
//!    fresh run (fresh workers, fresh dice); per cell, whether its first r attempts showed the
//!    fault, against `1 - (1 - P)^r`, and the repeats 95% / 99% need.
//! 3. **Where the time goes** (`sweep`): the per-phase time of each entry of a list of extra run
//!    arguments ([`DEFAULT_SWEEP`]); entries naming a flag this binary's `run` does not know are
//!    recorded as skipped.
//!
//! Nothing is written until every point ran: then `bench.json` and the SVG plots, atomically.
pub mod plots;
pub mod stats;

use crate::model::RunReport;
use serde::Serialize;
use serde_json::{json, Value};
use stats::Trial;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Instant;

pub const SCHEMA: &str = "rtprobe.bench/1";

/// The run-argument sweep of part 3, in one place: each entry is one run configuration (extra
/// `rtprobe run` arguments, split on whitespace). Entries with a flag the binary's `run` does not
/// know are skipped (recorded with the reason). `-j K` and `--threads K` entries above the
/// machine's cores are skipped too. Each entry names both `-j` and `--threads`, so the sweep does
/// not depend on the device's defaults.
pub const DEFAULT_SWEEP: &[&str] = &[
    "-j 1 --threads 1",
    "-j 1 --threads 2",
    "-j 1 --threads 4",
    "-j 1 --threads 8",
    "-j 1 --threads 16",
    "-j 2 --threads 1",
    "-j 4 --threads 1",
    "-j 8 --threads 1",
    "-j 1 --threads 1 --isolation process-per-cell",
];

/// Arguments every point's run gets: one attempt per cell, no workaround retries (bench measures
/// the matrix and its detection, not the follow-ups).
pub const BASE_ARGS: &[&str] = &["--no-confirm", "--patches", "none"];

#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    #[error("cannot start `{cmd}`: {source}")]
    Spawn { cmd: String, source: std::io::Error },
    #[error("`{cmd}` exited with code {code}: {stderr}")]
    RunFailed { cmd: String, code: i32, stderr: String },
    #[error("`{cmd}`: {why}")]
    Report { cmd: String, why: crate::model::LoadError },
    #[error("`{cmd}` ran no {what} cell: check the filter")]
    Empty { cmd: String, what: &'static str },
}

/// The output folder cannot take bench's files ([`check_out_dir`]).
#[derive(Debug, thiserror::Error)]
pub enum OutDirError {
    #[error("cannot create {}: {err}", .dir.display())]
    Create { dir: PathBuf, err: std::io::Error },
    #[error("cannot write in {}: {err}", .dir.display())]
    NotWritable { dir: PathBuf, err: std::io::Error },
}

#[derive(Clone, Debug, Serialize)]
pub struct BenchOptions {
    #[serde(skip)]
    pub exe: PathBuf,
    #[serde(skip)]
    pub work_dir: PathBuf,
    pub device: Option<String>,
    /// `--validate` for every run.
    pub validate: bool,
    pub sizes: Vec<u32>,
    /// `rtprobe run`'s default `--size` (the point the plots mark).
    pub default_size: u32,
    /// Filters of the timed matrix (empty: the default matrix).
    pub matrix_filter: Vec<String>,
    /// The cells injected with `value:f` (and their filter).
    pub inject_filter: String,
    pub fractions: Vec<f64>,
    pub seeds: Vec<u64>,
    pub flaky: Vec<f64>,
    pub flaky_filter: String,
    pub flaky_size: u32,
    /// At most this many rounds per flaky probability (each gets ceil(1.2 × its 99% repeats)).
    pub max_rounds: u32,
    /// `--timeout` of the flaky rounds (a device fault hangs on some drivers).
    pub flaky_timeout: Option<f64>,
    pub sweep: Vec<String>,
    pub sweep_filter: Vec<String>,
    pub sweep_size: u32,
    /// Run each timed point once first (not recorded but its wall time): warm shader caches.
    pub warmup: bool,
    /// Sample sizes above the default with `--shard 1/k`, k = pixels / default pixels (timed
    /// matrix) and pixels / (2 × default)² (detection), and scale the times up.
    pub sample_large: bool,
    pub quick: bool,
}

/// One child run: its command line and report.
struct Ran {
    command: String,
    wall_s: f64,
    report: RunReport,
}

pub struct Bench<'a> {
    opts: &'a BenchOptions,
    counter: usize,
    /// One line per point, for the terminal.
    pub progress: &'a mut dyn FnMut(&str),
}

fn size_arg(s: u32) -> String {
    format!("{s}x{s}")
}

fn shell_quote(a: &str) -> String {
    if a.chars().all(|c| c.is_ascii_alphanumeric() || "-_./=:,".contains(c)) {
        a.to_string()
    } else {
        format!("'{}'", a.replace('\'', "'\\''"))
    }
}

/// The shard count that keeps a point's work near that of the default size.
fn shard_for(pixels: u64, reference: u64) -> u64 {
    (pixels / reference.max(1)).max(1)
}

impl<'a> Bench<'a> {
    pub fn new(opts: &'a BenchOptions, progress: &'a mut dyn FnMut(&str)) -> Self {
        Bench { opts, counter: 0, progress }
    }

    fn base(&self) -> Vec<String> {
        let mut a: Vec<String> = BASE_ARGS.iter().map(|s| s.to_string()).collect();
        if let Some(d) = &self.opts.device {
            a.extend(["--device".into(), d.clone()]);
        }
        if self.opts.validate {
            a.push("--validate".into());
        }
        a
    }

    /// This executable with `args` (stdin closed, stderr captured; stdout as `stdout` says).
    fn spawn(
        &self,
        args: &[String],
        cmd: &str,
        stdout: Stdio,
    ) -> Result<std::process::Output, BenchError> {
        Command::new(&self.opts.exe)
            .args(args)
            .stdin(Stdio::null())
            .stdout(stdout)
            .stderr(Stdio::piped())
            .output()
            .map_err(|source| BenchError::Spawn { cmd: cmd.to_string(), source })
    }

    /// `rtprobe run ARGS` (plus the base arguments), its report read back and deleted.
    fn run(&mut self, args: &[String]) -> Result<Ran, BenchError> {
        self.counter += 1;
        let out = self.opts.work_dir.join(format!("point-{}.json", self.counter));
        let mut full = vec!["run".to_string()];
        full.extend(self.base());
        full.extend(args.iter().cloned());
        let command = std::iter::once("rtprobe".to_string())
            .chain(full.iter().map(|a| shell_quote(a)))
            .collect::<Vec<_>>()
            .join(" ");
        full.extend(["-o".to_string(), out.to_string_lossy().into_owned()]);
        let t = Instant::now();
        let o = self.spawn(&full, &command, Stdio::null())?;
        let wall_s = t.elapsed().as_secs_f64();
        let code = o.status.code().unwrap_or(-1);
        // 0: all passed; 1: findings (the injected ones); 11: an injection went undetected.
        if ![0, 1, 11].contains(&code) {
            return Err(BenchError::RunFailed { cmd: command, code, stderr: last_line(&o.stderr) });
        }
        let report = RunReport::load(&out)
            .map_err(|why| BenchError::Report { cmd: command.clone(), why })?;
        let _ = std::fs::remove_file(&out);
        Ok(Ran { command, wall_s, report })
    }

    /// How many cells `run --list ARGS` would run.
    fn to_run(&self, args: &[String]) -> Result<usize, BenchError> {
        let mut full = vec!["run".to_string(), "--list".into()];
        full.extend(self.base());
        full.extend(args.iter().cloned());
        let cmd = format!("rtprobe {}", full.join(" "));
        let o = self.spawn(&full, &cmd, Stdio::piped())?;
        if !o.status.success() {
            return Err(BenchError::RunFailed {
                cmd,
                code: o.status.code().unwrap_or(-1),
                stderr: last_line(&o.stderr),
            });
        }
        Ok(String::from_utf8_lossy(&o.stdout).lines().filter(|l| l.starts_with("run ")).count())
    }

    /// The long and short flags `rtprobe run --help` lists.
    fn known_flags(&self) -> Result<Vec<String>, BenchError> {
        let o =
            self.spawn(&["run".into(), "--help".into()], "rtprobe run --help", Stdio::piped())?;
        let text = String::from_utf8_lossy(&o.stdout);
        Ok(text
            .split(|c: char| c.is_whitespace() || c == ',' || c == '[' || c == ']' || c == '=')
            .filter(|w| w.starts_with('-') && w.len() > 1)
            .map(|w| w.to_string())
            .collect())
    }

    pub fn run_all(&mut self) -> Result<Value, BenchError> {
        let started = crate::report::time::now_unix();
        let t = Instant::now();
        let mut device = Value::Null;
        let size_time = self.size_time(&mut device)?;
        let detection = self.detection()?;
        let sweep = self.sweep()?;
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
                "sampling": "with sample_large, a size of p pixels runs `--shard 1/k` of the cells (k = p / default pixels for time, p / (2·default)² for detection, where only the first seed runs); estimated: per-cell phases scaled to the full cell count, per-worker phases (spawn_reference, device) kept, wall + the added per-cell time / jobs",
            },
            "default": default,
            "size_time": size_time,
            "detection": detection,
            "flaky": flaky,
            "sweep": sweep,
        }))
    }

    fn size_time(&mut self, device: &mut Value) -> Result<Value, BenchError> {
        let filters: Vec<String> = self
            .opts
            .matrix_filter
            .iter()
            .flat_map(|f| ["--filter".to_string(), f.clone()])
            .collect();
        let full_cells = self.to_run(&filters)?;
        let dpx = u64::from(self.opts.default_size).pow(2);
        let mut points = vec![];
        for (i, &s) in self.opts.sizes.iter().enumerate() {
            let px = u64::from(s).pow(2);
            let k = if self.opts.sample_large { shard_for(px, dpx) } else { 1 };
            let mut args = vec!["--size".to_string(), size_arg(s)];
            args.extend(filters.iter().cloned());
            if k > 1 {
                args.extend(["--shard".into(), format!("1/{k}")]);
            }
            // Warm the caches once: the pipelines do not depend on the size. (A sample's workers
            // may enable other feature sets and JIT a few pipelines cold: small beside the
            // trace and check of a large image.)
            let warmup =
                if self.opts.warmup && i == 0 { Some(self.run(&args)?.wall_s) } else { None };
            let r = self.run(&args)?;
            if device.is_null() {
                *device = r.report.device.clone();
            }
            let ph = phases(&r.report);
            let ran = r.report.cells.iter().filter(|c| !c.attempts.is_empty()).count();
            if ran == 0 {
                return Err(BenchError::Empty { cmd: r.command, what: "timed" });
            }
            let scale = full_cells as f64 / ran as f64;
            let (est_wall, est_ph) = estimate(&r, &ph, scale);
            (self.progress)(&format!(
                "time {}: {ran} cells, {:.1} s{}",
                size_arg(s),
                r.wall_s,
                if k > 1 {
                    format!(" (shard 1/{k}; all {full_cells} cells estimated {est_wall:.1} s)")
                } else {
                    String::new()
                }
            ));
            points.push(json!({
                "size": s, "pixels": px, "command": r.command, "shard": (k > 1).then(|| format!("1/{k}")),
                "cells_run": ran, "full_cells": full_cells, "scale": scale,
                "wall_s": r.wall_s, "warmup_wall_s": warmup, "report_wall_ms": r.report.timing.wall_ms,
                "phases_ms": ph, "workers": r.report.timing.workers_started,
                "estimated": { "wall_s": est_wall, "phases_ms": est_ph },
                "findings": r.report.tally.findings, "outcomes": r.report.summary,
            }));
        }
        Ok(json!({ "filter": self.opts.matrix_filter, "points": points }))
    }

    fn detection(&mut self) -> Result<Value, BenchError> {
        let dpx = 4 * u64::from(self.opts.default_size).pow(2);
        let filter = self.opts.inject_filter.clone();
        let mut points = vec![];
        let mut pooled = vec![];
        for &s in &self.opts.sizes {
            let px = u64::from(s).pow(2);
            let k = if self.opts.sample_large { shard_for(px, dpx) } else { 1 };
            // Above twice the default size every cell is caught at any f of interest (n in the
            // tens of thousands) and a run costs most: one seed there.
            let seeds = if px > dpx {
                &self.opts.seeds[..1.min(self.opts.seeds.len())]
            } else {
                &self.opts.seeds[..]
            };
            for &f in &self.opts.fractions {
                let mut all: Vec<Trial> = vec![];
                for &seed in seeds {
                    let mut args = vec![
                        "--size".into(),
                        size_arg(s),
                        "--filter".into(),
                        filter.clone(),
                        "--inject-fault".into(),
                        format!("{filter}@value:{f}:{seed}"),
                    ];
                    if k > 1 {
                        args.extend(["--shard".into(), format!("1/{k}")]);
                    }
                    let r = self.run(&args)?;
                    let (trials, not_compared) = trials_of(&r.report);
                    if trials.is_empty() && not_compared.is_empty() {
                        return Err(BenchError::Empty { cmd: r.command, what: "injected" });
                    }
                    let d = stats::aggregate(f, &trials);
                    (self.progress)(&format!("detection {} f={f} seed {seed}: {} of {} cells caught (predicted {:.3}), {:.1} s", size_arg(s), d.detected, d.trials, d.predicted, r.wall_s));
                    points.push(json!({ "size": s, "fraction": f, "seed": seed, "command": r.command, "wall_s": r.wall_s, "shard": (k > 1).then(|| format!("1/{k}")), "detection": d, "not_compared": not_compared, "trials": trials }));
                    all.extend(trials);
                }
                pooled.push(json!({ "size": s, "pixels": px, "fraction": f, "detection": stats::aggregate(f, &all) }));
            }
        }
        Ok(
            json!({ "filter": filter, "fractions": self.opts.fractions, "seeds": self.opts.seeds, "points": points, "pooled": pooled }),
        )
    }

    fn flaky(&mut self) -> Result<Value, BenchError> {
        let filter = self.opts.flaky_filter.clone();
        let mut out = vec![];
        for &p in &self.opts.flaky {
            let rounds = stats::repeats_needed(p, 0.99)
                .map(|r| ((r as f64 * 1.2).ceil() as u32).min(self.opts.max_rounds))
                .unwrap_or(1)
                .max(1);
            let mut per_cell: std::collections::BTreeMap<String, Vec<bool>> = Default::default();
            let (mut armed, mut armed_caught, mut unarmed_faulted) = (0usize, 0usize, 0usize);
            let (mut wall, mut attempt_ms) = (0.0, 0.0);
            let mut command = String::new();
            for _ in 0..rounds {
                let mut args = vec![
                    "--size".into(),
                    size_arg(self.opts.flaky_size),
                    "--filter".into(),
                    filter.clone(),
                    "--inject-fault".into(),
                    format!("{filter}@flaky:{p}"),
                ];
                if let Some(t) = self.opts.flaky_timeout {
                    args.extend(["--timeout".into(), t.to_string()]);
                }
                let r = self.run(&args)?;
                command = r.command.clone();
                wall += r.wall_s;
                for c in r.report.cells.iter().filter(|c| c.injected.is_some()) {
                    let Some(a) = c.attempts.first() else {
                        continue;
                    };
                    let fired = a.injected.as_ref().and_then(|i| i.armed) == Some(true);
                    let faulted = a.outcome.is_finding();
                    attempt_ms += a.wall_ms;
                    armed += usize::from(fired);
                    armed_caught += usize::from(fired && faulted);
                    unarmed_faulted += usize::from(!fired && faulted);
                    per_cell.entry(c.id.clone()).or_default().push(faulted);
                }
            }
            if per_cell.is_empty() {
                return Err(BenchError::Empty { cmd: command, what: "flaky-injected" });
            }
            let faulted: Vec<Vec<bool>> = per_cell.values().cloned().collect();
            let attempts = faulted.iter().map(Vec::len).sum::<usize>();
            let first = stats::first_fault_curve(&faulted, rounds as usize);
            let measured = stats::window_curve(&faulted, rounds as usize);
            let predicted: Vec<f64> =
                (1..=rounds).map(|r| stats::detect_probability(p, r as u64)).collect();
            let rate = if attempts > 0 {
                faulted.iter().flatten().filter(|f| **f).count() as f64 / attempts as f64
            } else {
                0.0
            };
            let needed = |c: f64| json!({ "predicted": stats::repeats_needed(p, c), "measured": stats::first_reaching(&measured, c), "measured_first": stats::first_reaching(&first, c), "from_measured_rate": stats::repeats_needed(rate, c) });
            (self.progress)(&format!(
                "flaky:{p}: {rounds} rounds × {} cells, rate {rate:.3}, {:.1} s",
                faulted.len(),
                wall
            ));
            out.push(json!({
                "probability": p, "rounds": rounds, "cells": faulted.len(), "command": command,
                "attempts": attempts, "armed": armed, "armed_detected": armed_caught, "faulted_unarmed": unarmed_faulted,
                "measured_rate": rate, "measured": measured, "measured_first": first, "predicted": predicted,
                "repeats_needed": { "0.95": needed(0.95), "0.99": needed(0.99) },
                "wall_s": wall, "wall_per_round_s": wall / rounds as f64,
                "attempt_wall_ms_mean": if attempts > 0 { attempt_ms / attempts as f64 } else { 0.0 },
                "per_cell": per_cell,
            }));
        }
        Ok(
            json!({ "filter": filter, "size": self.opts.flaky_size, "timeout_s": self.opts.flaky_timeout, "points": out }),
        )
    }

    fn sweep(&mut self) -> Result<Value, BenchError> {
        let known = self.known_flags()?;
        let cores = std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1);
        let mut filters: Vec<String> = self
            .opts
            .sweep_filter
            .iter()
            .flat_map(|f| ["--filter".to_string(), f.clone()])
            .collect();
        filters.extend(["--size".into(), size_arg(self.opts.sweep_size)]);
        let mut entries = vec![];
        let mut first: Option<(f64, serde_json::Map<String, Value>)> = None;
        for entry in &self.opts.sweep {
            let extra: Vec<String> = entry.split_whitespace().map(|s| s.to_string()).collect();
            if let Some(why) = skip_reason(&extra, &known, cores) {
                (self.progress)(&format!("sweep '{entry}': skipped ({why})"));
                entries.push(json!({ "args": entry, "skipped": why }));
                continue;
            }
            let mut args = filters.clone();
            args.extend(extra);
            let warmup = if self.opts.warmup { Some(self.run(&args)?.wall_s) } else { None };
            let r = self.run(&args)?;
            let ph = phases(&r.report);
            let (base, base_ph) = first.get_or_insert_with(|| (r.wall_s, ph.clone())).clone();
            let ratios: serde_json::Map<String, Value> = ph
                .iter()
                .map(|(k, v)| {
                    let b = base_ph[k].as_f64().unwrap_or(0.0);
                    (
                        k.clone(),
                        if b > 0.0 { json!(v.as_f64().unwrap_or(0.0) / b) } else { Value::Null },
                    )
                })
                .collect();
            (self.progress)(&format!(
                "sweep '{entry}': {:.2} s (×{:.2} of the first entry)",
                r.wall_s,
                r.wall_s / base
            ));
            entries.push(json!({
                "args": entry, "command": r.command, "wall_s": r.wall_s, "warmup_wall_s": warmup,
                "wall_ratio": r.wall_s / base, "cells": r.report.timing.cells_timed, "workers": r.report.timing.workers_started,
                "phases_ms": ph, "phase_ratio": ratios, "findings": r.report.tally.findings,
                // What the run used (under --validate, threads are 1 whatever the entry asked).
                "jobs_used": r.report.options.jobs, "threads_used": r.report.options.threads,
            }));
        }
        Ok(
            json!({ "filter": self.opts.sweep_filter, "size": self.opts.sweep_size, "entries": entries }),
        )
    }
}

/// A child's last stderr line, without its own `rtprobe: error: ` prefix.
fn last_line(stderr: &[u8]) -> String {
    let text = String::from_utf8_lossy(stderr);
    let last = text.lines().rev().find(|l| !l.trim().is_empty()).unwrap_or("").trim();
    last.strip_prefix("rtprobe: error: ").unwrap_or(last).to_string()
}

/// Why a sweep entry cannot run on this binary/machine: a flag `run` does not know, or more
/// `-j` workers or `--threads` than cores.
pub fn skip_reason(args: &[String], known: &[String], cores: usize) -> Option<String> {
    for a in args.iter().filter(|a| a.starts_with('-')) {
        let flag = a.split('=').next().unwrap_or(a);
        if !known.iter().any(|k| k == flag) {
            return Some(format!("this rtprobe's run does not know {flag}"));
        }
    }
    let value = |names: &[&str]| {
        args.windows(2)
            .find(|w| names.contains(&w[0].as_str()))
            .and_then(|w| w[1].parse::<usize>().ok())
    };
    if let Some(j) = value(&["-j", "--jobs"]).filter(|&j| j > cores.max(2)) {
        return Some(format!("-j {j} is more workers than this machine's {cores} cores"));
    }
    value(&["--threads"])
        .filter(|&t| t > cores.max(2))
        .map(|t| format!("--threads {t} is more threads than this machine's {cores} cores"))
}

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
fn estimate(
    r: &Ran,
    ph: &serde_json::Map<String, Value>,
    scale: f64,
) -> (f64, serde_json::Map<String, Value>) {
    let per_cell: f64 = ph
        .iter()
        .filter(|(k, _)| !PER_WORKER.contains(&k.as_str()))
        .map(|(_, v)| v.as_f64().unwrap_or(0.0))
        .sum();
    let jobs = (r.report.options.jobs as f64).max(1.0);
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

/// The injected cells of a detection run: those compared are trials; the others (a crash, an
/// error) are listed with their outcome.
pub fn trials_of(r: &RunReport) -> (Vec<Trial>, Vec<Value>) {
    let mut trials = vec![];
    let mut other = vec![];
    for c in r.cells.iter().filter(|c| c.injected.is_some()) {
        let Some(a) = c.attempts.first() else {
            continue;
        };
        match a.result.as_ref().and_then(|res| res.comparison.as_ref()) {
            Some(cmp) => trials.push(Trial {
                cell: c.id.clone(),
                n: cmp.probe_checked as u64,
                detected: a.outcome.is_finding(),
                mismatched: cmp.mismatched_pixels as u64,
            }),
            None => other
                .push(json!({ "cell": c.id, "outcome": a.outcome.as_str(), "detail": a.detail })),
        }
    }
    (trials, other)
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
    let probe = dir.join(format!(".rtprobe-bench-{}", std::process::id()));
    std::fs::write(&probe, b"").map_err(|err| OutDirError::NotWritable { dir: dir.into(), err })?;
    let _ = std::fs::remove_file(&probe);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sweep_entries_with_unknown_flags_or_too_many_jobs_are_skipped() {
        let known: Vec<String> =
            ["-j", "--jobs", "--isolation", "--size"].iter().map(|s| s.to_string()).collect();
        let a = |s: &str| s.split_whitespace().map(String::from).collect::<Vec<_>>();
        assert_eq!(skip_reason(&a("-j 1"), &known, 2), None);
        assert_eq!(skip_reason(&a("-j 1 --isolation process-per-cell"), &known, 2), None);
        assert!(skip_reason(&a("-j 1 --threads 2"), &known, 2).unwrap().contains("--threads"));
        assert!(skip_reason(&a("-j 8"), &known, 2).unwrap().contains("cores"));
        assert_eq!(skip_reason(&a("-j 2"), &known, 1), None, "two workers always run");
        assert_eq!(skip_reason(&a("--isolation=worker"), &known, 2), None);
        let known: Vec<String> = ["-j", "--threads"].iter().map(|s| s.to_string()).collect();
        assert_eq!(skip_reason(&a("-j 1 --threads 2"), &known, 2), None);
        assert!(skip_reason(&a("-j 1 --threads 16"), &known, 2).unwrap().contains("--threads 16"));
        assert_eq!(skip_reason(&a("-j 1 --threads 16"), &known, 16), None);
    }

    #[test]
    fn shards_keep_the_work_near_the_default_size() {
        assert_eq!(shard_for(64 * 64, 64 * 64), 1);
        assert_eq!(shard_for(8 * 8, 64 * 64), 1);
        assert_eq!(shard_for(512 * 512, 64 * 64), 64);
        assert_eq!(shard_for(256 * 256, 128 * 128), 4);
    }

    #[test]
    fn quoting_keeps_predicates_one_word() {
        assert_eq!(shell_quote("stage=raygen|miss@value:0.1:1"), "'stage=raygen|miss@value:0.1:1'");
        assert_eq!(shell_quote("64x64"), "64x64");
    }
}
