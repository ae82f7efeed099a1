//! The statistics of `rtprobe bench`: the binomial predictions it measures against, the repeats
//! a flaky fault needs, Wilson intervals for measured rates, and the aggregation of one
//! detection point's cells.
use serde::{Deserialize, Serialize};

/// The chance that at least one of `n` independent trials fires when each fires with `p`:
/// `1 - (1 - p)^n`. A wrong value on a fraction `f` of the records, `n` records checked: the
/// chance the cell is caught; a flaky fault of rate `p`, `n` attempts: the chance it shows.
pub fn detect_probability(p: f64, n: u64) -> f64 {
    let p = p.clamp(0.0, 1.0);
    if p >= 1.0 {
        return if n > 0 { 1.0 } else { 0.0 };
    }
    // ln1p keeps small p accurate at large n.
    1.0 - (n as f64 * (-p).ln_1p()).exp()
}

/// The fewest attempts `r` with `1 - (1 - p)^r >= confidence`: `ceil(ln(1 - c) / ln(1 - p))`.
/// `None` for p = 0 (never) and `Some(1)` for p = 1.
#[allow(clippy::neg_cmp_op_on_partial_ord)] // `!(p > 0.0)` also turns away NaN
pub fn repeats_needed(p: f64, confidence: f64) -> Option<u32> {
    if !(p > 0.0) {
        return None;
    }
    if p >= 1.0 || confidence <= 0.0 {
        return Some(1);
    }
    let r = ((1.0 - confidence).ln() / (-p).ln_1p()).ceil();
    // Guard the ceiling against rounding just above a whole number.
    let r = (r as u32).max(1);
    Some(if r > 1 && detect_probability(p, (r - 1) as u64) >= confidence { r - 1 } else { r })
}

/// The Wilson score interval (95%, z = 1.96) of `k` successes in `n` trials.
pub fn wilson(k: usize, n: usize) -> (f64, f64) {
    if n == 0 {
        return (0.0, 1.0);
    }
    let (k, n, z) = (k as f64, n as f64, 1.96f64);
    let p = k / n;
    let d = 1.0 + z * z / n;
    let c = (p + z * z / (2.0 * n)) / d;
    let h = z * (p * (1.0 - p) / n + z * z / (4.0 * n * n)).sqrt() / d;
    ((c - h).max(0.0), (c + h).min(1.0))
}

/// One injected cell of a detection point.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Trial {
    pub cell: String,
    /// Records the wrong value could be caught on (`comparison.probe_checked`).
    pub n: u64,
    /// The cell's outcome was a finding (a mismatch).
    pub detected: bool,
    /// Records that mismatched.
    pub mismatched: u64,
}

/// Measured against predicted detection over a point's trials.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Detection {
    pub trials: usize,
    pub detected: usize,
    pub measured: f64,
    /// Wilson 95% interval of `measured`.
    pub ci95: (f64, f64),
    /// Mean over the trials of `1 - (1 - f)^n`.
    pub predicted: f64,
    pub n_min: u64,
    pub n_mean: f64,
    pub n_max: u64,
    /// Mismatched records over checked ones (≈ f).
    pub corrupted_share: f64,
}

pub fn aggregate(f: f64, trials: &[Trial]) -> Detection {
    let k = trials.iter().filter(|t| t.detected).count();
    let n = trials.len();
    let checked: u64 = trials.iter().map(|t| t.n).sum();
    Detection {
        trials: n,
        detected: k,
        measured: if n > 0 { k as f64 / n as f64 } else { 0.0 },
        ci95: wilson(k, n),
        predicted: if n > 0 {
            trials.iter().map(|t| detect_probability(f, t.n)).sum::<f64>() / n as f64
        } else {
            0.0
        },
        n_min: trials.iter().map(|t| t.n).min().unwrap_or(0),
        n_mean: if n > 0 { checked as f64 / n as f64 } else { 0.0 },
        n_max: trials.iter().map(|t| t.n).max().unwrap_or(0),
        corrupted_share: if checked > 0 {
            trials.iter().map(|t| t.mismatched).sum::<u64>() as f64 / checked as f64
        } else {
            0.0
        },
    }
}

/// For each r in 1..=rounds: the share of cells that faulted in at least one of their first r
/// attempts. `faulted[c][i]`: cell c's attempt i faulted.
pub fn first_fault_curve(faulted: &[Vec<bool>], rounds: usize) -> Vec<f64> {
    (1..=rounds)
        .map(|r| {
            let hit = faulted.iter().filter(|a| a.iter().take(r).any(|f| *f)).count();
            if faulted.is_empty() {
                0.0
            } else {
                hit as f64 / faulted.len() as f64
            }
        })
        .collect()
}

/// For each r in 1..=rounds: the share of all windows of r consecutive attempts (every cell,
/// every start) holding at least one fault. Attempts are independent, so every window estimates
/// the same probability as the first r attempts, from many more (overlapping) samples.
pub fn window_curve(faulted: &[Vec<bool>], rounds: usize) -> Vec<f64> {
    (1..=rounds)
        .map(|r| {
            let (mut hit, mut all) = (0usize, 0usize);
            for a in faulted.iter().filter(|a| a.len() >= r) {
                for w in a.windows(r) {
                    all += 1;
                    hit += usize::from(w.iter().any(|f| *f));
                }
            }
            if all == 0 {
                0.0
            } else {
                hit as f64 / all as f64
            }
        })
        .collect()
}

/// The first r (1-based) at which `curve` reaches `confidence`.
pub fn first_reaching(curve: &[f64], confidence: f64) -> Option<u32> {
    curve.iter().position(|v| *v >= confidence).map(|i| i as u32 + 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn binomial_prediction() {
        assert!((detect_probability(0.5, 2) - 0.75).abs() < 1e-15);
        assert!((detect_probability(0.01, 100) - (1.0 - 0.99f64.powi(100))).abs() < 1e-12);
        assert_eq!(detect_probability(0.1, 0), 0.0);
        assert_eq!(detect_probability(1.0, 1), 1.0);
        assert_eq!(detect_probability(1.0, 0), 0.0);
        assert_eq!(detect_probability(0.0, 1000), 0.0);
        // Small f at large n: ln1p keeps it exact (1 - e^{-n f} for f → 0).
        let p = detect_probability(1e-9, 1_000_000);
        assert!((p - (1.0 - (-1e-3f64).exp())).abs() < 1e-9, "{p}");
    }

    #[test]
    fn repeats_needed_formula() {
        // 1 - 0.5^5 = 0.969 >= 0.95, 1 - 0.5^4 = 0.9375 < 0.95.
        assert_eq!(repeats_needed(0.5, 0.95), Some(5));
        assert_eq!(repeats_needed(0.5, 0.99), Some(7));
        assert_eq!(repeats_needed(0.1, 0.95), Some(29));
        assert_eq!(repeats_needed(0.1, 0.99), Some(44));
        assert_eq!(repeats_needed(0.3, 0.95), Some(9));
        assert_eq!(repeats_needed(1.0, 0.99), Some(1));
        assert_eq!(repeats_needed(0.0, 0.99), None);
        // Exactly on the boundary: 1 - 0.5^1 = 0.5.
        assert_eq!(repeats_needed(0.5, 0.5), Some(1));
        for p in [0.05, 0.1, 0.2, 0.3, 0.5, 0.7] {
            for c in [0.9, 0.95, 0.99] {
                let r = repeats_needed(p, c).unwrap();
                assert!(
                    detect_probability(p, r as u64) >= c
                        && (r == 1 || detect_probability(p, r as u64 - 1) < c),
                    "p {p} c {c} r {r}"
                );
            }
        }
    }

    #[test]
    fn wilson_interval() {
        let (lo, hi) = wilson(50, 100);
        assert!((lo - 0.4038).abs() < 1e-3 && (hi - 0.5962).abs() < 1e-3, "{lo} {hi}");
        let (lo, hi) = wilson(10, 10);
        assert!(hi == 1.0 && lo > 0.69 && lo < 0.73, "{lo}");
        assert_eq!(wilson(0, 0), (0.0, 1.0));
        assert_eq!(wilson(0, 10).0, 0.0);
    }

    #[test]
    fn aggregation_of_trials() {
        let t = |n, detected, mismatched| Trial { cell: "c".into(), n, detected, mismatched };
        let d = aggregate(0.5, &[t(1, true, 1), t(2, false, 0), t(0, false, 0), t(3, true, 2)]);
        assert_eq!((d.trials, d.detected), (4, 2));
        assert_eq!(d.measured, 0.5);
        assert!((d.predicted - (0.5 + 0.75 + 0.0 + 0.875) / 4.0).abs() < 1e-12);
        assert_eq!((d.n_min, d.n_max), (0, 3));
        assert!((d.n_mean - 1.5).abs() < 1e-12);
        assert!((d.corrupted_share - 0.5).abs() < 1e-12);
        let empty = aggregate(0.1, &[]);
        assert_eq!((empty.trials, empty.measured, empty.predicted), (0, 0.0, 0.0));
    }

    #[test]
    fn first_fault_curve_counts_cells_by_their_first_fault() {
        let f = vec![
            vec![true, false, false],
            vec![false, false, true],
            vec![false, false, false],
            vec![false, true, true],
        ];
        let c = first_fault_curve(&f, 3);
        assert_eq!(c, vec![0.25, 0.5, 0.75]);
        assert_eq!(first_reaching(&c, 0.5), Some(2));
        assert_eq!(first_reaching(&c, 0.95), None);
        assert!(first_fault_curve(&[], 2).iter().all(|v| *v == 0.0));
        // Windows: r=1 is the fault rate (4 of 12), r=3 the whole sequences (3 of 4).
        let w = window_curve(&f, 3);
        assert!((w[0] - 4.0 / 12.0).abs() < 1e-12 && (w[2] - 0.75).abs() < 1e-12, "{w:?}");
        // r=2: windows [t,f] [f,f] | [f,f] [f,t] | [f,f] [f,f] | [f,t] [t,t] → 4 of 8.
        assert!((w[1] - 0.5).abs() < 1e-12, "{w:?}");
    }
}
