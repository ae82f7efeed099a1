//! What a run shows while its rounds work: [`Progress`] is told how many attempts a round
//! schedules and when each ends (the CLI's progress bar; tests count them).
use crate::model::{Cell, Outcome};

/// Both default to nothing.
pub trait Progress {
    /// A round scheduled `n` more attempts.
    fn scheduled(&self, _n: u64) {}
    /// An attempt ended: the cell's, with its outcome (`None`: one apart from the report's cells,
    /// under GPU-AV).
    fn ended(&self, _cell: &Cell, _outcome: Option<Outcome>) {}
}
