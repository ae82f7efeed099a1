//! The supervisor's own fault injection, for its tests: `RTPROBE_WORKER_FAULT=<phase>:<action>`
//! makes a worker misbehave when it enters `<phase>` (snake_case [`Phase`] name). The worker is
//! rtprobe itself, so tests of deadlines, kills and fault attribution need a worker that hangs,
//! crashes, floods its output or loses its device on demand (as nextest and deqp-runner test
//! their runners). Read once when the worker starts; without the variable nothing here runs.
//!
//! Actions: `hang` (sleeps forever), `crash` (SIGSEGV, raised), `fault` (SIGSEGV from a real
//! invalid write, so the worker's fault handler writes its native backtrace), `spam` (prints non-protocol lines
//! without pause, never progresses), `lose` (the phase fails with `VK_ERROR_DEVICE_LOST`),
//! `no_compiler` (`setup` only: the shader compiler fails to start, as `shaderc::Compiler::new`
//! does when memory runs out, its only failure; the worker meets it where the executor starts
//! its compiler, after vkCreateDevice).
//! A `setup` hang, crash or spam happens just before vkCreateDevice (standing in for a hung or
//! crashing device creation); a `setup` loss happens after it, where the scene's acceleration
//! structures are built (a loss needs a device). A `prebuild` action happens as the worker starts
//! building a batch ahead of the cells' turns (only where it prebuilds: `--threads` above 1).
//!
//! `overlap:<hang|crash|spam|lose|hold>` acts in the `trace` of the first cell that runs while
//! the prebuild's threads still make pipelines (an overlapped cell, `runner::overlap`), and
//! nowhere else. With it the pool is held: its threads make the first pipeline only until that
//! cell is done, so the overlap happens whatever the machine's speed. `hold` only holds (for
//! twins of a real fault, an `--inject-fault` hang, say, in an overlapped cell).
use crate::model::Phase;
use crate::shadergen::compile::CompileError;
use crate::vk::VkError;
use std::io::Write;

pub const ENV: &str = "RTPROBE_WORKER_FAULT";
const ACTIONS: &str = "hang|crash|fault|spam|lose|no_compiler|hold";

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Action {
    Hang,
    Crash,
    /// A real invalid memory access (a write to a page mapped with no access): a SIGSEGV from
    /// the kernel, through the worker's fault handler (`native_crash`), as a driver's crash.
    Fault,
    Spam,
    Lose,
    NoCompiler,
    /// `overlap:hold`: nothing but the pool held.
    Hold,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Misbehave {
    pub phase: Phase,
    pub action: Action,
    /// `overlap:`: only in an overlapped cell's `phase` (`trace`), and the pool held.
    pub overlap: bool,
}

/// Where in the setup the hook runs (see the module doc).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SetupStep {
    CreateInstance,
    CreateDevice,
    Compiler,
    Scene,
}

impl Misbehave {
    pub fn parse(spec: &str) -> Result<Misbehave, String> {
        let (p, a) = spec
            .split_once(':')
            .ok_or_else(|| format!("{ENV}={spec:?}: expected <phase>:<{ACTIONS}>"))?;
        let overlap = p == "overlap";
        let phase = if overlap { Some(Phase::Trace) } else { Phase::parse(p) };
        let phase = phase.ok_or_else(|| format!("{ENV}: unknown phase {p:?}"))?;
        let action = match a {
            "hold" if overlap => Action::Hold,
            "hold" => return Err(format!("{ENV}: hold is an overlap action")),
            "hang" => Action::Hang,
            "crash" => Action::Crash,
            "fault" => Action::Fault,
            "spam" => Action::Spam,
            "lose" => Action::Lose,
            "no_compiler" if phase == Phase::Setup => Action::NoCompiler,
            "no_compiler" => return Err(format!("{ENV}: no_compiler is a setup action")),
            other => return Err(format!("{ENV}: unknown action {other:?} ({ACTIONS})")),
        };
        Ok(Misbehave { phase, action, overlap })
    }

    /// The hook of this process, read once from the environment.
    pub fn from_env() -> Result<Option<Misbehave>, String> {
        match std::env::var(ENV) {
            Ok(s) if !s.is_empty() => Misbehave::parse(&s).map(Some),
            _ => Ok(None),
        }
    }

    /// Called as the worker enters `phase` (with the setup step, for `setup`) outside an
    /// overlapped cell.
    pub fn at(&self, phase: Phase, step: Option<SetupStep>) -> Result<(), VkError> {
        if phase != self.phase || self.overlap {
            return Ok(());
        }
        self.act(phase, step)
    }

    /// Called as an overlapped cell enters `phase` (`overlap:` hooks and phase hooks alike act).
    pub fn at_overlapped(&self, phase: Phase) -> Result<(), VkError> {
        if phase != self.phase {
            return Ok(());
        }
        self.act(phase, None)
    }

    fn act(&self, phase: Phase, step: Option<SetupStep>) -> Result<(), VkError> {
        let wanted =
            if self.action == Action::Lose { SetupStep::Scene } else { SetupStep::CreateDevice };
        if phase == Phase::Setup && step != Some(wanted) {
            return Ok(());
        }
        match self.action {
            Action::Hang => loop {
                std::thread::sleep(std::time::Duration::from_secs(3600));
            },
            Action::Crash => unsafe {
                // Rust's own SIGSEGV handler ignores a raised signal; restore the default first.
                libc::signal(libc::SIGSEGV, libc::SIG_DFL);
                libc::raise(libc::SIGSEGV);
                libc::_exit(139)
            },
            Action::Fault => unsafe {
                let page = libc::mmap(
                    std::ptr::null_mut(),
                    4096,
                    libc::PROT_NONE,
                    libc::MAP_PRIVATE | libc::MAP_ANONYMOUS,
                    -1,
                    0,
                );
                (page as *mut u8).write_volatile(1);
                libc::_exit(139)
            },
            Action::Spam => {
                let mut out = std::io::stdout();
                loop {
                    let _ = out.write_all(b"driver debug: still busy (injected spam)\n");
                }
            }
            Action::Lose => {
                Err(VkError::DeviceLost { call: "injected device loss (RTPROBE_WORKER_FAULT)" })
            }
            Action::NoCompiler | Action::Hold => Ok(()),
        }
    }

    /// Called as the worker's setup starts its shader compiler: `setup:no_compiler` fails it.
    pub fn compiler(&self) -> Result<(), CompileError> {
        match self.action {
            Action::NoCompiler => Err(CompileError::Init),
            _ => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_phase_and_action() {
        assert_eq!(
            Misbehave::parse("pipeline:hang"),
            Ok(Misbehave { phase: Phase::Pipeline, action: Action::Hang, overlap: false })
        );
        assert_eq!(
            Misbehave::parse("overlap:crash"),
            Ok(Misbehave { phase: Phase::Trace, action: Action::Crash, overlap: true })
        );
        assert_eq!(Misbehave::parse("overlap:hold").unwrap().action, Action::Hold);
        assert!(Misbehave::parse("trace:hold").is_err(), "hold only holds the overlap's pool");
        assert_eq!(Misbehave::parse("between_cells:crash").unwrap().action, Action::Crash);
        assert!(Misbehave::parse("pipeline").is_err());
        assert!(Misbehave::parse("nowhere:hang").is_err());
        assert!(Misbehave::parse("trace:explode").is_err());
        assert_eq!(Misbehave::parse("setup:no_compiler").unwrap().action, Action::NoCompiler);
        assert!(Misbehave::parse("trace:no_compiler").is_err(), "the compiler starts in setup");
    }

    #[test]
    fn loss_fires_only_in_its_phase() {
        let m = Misbehave { phase: Phase::Trace, action: Action::Lose, overlap: false };
        assert!(m.at(Phase::Compile, None).is_ok());
        assert!(m.at(Phase::Trace, None).unwrap_err().is_device_lost());
        assert!(m.at_overlapped(Phase::Trace).unwrap_err().is_device_lost(), "in any cell");
        let o = Misbehave { overlap: true, ..m };
        assert!(o.at(Phase::Trace, None).is_ok(), "an overlap hook spares the other cells");
        assert!(o.at_overlapped(Phase::Compile).is_ok());
        assert!(o.at_overlapped(Phase::Trace).unwrap_err().is_device_lost());
        let s = Misbehave { phase: Phase::Setup, action: Action::Lose, overlap: false };
        assert!(s.at(Phase::Setup, Some(SetupStep::CreateDevice)).is_ok());
        assert!(s.at(Phase::Setup, Some(SetupStep::Scene)).is_err());
        assert!(s.compiler().is_ok(), "a device loss leaves the compiler alone");
    }

    #[test]
    fn no_compiler_fails_the_compiler_only() {
        let m = Misbehave::parse("setup:no_compiler").unwrap();
        for step in [SetupStep::CreateInstance, SetupStep::CreateDevice, SetupStep::Scene] {
            assert!(m.at(Phase::Setup, Some(step)).is_ok(), "{step:?}");
        }
        assert!(matches!(m.compiler(), Err(CompileError::Init)));
    }
}
