//! A child process's fatal signal with its native backtrace ([`install`], called first by each
//! child that drives a GPU: `run`'s worker, `run --shader`'s, `patch --verify`'s, `stress`'s):
//! when a driver (or rtprobe) faults inside one — SIGSEGV, SIGBUS, SIGILL, SIGFPE — the faulting thread writes one line
//! naming the signal and the fault address, then its frames as glibc's `backtrace_symbols_fd`
//! writes them (`/path/libnvidia-….so(+0x1a2b3c)[0x…]`), to stderr. `run`'s supervisor keeps a
//! worker's stderr tail in the attempt's `worker_exit` (and `report`'s issue text quotes it), the
//! other children's supervisors their stderr tails where they report a fault, so a
//! crash in the driver names the library and offset a driver team needs, where before the report
//! said only "killed by signal 11".
//!
//! The process still dies of the same signal: after writing, the handler puts back the handler
//! it replaced (Rust's own, which tells a stack overflow from other faults) and returns, so the
//! faulting instruction runs again under it; a signal some process sent (not a fault) gets its
//! line too, then is raised again with the default action. Only the first thread to fault writes
//! (two threads faulting at once would interleave their frames); the others go straight on to
//! die. The handler allocates nothing (`backtrace` is called once at install so that its first
//! call's library load happens outside it; the line is formatted on the stack), but glibc marks
//! `backtrace` and `backtrace_symbols_fd` AS-Unsafe (the loader's and the unwinder's locks): a fault
//! inside `dlopen` or an unwind could hang there, and the supervisor then reports a timeout, not a
//! crash. It runs on the thread's alternate stack where Rust made one (its main thread and the
//! threads it spawns); that stack is small (about 8 KiB), so on a stack overflow the backtrace may
//! itself overflow it and the process dies of SIGSEGV without Rust's overflow message.
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::OnceLock;

/// A thread has written its backtrace: later faults do not write theirs.
static WRITTEN: AtomicBool = AtomicBool::new(false);

/// The fatal signals a fault raises, with the handler each had before [`install`].
static PREVIOUS: OnceLock<Vec<(libc::c_int, libc::sigaction)>> = OnceLock::new();

/// The signals handled.
const SIGNALS: [libc::c_int; 4] = [libc::SIGSEGV, libc::SIGBUS, libc::SIGILL, libc::SIGFPE];

use crate::model::native_backtrace::MARK;

/// Install the handler for [`SIGNALS`] (once per process; later calls do nothing).
pub fn install() {
    PREVIOUS.get_or_init(|| {
        // The first call loads the unwinder (a dlopen, which allocates): not in the handler.
        let mut frames = [std::ptr::null_mut(); 4];
        unsafe { libc::backtrace(frames.as_mut_ptr(), frames.len() as libc::c_int) };
        SIGNALS.iter().filter_map(|&sig| replace(sig).map(|old| (sig, old))).collect()
    });
}

/// Our handler for `sig`, the previous one returned (`None`: `sigaction` failed; left alone).
fn replace(sig: libc::c_int) -> Option<libc::sigaction> {
    unsafe {
        let mut action: libc::sigaction = std::mem::zeroed();
        action.sa_sigaction = on_fatal as *const () as usize;
        action.sa_flags = libc::SA_SIGINFO | libc::SA_ONSTACK;
        libc::sigemptyset(&mut action.sa_mask);
        let mut old: libc::sigaction = std::mem::zeroed();
        (libc::sigaction(sig, &action, &mut old) == 0).then_some(old)
    }
}

extern "C" fn on_fatal(sig: libc::c_int, info: *mut libc::siginfo_t, _: *mut libc::c_void) {
    // SAFETY: the kernel passes a valid siginfo for an SA_SIGINFO handler.
    let (addr, code) = unsafe { ((*info).si_addr() as usize, (*info).si_code) };
    let mut line = Line::default();
    line.push(MARK.as_bytes());
    line.push(b" ");
    line.number(sig as u64, 10);
    line.push(b" (fault address 0x");
    line.number(addr as u64, 16);
    line.push(b"); native backtrace:\n");
    let mut frames = [std::ptr::null_mut(); 64];
    if !WRITTEN.swap(true, Ordering::SeqCst) {
        unsafe {
            libc::write(2, line.buf.as_ptr().cast(), line.len);
            let n = libc::backtrace(frames.as_mut_ptr(), frames.len() as libc::c_int);
            libc::backtrace_symbols_fd(frames.as_ptr(), n, 2);
        }
    }
    let previous = PREVIOUS.get().and_then(|p| p.iter().find(|(s, _)| *s == sig));
    // A fault (the kernel's, `si_code` > 0) happens again under the previous handler on return;
    // a signal sent by a process is raised again, with the default action.
    unsafe {
        match previous.filter(|_| code > 0) {
            Some((_, old)) => {
                libc::sigaction(sig, old, std::ptr::null_mut());
            }
            None => {
                libc::signal(sig, libc::SIG_DFL);
                libc::raise(sig);
            }
        }
    }
}

/// A line built on the stack, no allocation.
struct Line {
    buf: [u8; 160],
    len: usize,
}

impl Default for Line {
    fn default() -> Line {
        Line { buf: [0; 160], len: 0 }
    }
}

impl Line {
    fn push(&mut self, bytes: &[u8]) {
        let n = bytes.len().min(self.buf.len() - self.len);
        self.buf[self.len..self.len + n].copy_from_slice(&bytes[..n]);
        self.len += n;
    }

    /// `v` in `radix` (10 or 16), lowercase digits.
    fn number(&mut self, mut v: u64, radix: u64) {
        let mut digits = [0u8; 20];
        let mut i = digits.len();
        loop {
            i -= 1;
            digits[i] = b"0123456789abcdef"[(v % radix) as usize];
            v /= radix;
            if v == 0 {
                break;
            }
        }
        self.push(&digits[i..]);
    }
}

#[cfg(test)]
mod tests {
    use super::Line;

    #[test]
    fn the_line_formats_numbers_without_allocating_and_never_overflows() {
        let mut l = Line::default();
        l.number(11, 10);
        l.push(b" 0x");
        l.number(0xdead_0000_0000, 16);
        l.push(b" ");
        l.number(0, 16);
        assert_eq!(&l.buf[..l.len], b"11 0xdead00000000 0");
        for _ in 0..100 {
            l.push(b"0123456789");
        }
        assert_eq!(l.len, l.buf.len(), "a long line is cut, not overflowed");
    }
}
