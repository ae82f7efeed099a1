//! Process exit codes (documented in `--help` and docs/exit-codes.md) and the mapping from errors to them.
use crate::vk::VkError;

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
/// `run`: no finding, but a canary's fault, or an `--inject-fault`, was not detected:
/// classification is unproven.
pub const CANARY_UNDETECTED: u8 = 11;

pub const HELP: &str = "\
Exit codes:
  0  success (run: every cell passed or was unsupported)
  1  run: at least one cell faulted (device_lost, crash, timeout, error) or mismatched,
     or a worker faulted outside a cell (between cells, in teardown); stress: a case did not pass
  2  bad command-line arguments
  3  no Vulkan loader (libvulkan.so.1), or one older than Vulkan 1.2
  4  no Vulkan driver / physical device
  5  the device cannot do what was asked (e.g. no ray tracing pipeline)
  6  --device matches no device, or several
  7  a Vulkan call failed
  8  the device was lost outside a supervised cell
  9  bad input file or unwritable output
  10 internal error
  11 run: no finding, but a --canaries or --inject-fault fault was not detected (fault
     classification unproven)";

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

pub fn code_for(err: &anyhow::Error) -> u8 {
    for cause in err.chain() {
        if let Some(c) = cause.downcast_ref::<CodedError>() {
            return c.code;
        }
        if let Some(v) = cause.downcast_ref::<VkError>() {
            return match v {
                VkError::LoaderMissing { .. } | VkError::LoaderTooOld { .. } => NO_LOADER,
                VkError::NoDriver { .. } => NO_DRIVER,
                VkError::NotRtCapable { .. } | VkError::NoRtDevice { .. } | VkError::Unsupported { .. } => UNSUPPORTED_DEVICE,
                VkError::NoSuchDevice { .. } | VkError::AmbiguousDevice { .. } => BAD_DEVICE_SELECTION,
                VkError::DeviceLost { .. } => DEVICE_LOST,
                VkError::Call { .. } | VkError::NoMemoryType { .. } => VULKAN_ERROR,
            };
        }
        if cause.downcast_ref::<crate::atomic::WriteError>().is_some() || cause.downcast_ref::<std::io::Error>().is_some() {
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
        let e = anyhow::Error::from(VkError::NoSuchDevice { spec: "9".into(), available: "0: x".into() }).context("selecting");
        assert_eq!(code_for(&e), BAD_DEVICE_SELECTION);
        let e = anyhow::Error::from(VkError::DeviceLost { call: "vkQueueSubmit" });
        assert_eq!(code_for(&e), DEVICE_LOST);
        assert_eq!(code_for(&coded(BAD_INPUT, "bad json")), BAD_INPUT);
        assert_eq!(code_for(&anyhow::anyhow!("??")), INTERNAL);
    }
}
