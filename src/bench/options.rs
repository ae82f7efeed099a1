//! What a bench measures ([`BenchOptions`], checked by the CLI before any run), the default
//! run-argument sweep ([`DEFAULT_SWEEP`]) and the arguments every point's run gets
//! ([`BASE_ARGS`]).
use serde::Serialize;
use std::path::PathBuf;

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
    /// Part 4's sizes (empty: no mutants part) and the cells it mutates (`--filter`s).
    pub mutants_sizes: Vec<u32>,
    pub mutants_filter: Vec<String>,
    /// Run each timed point once first (not recorded but its wall time): warm shader caches.
    pub warmup: bool,
    /// Sample sizes above the default with `--shard 1/k`, k = pixels / default pixels (timed
    /// matrix) and pixels / (2 × default)² (detection), and scale the times up.
    pub sample_large: bool,
    pub quick: bool,
    /// `--cells`: only time against distinct cells, at these counts.
    pub cells: Vec<usize>,
    /// `--cells-cold`: each count's first run in new, empty cache folders.
    pub cells_cold: bool,
}
