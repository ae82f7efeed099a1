//! What reflecting a module fails with ([`ReflectError`]): bytes that are not SPIR-V, no entry
//! point or an ambiguous one, and a module whose types contradict themselves.

/// Why a module's interface cannot be read.
#[derive(Clone, Debug, thiserror::Error, PartialEq, Eq)]
pub enum ReflectError {
    #[error("not a SPIR-V module: {0}")]
    NotSpirv(String),
    #[error("the module has no entry point")]
    NoEntryPoint,
    #[error("the module has several entry points ({}); name one with --entry", .0.join(", "))]
    SeveralEntries(Vec<String>),
    #[error("the module has no entry point `{name}` (it has {}); name one of them with --entry", .present.join(", "))]
    NoSuchEntry { name: String, present: Vec<String> },
    /// An id a type or variable needs is missing or of the wrong kind.
    #[error("malformed module: {0}")]
    Malformed(String),
}
