//! Fault injection (`run --inject-fault 'PREDICATE[@KIND]'`): the generated shaders of every
//! cell whose axes match PREDICATE really misbehave at the probed read. This is how rtprobe's own
//! tests prove that each verdict can fail, and how a user proves detection on their own driver.
//!
//! PREDICATE has the `--filter` syntax (`axis=value[|value…]` terms joined by `,`). KIND:
//! - `device` (default): a load through an invalid device address, a real fault for the driver
//!   to report (`device_lost`, or `crash` on CPU drivers, or a hang where the driver spins);
//! - `hang`: an endless loop (the supervisor's deadline must fire);
//! - `value[:F[:SEED]]`: a wrong value on a fraction F of the probed pixels (default 1). The
//!   pixels are those whose hash (of the pixel and a salt) falls below F·2³²; without SEED the
//!   salt is 0 (the same pixels for every cell), with SEED each cell gets its own salt
//!   ([`value_salt`]: SEED and the cell id), so the cells of one run are independent draws
//!   (`rtprobe bench` measures detection against the binomial prediction with it);
//! - `nan`: the probed value's first component becomes a quiet NaN;
//! - `flaky:P`: the `device` fault, armed with probability P per attempt (the worker rolls a
//!   seeded die and arms the load through push constants; the roll is recorded).
//!
//! Injections never apply to canaries; the first matching injection wins.
use super::{Cell, Filter, FilterError};
use serde::{Deserialize, Serialize};

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum FaultKind {
    Device,
    Hang,
    Value {
        fraction: f64,
        /// Salts the pixel hash per cell (`value:F:SEED`); `None`: salt 0.
        #[serde(skip_serializing_if = "Option::is_none", default)]
        seed: Option<u64>,
    },
    Nan,
    Flaky {
        probability: f64,
    },
}

/// An `--inject-fault` that does not parse.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum InjectError {
    /// `what`: the argument ("value fraction", "flaky probability").
    #[error("{what} {arg:?} is not a number")]
    NotANumber { what: &'static str, arg: String },
    /// `close`: the interval's closing bracket, `)` or `]`.
    #[error("{what} must be in (0, 1{close}, got {arg}")]
    OutOfRange { what: &'static str, close: &'static str, arg: String },
    #[error("fault kind {kind:?} takes no argument (got {arg:?})")]
    TakesNoArgument { kind: String, arg: String },
    #[error("value seed {0:?} is not a whole number (value:F:SEED)")]
    Seed(String),
    #[error("flaky needs a probability: flaky:P with P in (0, 1)")]
    FlakyWithoutProbability,
    #[error("unknown fault kind {0:?}; kinds: device, hang, value[:F], nan, flaky:P")]
    UnknownKind(String),
    /// The cells' predicate (before `@`) is no filter.
    #[error("--inject-fault {spec:?}: {}", .filter.to_string().replace("--filter", "the predicate"))]
    Predicate { spec: String, filter: FilterError },
}

impl FaultKind {
    pub fn parse(s: &str) -> Result<FaultKind, InjectError> {
        let (name, arg) = match s.split_once(':') {
            Some((n, a)) => (n.trim(), Some(a.trim())),
            None => (s.trim(), None),
        };
        let fraction = |what: &'static str, a: &str, open_top: bool| -> Result<f64, InjectError> {
            let v: f64 = a.parse().map_err(|_| InjectError::NotANumber { what, arg: a.into() })?;
            let ok = v > 0.0 && if open_top { v < 1.0 } else { v <= 1.0 };
            if !ok {
                return Err(InjectError::OutOfRange {
                    what,
                    close: if open_top { ")" } else { "]" },
                    arg: a.into(),
                });
            }
            Ok(v)
        };
        let no_arg = |k: FaultKind| match arg {
            None => Ok(k),
            Some(a) => Err(InjectError::TakesNoArgument { kind: name.into(), arg: a.into() }),
        };
        match name {
            "device" => no_arg(FaultKind::Device),
            "hang" => no_arg(FaultKind::Hang),
            "nan" => no_arg(FaultKind::Nan),
            "value" => {
                let (f, seed) = match arg.map(|a| {
                    a.split_once(':').map(|(f, s)| (f.trim(), Some(s.trim()))).unwrap_or((a, None))
                }) {
                    Some((f, seed)) => (fraction("value fraction", f, false)?, seed),
                    None => (1.0, None),
                };
                let seed = seed
                    .map(|s| s.parse::<u64>().map_err(|_| InjectError::Seed(s.into())))
                    .transpose()?;
                Ok(FaultKind::Value { fraction: f, seed })
            }
            "flaky" => match arg {
                Some(a) => {
                    Ok(FaultKind::Flaky { probability: fraction("flaky probability", a, true)? })
                }
                None => Err(InjectError::FlakyWithoutProbability),
            },
            other => Err(InjectError::UnknownKind(other.into())),
        }
    }

    pub fn label(&self) -> String {
        match self {
            FaultKind::Device => "device".into(),
            FaultKind::Hang => "hang".into(),
            FaultKind::Value { fraction, seed: None } => format!("value:{fraction}"),
            FaultKind::Value { fraction, seed: Some(s) } => format!("value:{fraction}:{s}"),
            FaultKind::Nan => "nan".into(),
            FaultKind::Flaky { probability } => format!("flaky:{probability}"),
        }
    }

    /// The injected shader reads through `pc.badAddress` (the worker pushes the address).
    pub fn reads_bad_address(&self) -> bool {
        match self {
            FaultKind::Device | FaultKind::Flaky { .. } => true,
            FaultKind::Hang | FaultKind::Value { .. } | FaultKind::Nan => false,
        }
    }
}

/// One `--inject-fault` argument, parsed.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Injection {
    /// As the user wrote it (normalised kind).
    pub spec: String,
    pub predicate: Filter,
    pub fault: FaultKind,
}

impl Injection {
    pub fn parse(s: &str) -> Result<Injection, InjectError> {
        let s = s.trim();
        let (pred, kind) = match s.rsplit_once('@') {
            Some((p, k)) => (p, FaultKind::parse(k)?),
            None => (s, FaultKind::Device),
        };
        let predicate = Filter::parse(pred)
            .map_err(|filter| InjectError::Predicate { spec: s.into(), filter })?;
        Ok(Injection { spec: format!("{}@{}", pred.trim(), kind.label()), predicate, fault: kind })
    }

    pub fn matches(&self, cell: &Cell) -> bool {
        cell.canary.is_none() && self.predicate.matches(cell)
    }
}

/// What was injected into one attempt.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct InjectedFault {
    /// The `--inject-fault` argument that matched.
    pub spec: String,
    pub fault: FaultKind,
    /// For `flaky:P`: whether this attempt's die armed the fault.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub armed: Option<bool>,
    /// The worker's dice seed (with the cell id it replays the roll).
    pub seed: u64,
}

/// The fault `cell` gets in an attempt run by a worker whose dice seed is `seed`: the worker
/// and the supervisor both call this, so the report knows the roll even when the worker died.
pub fn roll(injections: &[Injection], cell: &Cell, seed: u64) -> Option<InjectedFault> {
    let i = for_cell(injections, cell)?;
    let armed = match i.fault {
        FaultKind::Flaky { probability } => Some(flaky_fires(probability, seed, &cell.id())),
        FaultKind::Device | FaultKind::Hang | FaultKind::Value { .. } | FaultKind::Nan => None,
    };
    Some(InjectedFault { spec: i.spec.clone(), fault: i.fault, armed, seed })
}

/// The injection that applies to `cell` (the first that matches), if any.
pub fn for_cell<'a>(injections: &'a [Injection], cell: &Cell) -> Option<&'a Injection> {
    injections.iter().find(|i| i.matches(cell))
}

/// Whether a flaky injection fires for this attempt: a die rolled from `seed` (the worker's,
/// recorded in the result) and the cell id, so a reported attempt can be replayed.
pub fn flaky_fires(probability: f64, seed: u64, cell_id: &str) -> bool {
    ((mix(seed, cell_id) >> 11) as f64 / (1u64 << 53) as f64) < probability
}

/// The pixel-hash salt of a `value:F` injection in `cell_id` (pushed as `pc.injectSalt`): 0
/// without a seed (every cell corrupts the same pixels), else a hash of the seed and the cell id
/// (never 0), so each cell of a run draws its own pixels.
pub fn value_salt(fault: FaultKind, cell_id: &str) -> u32 {
    match fault {
        FaultKind::Value { seed: Some(s), .. } => ((mix(s, cell_id) >> 32) as u32).max(1),
        FaultKind::Value { seed: None, .. }
        | FaultKind::Device
        | FaultKind::Hang
        | FaultKind::Nan
        | FaultKind::Flaky { .. } => 0,
    }
}

/// FNV-1a of the cell id over the seed, then the splitmix64 finaliser.
fn mix(seed: u64, cell_id: &str) -> u64 {
    let mut h: u64 = seed ^ 0x9e37_79b9_7f4a_7c15;
    for b in cell_id.bytes() {
        h = (h ^ b as u64).wrapping_mul(0x0100_0000_01b3);
    }
    h = (h ^ (h >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    h = (h ^ (h >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    h ^ (h >> 31)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{Canary, DescriptorModel, IndexSource, Resource, Stage};

    fn cell(stage: Stage, index: IndexSource) -> Cell {
        Cell::new(stage, Resource::StorageBuffer, index, DescriptorModel::DescriptorIndexing)
    }

    #[test]
    fn parses_every_kind_and_rejects_nonsense() {
        let i = Injection::parse("stage=closest_hit|any_hit,index=dynamic").unwrap();
        assert_eq!(i.fault, FaultKind::Device);
        assert_eq!(i.spec, "stage=closest_hit|any_hit,index=dynamic@device");
        assert_eq!(Injection::parse("stage=raygen@hang").unwrap().fault, FaultKind::Hang);
        assert_eq!(
            Injection::parse("stage=raygen@value:0.01").unwrap().fault,
            FaultKind::Value { fraction: 0.01, seed: None }
        );
        assert_eq!(
            Injection::parse("stage=raygen@value").unwrap().fault,
            FaultKind::Value { fraction: 1.0, seed: None }
        );
        let seeded = Injection::parse("stage=raygen@value:0.01:7").unwrap();
        assert_eq!(
            (seeded.fault, seeded.spec.as_str()),
            (FaultKind::Value { fraction: 0.01, seed: Some(7) }, "stage=raygen@value:0.01:7")
        );
        assert_eq!(Injection::parse("stage=raygen@nan").unwrap().fault, FaultKind::Nan);
        assert_eq!(
            Injection::parse("stage=raygen@flaky:0.5").unwrap().fault,
            FaultKind::Flaky { probability: 0.5 }
        );
        for bad in [
            "stage=raygen@flaky",
            "stage=raygen@flaky:1",
            "stage=raygen@value:0",
            "stage=raygen@value:x",
            "stage=raygen@value:0.5:x",
            "stage=raygen@value:0.5:-1",
            "stage=raygen@boom",
            "stage=nope@hang",
            "@hang",
            "stage=raygen@hang:3",
        ] {
            assert!(Injection::parse(bad).is_err(), "{bad} should not parse");
        }
    }

    #[test]
    fn errors_say_what_is_wrong() {
        let msg = |s: &str| Injection::parse(s).unwrap_err().to_string();
        assert_eq!(msg("stage=raygen@flaky:1"), "flaky probability must be in (0, 1), got 1");
        assert_eq!(msg("stage=raygen@value:2"), "value fraction must be in (0, 1], got 2");
        assert_eq!(msg("stage=raygen@value:x"), "value fraction \"x\" is not a number");
        assert_eq!(msg("stage=raygen@hang:3"), "fault kind \"hang\" takes no argument (got \"3\")");
        assert_eq!(
            msg("stage=raygen@value:0.5:x"),
            "value seed \"x\" is not a whole number (value:F:SEED)"
        );
        assert_eq!(
            msg("stage"),
            "--inject-fault \"stage\": filter term \"stage\" is not axis=value"
        );
        assert!(
            msg("colour=red@hang").contains("in the predicate; axes: "),
            "{}",
            msg("colour=red@hang")
        );
    }

    #[test]
    fn matches_by_predicate_never_canaries() {
        let i = Injection::parse("stage=closest_hit,index=dynamic@hang").unwrap();
        assert!(i.matches(&cell(Stage::ClosestHit, IndexSource::Dynamic)));
        assert!(!i.matches(&cell(Stage::ClosestHit, IndexSource::Literal)));
        assert!(!i.matches(&cell(Stage::Raygen, IndexSource::Dynamic)));
        let all = Injection::parse("canary=none|invalid_address@hang").unwrap();
        assert!(!all.matches(&Cell::canary(Canary::InvalidAddress)));
        let list = [i.clone(), Injection::parse("stage=closest_hit@nan").unwrap()];
        assert_eq!(
            for_cell(&list, &cell(Stage::ClosestHit, IndexSource::Dynamic)).unwrap().fault,
            FaultKind::Hang
        );
        assert_eq!(
            for_cell(&list, &cell(Stage::ClosestHit, IndexSource::Literal)).unwrap().fault,
            FaultKind::Nan
        );
    }

    #[test]
    fn flaky_die_has_the_asked_rate() {
        let n = 20_000;
        let fired = (0..n)
            .filter(|s| {
                flaky_fires(0.3, *s, "closest_hit.storage_buffer.dynamic.descriptor_indexing")
            })
            .count();
        let rate = fired as f64 / n as f64;
        assert!((rate - 0.3).abs() < 0.02, "rate {rate}");
        // Deterministic for the same seed and cell.
        assert_eq!(flaky_fires(0.5, 7, "a"), flaky_fires(0.5, 7, "a"));
    }

    #[test]
    fn value_salt_is_zero_without_a_seed_and_differs_per_cell_with_one() {
        let plain = FaultKind::Value { fraction: 0.1, seed: None };
        assert_eq!(value_salt(plain, "a"), 0);
        let seeded = FaultKind::Value { fraction: 0.1, seed: Some(3) };
        assert_ne!(value_salt(seeded, "a"), 0);
        assert_ne!(value_salt(seeded, "a"), value_salt(seeded, "b"));
        assert_ne!(
            value_salt(seeded, "a"),
            value_salt(FaultKind::Value { fraction: 0.1, seed: Some(4) }, "a")
        );
        assert_eq!(value_salt(seeded, "a"), value_salt(seeded, "a"));
        assert_eq!(value_salt(FaultKind::Nan, "a"), 0);
    }
}
