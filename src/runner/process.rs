//! Worker processes as the supervisor controls them: starting one (`rtprobe __worker JOB`, stdin
//! null, in its own process group, dying with the supervisor) with a thread that turns its stdout
//! into [`Input`]s and one that keeps its stderr's tail, waiting with a bound, the kernel state of
//! one that will not die, killing its process group, and how it ended. [`run_to_end`] runs a
//! child that is not a set of cells (`rtprobe stress`'s cases) the same way, under a deadline of
//! its own.
use super::groups;
use super::machine::Input;
use super::protocol::WorkerMsg;
use crate::model::WorkerExit;
use std::io::{BufRead, BufReader, Read};
use std::os::unix::process::ExitStatusExt;
use std::path::Path;
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::mpsc::{channel, RecvTimeoutError, Sender};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// The stderr kept of each worker (its last bytes).
const STDERR_TAIL: usize = 4000;

/// What a worker's output becomes: its slot, its id and one input.
pub(super) type Line = (usize, u64, Input);

/// `e` of a child that did not start, its line naming the executable and what it was for.
fn named(e: &std::io::Error, what: &str) -> std::io::Error {
    std::io::Error::new(e.kind(), super::self_exe::start_error(what, e))
}

/// A running worker process.
pub(super) struct Proc {
    child: Child,
    pid: i32,
    /// The worker's id (in log lines).
    worker: u64,
    stderr: Arc<Mutex<String>>,
}

impl Proc {
    /// Starts this executable as worker `worker` of slot `slot` on `job`; its lines go to `tx`,
    /// ending with [`Input::Eof`].
    pub fn start(job: &Path, slot: usize, worker: u64, tx: Sender<Line>) -> std::io::Result<Proc> {
        let mut cmd = Command::new(super::self_exe::spawn_path());
        cmd.arg("__worker")
            .arg(job)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        let mut child = groups::spawn_registered(&mut cmd).map_err(|e| named(&e, "a worker"))?;
        let pid = child.id() as i32;
        let stdout = child.stdout.take().expect("piped stdout");
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines() {
                let Ok(line) = line else { break };
                let input = match serde_json::from_str::<WorkerMsg>(&line) {
                    Ok(m) => Input::Msg(m),
                    Err(_) => Input::Garbage(line),
                };
                if tx.send((slot, worker, input)).is_err() {
                    return;
                }
            }
            let _ = tx.send((slot, worker, Input::Eof));
        });
        let stderr = Arc::new(Mutex::new(String::new()));
        keep_tail(child.stderr.take().expect("piped stderr"), stderr.clone());
        Ok(Proc { child, pid, worker, stderr })
    }

    /// Kills its group (see [`kill_group`]).
    pub fn kill(&mut self, grace: Duration, kill_wait: Duration) -> WorkerExit {
        kill_group(&mut self.child, self.pid, self.worker, &self.stderr, grace, kill_wait)
    }

    /// It has nothing more to say (`exiting`): a thread reaps it (by its pid; its `Child` is
    /// never waited on again), killing the group if it is still there after `bound`, so that
    /// nobody waits for its exit.
    pub fn release(&self, bound: Duration, kill_wait: Duration) {
        let (pid, worker) = (self.pid, self.worker);
        std::thread::spawn(move || {
            let reaped = |until: Instant| loop {
                let mut status = 0;
                // SAFETY: waitpid on our own child's pid, with a valid status pointer.
                let r = unsafe { libc::waitpid(pid, &mut status, libc::WNOHANG) };
                if r != 0 || Instant::now() >= until {
                    return r != 0;
                }
                std::thread::sleep(Duration::from_millis(5));
            };
            if !reaped(Instant::now() + bound) {
                tracing::debug!("worker {worker} said exiting but did not exit; killed");
                unsafe { libc::kill(-pid, libc::SIGKILL) };
                reaped(Instant::now() + kill_wait);
            }
            groups::unregister(pid);
        });
    }

    /// Its output ended: waits at most `grace` for the exit; one that closed its output but does
    /// not exit is treated as hung and killed.
    pub fn reap(&mut self, grace: Duration, kill_wait: Duration) -> WorkerExit {
        match poll_exit(&mut self.child, grace) {
            Some(status) => {
                groups::unregister(self.pid);
                exit_of(Some(status), &self.stderr)
            }
            None => self.kill(Duration::ZERO, kill_wait),
        }
    }
}

/// How a child of [`run_to_end`] ended: its exit, and whether it was killed for silence.
#[derive(Clone, Debug)]
pub struct ChildEnd {
    pub exit: WorkerExit,
    pub timed_out: bool,
}

impl ChildEnd {
    /// How a child (`who`, e.g. "the stress worker") that ended without its result ended, at
    /// `step`: killed after `silence`, or dead of a signal or a status; then the last line of
    /// its stderr and whether its group was abandoned.
    pub fn describe(&self, who: &str, step: &str, silence: std::time::Duration) -> String {
        let how = if self.timed_out {
            format!("was silent for {silence:?} and was killed")
        } else {
            match (self.exit.signal, self.exit.code) {
                (Some(s), _) => format!("died of signal {s} ({})", crate::model::signal_name(s)),
                (None, Some(c)) => format!("exited with status {c} and no result"),
                (None, None) => "ended without a result".into(),
            }
        };
        let tail = self.exit.stderr_tail.lines().rev().find(|l| !l.trim().is_empty());
        let tail = tail.map(|l| format!("; stderr: {}", l.chars().take(200).collect::<String>()));
        let abandoned =
            self.exit.abandoned.as_deref().map(|a| format!("; {a}")).unwrap_or_default();
        format!("{who} {how} at `{step}`{}{abandoned}", tail.unwrap_or_default())
    }
}

/// Runs this executable as `rtprobe SUBCOMMAND JOB` (stdin null, its own process group, dying
/// with this process, as a worker) to its end. Each stdout line goes to `on_line`, which returns
/// the silence allowed until the next (`silence`: until the first); past it the group is killed
/// (SIGTERM, `grace`, SIGKILL, at most `kill_wait`, else abandoned). A child that closes its
/// output but does not exit within `grace` is killed too.
pub fn run_to_end(
    subcommand: &str,
    job: &Path,
    silence: Duration,
    (grace, kill_wait): (Duration, Duration),
    on_line: &mut dyn FnMut(&str) -> Duration,
) -> std::io::Result<ChildEnd> {
    let mut cmd = Command::new(super::self_exe::spawn_path());
    cmd.arg(subcommand).arg(job).stdin(Stdio::null()).stdout(Stdio::piped()).stderr(Stdio::piped());
    let mut child = groups::spawn_registered(&mut cmd).map_err(|e| named(&e, subcommand))?;
    let pid = child.id() as i32;
    let (tx, rx) = channel::<String>();
    let stdout = child.stdout.take().expect("piped stdout");
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            if tx.send(line).is_err() {
                return;
            }
        }
    });
    let stderr = Arc::new(Mutex::new(String::new()));
    keep_tail(child.stderr.take().expect("piped stderr"), stderr.clone());
    let mut silence = silence;
    loop {
        match rx.recv_timeout(silence) {
            Ok(line) => silence = on_line(&line),
            Err(RecvTimeoutError::Disconnected) => {
                let exit = match poll_exit(&mut child, grace) {
                    Some(status) => {
                        groups::unregister(pid);
                        exit_of(Some(status), &stderr)
                    }
                    None => kill_group(&mut child, pid, 0, &stderr, Duration::ZERO, kill_wait),
                };
                return Ok(ChildEnd { exit, timed_out: false });
            }
            Err(RecvTimeoutError::Timeout) => {
                let exit = kill_group(&mut child, pid, 0, &stderr, grace, kill_wait);
                return Ok(ChildEnd { exit, timed_out: true });
            }
        }
    }
}

/// Keeps the last [`STDERR_TAIL`] bytes (or so) of `pipe` in `sink`, on a thread of its own.
fn keep_tail(mut pipe: impl Read + Send + 'static, sink: Arc<Mutex<String>>) {
    std::thread::spawn(move || {
        let mut buf = [0u8; 4096];
        while let Ok(n) = pipe.read(&mut buf) {
            if n == 0 {
                break;
            }
            if let Ok(mut s) = sink.lock() {
                s.push_str(&String::from_utf8_lossy(&buf[..n]));
                if s.len() > 2 * STDERR_TAIL {
                    let cut = s.len() - STDERR_TAIL;
                    let cut = (cut..s.len()).find(|i| s.is_char_boundary(*i)).unwrap_or(cut);
                    s.drain(..cut);
                }
            }
        }
    });
}

fn poll_exit(child: &mut Child, bound: Duration) -> Option<ExitStatus> {
    let until = Instant::now() + bound;
    loop {
        if let Ok(Some(s)) = child.try_wait() {
            return Some(s);
        }
        if Instant::now() >= until {
            return None;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// The process state letter and name from /proc (e.g. `D (disk sleep)`).
pub(super) fn proc_state(pid: i32) -> String {
    std::fs::read_to_string(format!("/proc/{pid}/stat"))
        .ok()
        .and_then(|s| {
            s.rsplit_once(')')
                .map(|(_, rest)| rest.split_whitespace().next().unwrap_or("?").to_string())
        })
        .map(|c| match c.as_str() {
            "D" => "D (uninterruptible sleep)".to_string(),
            "Z" => "Z (zombie)".to_string(),
            other => other.to_string(),
        })
        .unwrap_or_else(|| "unknown".into())
}

/// SIGTERM the group, wait `grace`, SIGKILL, wait at most `kill_wait`; a process still there is
/// abandoned (reported, never waited on again).
fn kill_group(
    child: &mut Child,
    pid: i32,
    worker: u64,
    stderr: &Arc<Mutex<String>>,
    grace: Duration,
    kill_wait: Duration,
) -> WorkerExit {
    unsafe { libc::kill(-pid, libc::SIGTERM) };
    let mut status = poll_exit(child, grace);
    if status.is_none() {
        unsafe { libc::kill(-pid, libc::SIGKILL) };
        status = poll_exit(child, kill_wait);
    }
    // Anything else left in the group.
    unsafe { libc::kill(-pid, libc::SIGKILL) };
    let mut exit = exit_of(status, stderr);
    if status.is_none() {
        let state = proc_state(pid);
        tracing::warn!(
            "worker {worker} (pid {pid}) did not die after SIGKILL; state {state}; abandoned"
        );
        exit.abandoned = Some(format!(
            "pid {pid} still alive {kill_wait:?} after SIGKILL, state {state}; abandoned"
        ));
    } else {
        groups::unregister(pid);
    }
    exit
}

fn exit_of(status: Option<ExitStatus>, stderr: &Arc<Mutex<String>>) -> WorkerExit {
    // Give the stderr reader a moment to drain.
    std::thread::sleep(Duration::from_millis(20));
    let tail = stderr.lock().map(|s| s.clone()).unwrap_or_default();
    WorkerExit {
        code: status.and_then(|s| s.code()),
        signal: status.and_then(|s| s.signal()),
        stderr_tail: tail,
        abandoned: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::process::Command;

    #[test]
    fn a_process_that_will_not_exit_is_not_waited_on_forever() {
        // A child that ignores SIGTERM stands in for one stuck in the kernel: poll_exit must
        // return within its bound rather than block.
        let mut child = Command::new("sh").args(["-c", "trap '' TERM; sleep 30"]).spawn().unwrap();
        let t = Instant::now();
        assert!(poll_exit(&mut child, Duration::from_millis(200)).is_none());
        assert!(t.elapsed() < Duration::from_secs(2));
        child.kill().unwrap();
        assert!(poll_exit(&mut child, Duration::from_secs(5)).is_some());
    }

    #[test]
    fn proc_state_reads_the_state_letter() {
        let s = proc_state(std::process::id() as i32);
        assert!(s == "R" || s == "S", "{s}");
        assert_eq!(proc_state(-1), "unknown");
    }
}
