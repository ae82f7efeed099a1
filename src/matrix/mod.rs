//! The test matrix: axes and their values (the report's vocabulary).
pub mod axes;

pub use axes::{AsAccess, DescriptorModel, IndexSource, Resource, Stage};
