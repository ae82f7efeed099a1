//! Part 4, detection with mutants: at each size, `rtprobe run --mutants` on the mutants filter's
//! cells, and per mutant how many of its applicable pairs were killed, survived (allowed by the
//! cell's rule, or a probe defect), crashed, or were not applicable; the kill rate over what must
//! be caught (`MutantCounts::kill_rate`) and the round's time per mutant attempt. Where injected
//! wrong values (part 1) measure how many records catch *a* wrong value, mutants measure whether
//! each emulated driver bug — the wrong descriptor, element, sampler or TLAS — is caught at all.
use super::child::{size_arg, Bench, BenchError};
use crate::model::MutantReport;
use serde_json::{json, Value};

/// The kill matrix's counts as bench records them: per mutant and in total.
pub fn counts_of(r: &MutantReport) -> Value {
    let per: serde_json::Map<String, Value> = r
        .counts
        .iter()
        .map(|(m, c)| (m.clone(), json!({ "counts": c, "kill_rate": c.kill_rate() })))
        .collect();
    let t = r.total();
    json!({ "per_mutant": per, "total": t, "kill_rate": t.kill_rate() })
}

impl Bench<'_> {
    /// At each of the mutants' sizes, the kill matrix of the mutants filter's cells.
    pub(super) fn mutants(&mut self) -> Result<Value, BenchError> {
        let mut points = vec![];
        for &s in &self.opts.mutants_sizes.clone() {
            let mut args = vec!["--size".into(), size_arg(s), "--mutants".into()];
            for f in &self.opts.mutants_filter {
                args.extend(["--filter".into(), f.clone()]);
            }
            let r = self.run(&args)?;
            let Some(m) = r.report.mutants.as_ref() else {
                return Err(BenchError::Empty { cmd: r.command, what: "mutant" });
            };
            let t = m.total();
            let attempts = t.applicable + t.not_run;
            (self.progress)(&format!(
                "mutants {}: {} of {} applicable killed ({} allowed survivors, {} probe defects, {} faults), {:.1} s",
                size_arg(s), t.killed, t.applicable, t.allowed, t.probe_defects, t.faults, m.wall_ms / 1e3
            ));
            points.push(json!({
                "size": s, "pixels": u64::from(s).pow(2), "command": r.command, "wall_s": r.wall_s,
                "round_wall_s": m.wall_ms / 1e3,
                "ms_per_mutant_attempt": (attempts > 0).then(|| m.wall_ms / attempts as f64),
                "cells_run": r.report.cells.iter().filter(|c| !c.attempts.is_empty()).count(),
                "counts": counts_of(m),
                "survivors": m.entries.iter().filter(|e| e.status == crate::model::MutantStatus::Survived).map(|e| json!({ "cell": e.cell, "mutant": e.mutant, "probe_defect": e.probe_defect, "allowed_by": e.allowed_by, "why": e.why })).collect::<Vec<_>>(),
            }));
        }
        Ok(json!({ "filter": self.opts.mutants_filter, "points": points }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{Mutant, MutantEntry, MutantStatus};

    #[test]
    fn counts_keep_every_mutant_and_the_rate_over_what_must_be_caught() {
        let e = |status, probe_defect| MutantEntry {
            cell: "c".into(),
            mutant: Mutant::IndexNext,
            status,
            why: String::new(),
            outcome: None,
            prediction: None,
            probe_defect,
            allowed_by: None,
            wall_ms: 0.0,
        };
        let mut r = MutantReport {
            mutants: vec![Mutant::IndexNext, Mutant::ValueBits],
            entries: vec![e(MutantStatus::Killed, false), e(MutantStatus::Survived, true)],
            ..Default::default()
        };
        r.recount();
        let v = counts_of(&r);
        assert_eq!(v["per_mutant"]["index-next"]["kill_rate"], json!(0.5));
        assert_eq!(v["per_mutant"]["value-bits"]["kill_rate"], Value::Null);
        assert_eq!(v["total"]["probe_defects"], json!(1));
    }
}
