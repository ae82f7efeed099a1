//! Process exit codes (documented in `--help` and docs/exit-codes.md) and the mapping from errors to them.
use crate::model::Halt;
use crate::shadergen::compile::CompileError;
use crate::vk::VkError;
use std::path::Path;

pub const OK: u8 = 0;
/// `run`: at least one cell faulted or mismatched, or a worker faulted outside a cell.
pub const FINDINGS: u8 = 1;
/// Bad command-line arguments (clap's own code).
pub const USAGE: u8 = 2;
pub const NO_LOADER: u8 = 3;
pub const NO_DRIVER: u8 = 4;
pub const UNSUPPORTED_DEVICE: u8 = 5;
pub const BAD_DEVICE_SELECTION: u8 = 6;
pub const VULKAN_ERROR: u8 = 7;
pub const DEVICE_LOST: u8 = 8;
pub const BAD_INPUT: u8 = 9;
pub const INTERNAL: u8 = 10;
/// `run`: no finding, but a canary's fault, an `--inject-fault`, or a `--mutants` mutant the
/// probe must catch (a probe defect) was not detected: classification is unproven.
pub const CANARY_UNDETECTED: u8 = 11;
/// The shader compiler (shaderc, linked in) could not be started: nothing can be compiled (in
/// this process, or in a worker of `run`: the run halts, [`halted`]).
pub const NO_SHADER_COMPILER: u8 = 12;

pub const HELP: &str = "\
Exit codes:
  0  success (run: every cell passed or was unsupported)
  1  run: at least one cell faulted (device_lost, crash, timeout, error) or mismatched,
     or a worker faulted outside a cell (between cells, in teardown); with --baseline, only what
     it did not expect; merge: the same for the merged report; stress: a case did not pass;
     patch --verify: the patched pipeline rendered differently from the unpatched one
  2  bad command-line arguments, or --filters that leave no cell to plan
  3  no Vulkan loader (libvulkan.so.1), or one older than Vulkan 1.2
  4  no Vulkan driver / physical device
  5  the device cannot do what was asked (e.g. no ray tracing pipeline; run: none of the
     planned cells)
  6  --device matches no device, or several
  7  a Vulkan call failed
  8  the device was lost outside a supervised cell
  9  bad input file, unwritable output, or a report another run is writing
  10 internal error
  11 run: no finding, but a --canaries or --inject-fault fault, or a --mutants mutant the probe
     must catch, was not detected (fault classification unproven)
  12 the shader compiler (shaderc) could not be started, by rtprobe or by a worker of run";

/// An error that carries its own exit code (bad input, unwritable output, ...).
#[derive(Debug, thiserror::Error)]
#[error("{message}")]
pub struct CodedError {
    pub code: u8,
    pub message: String,
}

/// `message` (a `String`, or a library error whose text is the message) with exit code `code`.
pub fn coded(code: u8, message: impl std::fmt::Display) -> anyhow::Error {
    CodedError { code, message: message.to_string() }.into()
}

/// A run that halted (a worker found what no cell can get past): its code, and one line that
/// says what to do. `report`: where the report so far was written.
pub fn halted(halt: Halt, report: &Path) -> anyhow::Error {
    let then = format!(
        "then run again, or add --resume {} to run the cells still without an attempt",
        report.display()
    );
    halted_then(halt, "the run", &then)
}

/// `bisect` whose runs halted: nothing was written.
pub fn bisect_halted(halt: Halt) -> anyhow::Error {
    halted_then(halt, "bisection", "then run bisect again (nothing was written)")
}

fn halted_then(halt: Halt, what: &str, then: &str) -> anyhow::Error {
    match halt {
        Halt::NoShaderCompiler => coded(
            NO_SHADER_COMPILER,
            format!(
                "a worker could not start the shader compiler (shaderc), so no cell can be \
                 compiled and {what} stopped: {}; {then}",
                no_compiler_cause(),
            ),
        ),
    }
}

/// Why a worker's shaderc did not start: the test hook when it is set, else memory.
fn no_compiler_cause() -> String {
    match std::env::var(crate::runner::misbehave::ENV) {
        Ok(v) if v.contains("no_compiler") => {
            format!("{}={v} made it fail on purpose; unset it", crate::runner::misbehave::ENV)
        }
        // `shaderc_compiler_initialize` fails only when its allocation does.
        _ => "shaderc fails to start only when memory runs out; free memory or raise the memory \
              limit (ulimit -v)"
            .into(),
    }
}

/// The code of a library error the CLI reports as text ([`coded`]): [`NO_SHADER_COMPILER`] when
/// `e`, or an error it wraps (its `source()` chain), is the shader compiler failing to start;
/// else `otherwise`.
pub fn compiler_or(e: &(dyn std::error::Error + 'static), otherwise: u8) -> u8 {
    let mut cause = Some(e);
    while let Some(c) = cause {
        if is_no_compiler(c) {
            return NO_SHADER_COMPILER;
        }
        cause = c.source();
    }
    otherwise
}

fn is_no_compiler(e: &(dyn std::error::Error + 'static)) -> bool {
    matches!(e.downcast_ref::<CompileError>(), Some(CompileError::Init))
}

/// The error and its causes on one line, each cause said once: a cause whose text the line
/// already holds (a library error that prints its source, as `WriteError` did) is left out.
pub fn one_line(err: &anyhow::Error) -> String {
    let mut line = String::new();
    for cause in err.chain() {
        let text = cause.to_string().replace('\n', " ");
        if line.contains(&text) {
            continue;
        }
        if !line.is_empty() {
            line += ": ";
        }
        line += &text;
    }
    line
}

/// The exit code of a run's verdict (`run`, and `merge` of its shards).
pub fn of_verdict(v: &crate::report::verdict::Verdict) -> u8 {
    match v.kind {
        crate::report::verdict::Kind::Pass => OK,
        crate::report::verdict::Kind::Findings => FINDINGS,
        crate::report::verdict::Kind::Undetected => CANARY_UNDETECTED,
    }
}

pub fn code_for(err: &anyhow::Error) -> u8 {
    for cause in err.chain() {
        if let Some(c) = cause.downcast_ref::<CodedError>() {
            return c.code;
        }
        if is_no_compiler(cause) {
            return NO_SHADER_COMPILER;
        }
        if let Some(v) = cause.downcast_ref::<VkError>() {
            return match v {
                VkError::LoaderMissing { .. } | VkError::LoaderTooOld { .. } => NO_LOADER,
                VkError::NoDriver { .. } => NO_DRIVER,
                VkError::NotRtCapable { .. }
                | VkError::NoRtDevice { .. }
                | VkError::Unsupported { .. } => UNSUPPORTED_DEVICE,
                VkError::NoSuchDevice { .. } | VkError::AmbiguousDevice { .. } => {
                    BAD_DEVICE_SELECTION
                }
                VkError::DeviceLost { .. } => DEVICE_LOST,
                VkError::Call { .. } | VkError::NoMemoryType { .. } => VULKAN_ERROR,
            };
        }
        if cause.downcast_ref::<crate::atomic::WriteError>().is_some()
            || cause.downcast_ref::<std::io::Error>().is_some()
            || cause.downcast_ref::<crate::scene::gltf::LoadError>().is_some()
            || cause.downcast_ref::<crate::scene::gltf::make::MakeError>().is_some()
        {
            return BAD_INPUT;
        }
    }
    INTERNAL
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn maps_vk_errors_through_context() {
        let e = anyhow::Error::from(VkError::NoSuchDevice {
            spec: "9".into(),
            available: "0: x".into(),
        })
        .context("selecting");
        assert_eq!(code_for(&e), BAD_DEVICE_SELECTION);
        let e = anyhow::Error::from(VkError::DeviceLost { call: "vkQueueSubmit" });
        assert_eq!(code_for(&e), DEVICE_LOST);
        assert_eq!(code_for(&coded(BAD_INPUT, "bad json")), BAD_INPUT);
        assert_eq!(code_for(&anyhow::anyhow!("??")), INTERNAL);
    }

    #[test]
    fn an_os_error_is_said_once() {
        let io = std::io::Error::from_raw_os_error(libc::EACCES);
        let e = anyhow::Error::from(crate::atomic::WriteError { path: "r.json".into(), err: io })
            .context("writing the report");
        let line = one_line(&e);
        assert_eq!(line.matches("os error 13").count(), 1, "{line}");
        assert!(line.starts_with("writing the report: cannot write r.json: "), "{line}");
        // A chain whose causes each add something keeps them all.
        let e = anyhow::anyhow!("inner").context("middle").context("outer");
        assert_eq!(one_line(&e), "outer: middle: inner");
    }

    #[test]
    fn a_run_halted_for_its_shader_compiler_exits_12_with_one_line() {
        let e = halted(Halt::NoShaderCompiler, Path::new("reports/r.json"));
        assert_eq!(code_for(&e), NO_SHADER_COMPILER);
        let line = format!("{e:#}");
        assert!(!line.contains('\n'), "{line}");
        assert!(line.contains("shader compiler (shaderc)") && line.contains("ulimit -v"), "{line}");
        assert!(line.contains("--resume reports/r.json"), "{line}");
        let b = format!("{:#}", bisect_halted(Halt::NoShaderCompiler));
        assert!(!b.contains('\n') && b.contains("bisection stopped"), "{b}");
        assert_eq!(code_for(&bisect_halted(Halt::NoShaderCompiler)), NO_SHADER_COMPILER);
    }

    #[test]
    fn the_shader_compiler_not_starting_has_its_own_code() {
        // Not a Vulkan call failure (7), nor an internal error (10).
        let e = anyhow::Error::from(CompileError::Init).context("compiling the probe");
        assert_eq!(code_for(&e), NO_SHADER_COMPILER);
        let shaders = crate::report::shaders::ShaderError::Compile(CompileError::Init);
        assert_eq!(compiler_or(&shaders, INTERNAL), NO_SHADER_COMPILER);
        let stress = crate::stress::TraceError::Compile(CompileError::Init);
        assert_eq!(compiler_or(&stress, INTERNAL), NO_SHADER_COMPILER);
        assert_eq!(code_for(&coded(compiler_or(&stress, INTERNAL), &stress)), NO_SHADER_COMPILER);
        // A GLSL error is the input's, and keeps the caller's code.
        let glsl = CompileError::Glsl { file: "x.rgen".into(), message: "syntax".into() };
        assert_eq!(compiler_or(&glsl, BAD_INPUT), BAD_INPUT);
        assert_eq!(code_for(&anyhow::Error::from(glsl)), INTERNAL);
        assert!(HELP.contains("\n  12 the shader compiler (shaderc) could not be started"));
    }
}
