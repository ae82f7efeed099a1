//! Runs cells on one device: [`Executor::prepare`] builds the scene's acceleration structures,
//! the probed resources and address tables that a worker's cells need before the first cell runs
//! (so a fault there is the worker's setup, not a cell's); per cell it creates descriptor bindings
//! and pipelines (reused after), records and submits the trace / draw / dispatch with a deadline,
//! reads the records back and compares them with the CPU reference, telling its caller each
//! [`Phase`](crate::model::Phase) it enters. Everything that can go wrong becomes an
//! [`Outcome`](crate::model::Outcome).
//!
//! Files, in the order a cell meets them: the executor and its options (`executor`), what the
//! cells need built first (`setup`), phase `compile` (`compile`), binding and the pipeline key
//! (`bind`, `pipeline_key`), building at the cell's turn or ahead of it (`build`, `prebuild`, with the compile's
//! executor-free part on the prebuild's threads: `analysed`),
//! what each step hands to the next (`built`) and what the driver saw of the cell's shape
//! (`seen`), whether its modules fit its layout (`fit`), the turn itself (`run`), recording the
//! three pipeline kinds (`record`), judging the records (`check`, `pictures`; an overlapped cell's on a thread of its own:
//! `checker`), a mutant cell's
//! mutation and prediction (`mutant`), error → outcome (`error`); below them resources and
//! samplers, the scene-layout cells' buffers (`layout_buffers`), bindings, the descriptor heap, pipelines whole or linked from group libraries
//! (`pipeline_library`), the pipeline cache kept between runs, and files (library and layout
//! identities use `crate::stable_hash`).
mod analysed;
mod bind;
pub mod bindings;
mod build;
mod built;
mod check;
pub mod checker;
mod compile;
pub mod error;
mod executor;
mod files;
mod fit;
pub mod heap;
mod layout_buffers;
mod layout_textures;
mod mutant;
pub mod pictures;
pub mod pipeline;
pub mod pipeline_cache;
mod pipeline_key;
mod pipeline_library;
mod pipeline_pool;
pub mod prebuild;
mod record;
pub mod resources;
mod run;
pub mod samplers;
mod seen;
mod setup;

pub use error::CellError;
pub use executor::{ExecOptions, Executor, PhaseHook};
pub use run::{Ran, Traced, CANARY_BAD_ADDRESS};
