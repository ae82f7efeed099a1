//! Part 3, where the time goes: the per-phase time of each entry of the run-argument sweep, and
//! its ratio to the first entry's; entries this binary or machine cannot run are recorded as
//! skipped ([`skip_reason`]).
use super::child::{size_arg, Bench, BenchError};
use super::timing::phases;
use serde_json::{json, Value};

impl Bench<'_> {
    /// Each sweep entry's wall and per-phase time, and its ratios to the first entry's.
    pub(super) fn sweep(&mut self) -> Result<Value, BenchError> {
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
}
