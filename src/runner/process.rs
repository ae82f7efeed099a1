//! Worker processes as the supervisor controls them: waiting with a bound, the kernel state of
//! one that will not die, killing its process group, and how it ended.
use super::groups;
use crate::model::{signal_name, Outcome, WorkerExit};
use std::os::unix::process::ExitStatusExt;
use std::process::{Child, ExitStatus};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

pub(super) fn poll_exit(child: &mut Child, bound: Duration) -> Option<ExitStatus> {
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
        .and_then(|s| s.rsplit_once(')').map(|(_, rest)| rest.split_whitespace().next().unwrap_or("?").to_string()))
        .map(|c| match c.as_str() {
            "D" => "D (uninterruptible sleep)".to_string(),
            "Z" => "Z (zombie)".to_string(),
            other => other.to_string(),
        })
        .unwrap_or_else(|| "unknown".into())
}

/// SIGTERM the group, wait `grace`, SIGKILL, wait at most `kill_wait`; a process still there is
/// abandoned (reported, never waited on again).
pub(super) fn kill_group(child: &mut Child, pid: i32, worker: u64, stderr: &Arc<Mutex<String>>, grace: Duration, kill_wait: Duration) -> WorkerExit {
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
        tracing::warn!("worker {worker} (pid {pid}) did not die after SIGKILL; state {state}; abandoned");
        exit.abandoned = Some(format!("pid {pid} still alive {kill_wait:?} after SIGKILL, state {state}; abandoned"));
    } else {
        groups::unregister(pid);
    }
    exit
}

pub(super) fn exit_of(status: Option<ExitStatus>, stderr: &Arc<Mutex<String>>) -> WorkerExit {
    // Give the stderr reader a moment to drain.
    std::thread::sleep(Duration::from_millis(20));
    let tail = stderr.lock().map(|s| s.clone()).unwrap_or_default();
    WorkerExit { code: status.and_then(|s| s.code()), signal: status.and_then(|s| s.signal()), stderr_tail: tail, abandoned: None }
}

pub(super) fn died(exit: &WorkerExit) -> (Outcome, String) {
    match (exit.signal, exit.code) {
        (Some(s), _) => (Outcome::Crash, format!("worker killed by signal {s} ({})", signal_name(s))),
        (None, Some(c)) if c != 0 => (Outcome::Crash, format!("worker exited with code {c}")),
        (None, Some(_)) => (Outcome::Error, "worker exited (code 0) early".into()),
        (None, None) => (Outcome::Error, "worker vanished".into()),
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
    fn a_death_is_a_crash_unless_the_exit_was_clean() {
        let exit = |code, signal| WorkerExit { code, signal, ..Default::default() };
        assert_eq!(died(&exit(None, Some(libc::SIGSEGV))).0, Outcome::Crash);
        assert!(died(&exit(None, Some(libc::SIGSEGV))).1.contains("SIGSEGV"));
        assert_eq!(died(&exit(Some(3), None)).0, Outcome::Crash);
        assert_eq!(died(&exit(Some(0), None)).0, Outcome::Error);
        assert_eq!(died(&exit(None, None)).0, Outcome::Error);
    }

    #[test]
    fn proc_state_reads_the_state_letter() {
        let s = proc_state(std::process::id() as i32);
        assert!(s == "R" || s == "S", "{s}");
        assert_eq!(proc_state(-1), "unknown");
    }
}
