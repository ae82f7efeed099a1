//! Workers never outlive the supervisor. Each worker is spawned in its own process group with
//! `PR_SET_PDEATHSIG(SIGKILL)` (set between fork and exec, then `getppid` checked, so a supervisor
//! that died before the `prctl` is noticed too): a killed supervisor takes its workers with it.
//! The live groups are kept in a fixed table that the supervisor's SIGINT / SIGTERM / SIGHUP
//! handler reads: it SIGKILLs every group, says so on stderr, and exits (128 + signal). Only
//! async-signal-safe calls run in the handler; the report on disk stays whole (rewritten
//! atomically: at once after a fault, after passes at most every 100 ms) and `--resume` finishes
//! the run, running again the passes of the last 0.1 s that were not saved. The message ends with
//! the command that does ([`set_resume_hint`]), made before the handler can need it. The handler
//! also removes each live supervisor's [`JobFolder`] with the job files no worker read yet.
use std::os::unix::process::CommandExt;
use std::process::Command;
use std::sync::atomic::{AtomicI32, AtomicPtr, AtomicU8, AtomicUsize, Ordering};
use std::sync::Once;

/// The end of the interrupt message: `; finish it with `COMMAND`\n` (leaked once per run, so the
/// handler reads it without allocating).
static HINT: AtomicPtr<u8> = AtomicPtr::new(std::ptr::null_mut());
static HINT_LEN: AtomicUsize = AtomicUsize::new(0);

/// The command that finishes an interrupted run (`rtprobe run --resume REPORT …`), for the
/// interrupt message.
pub fn set_resume_hint(command: &str) {
    let text: &'static [u8] =
        Box::leak(format!("; finish it with `{command}`\n").into_bytes().into_boxed_slice());
    HINT_LEN.store(0, Ordering::SeqCst);
    HINT.store(text.as_ptr() as *mut u8, Ordering::SeqCst);
    HINT_LEN.store(text.len(), Ordering::SeqCst);
}

/// The hint as set, or the generic one.
fn resume_hint() -> &'static [u8] {
    let (p, n) = (HINT.load(Ordering::SeqCst), HINT_LEN.load(Ordering::SeqCst));
    if p.is_null() || n == 0 {
        return b"; finish it with `rtprobe run --resume REPORT` (the report it was writing)\n";
    }
    // SAFETY: `p` and `n` describe a leaked, never freed slice (`set_resume_hint`).
    unsafe { std::slice::from_raw_parts(p, n) }
}

const MAX_GROUPS: usize = 256;
static GROUPS: [AtomicI32; MAX_GROUPS] = [const { AtomicI32::new(0) }; MAX_GROUPS];
static INSTALL: Once = Once::new();

/// Make `cmd` start a worker that dies with this process, in its own process group.
fn harden(cmd: &mut Command) {
    let parent = std::process::id() as libc::pid_t;
    cmd.process_group(0);
    // SAFETY: only async-signal-safe syscalls between fork and exec; no allocation.
    unsafe {
        cmd.pre_exec(move || {
            if libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGKILL as libc::c_ulong, 0, 0, 0) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            if libc::getppid() != parent {
                // The supervisor died between fork and prctl.
                libc::_exit(1);
            }
            // `spawn_registered` blocks the interrupt signals around the fork: not in the child.
            let mut none: libc::sigset_t = std::mem::zeroed();
            libc::sigemptyset(&mut none);
            libc::sigprocmask(libc::SIG_SETMASK, &none, std::ptr::null_mut());
            Ok(())
        });
    }
}

/// Remember a live worker group (for the signal handler).
pub fn register(pgid: i32) {
    for g in &GROUPS {
        if g.compare_exchange(0, pgid, Ordering::SeqCst, Ordering::SeqCst).is_ok() {
            return;
        }
    }
    tracing::warn!(
        "more than {MAX_GROUPS} live workers; worker {pgid} relies on PR_SET_PDEATHSIG alone"
    );
}

/// The interrupt signals the handler takes.
const SIGNALS: [libc::c_int; 3] = [libc::SIGINT, libc::SIGTERM, libc::SIGHUP];

/// The interrupt signals as a set.
fn signal_set() -> libc::sigset_t {
    // SAFETY: sigemptyset/sigaddset fill a set on the stack.
    unsafe {
        let mut set: libc::sigset_t = std::mem::zeroed();
        libc::sigemptyset(&mut set);
        for s in SIGNALS {
            libc::sigaddset(&mut set, s);
        }
        set
    }
}

/// Spawn `cmd` [`harden`]ed — in its own process group, dying with this process — and
/// [`register`] it with the interrupt signals blocked in between: an interrupt that came after
/// the fork and before the registration would leave the new child to `PR_SET_PDEATHSIG` alone,
/// alive while the handler removes its folders. The child starts with no signal blocked
/// (`harden`'s `pre_exec`).
pub fn spawn_registered(cmd: &mut Command) -> std::io::Result<std::process::Child> {
    harden(cmd);
    let set = signal_set();
    let mut old: libc::sigset_t = unsafe { std::mem::zeroed() };
    // SAFETY: this thread's mask, set and restored around the spawn.
    unsafe { libc::pthread_sigmask(libc::SIG_BLOCK, &set, &mut old) };
    let child = cmd.spawn();
    if let Ok(c) = &child {
        register(c.id() as i32);
    }
    unsafe { libc::pthread_sigmask(libc::SIG_SETMASK, &old, std::ptr::null_mut()) };
    child
}

pub fn unregister(pgid: i32) {
    for g in &GROUPS {
        if g.compare_exchange(pgid, 0, Ordering::SeqCst, Ordering::SeqCst).is_ok() {
            return;
        }
    }
}

/// SIGKILL every live worker group.
pub fn kill_all() {
    for g in &GROUPS {
        let pgid = g.load(Ordering::SeqCst);
        if pgid > 0 {
            // SAFETY: kill(2) is async-signal-safe.
            unsafe { libc::kill(-pgid, libc::SIGKILL) };
        }
    }
}

/// Wait (1 s at most in all) for the killed groups' leaders, this process's children, to die: a
/// child's own children (bench's `rtprobe run`'s workers, in groups of their own) are killed by
/// `PR_SET_PDEATHSIG` only once it has died, and may write in the folders until then — the
/// handler removes them after this, and once more 50 ms later. Async-signal-safe.
fn reap_killed() {
    for _ in 0..100 {
        let mut alive = false;
        for g in &GROUPS {
            let pgid = g.load(Ordering::SeqCst);
            // SAFETY: waitpid(2) is async-signal-safe; 0: not dead yet (-1: not a child).
            if pgid > 0 && unsafe { libc::waitpid(pgid, std::ptr::null_mut(), libc::WNOHANG) } == 0
            {
                alive = true;
            }
        }
        if !alive {
            return;
        }
        sleep_ms(10);
    }
}

/// nanosleep(2), async-signal-safe.
fn sleep_ms(ms: u64) {
    let t = libc::timespec { tv_sec: 0, tv_nsec: (ms * 1_000_000) as libc::c_long };
    // SAFETY: plain syscall on a stack value.
    unsafe { libc::nanosleep(&t, std::ptr::null_mut()) };
}

/// A supervisor's folder of job files: a fresh private one, removed when dropped, and by the
/// signal handler when the process is interrupted.
#[derive(Debug)]
pub struct JobFolder {
    dir: crate::tempdir::TempDir,
    slot: Option<usize>,
}

const MAX_FOLDERS: usize = 16;
/// The live job folders' paths, NUL-terminated (leaked: the handler may read one at any time).
static FOLDERS: [AtomicPtr<libc::c_char>; MAX_FOLDERS] =
    [const { AtomicPtr::new(std::ptr::null_mut()) }; MAX_FOLDERS];

impl JobFolder {
    /// A new folder `rtprobe-jobs-<pid>-…` under the temporary folder.
    pub fn new() -> std::io::Result<JobFolder> {
        JobFolder::named("rtprobe-jobs")
    }

    /// A new folder `<prefix>-<pid>-…` under the temporary folder (a command's children's work:
    /// `run --shader`'s, `patch --verify`'s, `bench`'s, `stress`'s).
    pub fn named(prefix: &str) -> std::io::Result<JobFolder> {
        use std::os::unix::ffi::OsStrExt;
        let dir = crate::tempdir::TempDir::named(prefix)?;
        let c = std::ffi::CString::new(dir.path().as_os_str().as_bytes())
            .map_err(std::io::Error::other)?;
        let p = c.into_raw();
        let slot = FOLDERS.iter().position(|f| {
            f.compare_exchange(std::ptr::null_mut(), p, Ordering::SeqCst, Ordering::SeqCst).is_ok()
        });
        if slot.is_none() {
            // SAFETY: `p` came from `into_raw` above and was stored nowhere.
            drop(unsafe { std::ffi::CString::from_raw(p) });
            tracing::warn!(
                "more than {MAX_FOLDERS} live job folders; {} is left to its supervisor alone",
                dir.path().display()
            );
        }
        Ok(JobFolder { dir, slot })
    }

    pub fn path(&self) -> &std::path::Path {
        self.dir.path()
    }
}

impl Drop for JobFolder {
    fn drop(&mut self) {
        // The path stays allocated: a handler running on another thread may be reading it.
        if let Some(i) = self.slot {
            FOLDERS[i].store(std::ptr::null_mut(), Ordering::SeqCst);
        }
    }
}

/// Remove every live job folder with the job files no worker read yet (async-signal-safe: raw
/// `open`, `getdents64`, `unlinkat`, `rmdir` on a buffer on the stack).
fn remove_folders() {
    for f in &FOLDERS {
        let p = f.load(Ordering::SeqCst);
        if !p.is_null() {
            // SAFETY: `p` is a leaked NUL-terminated path; only async-signal-safe calls.
            unsafe {
                empty(p);
                libc::rmdir(p);
            }
        }
    }
}

/// How deep the handler empties a work folder: a job folder holds files; `run --shader`'s GPU-AV
/// re-runs put theirs in folders of its work folder; `bench --cells-cold`'s driver caches lie
/// five levels down (`cold-N/mesa/mesa_shader_cache_db/partK/FILE`) and deeper on NVIDIA.
const DEPTH: u32 = 8;

/// Unlink the files of the folder `path` and of its folders, [`DEPTH`] levels down.
///
/// # Safety
/// `path` is a NUL-terminated path.
unsafe fn empty(path: *const libc::c_char) {
    let fd =
        libc::open(path, libc::O_RDONLY | libc::O_DIRECTORY | libc::O_NOFOLLOW | libc::O_CLOEXEC);
    if fd >= 0 {
        empty_fd(fd, DEPTH);
        libc::close(fd);
    }
}

/// Unlink every entry of the open folder `fd`; a folder among them (where `depth` allows) is
/// emptied and removed. Only async-signal-safe calls; 4 KiB of stack per level.
///
/// # Safety
/// `fd` is an open folder.
unsafe fn empty_fd(fd: libc::c_int, depth: u32) {
    // u64s: `linux_dirent64` records are 8-byte aligned.
    let mut buf = [0u64; 512];
    loop {
        let n =
            libc::syscall(libc::SYS_getdents64, fd, buf.as_mut_ptr(), std::mem::size_of_val(&buf));
        if n <= 0 {
            break;
        }
        let base = buf.as_ptr().cast::<u8>();
        let mut off = 0usize;
        while off < n as usize {
            let d = base.add(off).cast::<libc::dirent64>();
            let name = std::ptr::addr_of!((*d).d_name).cast::<libc::c_char>();
            let dot = *name == b'.' as libc::c_char;
            let special = dot
                && (*name.add(1) == 0
                    || (*name.add(1) == b'.' as libc::c_char && *name.add(2) == 0));
            if !special && libc::unlinkat(fd, name, 0) != 0 && depth > 0 {
                let flags = libc::O_RDONLY | libc::O_DIRECTORY | libc::O_NOFOLLOW | libc::O_CLOEXEC;
                let sub = libc::openat(fd, name, flags);
                if sub >= 0 {
                    empty_fd(sub, depth - 1);
                    libc::close(sub);
                    libc::unlinkat(fd, name, libc::AT_REMOVEDIR);
                }
            }
            off += (*d).d_reclen as usize;
        }
    }
}

/// What an interrupt leaves behind, as its message says.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum Left {
    /// `run`'s report: every fault and all passes but those of the last 0.1 s (`--resume`).
    Report,
    /// No report: `run --shader` writes it at its end.
    NoReport,
    /// Nothing: `patch --verify`, `bench` and `stress` write their outputs at their end.
    Nothing,
    /// Outputs being written: theirs, once their children have ended.
    Writing,
}

/// What an interrupt leaves, as a [`Left`] (the handler reads it without allocating).
static LEFT: AtomicU8 = AtomicU8::new(Left::Report as u8);

/// Install the handler (once per process) and say what an interrupt leaves from now on.
pub fn handle_interrupts(left: Left) {
    // The message first: a signal right after the install says the right thing.
    LEFT.store(left as u8, Ordering::SeqCst);
    install_handlers();
}

/// The message's end for what is left, and the resume hint where a report is.
fn left_message() -> (&'static [u8], &'static [u8]) {
    const NO_REPORT: u8 = Left::NoReport as u8;
    const NOTHING: u8 = Left::Nothing as u8;
    const WRITING: u8 = Left::Writing as u8;
    match LEFT.load(Ordering::SeqCst) {
        NO_REPORT => (b"every child was killed; no report was written\n", b""),
        NOTHING => (b"every child was killed; nothing was written\n", b""),
        WRITING => (b"every child had ended and the outputs were being written: each file finished is whole; one cut short, if any, is left as `.NAME.tmp-PID-N` beside it (or cut short on stdout)\n", b""),
        _ => (
            b"every worker was killed; the report keeps every fault and all passes but those of the last 0.1 s (complete: false)",
            resume_hint(),
        ),
    }
}

extern "C" fn on_signal(sig: libc::c_int) {
    kill_all();
    reap_killed();
    remove_folders();
    // A grandchild (a killed child's worker, dying by PR_SET_PDEATHSIG) may still have made
    // something in a folder: once more after it has had time to die.
    sleep_ms(50);
    remove_folders();
    let what: &[u8] = match sig {
        libc::SIGINT => b"\nrtprobe: interrupted (SIGINT): ",
        libc::SIGTERM => b"\nrtprobe: terminated (SIGTERM): ",
        _ => b"\nrtprobe: hung up (SIGHUP): ",
    };
    let (then, hint) = left_message();
    // SAFETY: write(2) and _exit(2) are async-signal-safe; the pieces are static slices.
    unsafe {
        for piece in [what, then, hint] {
            libc::write(2, piece.as_ptr().cast(), piece.len());
        }
        libc::_exit(128 + sig);
    }
}

/// Install the SIGINT / SIGTERM / SIGHUP handler (once per process), leaving what it says as it
/// is (a supervisor inside `run --shader` keeps its message).
pub fn install_handlers() {
    INSTALL.call_once(|| {
        for sig in SIGNALS {
            // SAFETY: a plain handler that only calls async-signal-safe functions.
            unsafe {
                let mut sa: libc::sigaction = std::mem::zeroed();
                sa.sa_sigaction = on_signal as extern "C" fn(libc::c_int) as usize;
                // The others blocked while it runs (it waits up to 1 s): a second signal must not
                // run it again over the first, with its own message and exit status.
                sa.sa_mask = signal_set();
                libc::sigaction(sig, &sa, std::ptr::null_mut());
            }
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_interrupt_message_ends_with_the_command_set() {
        assert!(std::str::from_utf8(resume_hint())
            .unwrap()
            .starts_with("; finish it with `rtprobe run --resume "));
        set_resume_hint("rtprobe run --resume reports/r.json");
        assert_eq!(resume_hint(), b"; finish it with `rtprobe run --resume reports/r.json`\n");
    }

    /// The handler's unlinking empties a job folder of many unread job files (more than one
    /// `getdents64` buffer's worth), so that its `rmdir` succeeds; without it the `rmdir` fails.
    #[test]
    fn the_handler_empties_a_job_folder_then_removes_it() {
        let dir = crate::tempdir::TempDir::named("rtprobe-jobs-test").unwrap();
        for i in 0..300 {
            std::fs::write(dir.path().join(format!("job-{i}.json")), b"{}").unwrap();
        }
        // A GPU-AV re-run's folder of `run --shader`, with its own files.
        std::fs::create_dir(dir.path().join("gpu-av")).unwrap();
        std::fs::write(dir.path().join("gpu-av/unpatched-job-1.json"), b"{}").unwrap();
        // `bench --cells-cold`'s driver cache, five levels down, and a file as deep as the
        // handler goes (DEPTH folders: one level less and it stays).
        let mesa = dir.path().join("cold-1/mesa/mesa_shader_cache_db/part0");
        std::fs::create_dir_all(&mesa).unwrap();
        std::fs::write(mesa.join("mesa_cache.db"), b"x").unwrap();
        // NVIDIA's cache is deeper (`GLCache/<key>/<h>/<h>/FILE`): DEPTH below 6 leaves it.
        let nv = dir.path().join("cold-2/nvidia/GLCache/k/0a/1b");
        std::fs::create_dir_all(&nv).unwrap();
        std::fs::write(nv.join("cache"), b"x").unwrap();
        let deep: std::path::PathBuf = (0..DEPTH).map(|k| format!("d{k}")).collect();
        std::fs::create_dir_all(dir.path().join(&deep)).unwrap();
        std::fs::write(dir.path().join(&deep).join("f"), b"x").unwrap();
        // A link to a folder is unlinked, never followed.
        let outside = crate::tempdir::TempDir::named("rtprobe-outside-test").unwrap();
        std::fs::write(outside.path().join("keep"), b"1").unwrap();
        std::os::unix::fs::symlink(outside.path(), dir.path().join("link")).unwrap();
        let c = std::ffi::CString::new(dir.path().to_str().unwrap()).unwrap();
        // The twin: rmdir alone leaves it (ENOTEMPTY).
        assert_ne!(unsafe { libc::rmdir(c.as_ptr()) }, 0);
        unsafe { empty(c.as_ptr()) };
        assert_eq!(unsafe { libc::rmdir(c.as_ptr()) }, 0, "{:?}", std::io::Error::last_os_error());
        assert!(!dir.path().exists());
        assert!(outside.path().join("keep").exists(), "the link's target is left alone");
    }

    #[test]
    fn a_job_folder_is_registered_while_it_lives() {
        let f = JobFolder::new().unwrap();
        let path = f.path().to_path_buf();
        let named = |p: &std::path::Path| {
            FOLDERS.iter().any(|s| {
                let q = s.load(Ordering::SeqCst);
                // SAFETY: registered paths are leaked NUL-terminated strings.
                !q.is_null()
                    && unsafe { std::ffi::CStr::from_ptr(q) }.to_bytes()
                        == p.as_os_str().as_encoded_bytes()
            })
        };
        assert!(named(&path));
        drop(f);
        assert!(!named(&path) && !path.exists());
    }

    #[test]
    fn groups_are_registered_and_forgotten() {
        register(999_999);
        assert!(GROUPS.iter().any(|g| g.load(Ordering::SeqCst) == 999_999));
        unregister(999_999);
        assert!(!GROUPS.iter().any(|g| g.load(Ordering::SeqCst) == 999_999));
    }
}
