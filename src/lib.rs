//! rtprobe: find and pin down GPU driver faults in Vulkan ray tracing.
//!
//! The flow (see ARCHITECTURE.md): CLI → plan → supervisor → workers (device, scene, shaders,
//! trace) → CPU reference → outcome → report.
pub mod atomic;
pub mod bench;
pub mod bisect;
pub mod campaign;
pub mod caps;
pub mod cli;
pub mod exec;
pub mod fleet;
pub mod harness;
pub mod interface;
pub mod matrix;
pub mod model;
pub mod mutants;
pub mod native_crash;
pub mod patches;
pub mod pool;
pub mod probe;
pub mod reference;
pub mod reflect;
pub mod report;
pub mod runner;
pub mod scene;
pub mod shadergen;
pub mod shape;
pub mod stable_hash;
pub mod stress;
pub mod tempdir;
pub mod tools;
pub mod vk;
