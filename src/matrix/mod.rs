//! The test matrix: the plan built from options and device features before any GPU work (the
//! axes, cells and their ids live in `model`).
pub mod plan;

pub use plan::PlanOptions;
