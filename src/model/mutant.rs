//! `run --mutants`: the emulated driver bugs ([`Mutant`], the `mutant` axis: a SPIR-V mutation of
//! the probed stage, applied by the worker after the cell's workarounds) and the report's kill
//! matrix ([`MutantReport`]: per cell and mutant, killed / survived / not applicable, with why).
//! What the CPU reference predicts for a mutant rides on its comparison
//! (`comparison::MutantPrediction`). The rewrites are `mutants`'s, the verdicts
//! `report::mutants`'s, the round `campaign`'s.
use super::{MutantPrediction, Outcome};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// A driver-bug class emulated by mutating the probed stage's SPIR-V. Drivers seldom write
/// garbage; they read the wrong thing: every mutant but `value-bits` makes the probe read another
/// descriptor, element, sampler or acceleration structure, always inside the resource (an
/// out-of-bounds read would emulate another bug, and can hang a GPU).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Mutant {
    /// The descriptor index becomes 0.
    IndexZero,
    /// The descriptor index becomes index + 1, modulo the array length.
    IndexNext,
    /// The descriptor index becomes the first active lane's (`OpGroupNonUniformBroadcastFirst`).
    IndexBroadcast,
    /// A hit stage's runtime base is dropped from `base + (custom & mask)`.
    BaseDropped,
    /// The packed resource's element (buffer element or array layer) becomes 0
    /// (`index=dynamic_element`).
    ElementZero,
    /// The descriptor offset is computed with twice the descriptor stride, the index kept inside
    /// the array: `2 · (index mod ⌈n/2⌉)`.
    StrideDouble,
    /// The sampler heap index becomes the next sampler (modulo the samplers).
    SamplerNext,
    /// The acceleration structure's address becomes the next entry of the address table.
    TlasOther,
    /// The probed value's last word gets its 3 low bits flipped.
    ValueBits,
}

impl Mutant {
    pub const ALL: &'static [Mutant] = &[
        Mutant::IndexZero,
        Mutant::IndexNext,
        Mutant::IndexBroadcast,
        Mutant::BaseDropped,
        Mutant::ElementZero,
        Mutant::StrideDouble,
        Mutant::SamplerNext,
        Mutant::TlasOther,
        Mutant::ValueBits,
    ];
    pub const NAMES: &'static [&'static str] = &[
        "index-zero",
        "index-next",
        "index-broadcast",
        "base-dropped",
        "element-zero",
        "stride-double",
        "sampler-next",
        "tlas-other",
        "value-bits",
    ];

    pub fn parse(s: &str) -> Option<Mutant> {
        Mutant::ALL.iter().copied().find(|m| m.as_str() == s)
    }

    pub fn as_str(self) -> &'static str {
        match self {
            Mutant::IndexZero => "index-zero",
            Mutant::IndexNext => "index-next",
            Mutant::IndexBroadcast => "index-broadcast",
            Mutant::BaseDropped => "base-dropped",
            Mutant::ElementZero => "element-zero",
            Mutant::StrideDouble => "stride-double",
            Mutant::SamplerNext => "sampler-next",
            Mutant::TlasOther => "tlas-other",
            Mutant::ValueBits => "value-bits",
        }
    }

    /// The driver-bug class the mutant emulates, in a driver engineer's words.
    pub fn emulates(self) -> &'static str {
        match self {
            Mutant::IndexZero => "the descriptor index dropped: the array's first descriptor is read",
            Mutant::IndexNext => "an off-by-one descriptor offset: the next descriptor is read",
            Mutant::IndexBroadcast => "a non-uniform descriptor index treated as uniform: every lane reads the first active lane's descriptor",
            Mutant::BaseDropped => "a runtime base lost from base + custom index",
            Mutant::ElementZero => "the element offset inside one descriptor lost (buffer element, array layer)",
            Mutant::StrideDouble => "the heap / descriptor-buffer offset computed with a wrong stride (twice the descriptor size, kept inside the array)",
            Mutant::SamplerNext => "the wrong sampler descriptor",
            Mutant::TlasOther => "an acceleration structure address resolved to another TLAS",
            Mutant::ValueBits => "a corrupted result word (low bits flipped; probe values are exact, so beyond any tolerance)",
        }
    }
}

/// Parse `--mutant NAME[,NAME…]` values: every name must be a mutant's.
pub fn parse_list(s: &str) -> Result<Vec<Mutant>, String> {
    s.split(',')
        .map(str::trim)
        .filter(|n| !n.is_empty())
        .map(|n| {
            Mutant::parse(n)
                .ok_or_else(|| format!("unknown mutant {n:?}; use {}", Mutant::NAMES.join(", ")))
        })
        .collect()
}

/// A (cell, mutant) pair's verdict in the kill matrix.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MutantStatus {
    /// The mutant ran and the cell's comparison flagged it (a `mismatch`).
    Killed,
    /// The mutant ran and passed.
    Survived,
    /// Not applicable: the reference predicts the same records (e.g. a broadcast of a literal index).
    Equivalent,
    /// Not applicable: the probe has nothing this mutant rewrites (e.g. no sampler index).
    NoTarget,
    /// The mutant crashed, lost the device or timed out: reported apart, never a kill.
    Fault,
    /// rtprobe could not run it (an error, the device lacks what it needs, the run stopped).
    NotRun,
}

impl MutantStatus {
    pub const ALL: &'static [MutantStatus] = &[
        MutantStatus::Killed,
        MutantStatus::Survived,
        MutantStatus::Equivalent,
        MutantStatus::NoTarget,
        MutantStatus::Fault,
        MutantStatus::NotRun,
    ];

    pub fn as_str(self) -> &'static str {
        match self {
            MutantStatus::Killed => "killed",
            MutantStatus::Survived => "survived",
            MutantStatus::Equivalent => "not applicable: equivalent",
            MutantStatus::NoTarget => "not applicable: no target",
            MutantStatus::Fault => "fault",
            MutantStatus::NotRun => "not run",
        }
    }

    /// The mutant applied to the cell: it ran and the reference predicted other records.
    pub fn applicable(self) -> bool {
        match self {
            MutantStatus::Killed | MutantStatus::Survived | MutantStatus::Fault => true,
            MutantStatus::Equivalent | MutantStatus::NoTarget | MutantStatus::NotRun => false,
        }
    }
}

/// One cell of the kill matrix.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MutantEntry {
    /// The unmutated cell's id (the mutant cell's is this with `.mutant-<name>`).
    pub cell: String,
    pub mutant: Mutant,
    pub status: MutantStatus,
    /// Why, in words: the outcome's detail, what was predicted, or why nothing was run.
    pub why: String,
    /// The mutant attempt's outcome (absent when none ran).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub outcome: Option<Outcome>,
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub prediction: Option<MutantPrediction>,
    /// A survivor the reference says the comparison must flag: a defect of the probe.
    #[serde(skip_serializing_if = "std::ops::Not::not", default)]
    pub probe_defect: bool,
    /// A survivor the cell's rule allows (its read is undefined): the spec rule (VUID, version).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub allowed_by: Option<String>,
    #[serde(default)]
    pub wall_ms: f64,
}

/// Per mutant: how many cells it was tried on and what became of it.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct MutantCounts {
    /// Cells it was considered for.
    pub cells: usize,
    /// Ran, and the reference predicted other records (killed + survived + faults).
    pub applicable: usize,
    pub killed: usize,
    pub survived: usize,
    /// Of the survivors, those the cell's rule allows (undefined reads).
    pub allowed: usize,
    /// Of the survivors, those the reference says must be caught: probe defects.
    pub probe_defects: usize,
    pub equivalent: usize,
    pub no_target: usize,
    pub faults: usize,
    pub not_run: usize,
}

impl MutantCounts {
    /// Count `e`.
    pub fn add(&mut self, e: &MutantEntry) {
        self.cells += 1;
        self.applicable += usize::from(e.status.applicable());
        match e.status {
            MutantStatus::Killed => self.killed += 1,
            MutantStatus::Survived => self.survived += 1,
            MutantStatus::Equivalent => self.equivalent += 1,
            MutantStatus::NoTarget => self.no_target += 1,
            MutantStatus::Fault => self.faults += 1,
            MutantStatus::NotRun => self.not_run += 1,
        }
        self.allowed += usize::from(e.allowed_by.is_some());
        self.probe_defects += usize::from(e.probe_defect);
    }

    /// Killed among the applicable mutants that must be caught (survivors the rule allows left
    /// out), as a fraction; `None` when there is none.
    pub fn kill_rate(&self) -> Option<f64> {
        let must = self.killed + self.probe_defects;
        (must > 0).then(|| self.killed as f64 / must as f64)
    }
}

/// The report's kill matrix (`run --mutants`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MutantReport {
    /// The mutants asked for.
    pub mutants: Vec<Mutant>,
    /// `--mutants-sample N:SEED` as given (absent: every pair).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub sample: Option<String>,
    /// Per mutant (by name).
    pub counts: BTreeMap<String, MutantCounts>,
    /// Wall time of the mutants round.
    pub wall_ms: f64,
    /// The kill matrix, cell by cell in plan order, mutants in [`Mutant::ALL`] order.
    pub entries: Vec<MutantEntry>,
}

impl MutantReport {
    /// Recount [`MutantReport::counts`] from the entries.
    pub fn recount(&mut self) {
        let mut counts: BTreeMap<String, MutantCounts> =
            self.mutants.iter().map(|m| (m.as_str().to_string(), Default::default())).collect();
        for e in &self.entries {
            counts.entry(e.mutant.as_str().to_string()).or_default().add(e);
        }
        self.counts = counts;
    }

    /// Survivors the reference says must be caught: defects of the probe.
    pub fn probe_defects(&self) -> impl Iterator<Item = &MutantEntry> {
        self.entries.iter().filter(|e| e.probe_defect)
    }

    /// All counts added up.
    pub fn total(&self) -> MutantCounts {
        let mut t = MutantCounts::default();
        for e in &self.entries {
            t.add(e);
        }
        t
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_match_serde() {
        assert_eq!(Mutant::ALL.len(), Mutant::NAMES.len());
        for (m, n) in Mutant::ALL.iter().zip(Mutant::NAMES) {
            assert_eq!(m.as_str(), *n);
            assert_eq!(Mutant::parse(n), Some(*m));
            assert_eq!(serde_json::to_value(m).unwrap(), serde_json::json!(n));
        }
        assert_eq!(
            parse_list("index-zero, value-bits").unwrap(),
            [Mutant::IndexZero, Mutant::ValueBits]
        );
        assert!(parse_list("index-zero,index-one").unwrap_err().contains("index-one"));
    }

    fn entry(mutant: Mutant, status: MutantStatus, defect: bool, allowed: bool) -> MutantEntry {
        MutantEntry {
            cell: "c".into(),
            mutant,
            status,
            why: String::new(),
            outcome: None,
            prediction: None,
            probe_defect: defect,
            allowed_by: allowed.then(|| "VUID".into()),
            wall_ms: 0.0,
        }
    }

    #[test]
    fn counts_split_applicable_from_not_applicable_and_faults_from_kills() {
        let mut r = MutantReport {
            mutants: vec![Mutant::IndexZero, Mutant::SamplerNext],
            entries: vec![
                entry(Mutant::IndexZero, MutantStatus::Killed, false, false),
                entry(Mutant::IndexZero, MutantStatus::Survived, true, false),
                entry(Mutant::IndexZero, MutantStatus::Survived, false, true),
                entry(Mutant::IndexZero, MutantStatus::Fault, false, false),
                entry(Mutant::IndexZero, MutantStatus::Equivalent, false, false),
                entry(Mutant::SamplerNext, MutantStatus::NoTarget, false, false),
            ],
            ..Default::default()
        };
        r.recount();
        let z = &r.counts["index-zero"];
        assert_eq!(
            (z.cells, z.applicable, z.killed, z.survived, z.allowed, z.probe_defects, z.faults),
            (5, 4, 1, 2, 1, 1, 1)
        );
        assert_eq!(z.equivalent, 1);
        // A fault is applicable but no kill: the rate is over what must be caught.
        assert_eq!(z.kill_rate(), Some(0.5));
        assert_eq!(r.counts["sampler-next"].no_target, 1);
        assert_eq!(r.counts["sampler-next"].kill_rate(), None);
        assert_eq!(r.probe_defects().count(), 1);
        assert_eq!(r.total().cells, 6);
    }
}
