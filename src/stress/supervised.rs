//! `rtprobe stress`'s cases, each in a worker process of its own (`rtprobe __stress JOB`: see
//! `worker`), run through `runner::process::run_to_end` as the run supervisor runs its workers:
//! its own process group, dying with this process, killed (SIGTERM, grace, SIGKILL) when it
//! stays silent past its deadline. The deadline restarts with each line of progress: the setup
//! (device, shader compiles) gets [`SETUP_SILENCE`] more, each part twice the fence deadline (an
//! AS build and a trace, each fenced in the worker) plus [`PART_SLACK`]; the CPU's judging sends
//! a heartbeat (the case's rays judged so far) every `worker::BEAT`, and a trace a line after each
//! submission of a part's rays (`gpu::CHUNK_RAYS`), so a long check or trace that is alive is never
//! killed and a silent one is. What the lines say reaches the user through [`Supervised::say`], at
//! most every [`Supervised::every`] and when a case starts and ends. A worker that dies is the case's `crash`, one killed for silence its `timeout`,
//! each with the step it was in, its signal and the end of its stderr; the next case starts in a
//! fresh worker, so one crash or hang no longer ends the run.
use super::result::{CaseResult, Verdict};
use super::worker::{CaseJob, CaseOutput, Progress};
use super::{cases, CaseKind, StressOptions};
use crate::runner::process::{run_to_end, ChildEnd};
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// Silence allowed before a worker is ready, on top of a part's.
pub const SETUP_SILENCE: Duration = Duration::from_secs(60);
/// Silence allowed per part beyond twice the fence deadline.
pub const PART_SLACK: Duration = Duration::from_secs(10);
/// SIGTERM to SIGKILL, and how long a killed worker is waited for.
const GRACE: Duration = Duration::from_secs(2);
const KILL_WAIT: Duration = Duration::from_secs(5);

/// How the cases of one `rtprobe stress` run are run.
pub struct Supervised {
    pub device_index: usize,
    /// Fence deadline of one submission in the worker.
    pub timeout: Duration,
    pub ray_query: bool,
    pub validate: bool,
    /// Where job and result files go (the caller removes it).
    pub dir: PathBuf,
    /// Where progress lines go (stderr), and the longest a line waits while a case runs.
    pub say: Box<dyn Fn(&str)>,
    pub every: Duration,
}

/// `trace square-65536: 131072/2268142 rays`, `index: 4096/65536 triangles`
pub fn describe(p: &Progress) -> String {
    match (p.done, p.total) {
        (Some(done), Some(total)) => {
            format!("{}: {done}/{total} {}", p.step, p.unit.as_deref().unwrap_or("rays"))
        }
        _ => p.step.clone(),
    }
}

impl Supervised {
    /// Runs `kind` in a worker: its result and the validation errors the worker counted.
    pub fn case(&self, kind: CaseKind, opts: &StressOptions) -> (CaseResult, u64) {
        let name = kind.as_str();
        let (job_path, result) =
            (self.dir.join(format!("{name}.job.json")), self.dir.join(format!("{name}.out.json")));
        let job = CaseJob {
            device_index: self.device_index,
            case: name.into(),
            seed: opts.seed,
            full: opts.full,
            timeout: self.timeout,
            ray_query: self.ray_query,
            validate: self.validate,
            result: result.clone(),
        };
        let text = serde_json::to_vec(&job).expect("a job serializes");
        if let Err(e) = crate::atomic::write_atomic(&job_path, &text) {
            return (error(kind, format!("writing the stress job: {e}")), 0);
        }
        let part = self.timeout * 2 + PART_SLACK;
        let mut step = String::from("start");
        let start = Instant::now();
        let mut said = start;
        (self.say)(&format!("[{:>7.1}s] stress {name}: start", 0.0));
        let end = run_to_end(
            "__stress",
            &job_path,
            part + SETUP_SILENCE,
            (GRACE, KILL_WAIT),
            &mut |line| {
                if let Ok(p) = serde_json::from_str::<Progress>(line) {
                    if said.elapsed() >= self.every {
                        said = Instant::now();
                        let at = start.elapsed().as_secs_f64();
                        (self.say)(&format!("[{at:>7.1}s] stress {name}: {}", describe(&p)));
                    }
                    step = p.step;
                }
                if step == "setup" {
                    part + SETUP_SILENCE
                } else {
                    part
                }
            },
        );
        let at = start.elapsed().as_secs_f64();
        (self.say)(&format!("[{at:>7.1}s] stress {name}: worker ended after `{step}`"));
        let _ = std::fs::remove_file(&job_path);
        let end = match end {
            Ok(end) => end,
            Err(e) => return (error(kind, format!("cannot start a stress worker: {e}")), 0),
        };
        let out =
            std::fs::read(&result).ok().and_then(|b| serde_json::from_slice::<CaseOutput>(&b).ok());
        let _ = std::fs::remove_file(&result);
        match out {
            Some(o) => (o.result, o.validation_errors),
            None => (died(kind, opts, &end, &step, part), 0),
        }
    }
}

fn error(kind: CaseKind, detail: String) -> CaseResult {
    CaseResult::without_results(kind, Verdict::Error, detail, 0)
}

/// The case of a worker that ended without its result: killed for silence, or dead.
pub fn died(
    kind: CaseKind,
    opts: &StressOptions,
    end: &ChildEnd,
    step: &str,
    part: Duration,
) -> CaseResult {
    let detail = end.describe("the stress worker", step, part);
    let verdict = if end.timed_out { Verdict::Timeout } else { Verdict::Crash };
    let rays = cases::build(kind, opts).map_or(0, |p| p.iter().map(|p| p.rays.len()).sum());
    CaseResult::without_results(kind, verdict, detail, rays)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::WorkerExit;

    fn end(signal: Option<i32>, timed_out: bool) -> ChildEnd {
        let exit = WorkerExit {
            code: None,
            signal,
            stderr_tail: "lavapipe: boom\n\n".into(),
            abandoned: None,
        };
        ChildEnd { exit, timed_out }
    }

    #[test]
    fn a_dead_or_silent_worker_is_its_case_outcome_with_where_and_why() {
        let opts = StressOptions { cases: vec![], seed: 1, full: false };
        let part = Duration::from_secs(12);
        let c = died(
            CaseKind::Tmin,
            &opts,
            &end(Some(libc::SIGSEGV), false),
            "trace tmin-256ulp",
            part,
        );
        assert_eq!(c.verdict, Verdict::Crash);
        let d = c.detail.unwrap();
        assert!(
            d.contains("signal 11 (SIGSEGV) at `trace tmin-256ulp`; stderr: lavapipe: boom"),
            "{d}"
        );
        let rays: usize =
            cases::build(CaseKind::Tmin, &opts).unwrap().iter().map(|p| p.rays.len()).sum();
        assert_eq!(c.metrics.rays, rays, "the rays it would have traced");
        let t = died(CaseKind::Tmin, &opts, &end(Some(libc::SIGTERM), true), "ready", part);
        assert_eq!(t.verdict, Verdict::Timeout);
        assert!(t.detail.unwrap().contains("was silent for 12s and was killed at `ready`"));
    }
}
