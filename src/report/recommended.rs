//! Per finding: does the engines' recommended pattern work on this driver? Issue 9's fault is a
//! dynamic descriptor (heap) index; engines are told to keep one descriptor at a constant slot and
//! move the dynamic value inside it (`index=dynamic_element`: geometry, one SSBO read at a
//! dynamic element offset; materials, one `texture2DArray` sampled at a dynamic layer). The
//! nearest such cell (`Cell::recommended_pattern`: same stage, resource, model, heap access) is
//! looked up among the report's cells; `rtprobe run --patches faults` schedules it when the plan
//! did not hold it ([`missing`]) and runs it as often as the findings it stands for ([`retries`]),
//! as it does for workarounds.
use crate::model::Cell;
use crate::model::Outcome;
use crate::model::{CellReport, RunReport};
use crate::model::{PatternResult, PatternStatus};

/// The pattern result of `finding` from the cells of `report`.
pub fn result(report: &RunReport, finding: &Cell) -> PatternResult {
    let (pattern, cell) = match finding.recommended_pattern() {
        Ok(x) => x,
        Err(reason) => {
            return PatternResult {
                pattern: None,
                cell: None,
                status: PatternStatus::NotApplicable { reason },
            }
        }
    };
    let id = cell.id();
    let status = match report.cells.iter().find(|c| c.id == id) {
        None => PatternStatus::NotRun {
            reason: format!(
                "not in this run: `rtprobe run --filter '{}'`, or `--patches faults` schedules it",
                crate::model::registry::exact_filter(&cell)
            ),
        },
        Some(c) => status_of(
            c,
            report.cells.iter().find(|x| x.cell == *finding).and_then(|f| f.incidence.as_ref()),
        ),
    };
    PatternResult { pattern: Some(pattern), cell: Some(id), status }
}

fn status_of(c: &CellReport, finding: Option<&crate::model::Incidence>) -> PatternStatus {
    let ran: Vec<_> = c.attempts.iter().filter(|a| !a.not_run()).collect();
    let attempts = ran.len() as u32;
    match c.outcome {
        Outcome::Pass => PatternStatus::Passes {
            passed: attempts,
            attempts,
            miss_probability: finding
                .map(|i| crate::model::stats::pass_miss(i.faulted, i.attempts, attempts)),
        },
        Outcome::Unsupported | Outcome::NotImplemented => PatternStatus::NotRun {
            reason: format!(
                "{}: {}",
                c.outcome.as_str(),
                c.reason.as_deref().unwrap_or("no reason recorded")
            ),
        },
        Outcome::Mismatch
        | Outcome::DeviceLost
        | Outcome::Crash
        | Outcome::Timeout
        | Outcome::Error
            if attempts == 0 =>
        {
            PatternStatus::NotRun {
                reason: format!(
                    "its worker's setup failed: {}",
                    c.reason.as_deref().unwrap_or(c.outcome.as_str())
                ),
            }
        }
        Outcome::Mismatch
        | Outcome::DeviceLost
        | Outcome::Crash
        | Outcome::Timeout
        | Outcome::Error => PatternStatus::Fails {
            outcome: c.outcome,
            faulted: ran.iter().filter(|a| a.outcome.is_finding()).count() as u32,
            attempts,
        },
    }
}

/// Attach to every finding its recommended pattern's result.
pub fn annotate(report: &mut RunReport) {
    let results: Vec<(usize, PatternResult)> = report
        .cells
        .iter()
        .enumerate()
        .filter(|(_, c)| c.cell.canary.is_none() && c.cell.patch.is_none())
        .map(|(i, c)| (i, c.outcome.is_finding().then(|| result(report, &c.cell))))
        .filter_map(|(i, r)| r.map(|r| (i, r)))
        .collect();
    for c in report.cells.iter_mut() {
        c.recommended = None;
    }
    for (i, r) in results {
        report.cells[i].recommended = Some(r);
    }
}

/// The pattern cells of the report's findings that the report does not hold (to schedule).
pub fn missing(report: &RunReport) -> Vec<Cell> {
    let mut out: Vec<Cell> = Vec::new();
    for f in report.findings() {
        if let Ok((_, cell)) = f.cell.recommended_pattern() {
            if !report.cells.iter().any(|c| c.cell == cell) && !out.contains(&cell) {
                out.push(cell);
            }
        }
    }
    out
}

/// Pattern cells that passed with fewer attempts than a finding they stand for: one pass against
/// an intermittent fault proves nothing, so they run again until they match.
pub fn retries(report: &RunReport) -> Vec<Cell> {
    let mut out: Vec<Cell> = Vec::new();
    for f in report.findings() {
        let Ok((_, cell)) = f.cell.recommended_pattern() else {
            continue;
        };
        let Some(p) = report.cells.iter().find(|c| c.cell == cell) else {
            continue;
        };
        let ran = p.attempts.iter().filter(|a| !a.not_run()).count();
        if p.outcome == Outcome::Pass && ran > 0 && ran < f.attempts.len() && !out.contains(&cell) {
            out.push(cell);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::Attempt;
    use crate::model::{DescriptorModel, HeapAccess, IndexSource, Resource, Stage};

    fn heap(resource: Resource, index: IndexSource) -> Cell {
        Cell {
            stage: Stage::ClosestHit,
            resource,
            index,
            nonuniform: false,
            as_access: None,
            descriptor_model: DescriptorModel::DescriptorHeap,
            heap_access: Some(HeapAccess::Direct),
            canary: None,
            patch: None,
            reorder: None,
            base: None,
            sampler: (resource == Resource::SampledImage)
                .then_some(crate::model::axes::SamplerIndex::Dynamic),
            mutant: None,
            scene_layout: None,
            copy: 0,
        }
    }

    fn ran(cell: Cell, outcomes: &[Outcome]) -> CellReport {
        let mut c = CellReport::new(&cell, Attempt::for_tests(outcomes[0], false));
        for o in &outcomes[1..] {
            c.attempts.push(Attempt::for_tests(*o, true));
        }
        c.refresh();
        c
    }

    #[test]
    fn each_finding_says_whether_its_pattern_passes_fails_or_did_not_run() {
        let ssbo = heap(Resource::StorageBuffer, IndexSource::Dynamic);
        let tex = heap(Resource::SampledImage, IndexSource::Dynamic);
        let ubo = heap(Resource::UniformBuffer, IndexSource::Dynamic);
        let geometry = heap(Resource::StorageBuffer, IndexSource::DynamicElement);
        let mut r = RunReport::for_tests(vec![
            ran(ssbo, &[Outcome::DeviceLost, Outcome::DeviceLost, Outcome::DeviceLost]),
            ran(tex, &[Outcome::DeviceLost]),
            ran(ubo, &[Outcome::Crash]),
            ran(geometry, &[Outcome::Pass]),
        ]);
        // The geometry pattern passed once against a finding seen 3 times: run it again.
        assert_eq!(retries(&r), vec![geometry]);
        // The materials pattern is not in the report: scheduled.
        assert_eq!(missing(&r), vec![heap(Resource::SampledImage, IndexSource::DynamicElement)]);
        annotate(&mut r);
        let line = |c: &Cell| {
            r.cells.iter().find(|x| x.cell == *c).unwrap().recommended.as_ref().map(|p| p.line())
        };
        assert_eq!(
            line(&ssbo).unwrap(),
            "recommended pattern geometry (one storage buffer at a spec-constant slot, dynamic element offset; closest_hit.storage_buffer.dynamic_element.descriptor_heap.direct): not proven (1 pass; need 11 for 99%)"
        );
        // 1 pass against 3 of 3: (1 - 0.05^(1/3))^1 ≈ 0.63, in the JSON too.
        let geo = r.cells.iter().find(|x| x.cell == ssbo).unwrap().recommended.clone().unwrap();
        assert!(
            matches!(geo.status, PatternStatus::Passes { miss_probability: Some(m), .. } if (m - crate::model::stats::pass_miss(3, 3, 1)).abs() < 1e-12)
        );
        assert!(
            line(&tex).unwrap().contains("materials")
                && line(&tex).unwrap().contains("not run (not in this run"),
            "{:?}",
            line(&tex)
        );
        assert!(
            line(&ubo)
                .unwrap()
                .starts_with("recommended pattern: none (rtprobe has no recommended"),
            "{:?}",
            line(&ubo)
        );
        assert_eq!(line(&geometry), None, "a passing cell carries no pattern result");
        // A pattern that faults too is a failure, never a pass.
        let mut bad = RunReport::for_tests(vec![
            ran(ssbo, &[Outcome::DeviceLost]),
            ran(geometry, &[Outcome::Pass, Outcome::Mismatch]),
        ]);
        annotate(&mut bad);
        let p = bad.cells[0].recommended.clone().unwrap();
        assert_eq!(
            p.status,
            PatternStatus::Fails { outcome: Outcome::Mismatch, faulted: 1, attempts: 2 }
        );
        assert!(p.line().ends_with("fails: mismatch (1 of 2 attempts)"), "{}", p.line());
        // Unsupported pattern cells say why.
        let mut un = RunReport::for_tests(vec![
            ran(ssbo, &[Outcome::DeviceLost]),
            CellReport::unrun(
                &geometry,
                Outcome::Unsupported,
                "device lacks descriptorHeap".into(),
            ),
        ]);
        annotate(&mut un);
        assert!(un.cells[0]
            .recommended
            .as_ref()
            .unwrap()
            .line()
            .ends_with("not run (unsupported: device lacks descriptorHeap)"));
        // JSON keeps the status tag.
        let v = serde_json::to_value(&bad.cells[0].recommended).unwrap();
        assert_eq!(v["status"], "fails");
        assert_eq!(v["pattern"], "geometry");
    }
}
