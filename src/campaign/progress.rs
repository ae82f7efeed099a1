//! What a run shows while its rounds work: [`Progress`] is told how many attempts a round
//! schedules, which round starts and when each attempt ends (the CLI's progress bar or, without
//! a terminal, its progress lines; tests count them).
use crate::model::{Cell, Outcome};

/// Each defaults to nothing.
pub trait Progress {
    /// A round scheduled `n` more attempts.
    fn scheduled(&self, _n: u64) {}
    /// A round after the matrix starts, running `n` attempts: its name (`confirm`, `repeat`,
    /// `workarounds`, `patterns`, `verify`, `gpu-av`, `mutants`, `canaries`) and how they run.
    fn round(&self, _name: &'static str, _n: u64, _alone: bool) {}
    /// An attempt ended: the cell's, with its outcome (`None`: one apart from the report's cells,
    /// under GPU-AV or a mutant's).
    fn ended(&self, _cell: &Cell, _outcome: Option<Outcome>) {}
    /// Every round is done (the summary comes next).
    fn finish(&self) {}
}
