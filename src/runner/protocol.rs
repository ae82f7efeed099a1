//! The supervisor ↔ worker protocol. The supervisor writes a [`WorkerJob`] to a file and starts
//! `rtprobe __worker FILE` with stdin closed; the worker answers with one JSON [`WorkerMsg`] per
//! line on stdout. The worker never decides that it is dead: the supervisor does, from deadlines,
//! end of output and exit status.
use crate::matrix::Cell;
use crate::outcome::CellResult;
use crate::scene::SceneParams;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct WorkerJob {
    pub device_index: usize,
    pub scene: SceneParams,
    /// Fence deadline inside the worker (shorter than the supervisor's hard deadline).
    pub fence_timeout_ms: u64,
    pub validate: bool,
    /// `--inject-fault` injections (the worker applies the first that matches each cell).
    #[serde(default)]
    pub inject: Vec<crate::matrix::inject::Injection>,
    /// Seed of the flaky-injection dice.
    #[serde(default)]
    pub inject_seed: u64,
    pub dump: Option<PathBuf>,
    pub cells: Vec<Cell>,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum WorkerMsg {
    /// Device created and CPU reference computed.
    Ready { device_ms: f64, reference_ms: f64 },
    Start { cell: String },
    Result { cell: String, result: CellResult },
    /// The worker cannot run at all (e.g. device creation failed).
    Fatal { message: String },
}
