//! Which rounds a run makes ([`Policy`], from its options) and what they run with ([`Campaign`]:
//! the oracle, the report's recorder, the device's support).
use super::{Oracle, Recorder};
use crate::model::report::RunOptions;
use crate::model::{Cell, Isolation, PatchMode};

/// Which rounds a run makes after its matrix.
#[derive(Clone, Debug, PartialEq)]
pub struct Policy {
    /// Re-run each fault alone once (`--no-confirm` off, under `--isolation worker` only: with
    /// a process per cell every attempt already ran alone).
    pub confirm: bool,
    /// `--repeat N`: every faulting cell gets N attempts in all.
    pub repeat: Option<u32>,
    /// `--patches faults`: retry findings with each applicable workaround and their recommended
    /// pattern, then verify the passing ones.
    pub workarounds: bool,
    /// `--validate=gpu-av`: re-run findings under GPU-AV; `Some(layer)`, the installed
    /// validation layer's spec version (`None`: not installed).
    pub gpu_av: Option<Option<u32>>,
}

impl Policy {
    /// The rounds `options` ask for; `layer` is asked only under `--validate=gpu-av`.
    pub fn of(options: &RunOptions, layer: impl FnOnce() -> Option<u32>) -> Policy {
        Policy {
            confirm: options.confirm && options.isolation == Isolation::Worker,
            repeat: options.repeat,
            workarounds: options.patches == PatchMode::Faults,
            gpu_av: options.gpu_av.then(layer),
        }
    }
}

/// What the rounds run with: the oracle, the recorder of the report, and which cells the device
/// can run (workaround and pattern cells outside the plan are checked here).
pub struct Campaign<'a> {
    pub oracle: &'a mut dyn Oracle,
    pub rec: &'a mut Recorder,
    pub supported: &'a dyn Fn(&Cell) -> bool,
}
