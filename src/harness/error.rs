//! What running a user pipeline in the harness can fail with.
use crate::scene::gpu::BuildError;
use crate::vk::VkError;
use std::time::Duration;

#[derive(Debug, thiserror::Error)]
pub enum HarnessError {
    #[error(transparent)]
    Vk(#[from] VkError),
    #[error(transparent)]
    Build(#[from] BuildError),
    /// Something the harness cannot run yet (a stage, a binding type, a pipeline without raygen).
    #[error("{0}")]
    Unsupported(String),
    /// The modules disagree with each other or with the contract.
    #[error("{0}")]
    Interface(String),
    /// A fence wait past its deadline: a trace's (`--timeout`), or the setup's uploads'
    /// (`--setup-timeout`; the child's message then starts `setup:`).
    #[error("a submission did not finish within {0:?}")]
    Timeout(Duration),
}
