//! What `run` shows while it works. On a terminal, a bar (attempts ended against attempts
//! scheduled, the last outcome and cell). Without one — a CI log, `CI` set, `NO_COLOR` — lines
//! on stderr at a bounded rate: one when a round starts, and a count line at most every
//! [`interval`] (`RTPROBE_PROGRESS_SECS`, default 10 s; 0 prints one per attempt), like
//! nextest's status lines, so a log shows the run moving long before its summary.
use super::out;
use crate::campaign::Progress;
use crate::model::{Cell, Outcome};
use std::collections::BTreeMap;
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// The bar, or the lines, as stderr calls for.
pub fn for_stderr() -> Box<dyn Progress> {
    if out::plain_stderr() {
        Box::new(Lines::new(interval()))
    } else {
        Box::new(Bar::new())
    }
}

/// The longest a progress line waits: `RTPROBE_PROGRESS_SECS` (seconds, 0..=3600), default 10.
pub fn interval() -> Duration {
    let secs = std::env::var("RTPROBE_PROGRESS_SECS")
        .ok()
        .and_then(|v| v.trim().parse::<f64>().ok())
        .filter(|s| (0.0..=3600.0).contains(s))
        .unwrap_or(10.0);
    Duration::from_secs_f64(secs)
}

/// The progress bar: attempts scheduled against attempts ended, the last one's outcome and cell.
pub struct Bar(indicatif::ProgressBar);

impl Bar {
    fn new() -> Bar {
        let bar = indicatif::ProgressBar::new(0);
        bar.set_style(
            indicatif::ProgressStyle::with_template("{bar:30} {pos}/{len} {elapsed} {msg}")
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        Bar(bar)
    }
}

impl Progress for Bar {
    fn scheduled(&self, n: u64) {
        self.0.inc_length(n);
    }
    fn ended(&self, cell: &Cell, outcome: Option<Outcome>) {
        self.0.inc(1);
        if let Some(o) = outcome {
            self.0.set_message(format!("{} {}", o.as_str(), cell.id()));
        }
    }
    fn finish(&self) {
        self.0.finish_and_clear();
    }
}

#[derive(Default)]
struct Count {
    scheduled: u64,
    ended: u64,
    by_outcome: BTreeMap<&'static str, u64>,
    last: Option<(Outcome, String)>,
    said: Option<Instant>,
}

/// Progress lines for logs.
pub struct Lines {
    start: Instant,
    every: Duration,
    count: Mutex<Count>,
    /// Where the lines go (stderr; a test's buffer).
    sink: Box<dyn Fn(&str) + Send + Sync>,
}

impl Lines {
    pub fn new(every: Duration) -> Lines {
        Lines::to(every, Box::new(|l: &str| out::stderr(&format!("{l}\n"))))
    }

    fn to(every: Duration, sink: Box<dyn Fn(&str) + Send + Sync>) -> Lines {
        Lines { start: Instant::now(), every, count: Mutex::new(Count::default()), sink }
    }

    fn say(&self, c: &mut Count, what: &str) {
        c.said = Some(Instant::now());
        (self.sink)(&format!("[{:>7.1}s] {what}", self.start.elapsed().as_secs_f64()));
    }

    /// `12/43 attempts (pass 10, crash 2); last: crash CELL`
    fn counts(c: &Count) -> String {
        let outcomes: Vec<String> = c.by_outcome.iter().map(|(o, n)| format!("{o} {n}")).collect();
        let last = c.last.as_ref().map(|(o, id)| format!("; last: {} {id}", o.as_str()));
        format!(
            "{}/{} attempts ({}){}",
            c.ended,
            c.scheduled,
            if outcomes.is_empty() { "none yet".into() } else { outcomes.join(", ") },
            last.unwrap_or_default()
        )
    }
}

impl Progress for Lines {
    fn scheduled(&self, n: u64) {
        let mut c = self.count.lock().unwrap_or_else(|p| p.into_inner());
        c.scheduled += n;
    }
    fn round(&self, name: &'static str, n: u64, alone: bool) {
        let mut c = self.count.lock().unwrap_or_else(|p| p.into_inner());
        let how = if alone { ", each alone in a fresh worker" } else { "" };
        let line = format!("round {name}: {}{how}", crate::model::plural(n as usize, "attempt"));
        self.say(&mut c, &line);
    }
    fn ended(&self, cell: &Cell, outcome: Option<Outcome>) {
        let mut c = self.count.lock().unwrap_or_else(|p| p.into_inner());
        c.ended += 1;
        if let Some(o) = outcome {
            *c.by_outcome.entry(o.as_str()).or_default() += 1;
            c.last = Some((o, cell.id()));
        }
        let due = c.said.is_none_or(|t| t.elapsed() >= self.every);
        if due {
            let line = Lines::counts(&c);
            self.say(&mut c, &line);
        }
    }
    fn finish(&self) {
        let mut c = self.count.lock().unwrap_or_else(|p| p.into_inner());
        let line = format!("done: {}", Lines::counts(&c));
        self.say(&mut c, &line);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{DescriptorModel, IndexSource, Resource, Stage};
    use std::sync::Arc;

    fn lines(every: Duration) -> (Lines, Arc<Mutex<Vec<String>>>) {
        let got = Arc::new(Mutex::new(Vec::new()));
        let g = got.clone();
        (Lines::to(every, Box::new(move |l: &str| g.lock().unwrap().push(l.to_string()))), got)
    }

    fn cell() -> Cell {
        Cell::new(
            Stage::Raygen,
            Resource::StorageBuffer,
            IndexSource::Literal,
            DescriptorModel::DescriptorIndexing,
        )
    }

    #[test]
    fn lines_come_at_a_bounded_rate_and_end_with_the_counts() {
        let (p, got) = lines(Duration::from_secs(3600));
        p.scheduled(3);
        for o in [Outcome::Pass, Outcome::Crash, Outcome::Pass] {
            p.ended(&cell(), Some(o));
        }
        p.round("confirm", 1, true);
        p.finish();
        let got = got.lock().unwrap();
        // The first attempt's line, then nothing until the hour is up; rounds and the end always.
        assert_eq!(got.len(), 3, "{got:?}");
        assert!(got[0].ends_with("] 1/3 attempts (pass 1); last: pass raygen.storage_buffer.literal.descriptor_indexing"), "{got:?}");
        assert!(
            got[1].ends_with("] round confirm: 1 attempt, each alone in a fresh worker"),
            "{got:?}"
        );
        assert!(got[2].ends_with("] done: 3/3 attempts (crash 1, pass 2); last: pass raygen.storage_buffer.literal.descriptor_indexing"), "{got:?}");
    }

    #[test]
    fn an_interval_of_zero_says_every_attempt() {
        let (p, got) = lines(Duration::ZERO);
        p.scheduled(2);
        p.ended(&cell(), Some(Outcome::Pass));
        p.ended(&cell(), Some(Outcome::Pass));
        assert_eq!(got.lock().unwrap().len(), 2);
    }
}
