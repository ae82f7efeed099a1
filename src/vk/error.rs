//! Errors of the Vulkan layer. `DeviceLost` is its own variant: callers never have to look inside
//! a generic error to learn that the device is gone. Every `vk::Result` is mapped where the call
//! is made, through [`VkResultExt::at`], so the message names the call that failed.
use ash::vk;

#[derive(Debug, thiserror::Error)]
pub enum VkError {
    #[error("no Vulkan loader could be loaded ({detail}); install libvulkan1 (scripts/setup does) or set RTPROBE_VULKAN_LIB to the path of libvulkan.so.1")]
    LoaderMissing { detail: String },
    #[error("the Vulkan loader supports only Vulkan {found}; rtprobe needs 1.2 or newer: update libvulkan1")]
    LoaderTooOld { found: String },
    #[error("no Vulkan driver found ({detail}); install lavapipe (scripts/setup) or your GPU driver, or point VK_DRIVER_FILES at an ICD JSON")]
    NoDriver { detail: String },
    #[error("--device {spec:?} matches no device (available: {available}); run `rtprobe devices` to list them")]
    NoSuchDevice { spec: String, available: String },
    #[error("--device {spec:?} matches several devices ({matches}); pass the index instead")]
    AmbiguousDevice { spec: String, matches: String },
    #[error("device {index} ({name}) cannot run ray tracing pipelines: {missing}; pick another with --device (see `rtprobe devices`)")]
    NotRtCapable { index: usize, name: String, missing: String },
    #[error("no device can run ray tracing pipelines ({details}); see `rtprobe devices`")]
    NoRtDevice { details: String },
    #[error("the device was lost during {call}")]
    DeviceLost { call: &'static str },
    #[error("{call} failed: {result}")]
    Call { call: &'static str, result: vk::Result },
    #[error("device {index} ({name}) lacks what this work needs: {missing}")]
    Unsupported { index: usize, name: String, missing: String },
    #[error("{what}: no memory type fits (type bits {type_bits:#x}, wanted {flags:?})")]
    NoMemoryType { what: &'static str, type_bits: u32, flags: vk::MemoryPropertyFlags },
}

impl VkError {
    /// Classify a failed call. `ERROR_DEVICE_LOST` always becomes [`VkError::DeviceLost`].
    pub fn from_result(call: &'static str, result: vk::Result) -> Self {
        if result == vk::Result::ERROR_DEVICE_LOST {
            VkError::DeviceLost { call }
        } else {
            VkError::Call { call, result }
        }
    }

    pub fn is_device_lost(&self) -> bool {
        matches!(self, VkError::DeviceLost { .. })
    }
}

/// Maps a raw `vk::Result` error at the call site, naming the call.
pub trait VkResultExt<T> {
    fn at(self, call: &'static str) -> Result<T, VkError>;
}

impl<T> VkResultExt<T> for Result<T, vk::Result> {
    fn at(self, call: &'static str) -> Result<T, VkError> {
        self.map_err(|r| VkError::from_result(call, r))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn device_lost_is_its_own_variant() {
        let e: Result<(), _> = Err(vk::Result::ERROR_DEVICE_LOST);
        let e = e.at("vkQueueSubmit").unwrap_err();
        assert!(e.is_device_lost());
        assert_eq!(e.to_string(), "the device was lost during vkQueueSubmit");
        let o: Result<(), _> = Err(vk::Result::ERROR_OUT_OF_DEVICE_MEMORY);
        assert!(!o.at("vkAllocateMemory").unwrap_err().is_device_lost());
    }
}
