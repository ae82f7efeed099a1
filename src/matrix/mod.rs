//! The test matrix: the plan built from options and device features before any GPU work (the
//! axes, cells and their ids live in `model`), and why filters leave nothing to plan (`empty`).
pub mod empty;
pub mod plan;

pub use plan::PlanOptions;
