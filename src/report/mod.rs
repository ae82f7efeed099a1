//! Renderers over the data layer: the run report's writer and its lock, timestamps, JUnit, the
//! terminal summary and the run's one verdict, the vendor issue, the recommended-pattern, GPU-AV
//! and mutants rounds' scheduling and verdicts,
//! a cell's shaders as a reader gets them, the repro bundle's Amber script, and SVG charts.
pub mod amber;
pub mod chart;
pub mod gpu_av;
pub mod issue;
pub mod junit;
pub mod lock;
pub mod mutants;
pub mod recommended;
pub mod reduce_issue;
pub mod shader_junit;
pub mod shaders;
pub mod summary;
pub mod time;
pub mod verdict;
pub mod writer;
