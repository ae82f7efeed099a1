//! What a SPIR-V patch can fail with: not a module, nothing to patch, a bad option, an invalid
//! result.

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum PatchError {
    #[error("not a SPIR-V module: {0}")]
    NotSpirv(String),
    #[error("{patch}: nothing to patch: {what}")]
    NothingToPatch { patch: &'static str, what: String },
    #[error("{patch}: cannot rewrite %{id}: {what}")]
    Unsupported { patch: &'static str, id: u32, what: String },
    #[error("{patch}: {what}")]
    BadOption { patch: &'static str, what: String },
    #[error("unknown patch {0:?}; `rtprobe patch --list` shows them")]
    Unknown(String),
    #[error("option {0:?} belongs to none of the applied patches")]
    UnknownOption(String),
    #[error("internal error while patching ({0}); please report it with the input module")]
    Internal(String),
}
