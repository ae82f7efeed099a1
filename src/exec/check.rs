//! Judging a cell from its records: a canary that ran to completion passes; otherwise the records
//! are compared with the CPU reference (reads the compiler left undecorated judged as undefined),
//! with pictures of a mismatch under `--dump`, and the note on a dropped `nonuniformEXT` added.
use super::executor::Executor;
use super::heap::DroppedNonUniform;
use super::pictures;
use crate::model::{Cell, CellResult, Outcome, Timings};
use crate::probe::spec::{ProbeSpec, ReadIndex};
use crate::probe::Record;
use crate::reference;
use std::time::Instant;

impl Executor {
    /// The cell's result from its records: [`Executor::check`] (its time added to
    /// `timings.check_ms`), with the note on a dropped `nonuniformEXT` after its detail.
    pub(super) fn judge(
        &self,
        cell: &Cell,
        records: &[Record],
        dropped: Option<DroppedNonUniform>,
        timings: &mut Timings,
    ) -> CellResult {
        let t = Instant::now();
        let r = self.check(cell, records, dropped);
        let note = dropped.map(|d| d.note());
        timings.check_ms += t.elapsed().as_secs_f64() * 1e3;
        let detail = match (r.detail.clone(), note) {
            (Some(d), Some(n)) => Some(format!("{d}; {n}")),
            (d, n) => d.or(n),
        };
        CellResult { timings: timings.clone(), detail, ..r }
    }

    /// Compare `records` with the reference; `dropped`: the driver saw the cell's non-uniform
    /// descriptor or sampler index without `NonUniform` (the compiler dropped it), so that part of
    /// the read is judged as undefined.
    fn check(
        &self,
        cell: &Cell,
        records: &[Record],
        dropped: Option<DroppedNonUniform>,
    ) -> CellResult {
        let none = |outcome, detail: &str| CellResult {
            outcome,
            detail: Some(detail.into()),
            timings: Timings::default(),
            comparison: None,
            fault: None,
            validation_errors: 0,
        };
        if let Some(c) = cell.canary {
            return none(
                Outcome::Pass,
                &format!(
                    "canary {} ran to completion: this driver did not fault on it",
                    c.as_str()
                ),
            );
        }
        let undefined = reference::Undefined {
            descriptor: ProbeSpec::of(cell).read == ReadIndex::Undefined
                || dropped.is_some_and(|d| d.resource),
            sampler: dropped.is_some_and(|d| d.sampler),
        };
        let expected = reference::expected_with(cell, &self.scene, &self.sref, undefined);
        let (w, h) = (self.scene.params.width, self.scene.params.height);
        let mut cmp = reference::compare(&expected, records, w);
        let outcome = if cmp.passed() { Outcome::Pass } else { Outcome::Mismatch };
        let mut detail = (!cmp.passed()).then(|| {
            format!(
                "{} of {} compared pixels differ ({:?})",
                cmp.mismatched_pixels, cmp.compared, cmp.by_field
            )
        });
        if let (Some(dir), Some(d)) =
            (self.opts.dump.as_ref().filter(|_| !cmp.passed()), detail.as_mut())
        {
            match pictures::write(&dir.join(cell.id()), &expected, records, w, h) {
                Ok(paths) => cmp.pictures = paths,
                Err(e) => d.push_str(&format!("; pictures not written: {e}")),
            }
        }
        CellResult {
            outcome,
            detail,
            timings: Timings::default(),
            comparison: Some(cmp),
            fault: None,
            validation_errors: 0,
        }
    }
}
