//! Part 2, repeats against flaky faults: rounds of `--inject-fault 'F@flaky:P'`, each a fresh
//! run; per cell, whether its first r attempts showed the fault, against `1 - (1 - P)^r`, and the
//! repeats 95% / 99% need.
use super::child::{size_arg, Bench, BenchError};
use super::stats;
use serde_json::{json, Value};

impl Bench<'_> {
    /// Per flaky probability, the rounds its 99% repeats need (capped), and the measured against
    /// the predicted detection per number of repeats.
    pub(super) fn flaky(&mut self) -> Result<Value, BenchError> {
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
}
