//! The run's events into its report: every attempt into the [`ReportWriter`] (saved at once
//! after a fault or worker event, passes at most every [`SAVE_INTERVAL`] and every
//! [`SAVE_COST_FACTOR`] times the last save's duration), workers' setup times,
//! prebuilds and pipeline cache use into the report's timing and cache summary, and a halt (the
//! run cannot go on) kept for the rounds and the CLI.
use super::{Event, Progress};
use crate::atomic::WriteError;
use crate::model::{Halt, Outcome};
use crate::report::writer::ReportWriter;
use std::time::{Duration, Instant};

/// Passes are saved at most this often: the whole report is rewritten on each save (2 MB for the
/// H100's default matrix), and saving after every pass made the supervisor the bottleneck of a
/// fast GPU run. Faults, worker events and the end of the run are saved at once.
pub const SAVE_INTERVAL: Duration = Duration::from_millis(100);

/// Passes are saved at most once per this many times the last save took, whatever
/// [`SAVE_INTERVAL`] allows: a save grows with the report, so a fixed interval makes a run of n
/// cells spend time in n² (5,000 cells: a 20 MB report every 100 ms); with the interval tied to
/// the save's cost, saving stays under 1/SAVE_COST_FACTOR of the run.
pub const SAVE_COST_FACTOR: u32 = 8;

/// When a pass may be saved: [`SAVE_INTERVAL`] after the last save, or [`SAVE_COST_FACTOR`]
/// times the last save's duration, whichever is later.
pub fn pass_save_due(since_last: Duration, last_cost: Duration) -> bool {
    since_last >= SAVE_INTERVAL.max(last_cost * SAVE_COST_FACTOR)
}

/// Records a run's events in its report as they come.
pub struct Recorder {
    pub writer: ReportWriter,
    pub progress: Box<dyn Progress>,
    /// Sum of the workers' device setup times (for `timing.device_ms_mean`).
    pub device_ms_sum: f64,
    /// Sum and count of this session's scene AS builds (for `timing.as_build_ms_mean`; a
    /// resumed report's earlier builds are in its mean already).
    pub as_build_ms_sum: f64,
    pub as_builds: usize,
    /// The first save that failed (the run goes on; the CLI reports it at the end).
    pub save_error: Option<WriteError>,
    /// What stopped the run ([`Event::Halt`]): no round runs anything more.
    pub halted: Option<Halt>,
    /// When the report was last written, and how long that took.
    last_save: Instant,
    last_cost: Duration,
}

impl Recorder {
    pub fn new(writer: ReportWriter, progress: Box<dyn Progress>) -> Self {
        Recorder {
            writer,
            progress,
            device_ms_sum: 0.0,
            as_build_ms_sum: 0.0,
            as_builds: 0,
            save_error: None,
            halted: None,
            last_save: Instant::now(),
            last_cost: Duration::ZERO,
        }
    }

    /// Save the report: at once when `urgent`, else passes at most as often as
    /// [`pass_save_due`] allows.
    pub(super) fn save(&mut self, urgent: bool) {
        if !urgent && !pass_save_due(self.last_save.elapsed(), self.last_cost) {
            return;
        }
        let t = Instant::now();
        if let Err(e) = self.writer.save(false) {
            self.save_error.get_or_insert(e);
        }
        self.last_cost = t.elapsed();
        self.last_save = Instant::now();
    }

    pub fn on_event(&mut self, ev: Event) {
        match ev {
            Event::WorkerReady {
                device_ms,
                create_ms,
                as_build_ms,
                setup_wait_ms,
                pipeline_cache,
                driver_cache,
                ..
            } => {
                let t = &mut self.writer.report.timing;
                t.workers_started += 1;
                t.device_create_ms += create_ms;
                t.setup_wait_ms += setup_wait_ms;
                self.device_ms_sum += device_ms;
                if let Some(ms) = as_build_ms {
                    t.as_builds += 1;
                    t.as_build_ms_max = t.as_build_ms_max.max(ms);
                    self.as_build_ms_sum += ms;
                    self.as_builds += 1;
                }
                if let Some(c) = driver_cache {
                    self.writer.report.driver_cache.get_or_insert_with(Default::default).ready(c);
                }
                if let Some(l) = pipeline_cache {
                    let s = self.writer.report.pipeline_cache.get_or_insert_with(Default::default);
                    s.file = Some(l.path);
                    if l.loaded_bytes > 0 {
                        s.workers_loaded += 1;
                        s.loaded_bytes = s.loaded_bytes.max(l.loaded_bytes);
                    }
                    if let Some(why) = l.ignored.filter(|w| !s.ignored.contains(w)) {
                        s.ignored.push(why);
                    }
                }
            }
            Event::Prebuilt { wall_ms, pipelines, overlapped, checked_apart, .. } => {
                self.writer.report.timing.prebuild_ms += wall_ms;
                self.writer.report.timing.prebuilt_pipelines += pipelines;
                self.writer.report.timing.overlapped_cells += overlapped;
                self.writer.report.timing.checked_apart += checked_apart;
            }
            Event::CacheSaved(saved) => {
                let s = self.writer.report.pipeline_cache.get_or_insert_with(Default::default);
                match saved {
                    Ok(bytes) => {
                        s.saves += 1;
                        s.saved_bytes = bytes;
                    }
                    Err(e) if !s.save_errors.contains(&e) => s.save_errors.push(e),
                    Err(_) => {}
                }
            }
            Event::Worker(w) => {
                self.writer.record_worker(w);
                self.save(true);
            }
            Event::Attempt { cell, attempt } => {
                self.progress.ended(&cell, Some(attempt.outcome));
                let urgent = attempt.outcome != Outcome::Pass;
                self.writer.record(&cell, attempt);
                self.save(urgent);
            }
            Event::Halt(h) => {
                self.halted.get_or_insert(h);
                self.save(true);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn passes_wait_for_the_interval_and_for_a_multiple_of_the_last_save() {
        let ms = Duration::from_millis;
        assert!(!pass_save_due(ms(50), ms(0)));
        assert!(pass_save_due(ms(100), ms(1)));
        // A 100 ms save (a large report) holds the next pass save off for 800 ms.
        assert!(!pass_save_due(ms(500), ms(100)));
        assert!(pass_save_due(ms(800), ms(100)));
    }
}
