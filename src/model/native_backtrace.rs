//! What a worker's fault handler writes to stderr (`crate::native_crash`): a line starting with
//! [`MARK`] (the signal and the fault address), then one frame a line, innermost first, as
//! glibc's `backtrace_symbols_fd` writes them. [`top`] reads them back out of a stderr tail for the
//! texts that quote a crash: the frames where it faulted, not the process's start.

/// The first line a worker's fault handler writes.
pub const MARK: &str = "rtprobe worker: fatal signal";

/// Frames before the faulting one: the handler itself and the kernel's signal trampoline.
const HANDLER_FRAMES: usize = 2;

/// The last native backtrace in `tail`: its [`MARK`] line and its `n` innermost frames below the
/// handler's own, joined with ` | ` (`None`: no backtrace there).
pub fn top(tail: &str, n: usize) -> Option<String> {
    let at = tail.rfind(MARK)?;
    let mut lines = tail[at..].lines();
    let head = lines.next()?.trim();
    let frames: Vec<&str> = lines
        .map(str::trim)
        .take_while(|l| l.contains("[0x"))
        .skip(HANDLER_FRAMES)
        .take(n)
        .collect();
    Some(std::iter::once(head).chain(frames).collect::<Vec<_>>().join(" | "))
}

#[cfg(test)]
mod tests {
    use super::*;

    const TAIL: &str = "driver: a warning\n\
rtprobe worker: fatal signal 11 (fault address 0x7fa0e9260000); native backtrace:\n\
/proc/self/exe(+0x525f7a)[0x55ccc2235f7a]\n\
/lib/x86_64-linux-gnu/libc.so.6(+0x3c050)[0x7fa0ea37a050]\n\
/usr/lib/libnvidia-glcore.so.580(+0x1a2b3c)[0x7fa0e0000000]\n\
/proc/self/exe(+0x451a1d)[0x55ccc2161a1d]\n\
/lib/x86_64-linux-gnu/libc.so.6(__libc_start_main+0x85)[0x7fa0ea365305]\n";

    #[test]
    fn the_top_frames_are_below_the_handler_and_the_trampoline() {
        let t = top(TAIL, 2).unwrap();
        assert_eq!(
            t,
            "rtprobe worker: fatal signal 11 (fault address 0x7fa0e9260000); native backtrace: \
             | /usr/lib/libnvidia-glcore.so.580(+0x1a2b3c)[0x7fa0e0000000] \
             | /proc/self/exe(+0x451a1d)[0x55ccc2161a1d]"
        );
    }

    #[test]
    fn a_tail_without_a_backtrace_has_none() {
        assert_eq!(top("driver: a warning\nlast line\n", 4), None);
        // (a mark cut off by the tail's start is no backtrace either: the frames are what count)
        assert_eq!(top("/proc/self/exe(+0x1)[0x2]\n", 4), None);
    }
}
