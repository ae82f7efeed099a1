//! Does GPU-Assisted Validation mask a finding? (`run --validate=gpu-av`; issue 9 saw GPU-AV hide
//! the heap fault.) After the run, each finding is re-run alone under the validation layer with
//! GPU-AV on, next to a control: the same cell with a literal index, which passed without GPU-AV.
//! The verdict per finding: `masked` (it passes under GPU-AV), `still_faults`, `gpu_av_failed`
//! (the control, which passes without GPU-AV, faults with it: GPU-AV itself breaks the pipeline,
//! as on lavapipe 26's closest-hit heap pipelines), or `not_run` with the reason (no validation
//! layer; a layer built before VK_EXT_descriptor_heap for a heap cell; the cell's own
//! `unsupported` / `not_implemented`). These attempts are kept apart from the cell's own: GPU-AV
//! changes the pipeline, so they never decide the cell's verdict.
use crate::matrix::{Cell, DescriptorModel, IndexSource};
use crate::outcome::Outcome;
use crate::report::run_report::RunReport;
use crate::runner::supervisor::Attempt;
use serde::{Deserialize, Serialize};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GpuAvVerdict {
    Masked,
    StillFaults,
    GpuAvFailed,
    NotRun,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GpuAvResult {
    pub verdict: GpuAvVerdict,
    /// The outcome under GPU-AV (`unsupported` / `not_implemented` when it did not run).
    pub outcome: Outcome,
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub detail: Option<String>,
    /// Validation errors the layer reported during the attempt.
    #[serde(default)]
    pub validation_errors: u64,
    /// The control cell and its outcome under GPU-AV, when one ran.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub control: Option<(String, Outcome)>,
}

impl GpuAvResult {
    fn not_run(outcome: Outcome, reason: String) -> Self {
        GpuAvResult { verdict: GpuAvVerdict::NotRun, outcome, detail: Some(reason), validation_errors: 0, control: None }
    }

    /// `GPU-AV: masked (passes under GPU-AV; 0 validation errors)`
    pub fn line(&self) -> String {
        let errors = if self.validation_errors > 0 { format!("; GPU-AV reported {} validation errors", self.validation_errors) } else { String::new() };
        match self.verdict {
            GpuAvVerdict::Masked => format!("GPU-AV: masked (passes under GPU-AV{errors})"),
            GpuAvVerdict::StillFaults => format!("GPU-AV: still faults ({}{errors})", self.outcome.as_str()),
            GpuAvVerdict::GpuAvFailed => {
                let control = match &self.control {
                    Some((c, o)) => format!("its control {c} passes without GPU-AV and is {} with it", o.as_str()),
                    None => "no control".into(),
                };
                format!("GPU-AV: GPU-AV itself failed ({} under GPU-AV; {control}{errors})", self.outcome.as_str())
            }
            GpuAvVerdict::NotRun => format!("GPU-AV: not run ({}: {})", self.outcome.as_str(), self.detail.as_deref().unwrap_or("no reason")),
        }
    }
}

/// The control of `finding`: the same cell with a literal index (no dynamic descriptor access),
/// when the report has it passing without GPU-AV.
pub fn control(report: &RunReport, finding: &Cell) -> Option<Cell> {
    let c = Cell { index: IndexSource::Literal, nonuniform: false, patch: None, reorder: None, ..*finding };
    (c != *finding && report.cells.iter().any(|x| x.cell == c && x.outcome == Outcome::Pass)).then_some(c)
}

/// What to run under GPU-AV: the findings GPU-AV can check and their controls; the others with
/// the reason they cannot run. `layer`: the installed validation layer's specVersion.
pub fn schedule(report: &RunReport, layer: Option<u32>) -> (Vec<Cell>, Vec<(Cell, GpuAvResult)>) {
    let mut run = Vec::new();
    let mut skipped = Vec::new();
    for f in report.findings() {
        let gap = match layer {
            None => Some((Outcome::Unsupported, "VK_LAYER_KHRONOS_validation is not installed".to_string())),
            Some(v) if f.cell.descriptor_model == DescriptorModel::DescriptorHeap => crate::vk::instance::gpu_av_heap_gap(v).map(|r| (Outcome::Unsupported, r)),
            Some(_) => None,
        };
        match gap {
            Some((o, reason)) => skipped.push((f.cell, GpuAvResult::not_run(o, reason))),
            None => {
                run.push(f.cell);
                if let Some(c) = control(report, &f.cell) {
                    if !run.contains(&c) {
                        run.push(c);
                    }
                }
            }
        }
    }
    (run, skipped)
}

/// Attach each finding's GPU-AV result from the attempts under GPU-AV (`got`) and the findings
/// that could not run (`skipped`).
pub fn annotate(report: &mut RunReport, got: &[(Cell, Attempt)], skipped: &[(Cell, GpuAvResult)]) {
    let under = |c: &Cell| got.iter().find(|(x, _)| x == c).map(|(_, a)| a);
    let mut results = Vec::new();
    for f in report.findings() {
        if let Some((_, r)) = skipped.iter().find(|(c, _)| *c == f.cell) {
            results.push((f.cell, r.clone()));
            continue;
        }
        let Some(a) = under(&f.cell) else { continue };
        let ctl = control(report, &f.cell).and_then(|c| under(&c).map(|ca| (c.id(), ca.outcome)));
        let validation_errors = a.result.as_ref().map(|r| r.validation_errors).unwrap_or(0);
        let verdict = match a.outcome {
            Outcome::Pass => GpuAvVerdict::Masked,
            Outcome::Unsupported | Outcome::NotImplemented => GpuAvVerdict::NotRun,
            Outcome::Mismatch | Outcome::DeviceLost | Outcome::Crash | Outcome::Timeout | Outcome::Error => {
                if ctl.as_ref().is_some_and(|(_, o)| o.is_finding()) {
                    GpuAvVerdict::GpuAvFailed
                } else {
                    GpuAvVerdict::StillFaults
                }
            }
        };
        results.push((f.cell, GpuAvResult { verdict, outcome: a.outcome, detail: a.detail.clone(), validation_errors, control: ctl }));
    }
    for c in report.cells.iter_mut() {
        c.gpu_av = results.iter().find(|(x, _)| *x == c.cell).map(|(_, r)| r.clone());
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::matrix::{HeapAccess, Resource, Stage};
    use crate::report::run_report::CellReport;
    use ash::vk;

    fn cell(model: DescriptorModel, index: IndexSource) -> Cell {
        let heap_access = (model == DescriptorModel::DescriptorHeap).then_some(HeapAccess::Direct);
        Cell { stage: Stage::ClosestHit, resource: Resource::StorageBuffer, index, nonuniform: false, as_access: None, descriptor_model: model, heap_access, canary: None, patch: None, reorder: None }
    }

    fn ran(c: Cell, o: Outcome) -> CellReport {
        CellReport::new(&c, Attempt::for_tests(o, false))
    }

    #[test]
    fn masked_still_faulting_gpu_av_failing_and_old_layers_are_told_apart() {
        let heap = cell(DescriptorModel::DescriptorHeap, IndexSource::Dynamic);
        let heap_ctl = cell(DescriptorModel::DescriptorHeap, IndexSource::Literal);
        let di = cell(DescriptorModel::DescriptorIndexing, IndexSource::Dynamic);
        let di_ctl = cell(DescriptorModel::DescriptorIndexing, IndexSource::Literal);
        let report = RunReport::for_tests(vec![ran(heap, Outcome::DeviceLost), ran(heap_ctl, Outcome::Pass), ran(di, Outcome::Crash), ran(di_ctl, Outcome::Pass)]);
        // Bookworm's layers: heap findings cannot run under GPU-AV, with the layer's version.
        let (run, skipped) = schedule(&report, Some(vk::make_api_version(0, 1, 3, 239)));
        assert_eq!(run, vec![di, di_ctl]);
        assert_eq!(skipped.len(), 1);
        assert_eq!(skipped[0].1.line(), "GPU-AV: not run (unsupported: validation layers 1.3.239 predate VK_EXT_descriptor_heap)");
        // 1.4.363: everything runs, each finding with its control.
        let (run, skipped) = schedule(&report, Some(vk::make_api_version(0, 1, 4, 363)));
        assert_eq!((run.len(), skipped.len()), (4, 0));
        let verdict = |got: Vec<(Cell, Outcome)>| {
            let mut r = report.clone();
            let got: Vec<(Cell, Attempt)> = got.into_iter().map(|(c, o)| (c, Attempt::for_tests(o, true))).collect();
            annotate(&mut r, &got, &[]);
            (r.cells[0].gpu_av.clone().unwrap(), r.cells[2].gpu_av.clone().unwrap())
        };
        // Masked: passes under GPU-AV. Still faults: faults with a control that passes.
        let (h, d) = verdict(vec![(heap, Outcome::Pass), (heap_ctl, Outcome::Pass), (di, Outcome::Crash), (di_ctl, Outcome::Pass)]);
        assert_eq!((h.verdict, d.verdict), (GpuAvVerdict::Masked, GpuAvVerdict::StillFaults));
        assert_eq!(h.line(), "GPU-AV: masked (passes under GPU-AV)");
        assert_eq!(d.line(), "GPU-AV: still faults (crash)");
        // GPU-AV itself failed: the control crashes under GPU-AV too (lavapipe 26's closest-hit heap pipelines).
        let (h, _) = verdict(vec![(heap, Outcome::Crash), (heap_ctl, Outcome::Crash), (di, Outcome::Crash), (di_ctl, Outcome::Pass)]);
        assert_eq!(h.verdict, GpuAvVerdict::GpuAvFailed);
        assert!(h.line().contains("its control closest_hit.storage_buffer.literal.descriptor_heap.direct passes without GPU-AV and is crash with it"), "{}", h.line());
        // No layer at all.
        let (run, skipped) = schedule(&report, None);
        assert!(run.is_empty() && skipped.iter().all(|(_, r)| r.line().contains("VK_LAYER_KHRONOS_validation is not installed")));
    }
}
