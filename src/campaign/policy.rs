//! Which rounds a run makes ([`Policy`], from its options) and what they run with ([`Campaign`]:
//! the oracle, the report's recorder, the device's support).
use super::{Oracle, Recorder};
use crate::model::report::RunOptions;
use crate::model::{Cell, Isolation, Mutant, MutantPrediction, PatchMode};
use crate::report::mutants::Sample;

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
    /// `--mutants`: the mutants round (`report::mutants`).
    pub mutants: Option<MutantPolicy>,
}

/// Which mutants the mutants round tries, on every pair or a seeded sample of them.
#[derive(Clone, Debug, PartialEq)]
pub struct MutantPolicy {
    pub mutants: Vec<Mutant>,
    pub sample: Option<Sample>,
}

impl Policy {
    /// The rounds `options` ask for; `layer` is asked only under `--validate=gpu-av`.
    pub fn of(options: &RunOptions, layer: impl FnOnce() -> Option<u32>) -> Policy {
        Policy {
            confirm: options.confirm && options.isolation == Isolation::Worker,
            repeat: options.repeat,
            workarounds: options.patches == PatchMode::Faults,
            gpu_av: options.gpu_av.then(layer),
            mutants: (!options.mutants.is_empty()).then(|| MutantPolicy {
                mutants: options.mutants.clone(),
                sample: options.mutants_sample.as_deref().and_then(|s| Sample::parse(s).ok()),
            }),
        }
    }
}

/// What the rounds run with: the oracle, the recorder of the report, which cells the device can
/// run (workaround, pattern and mutant cells outside the plan are checked here), and whether a
/// mutant cell can apply before it runs (`report::mutants::Applies`: `Err` when the probe has
/// nothing it rewrites, else the reference's prediction).
pub struct Campaign<'a> {
    pub oracle: &'a mut dyn Oracle,
    pub rec: &'a mut Recorder,
    pub supported: &'a dyn Fn(&Cell) -> bool,
    pub applies: &'a dyn Fn(&Cell) -> Result<MutantPrediction, String>,
}
