//! `rtprobe bench`: arguments into [`BenchOptions`] (every value checked before any run), the
//! output directory checked writable, the points run ([`crate::bench::Bench`]), then bench.json
//! and the plots written atomically — nothing is written when a point fails.
use super::args::BenchArgs;
use super::commands::Globals;
use super::exit::{self, coded};
use super::out::{errln, outln};
use crate::atomic::write_atomic;
use crate::bench::{self, Bench, BenchError, BenchOptions};
use crate::model::Filter;
use crate::report::time;
use anyhow::{Context, Result};
use std::path::PathBuf;

const DEFAULT_SIZE: u32 = 64;
const INJECT_FILTER: &str = "descriptor_model=descriptor_indexing,resource=storage_buffer";
const FLAKY_FILTER: &str =
    "descriptor_model=descriptor_indexing,resource=storage_buffer,index=literal";
const QUICK_FILTER: &str = "descriptor_model=descriptor_indexing,resource=storage_buffer,stage=raygen|closest_hit,index=literal|dynamic";
const QUICK_FLAKY_FILTER: &str = "descriptor_model=descriptor_indexing,resource=storage_buffer,stage=raygen|closest_hit,index=literal";
const MUTANTS_FILTER: &str =
    "descriptor_model=descriptor_indexing,resource=storage_buffer|acceleration_structure";

/// What each flag left out defaults to: one set for a full bench, one for `--quick`.
struct Defaults {
    sizes: &'static [u32],
    fractions: &'static [f64],
    flaky: &'static [f64],
    seeds: &'static [u64],
    /// Also the sweep's filter.
    inject_filter: &'static str,
    flaky_filter: &'static str,
    /// Empty: the default matrix.
    matrix_filter: &'static [&'static str],
    sweep: &'static [&'static str],
    max_rounds: u32,
    mutants_sizes: &'static [u32],
    mutants_filter: &'static str,
}

const FULL: Defaults = Defaults {
    sizes: &[8, 16, 32, 64, 128, 256, 512],
    fractions: &[0.001, 0.01, 0.1],
    flaky: &[0.1, 0.3, 0.5],
    seeds: &[1, 2],
    inject_filter: INJECT_FILTER,
    flaky_filter: FLAKY_FILTER,
    matrix_filter: &[],
    sweep: bench::DEFAULT_SWEEP,
    max_rounds: 30,
    mutants_sizes: &[8, 16, 64],
    mutants_filter: MUTANTS_FILTER,
};

const QUICK: Defaults = Defaults {
    sizes: &[8, 16],
    fractions: &[0.001, 1.0],
    flaky: &[0.5],
    seeds: &[1],
    inject_filter: QUICK_FILTER,
    flaky_filter: QUICK_FLAKY_FILTER,
    matrix_filter: &[QUICK_FILTER],
    sweep: &["-j 1 --threads 1", "-j 2 --threads 1", "-j 1 --threads 2"],
    max_rounds: 3,
    mutants_sizes: &[16],
    mutants_filter: QUICK_FILTER,
};

/// `given`, or `default` when the flag was left out.
fn or_default<T: Clone>(given: &[T], default: &[T]) -> Vec<T> {
    if given.is_empty() {
        default.to_vec()
    } else {
        given.to_vec()
    }
}

/// `N` or `NxN`: a square size, N a multiple of 8 in 8..=2048; errors name `flag`.
fn parse_size(flag: &str, s: &str) -> Result<u32> {
    let t = s.trim();
    let n = match t.split_once(['x', 'X']) {
        Some((w, h)) if w.trim() == h.trim() => w.trim(),
        Some(_) => {
            return Err(coded(
                exit::USAGE,
                format!("{flag}: {s:?} is not square (bench sizes are N or NxN)"),
            ))
        }
        None => t,
    };
    match n.parse::<u32>() {
        Ok(n) if (8..=2048).contains(&n) && n % 8 == 0 => Ok(n),
        _ => Err(coded(
            exit::USAGE,
            format!("{flag}: unknown size {s:?} (N or NxN with N a multiple of 8 in 8..=2048)"),
        )),
    }
}

fn check_filter(flag: &str, f: &str) -> Result<()> {
    Filter::parse(f).map(|_| ()).map_err(|e| coded(exit::USAGE, format!("{flag}: {e}")))
}

/// The filters of the five parts, each checked.
struct Filters {
    inject: String,
    flaky: String,
    matrix: Vec<String>,
    sweep: Vec<String>,
    mutants: Vec<String>,
}

impl Filters {
    fn of(a: &BenchArgs, d: &Defaults) -> Result<Filters> {
        let f = Filters {
            inject: a.inject_filter.clone().unwrap_or_else(|| d.inject_filter.into()),
            flaky: a.flaky_filter.clone().unwrap_or_else(|| d.flaky_filter.into()),
            matrix: if a.matrix_filter.is_empty() {
                d.matrix_filter.iter().map(|s| s.to_string()).collect()
            } else {
                a.matrix_filter.clone()
            },
            sweep: or_default(&a.sweep_filter, &[d.inject_filter.to_string()]),
            mutants: or_default(&a.mutants_filter, &[d.mutants_filter.to_string()]),
        };
        check_filter("--inject-filter", &f.inject)?;
        check_filter("--flaky-filter", &f.flaky)?;
        for m in f.matrix.iter().chain(&f.sweep) {
            check_filter("--matrix-filter/--sweep-filter", m)?;
        }
        for m in &f.mutants {
            check_filter("--mutants-filter", m)?;
        }
        Ok(f)
    }
}

/// The injected fractions and flaky probabilities, each in its range.
fn probabilities(a: &BenchArgs, d: &Defaults) -> Result<(Vec<f64>, Vec<f64>)> {
    let fractions = or_default(&a.fractions, d.fractions);
    if let Some(f) = fractions.iter().find(|f| !(**f > 0.0 && **f <= 1.0)) {
        return Err(coded(exit::USAGE, format!("--fractions: {f} is outside (0, 1]")));
    }
    let flaky = if a.no_flaky { vec![] } else { or_default(&a.flaky, d.flaky) };
    if let Some(p) = flaky.iter().find(|p| !(**p > 0.0 && **p < 1.0)) {
        return Err(coded(exit::USAGE, format!("--flaky: {p} is outside (0, 1)")));
    }
    Ok((fractions, flaky))
}

/// `--flaky-timeout` and `--max-rounds` in their ranges.
fn check_flaky_limits(a: &BenchArgs) -> Result<()> {
    if let Some(t) = a.flaky_timeout.filter(|t| !(*t > 0.0 && *t <= 3600.0)) {
        return Err(coded(
            exit::USAGE,
            format!("--flaky-timeout: {t} is outside (0, 3600] seconds"),
        ));
    }
    if a.max_rounds == Some(0) || a.max_rounds.is_some_and(|r| r > 1000) {
        return Err(coded(exit::USAGE, "--max-rounds must be 1..=1000"));
    }
    Ok(())
}

/// The run-argument sweep; an entry with a flag bench sets itself or that cannot be swept is
/// refused.
fn sweep_args(a: &BenchArgs, d: &Defaults) -> Result<Vec<String>> {
    let sweep = if a.sweep_args.is_empty() {
        d.sweep.iter().map(|s| s.to_string()).collect()
    } else {
        a.sweep_args.clone()
    };
    if let Some(e) = sweep.iter().find(|e| {
        e.split_whitespace()
            .any(|w| matches!(w, "-o" | "--out" | "--resume" | "--list" | "--cell-spec"))
    }) {
        return Err(coded(exit::USAGE, format!("--sweep-args {e:?}: bench chooses -o itself; --resume, --list and --cell-spec cannot be swept")));
    }
    Ok(sweep)
}

/// Every flag checked, and defaulted (full or `--quick`), before any run.
fn options(g: &Globals, a: &BenchArgs) -> Result<BenchOptions> {
    let q = a.quick;
    let d = if q { &QUICK } else { &FULL };
    let sizes = if a.sizes.is_empty() {
        d.sizes.to_vec()
    } else {
        a.sizes.iter().map(|s| parse_size("--sizes", s)).collect::<Result<_>>()?
    };
    let (fractions, flaky) = probabilities(a, d)?;
    check_flaky_limits(a)?;
    let filters = Filters::of(a, d)?;
    let sweep = sweep_args(a, d)?;
    let mutants_sizes = if a.no_mutants {
        vec![]
    } else if a.mutants_sizes.is_empty() {
        d.mutants_sizes.to_vec()
    } else {
        a.mutants_sizes.iter().map(|s| parse_size("--mutants-sizes", s)).collect::<Result<_>>()?
    };
    let exe = crate::runner::self_exe::spawn_path();
    Ok(BenchOptions {
        exe,
        // Set by `bench` to its work folder, made once the options are checked.
        work_dir: PathBuf::new(),
        device: a.device.clone(),
        validate: g.validate,
        sizes,
        default_size: DEFAULT_SIZE,
        matrix_filter: filters.matrix,
        inject_filter: filters.inject,
        fractions,
        seeds: or_default(&a.seeds, d.seeds),
        flaky,
        flaky_filter: filters.flaky,
        flaky_size: a
            .flaky_size
            .as_deref()
            .map(|s| parse_size("--flaky-size", s))
            .transpose()?
            .unwrap_or(16),
        max_rounds: a.max_rounds.unwrap_or(d.max_rounds),
        flaky_timeout: a.flaky_timeout,
        sweep,
        sweep_filter: filters.sweep,
        sweep_size: DEFAULT_SIZE,
        mutants_sizes,
        mutants_filter: filters.mutants,
        warmup: !a.no_warmup && !q,
        sample_large: !a.no_sample,
        quick: q,
        cells: check_cells(&a.cells)?,
        cells_cold: a.cells_cold,
    })
}

/// `--cells`: each N in 1..=100000 (what `run --cells-scale` takes), at least two of them.
fn check_cells(cells: &[usize]) -> Result<Vec<usize>> {
    if let Some(n) = cells.iter().find(|n| **n == 0 || **n > 100_000) {
        return Err(coded(exit::USAGE, format!("--cells: {n} is outside 1..=100000")));
    }
    // Distinct counts: `--cells 5,5` fitted a line through one point (NaN slope in the plot).
    let distinct: std::collections::BTreeSet<_> = cells.iter().collect();
    if !cells.is_empty() && distinct.len() < 2 {
        return Err(coded(exit::USAGE, "--cells needs two different counts or more to fit a line"));
    }
    Ok(cells.to_vec())
}

pub fn bench(g: &Globals, a: &BenchArgs) -> Result<u8> {
    let mut opts = options(g, a)?;
    let out = a.out.clone().unwrap_or_else(|| {
        PathBuf::from("reports").join(format!("bench-{}", time::stamp(time::now_unix())))
    });
    bench::check_out_dir(&out).map_err(|e| coded(exit::BAD_INPUT, format!("-o: {e}")))?;
    // An interrupt kills the `rtprobe run` children (each in its own process group, its
    // temporary folder inside the work folder) and removes the work folder; nothing written.
    crate::runner::groups::handle_interrupts(crate::runner::groups::Left::Nothing);
    let work = super::paths::work_dir("rtprobe-bench")?;
    opts.work_dir = work.path().to_path_buf();
    let mut progress = |line: &str| errln!("bench: {line}");
    let result = Bench::new(&opts, &mut progress).run_all();
    drop(work);
    let value = result.map_err(|e| match &e {
        // A run's own usage or device error keeps its exit code.
        BenchError::RunFailed { code, .. } if (2..=10).contains(code) => {
            coded(*code as u8, e.to_string())
        }
        BenchError::Empty { .. } => coded(exit::USAGE, e.to_string()),
        BenchError::RunFailed { .. } | BenchError::Spawn { .. } | BenchError::Report { .. } => {
            coded(exit::INTERNAL, e.to_string())
        }
    })?;
    crate::runner::groups::handle_interrupts(crate::runner::groups::Left::Writing);
    let json = serde_json::to_vec_pretty(&value).expect("bench value serializes");
    let plots = bench::plots::all(&value);
    for (name, svg) in &plots {
        write_atomic(&out.join(name), svg.as_bytes()).with_context(|| format!("writing {name}"))?;
    }
    // bench.json last: its presence says every plot beside it is complete.
    write_atomic(&out.join("bench.json"), &json).with_context(|| "writing bench.json")?;
    print_summary(&value);
    outln!("bench: {} ({} plots)", out.join("bench.json").display(), plots.len());
    Ok(exit::OK)
}

fn print_summary(v: &serde_json::Value) {
    for (name, f) in [("first", &v["cells"]["fit_first"]), ("again", &v["cells"]["fit_again"])] {
        if let (Some(ms), Some(s), Some(r2)) =
            (f["per_cell_ms"].as_f64(), f["fixed_s"].as_f64(), f["r2"].as_f64())
        {
            outln!("cells, {name}: {ms:.2} ms per cell + {s:.2} s fixed (R² {r2:.4})");
        }
    }
    if v.get("cells").is_some() {
        return;
    }
    let d = &v["default"];
    match d["matrix_wall_s"].as_f64() {
        Some(t) => outln!("default size {0}×{0}: matrix {t:.1} s", d["size"]),
        None => outln!("default size {0}×{0}: not among --sizes", d["size"]),
    }
    for x in d["detection"].as_array().into_iter().flatten() {
        outln!(
            "  f={}: caught {:.3} (predicted {:.3}, n mean {:.0})",
            x["fraction"],
            x["measured"].as_f64().unwrap_or(f64::NAN),
            x["predicted"].as_f64().unwrap_or(f64::NAN),
            x["n_mean"].as_f64().unwrap_or(0.0)
        );
    }
    for p in v["mutants"]["points"].as_array().into_iter().flatten() {
        let t = &p["counts"]["total"];
        outln!(
            "mutants {0}×{0}: {1} of {2} applicable killed (kill rate {3}), {4} allowed survivors, {5} probe defects, {6} faults; {7:.0} ms per mutant attempt",
            p["size"],
            t["killed"],
            t["applicable"],
            p["counts"]["kill_rate"],
            t["allowed"],
            t["probe_defects"],
            t["faults"],
            p["ms_per_mutant_attempt"].as_f64().unwrap_or(f64::NAN)
        );
    }
    for p in v["flaky"]["points"].as_array().into_iter().flatten() {
        let n = &p["repeats_needed"];
        outln!(
            "flaky:{}: rate {:.3}; repeats for 95%: {} predicted, {} measured; 99%: {} / {}",
            p["probability"],
            p["measured_rate"].as_f64().unwrap_or(0.0),
            n["0.95"]["predicted"],
            n["0.95"]["measured"],
            n["0.99"]["predicted"],
            n["0.99"]["measured"]
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_square_multiples_of_eight_only() {
        assert_eq!(parse_size("--sizes", "64").unwrap(), 64);
        assert_eq!(parse_size("--sizes", "512x512").unwrap(), 512);
        for bad in ["63", "0", "4096", "64x32", "abc", "", "-8"] {
            assert!(parse_size("--sizes", bad).is_err(), "{bad}");
        }
        // The error names the flag the size came from.
        let e = parse_size("--flaky-size", "12").unwrap_err().to_string();
        assert!(e.starts_with("--flaky-size: unknown size \"12\""), "{e}");
    }
}
