//! Everything that talks to Vulkan directly: the instance, the per-device feature/property
//! struct ([`DeviceInfo`]), logical device creation ([`Gpu`]) and the error type with its
//! first-class `DeviceLost`. Nothing here knows about the CLI or reports.
pub mod binary;
pub mod device;
pub mod driver_version;
pub mod error;
pub mod features;
pub mod heap;
pub mod instance;
pub mod rt_ext;
pub mod shader_features;

pub use device::{GoogleHlsl, Gpu, Requirements, Robustness};
pub use error::{VkError, VkResultExt};
pub use features::DeviceInfo;
pub use instance::{Instance, InstanceOptions};
pub use shader_features::ShaderFeatures;
pub mod fault;
pub mod memory;
pub mod submit;
