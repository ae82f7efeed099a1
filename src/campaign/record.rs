//! The run's events into its report: every attempt into the [`ReportWriter`] (saved at once
//! after a fault or worker event, passes at most every [`SAVE_INTERVAL`]), workers' setup times,
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

/// Records a run's events in its report as they come.
pub struct Recorder {
    pub writer: ReportWriter,
    pub progress: Box<dyn Progress>,
    /// Sum of the workers' device setup times (for `timing.device_ms_mean`).
    pub device_ms_sum: f64,
    /// The first save that failed (the run goes on; the CLI reports it at the end).
    pub save_error: Option<WriteError>,
    /// What stopped the run ([`Event::Halt`]): no round runs anything more.
    pub halted: Option<Halt>,
    /// When the report was last written.
    last_save: Instant,
}

impl Recorder {
    pub fn new(writer: ReportWriter, progress: Box<dyn Progress>) -> Self {
        Recorder {
            writer,
            progress,
            device_ms_sum: 0.0,
            save_error: None,
            halted: None,
            last_save: Instant::now(),
        }
    }

    fn save(&mut self, urgent: bool) {
        if !urgent && self.last_save.elapsed() < SAVE_INTERVAL {
            return;
        }
        self.last_save = Instant::now();
        if let Err(e) = self.writer.save(false) {
            self.save_error.get_or_insert(e);
        }
    }

    pub fn on_event(&mut self, ev: Event) {
        match ev {
            Event::WorkerReady { device_ms, pipeline_cache, pipeline_binaries, .. } => {
                self.writer.report.timing.workers_started += 1;
                self.device_ms_sum += device_ms;
                if let Some(b) = pipeline_binaries {
                    self.writer
                        .report
                        .pipeline_binaries
                        .get_or_insert_with(Default::default)
                        .ready(b);
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
            Event::Prebuilt { wall_ms, pipelines, .. } => {
                self.writer.report.timing.prebuild_ms += wall_ms;
                self.writer.report.timing.prebuilt_pipelines += pipelines;
            }
            Event::Binaries(stats) => {
                let s = self.writer.report.pipeline_binaries.get_or_insert_with(Default::default);
                s.totals.add(&stats);
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
