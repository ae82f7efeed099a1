//! Reports: atomic writes, timestamps, the run report schema and its writer, JUnit, mismatch
//! pictures and the terminal summary.
pub mod amber;
pub mod atomic;
pub mod chart;
pub mod gpu_av;
pub mod junit;
pub mod issue;
pub mod pictures;
pub mod recommended;
pub mod run_report;
pub mod shaders;
pub mod summary;
pub mod time;

pub use atomic::write_atomic;
