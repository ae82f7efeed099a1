//! rtprobe: find and pin down GPU driver faults in Vulkan ray tracing.
//!
//! The flow (see ARCHITECTURE.md): CLI → plan → supervisor → workers (device, scene, shaders,
//! trace) → CPU reference → outcome → report.
pub mod model;
pub mod caps;
pub mod cli;
pub mod matrix;
pub mod report;
pub mod vk;
pub mod probe;
pub mod reference;
pub mod scene;
pub mod shadergen;
pub mod exec;
pub mod runner;
pub mod patches;
pub mod bisect;
pub mod campaign;
pub mod fleet;
pub mod stress;
pub mod bench;
pub mod pool;
pub mod atomic;
