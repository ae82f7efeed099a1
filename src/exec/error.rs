//! What running one cell can fail with, the outcome each failure means (error → outcome is
//! decided here once: a lost device is `device_lost` wherever it surfaced), and the cell's result
//! made from it.
use crate::model::{CellResult, Outcome, Timings};
use crate::scene::gpu::BuildError;
use crate::shadergen::compile::CompileError;
use crate::vk::{fault, Gpu, VkError};
use ash::vk;
use std::time::Duration;

#[derive(Debug, thiserror::Error)]
pub enum CellError {
    #[error(transparent)]
    Vk(#[from] VkError),
    #[error(transparent)]
    Compile(#[from] CompileError),
    #[error(transparent)]
    Build(#[from] BuildError),
    #[error("{0} did not finish within the deadline")]
    Timeout(&'static str),
    /// A bundle's SPIR-V or a `--dump` file.
    #[error(transparent)]
    Io(#[from] super::files::FileError),
    #[error("as-to-address patch: {0}")]
    Patch(#[from] crate::patches::PatchError),
    /// A mutant that could not be applied (`run --mutants`): not a run of the cell.
    #[error("mutant: {0}")]
    Mutant(crate::patches::PatchError),
    /// rtprobe's own gap (outcome `not_implemented`).
    #[error("not implemented in rtprobe: {0}")]
    NotImplemented(String),
    /// A queried limit of the device rules the cell out at this scene size (outcome `unsupported`).
    #[error("{0}")]
    Unsupported(String),
    /// A module does not fit the cell's layout (a bundle's or user's SPIR-V; `interface`): the
    /// cell's `error`, never handed to the driver.
    #[error("the shaders do not fit the cell's pipeline layout: {0}")]
    Interface(crate::interface::Mismatch),
    /// The run's scene file (`run --scene`) could not be loaded again, or changed.
    #[error(transparent)]
    Scene(#[from] crate::scene::gltf::LoadError),
    /// The prebuild's pipeline threads ended before making every pipeline (one panicked): the
    /// worker's, never a cell's (`exec::prebuild` aborts the batch with it).
    #[error("the prebuild's pipeline threads ended before making every pipeline")]
    PoolEnded,
}

impl CellError {
    /// The outcome this error means: a lost device is `device_lost` wherever it surfaced (AS
    /// build, upload, submit), a fence wait past the deadline is `timeout`, anything else `error`.
    pub fn outcome(&self) -> Outcome {
        match self {
            CellError::Vk(e) | CellError::Build(BuildError::Vk(e)) => vk_outcome(e),
            CellError::Timeout(_) | CellError::Build(BuildError::TimedOut(_)) => Outcome::Timeout,
            CellError::Compile(_)
            | CellError::Io(_)
            | CellError::Patch(_)
            | CellError::Mutant(_)
            | CellError::Interface(_)
            | CellError::Scene(_)
            | CellError::PoolEnded => Outcome::Error,
            CellError::NotImplemented(_) => Outcome::NotImplemented,
            CellError::Unsupported(_) => Outcome::Unsupported,
        }
    }

    /// The result of a cell that failed with this error: its outcome, the error as the detail
    /// (with the fence wait limit `timeout` for a timeout), and after a device loss what the
    /// device reports on the fault (VK_EXT_device_fault).
    pub fn result(&self, gpu: &Gpu, timeout: Duration, timings: Timings) -> CellResult {
        let outcome = self.outcome();
        let detail = if outcome == Outcome::Timeout {
            format!("{self} (fence wait limit {timeout:?})")
        } else {
            self.to_string()
        };
        let fault = if outcome == Outcome::DeviceLost { fault::query(gpu) } else { None };
        CellResult {
            outcome,
            detail: Some(detail),
            timings,
            comparison: None,
            fault,
            validation_errors: 0,
        }
    }
}

fn vk_outcome(e: &VkError) -> Outcome {
    match e {
        VkError::DeviceLost { .. } => Outcome::DeviceLost,
        VkError::Call { result, .. } if *result == vk::Result::TIMEOUT => Outcome::Timeout,
        _ => Outcome::Error,
    }
}
