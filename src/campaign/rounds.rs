//! Each round of a run: which cells it runs again (a pure function of the report so far, where
//! the round has a policy of its own) and how (together or alone), recording what comes back.
//! Rounds that repeat until their cells have enough attempts stop when a batch adds none (an
//! oracle that could not run them), so that they never loop. Once the run halted (a worker found
//! what no cell can get past) no round runs anything.
use super::Campaign;
use super::{Event, Mode};
use crate::model::{Attempt, Cell, MutantPrediction, Outcome, RunReport};
use crate::report::{gpu_av, mutants, recommended};
use std::collections::{HashMap, HashSet};

/// The cells to confirm: planned probe cells whose one attempt ran and faulted
/// (`worth_confirming`). A round's retries (workaround variants, recommended patterns) are
/// judged by their own rounds: a resumed report never confirms them.
pub fn confirm_cells(report: &RunReport) -> Vec<Cell> {
    report
        .cells
        .iter()
        .filter(|c| {
            c.cell.canary.is_none()
                && !c.is_retry(report.options.patches)
                && c.attempts.len() == 1
                && !c.attempts[0].not_run()
                && c.outcome.worth_confirming()
        })
        .map(|c| c.cell)
        .collect()
}

/// The faulting cells with fewer than `n` attempts.
pub fn repeat_cells(report: &RunReport, n: u32) -> Vec<Cell> {
    report.findings().filter(|c| (c.attempts.len() as u32) < n).map(|c| c.cell).collect()
}

/// Every finding with each workaround that applies to it, where the device can run the variant
/// and it has not run yet (`done`: not again after a resume).
pub fn workaround_cells(
    report: &RunReport,
    done: &HashSet<String>,
    supported: &dyn Fn(&Cell) -> bool,
) -> Vec<Cell> {
    report
        .findings()
        .flat_map(|c| {
            c.cell.applicable_patches().into_iter().map(move |p| Cell { patch: Some(p), ..c.cell })
        })
        .filter(|c| supported(c) && !done.contains(&c.id()))
        .collect()
}

/// Workaround variants and recommended patterns that pass with fewer attempts than the finding
/// they stand for: one pass against an intermittent fault proves nothing, so they run again
/// until they match its count; one fault ends that.
pub fn verify_cells(report: &RunReport) -> Vec<Cell> {
    let mut more: Vec<Cell> = report
        .cells
        .iter()
        .filter(|v| v.cell.patch.is_some() && v.outcome == Outcome::Pass)
        .filter(|v| {
            report
                .cells
                .iter()
                .find(|b| b.cell == v.cell.base())
                .is_some_and(|b| b.outcome.is_finding() && v.attempts.len() < b.attempts.len())
        })
        .map(|v| v.cell)
        .collect();
    more.extend(recommended::retries(report));
    more
}

impl Campaign<'_> {
    /// Run `cells` as `mode` says, recording every event; the attempts that came back (none
    /// once the run halted).
    pub(super) fn batch(&mut self, cells: &[Cell], mode: Mode) -> usize {
        if self.rec.halted.is_some() {
            return 0;
        }
        let rec = &mut *self.rec;
        let mut attempts = 0;
        self.oracle.run(cells, mode, &mut |ev| {
            attempts += matches!(ev, Event::Attempt { .. }) as usize;
            rec.on_event(ev)
        });
        attempts
    }

    /// A round's batch (`name`: which round): the progress learns of it first; nothing to run
    /// (or a halted run) is no batch.
    pub(super) fn round(&mut self, name: &'static str, cells: &[Cell], mode: Mode) -> usize {
        if cells.is_empty() || self.rec.halted.is_some() {
            return 0;
        }
        self.rec.progress.scheduled(cells.len() as u64);
        self.rec.progress.round(name, cells.len() as u64, mode != Mode::Shared);
        self.batch(cells, mode)
    }

    /// Run `next(report)` alone until it is empty (or a batch adds nothing).
    fn until_done(&mut self, name: &'static str, next: &dyn Fn(&RunReport) -> Vec<Cell>) {
        loop {
            let more = next(&self.rec.writer.report);
            if more.is_empty() || self.round(name, &more, Mode::Alone) == 0 {
                break;
            }
        }
    }

    /// The plan's cells, together (the progress already counts them).
    pub fn matrix(&mut self, cells: &[Cell]) {
        self.batch(cells, Mode::Shared);
    }

    /// Each fault again, alone in a fresh worker.
    pub fn confirm(&mut self) {
        let again = confirm_cells(&self.rec.writer.report);
        self.round("confirm", &again, Mode::Alone);
    }

    /// Every faulting cell until it has `n` attempts in all, each alone in a fresh worker.
    pub fn repeat(&mut self, n: u32) {
        self.until_done("repeat", &|r| repeat_cells(r, n));
    }

    /// The findings' workaround variants the device can run, once, together.
    pub fn workarounds(&mut self) {
        let retries =
            workaround_cells(&self.rec.writer.report, &self.rec.writer.done(), self.supported);
        self.round("workarounds", &retries, Mode::Shared);
    }

    /// The recommended pattern nearest each finding (`report::recommended`), where the report
    /// lacks it and the device can run it, once, together.
    pub fn patterns(&mut self) {
        let supported = self.supported;
        let patterns: Vec<Cell> = recommended::missing(&self.rec.writer.report)
            .into_iter()
            .filter(|c| supported(c))
            .collect();
        self.round("patterns", &patterns, Mode::Shared);
    }

    /// Passing variants and patterns again, alone, until they have their finding's attempts.
    pub fn verify(&mut self) {
        self.until_done("verify", &verify_cells);
    }

    /// Each finding again, alone, under GPU-AV, next to its control (`report::gpu_av`), kept
    /// apart from the cells' own attempts. A finding that passes runs again until it has the
    /// passes its own incidence needs (`gpu_av::more`); at most `gpu_av::CAP` rounds. `layer`:
    /// the validation layer's spec version.
    pub fn gpu_av(&mut self, layer: Option<u32>) {
        let (mut again, skipped) = gpu_av::schedule(&self.rec.writer.report, layer);
        let mut got: Vec<(Cell, crate::model::Attempt)> = Vec::new();
        for _ in 0..gpu_av::CAP {
            if again.is_empty() || self.rec.halted.is_some() {
                break;
            }
            let progress = &*self.rec.progress;
            progress.scheduled(again.len() as u64);
            progress.round("gpu-av", again.len() as u64, true);
            let halted = &mut self.rec.halted;
            self.oracle.run(&again, Mode::GpuAv, &mut |ev| match ev {
                Event::Attempt { cell, attempt } => {
                    progress.ended(&cell, None);
                    got.push((cell, attempt));
                }
                Event::Halt(h) => *halted = Some(h),
                _ => {}
            });
            again = gpu_av::more(&self.rec.writer.report, &got);
        }
        gpu_av::annotate(&mut self.rec.writer.report, &got, &skipped);
    }

    /// Each mutant on every cell that ran and passed, where the reference says it can apply and
    /// the device can run it (`report::mutants::schedule`), together; their attempts kept apart
    /// from the cells' own, each verdict into the report's kill matrix as it comes (saved like a
    /// pass or a fault, so that `--resume` runs only the pairs left).
    pub fn mutants(&mut self, policy: &super::MutantPolicy) {
        let t = std::time::Instant::now();
        let (run, decided) = mutants::schedule(
            &self.rec.writer.report,
            &policy.mutants,
            policy.sample,
            (self.applies, self.supported),
        );
        let sample = self.rec.writer.report.options.mutants_sample.clone();
        let r = &mut self.rec.writer.report;
        mutants::annotate(r, &policy.mutants, sample.as_deref(), decided, 0.0);
        let before: HashMap<Cell, MutantPrediction> = run.iter().copied().collect();
        let cells: Vec<Cell> = run.iter().map(|(c, _)| *c).collect();
        let mut judged: HashSet<Cell> = HashSet::new();
        self.apart("mutants", &cells, Mode::Shared, &mut |rec, cell, attempt| {
            if let (Some(m), Some(b)) = (cell.mutant, before.get(&cell)) {
                let e = mutants::verdict((&cell, m), *b, Some(&attempt));
                mutants::record(&mut rec.writer.report, e);
                judged.insert(cell);
                rec.save(attempt.outcome != Outcome::Pass);
            }
        });
        let missing: Vec<_> = run
            .iter()
            .filter(|(c, _)| !judged.contains(c))
            .filter_map(|(c, b)| c.mutant.map(|m| mutants::verdict((c, m), *b, None)))
            .collect();
        let wall_ms = t.elapsed().as_secs_f64() * 1e3;
        let r = &mut self.rec.writer.report;
        mutants::annotate(r, &policy.mutants, sample.as_deref(), missing, wall_ms);
    }

    /// Run `cells` as `mode` says (the round `name`), each attempt handed to `on_attempt` (with
    /// the recorder) and kept apart from the cells' own, so the progress counts no outcome of
    /// it; worker readiness and caches still reach the report, a halt stops the run.
    fn apart(
        &mut self,
        name: &'static str,
        cells: &[Cell],
        mode: Mode,
        on_attempt: &mut dyn FnMut(&mut super::Recorder, Cell, Attempt),
    ) {
        if cells.is_empty() || self.rec.halted.is_some() {
            return;
        }
        self.rec.progress.scheduled(cells.len() as u64);
        self.rec.progress.round(name, cells.len() as u64, mode != Mode::Shared);
        let rec = &mut *self.rec;
        self.oracle.run(cells, mode, &mut |ev| match ev {
            Event::Attempt { cell, attempt } => {
                rec.progress.ended(&cell, None);
                on_attempt(rec, cell, attempt);
            }
            // A worker's fault outside a cell during the round is no cell's and no finding.
            Event::Worker(_) => {}
            ev @ (Event::WorkerReady { .. }
            | Event::Prebuilt { .. }
            | Event::CacheSaved(_)
            | Event::Halt(_)) => rec.on_event(ev),
        });
    }

    /// The canaries, together, after everything else (the progress already counts them).
    pub fn canaries(&mut self, canaries: &[Cell]) {
        if !canaries.is_empty() {
            self.rec.progress.round("canaries", canaries.len() as u64, false);
            self.batch(canaries, Mode::Shared);
        }
    }
}
