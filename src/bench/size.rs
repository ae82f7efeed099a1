//! Part 1, size against time and detection: for each image size, the matrix's time (at large
//! sizes a `--shard 1/k` sample, scaled up), and the share of cells caught with a wrong value on
//! a fraction f of the records against `1 - (1 - f)^n`.
use super::child::{size_arg, Bench, BenchError};
use super::stats::{self, Trial};
use super::timing::{estimate, phases};
use crate::model::RunReport;
use serde_json::{json, Value};

/// The shard count that keeps a point's work near that of the default size.
fn shard_for(pixels: u64, reference: u64) -> u64 {
    (pixels / reference.max(1)).max(1)
}

impl Bench<'_> {
    /// The matrix's time at each size (the first run's device into `device`).
    pub(super) fn size_time(&mut self, device: &mut Value) -> Result<Value, BenchError> {
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

    /// At each size, fraction and seed, the injected cells caught against the prediction; pooled
    /// over the seeds per size and fraction.
    pub(super) fn detection(&mut self) -> Result<Value, BenchError> {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_keep_the_work_near_the_default_size() {
        assert_eq!(shard_for(64 * 64, 64 * 64), 1);
        assert_eq!(shard_for(8 * 8, 64 * 64), 1);
        assert_eq!(shard_for(512 * 512, 64 * 64), 64);
        assert_eq!(shard_for(256 * 256, 128 * 128), 4);
    }
}
