//! Judging a cell from its records: a canary that ran to completion passes; otherwise the records
//! are compared with the CPU reference (a read is undefined as the driver saw it: `seen`), with
//! the records and pictures of a mismatch under `--dump`, and the note on what the driver saw
//! added. What judging reads is a [`World`]: the executor's, or a [`super::checker::Checker`]
//! thread's copy of it (an overlapped cell is judged off the cell thread).
use super::built::Seen;
use super::executor::{ExecOptions, Executor};
use super::pictures;
use crate::model::comparison::HeapDetail;
use crate::model::{Cell, CellResult, Outcome, Stage, Timings};
use crate::probe::spec::ProbeSpec;
use crate::probe::Record;
use crate::reference::{self, ExpectedMemo, SceneReference};
use crate::scene::Scene;
use std::time::Instant;

/// What judging a cell reads: the scene and its CPU reference, the executor's options (`--dump`,
/// the lane mode) and the stages where the device lists subgroup ballot. Nothing of it changes
/// once the executor's setup is done, so a checker thread may hold a copy.
#[derive(Clone, Copy)]
pub(super) struct World<'a> {
    pub(super) scene: &'a Scene,
    pub(super) sref: &'a SceneReference,
    pub(super) opts: &'a ExecOptions,
    pub(super) ballot: &'a [Stage],
}

impl Executor {
    /// What judging this executor's cells reads.
    pub(super) fn world(&self) -> World<'_> {
        World { scene: &self.scene, sref: &self.sref, opts: &self.opts, ballot: &self.ballot }
    }
}

impl World<'_> {
    /// The cell's result from its records: [`Executor::check`] (its time added to
    /// `timings.check_ms`), with the note on what the driver saw after its detail. `expected`:
    /// the reference's records, kept from cell to cell (and reused by the next cell with the
    /// same key).
    pub(super) fn judge(
        &self,
        cell: &Cell,
        (records, expected): (&[Record], &mut ExpectedMemo),
        (seen, heap): (Seen, Option<HeapDetail>),
        timings: &mut Timings,
    ) -> CellResult {
        let t = Instant::now();
        let r = self.check(cell, (records, expected), seen, heap);
        let note = seen.note(cell);
        timings.check_ms += t.elapsed().as_secs_f64() * 1e3;
        let detail = match (r.detail.clone(), note) {
            (Some(d), Some(n)) => Some(format!("{d}; {n}")),
            (d, n) => d.or(n),
        };
        CellResult { timings: timings.clone(), detail, ..r }
    }

    /// Compare `records` with the reference (from `expected`); `seen`: whether the driver saw
    /// the cell's descriptor index as undefined, and the lane evidence the records carry; `heap`:
    /// a heap cell's descriptors ([`Executor::heap_detail`]).
    fn check(
        &self,
        cell: &Cell,
        (records, expected): (&[Record], &mut ExpectedMemo),
        seen: Seen,
        heap: Option<HeapDetail>,
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
        let undefined = reference::Undefined { descriptor: seen.undefined(cell) };
        let expected = expected.get(cell, (self.scene, self.sref), undefined, seen.lanes);
        let (w, h) = (self.scene.params.width, self.scene.params.height);
        let lanes = seen.lanes.recorded().then(|| {
            reference::lanes::Lanes::for_stage(records, cell.stage).judged_by(seen.lanes.usable())
        });
        let mut cmp = reference::compare_with(expected, records, w, lanes.as_ref());
        cmp.mutant = self.predict_mutant(cell, (undefined, seen.lanes), expected, records);
        cmp.lane_evidence = seen.lanes;
        cmp.heap = heap;
        if let Some(split) = cmp.lanes.as_mut() {
            split.evidence = seen.lanes;
        }
        let outcome = if cmp.passed() { Outcome::Pass } else { Outcome::Mismatch };
        let mut detail = (!cmp.passed()).then(|| crate::model::comparison::mismatch_detail(&cmp));
        if let Some(dir) = self.opts.dump.as_ref() {
            if let Err(e) = super::files::dump_records(dir, cell, records) {
                detail = Some(match detail {
                    Some(d) => format!("{d}; records not written: {e}"),
                    None => format!("records not written: {e}"),
                });
            }
        }
        if let (Some(dir), Some(d)) =
            (self.opts.dump.as_ref().filter(|_| !cmp.passed()), detail.as_mut())
        {
            match pictures::write(&dir.join(cell.id()), expected, records, w, h) {
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

impl Executor {
    /// A heap cell's probed descriptors in the heap and binding 2's mapping (`None` under other
    /// models, or before its binding exists).
    pub(super) fn heap_detail(&self, cell: &Cell) -> Option<HeapDetail> {
        let spec = ProbeSpec::of(cell);
        let access = spec.heap?;
        let shaders = crate::shadergen::generate(cell);
        let key = super::bind::layout_key(&spec, &shaders, self.opts.all_stages);
        let l = self.bindings.get(&key)?.heap_layout()?;
        let records = super::pipeline::shader_records(&spec, Some(&l));
        let hex: Vec<String> = records.hit_triangles.iter().map(|b| format!("{b:02x}")).collect();
        Some(crate::model::comparison::HeapDetail {
            mapping: super::heap::describe_mapping(access, &l),
            mappings: super::heap::PipelineMapping::new(access, &l).entries(),
            shader_record: hex.join(" "),
            probe_offset: l.probe,
            probe_stride: l.probe_stride,
        })
    }
}
