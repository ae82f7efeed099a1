//! Time against the number of distinct cells (`rtprobe bench --cells 100,500,…`): each point is
//! a child `rtprobe run --cells-scale N` — the matrix's first N cells, or all of them and then
//! copies, each copy with a constant of its own in its first stage, so shaders and a pipeline of
//! its own (`--repeat` would re-run cells, not make new ones) — run twice in a row: `first`, with
//! `--cells-cold` in new, empty cache folders (rtprobe's pipeline cache, NVIDIA's and Mesa's
//! shader caches: every pipeline compiled), else in the user's; then `again`, the same command
//! with the same folders (every pipeline in the caches). A least-squares line through each
//! series gives the per-cell slope, the fixed part and R².
use super::child::{Bench, BenchError};
use super::timing::phases;
use serde_json::{json, Value};

/// A least-squares line `y = intercept + slope · x` and its coefficient of determination.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fit {
    pub slope: f64,
    pub intercept: f64,
    pub r2: f64,
}

/// The line through `points`; `None` with fewer than two distinct x.
pub fn fit(points: &[(f64, f64)]) -> Option<Fit> {
    let n = points.len() as f64;
    let mx = points.iter().map(|p| p.0).sum::<f64>() / n;
    let my = points.iter().map(|p| p.1).sum::<f64>() / n;
    let sxx: f64 = points.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let sxy: f64 = points.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let syy: f64 = points.iter().map(|p| (p.1 - my).powi(2)).sum();
    if points.len() < 2 || sxx <= 0.0 {
        return None;
    }
    let slope = sxy / sxx;
    let intercept = my - slope * mx;
    let sse: f64 = points.iter().map(|p| (p.1 - intercept - slope * p.0).powi(2)).sum();
    let r2 = if syy > 0.0 { 1.0 - sse / syy } else { 1.0 };
    Some(Fit { slope, intercept, r2 })
}

fn fit_json(f: Option<Fit>) -> Value {
    match f {
        Some(f) => json!({ "per_cell_ms": f.slope * 1e3, "fixed_s": f.intercept, "r2": f.r2 }),
        None => Value::Null,
    }
}

/// Cache folders of a cold point: one new folder each for rtprobe's pipeline cache and the
/// drivers' shader caches.
fn cold_env(dir: &std::path::Path) -> Vec<(&'static str, std::path::PathBuf)> {
    vec![
        ("RTPROBE_CACHE_DIR", dir.join("rtprobe")),
        ("__GL_SHADER_DISK_CACHE_PATH", dir.join("nvidia")),
        ("MESA_SHADER_CACHE_DIR", dir.join("mesa")),
    ]
}

impl Bench<'_> {
    /// Every `--cells` point, first and again, and the fitted lines (the first run's device into
    /// `device`).
    pub(super) fn cells(&mut self, device: &mut Value) -> Result<Value, BenchError> {
        let mut points = vec![];
        for &n in &self.opts.cells {
            let args = vec!["--cells-scale".to_string(), n.to_string()];
            let env = match self.opts.cells_cold {
                true => {
                    let dir = self.opts.work_dir.join(format!("cold-{n}"));
                    let env = cold_env(&dir);
                    for (_, d) in &env {
                        let _ = std::fs::create_dir_all(d);
                    }
                    env
                }
                false => vec![],
            };
            let first = self.run_env(&args, &env)?;
            let again = self.run_env(&args, &env)?;
            if let Some((_, d)) = env.first() {
                let _ = std::fs::remove_dir_all(d.parent().unwrap_or(d));
            }
            if device.is_null() {
                *device = again.report.device.clone();
            }
            let ran = again.report.cells.iter().filter(|c| !c.attempts.is_empty()).count();
            (self.progress)(&format!(
                "cells {n}: {ran} run, first {:.1} s, again {:.1} s",
                first.wall_s, again.wall_s
            ));
            points.push(json!({
                "cells": n, "cells_run": ran, "command": again.command,
                "first_wall_s": first.wall_s, "again_wall_s": again.wall_s,
                "first_phases_ms": phases(&first.report), "again_phases_ms": phases(&again.report),
                "pipelines": again.report.timing.prebuilt_pipelines,
                "outcomes": again.report.summary,
            }));
        }
        let series = |key: &str| -> Vec<(f64, f64)> {
            points
                .iter()
                .map(|p| (p["cells"].as_f64().unwrap_or(0.0), p[key].as_f64().unwrap_or(0.0)))
                .collect()
        };
        Ok(json!({
            "cold": self.opts.cells_cold,
            "points": points,
            "fit_first": fit_json(fit(&series("first_wall_s"))),
            "fit_again": fit_json(fit(&series("again_wall_s"))),
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_line_is_fitted_exactly_and_scatter_lowers_r2() {
        let line: Vec<(f64, f64)> =
            [100.0, 500.0, 1000.0, 5000.0].iter().map(|&x| (x, 0.5 + 0.002 * x)).collect();
        let f = fit(&line).unwrap();
        assert!((f.slope - 0.002).abs() < 1e-12 && (f.intercept - 0.5).abs() < 1e-9, "{f:?}");
        assert!((f.r2 - 1.0).abs() < 1e-12);
        // The twin: a quadratic's points are no line; R² falls below the 0.99.
        let quad: Vec<(f64, f64)> =
            [100.0, 500.0, 1000.0, 2000.0, 5000.0].iter().map(|&x| (x, 1e-6 * x * x)).collect();
        assert!(fit(&quad).unwrap().r2 < 0.99);
        assert_eq!(fit(&[(1.0, 2.0)]), None);
        assert_eq!(fit(&[(1.0, 2.0), (1.0, 3.0)]), None);
    }
}
