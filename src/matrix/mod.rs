//! The test matrix: axes and their values (the report's vocabulary), cells and their ids, and the
//! plan built from options and device features before any GPU work.
pub mod axes;
pub mod cell;
pub mod inject;
pub mod plan;

pub use axes::{AsAccess, BaseSource, DescriptorModel, HeapAccess, IndexSource, Reorder, Resource, SamplerIndex, Stage};
pub use cell::{Canary, Cell};
pub use plan::{Filter, PlanOptions, RunPlan};
