//! The statistics every verdict is judged by (bisection, workaround passes, GPU-AV, a cell's
//! incidence). How sure bisection is of a verdict: the one-sided Clopper–Pearson lower bound on a faulting
//! cell's fault rate, and the chance that a passing cell's attempts all missed a fault of at least
//! that rate.
//!
//! Clopper & Pearson (1934): for `k` faults in `n` independent attempts, the lower `1 - alpha`
//! bound is the `p` at which `k` or more faults have probability exactly `alpha`,
//! `P(X >= k | n, p) = alpha`. That tail is the regularized incomplete beta `I_p(k, n - k + 1)`,
//! so the bound is the `alpha` quantile of `Beta(k, n - k + 1)`; for integer parameters the tail is
//! a finite binomial sum, computed here in log space and inverted by bisection (it rises
//! monotonically in `p`). Closed forms it must meet: `k = n` gives `alpha^(1/n)`, `k = 1` gives
//! `1 - (1 - alpha)^(1/n)`, `k = 0` gives 0.

/// The confidence of every bound bisection prints (`p >= x at 95%`).
pub const CONFIDENCE: f64 = 0.95;

/// The miss probability below which a pass counts (bisection's default `--max-miss`, a
/// verified workaround).
pub const DEFAULT_MAX_MISS: f64 = 0.01;

/// `P(X >= k)` for `X ~ Binomial(n, p)`.
pub fn binomial_tail(k: u32, n: u32, p: f64) -> f64 {
    if k == 0 {
        return 1.0;
    }
    if k > n || p <= 0.0 {
        return 0.0;
    }
    if p >= 1.0 {
        return 1.0;
    }
    let (lp, lq) = (p.ln(), (1.0 - p).ln());
    // ln C(n, j), built up term by term from ln C(n, k).
    let mut lc: f64 = (0..k).map(|i| ((n - i) as f64).ln() - ((i + 1) as f64).ln()).sum();
    let mut sum = 0.0;
    for j in k..=n {
        sum += (lc + j as f64 * lp + (n - j) as f64 * lq).exp();
        if j < n {
            lc += ((n - j) as f64).ln() - ((j + 1) as f64).ln();
        }
    }
    sum.min(1.0)
}

/// The `alpha` quantile of `Beta(a, b)` for integer `a >= 1`, `b >= 1`: the `x` with
/// `I_x(a, b) = alpha`, through `I_x(a, b) = P(X >= a)` for `X ~ Binomial(a + b - 1, x)`.
pub fn beta_quantile_int(alpha: f64, a: u32, b: u32) -> f64 {
    let n = a + b - 1;
    let (mut lo, mut hi) = (0.0f64, 1.0f64);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if binomial_tail(a, n, mid) < alpha {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo < 1e-15 {
            break;
        }
    }
    0.5 * (lo + hi)
}

/// The one-sided Clopper–Pearson lower bound on the fault rate of a cell that faulted `k` of `n`
/// attempts, at confidence `1 - alpha`.
pub fn cp_lower(k: u32, n: u32, alpha: f64) -> f64 {
    match (k, n) {
        (0, _) | (_, 0) => 0.0,
        (k, n) if k >= n => alpha.powf(1.0 / n as f64),
        (k, n) => beta_quantile_int(alpha, k, n - k + 1),
    }
}

/// [`cp_lower`] at [`CONFIDENCE`].
pub fn rate_bound(k: u32, n: u32) -> f64 {
    cp_lower(k, n, 1.0 - CONFIDENCE)
}

/// The chance that `n` independent attempts all miss (pass) a fault of rate `p`: `(1 - p)^n`
/// (binomial, independent attempts; `p` clamped to [0, 1]).
pub fn miss(p: f64, n: u32) -> f64 {
    (1.0 - p.clamp(0.0, 1.0)).powi(n as i32)
}

/// The chance that `passes` passing attempts would all have missed a fault as frequent as a
/// finding that faulted `faulted` of `attempts` times: `(1 - bound)^passes`, `bound` the
/// finding's Clopper–Pearson lower rate bound ([`rate_bound`]).
pub fn pass_miss(faulted: u32, attempts: u32, passes: u32) -> f64 {
    miss(rate_bound(faulted, attempts), passes)
}

/// Passes held to a finding, in words: proven when they would have missed a fault as frequent
/// as the finding's with probability below [`DEFAULT_MAX_MISS`] (`passes (19 of 19; a fault as
/// frequent as this finding's would be missed with p ≤ 0.009)`), else `not proven (2 passes;
/// need 19 for 99%)`; without a finding to hold them to, `passes (2 of 2)`.
pub fn passes_text(passed: u32, attempts: u32, miss_probability: Option<f64>) -> String {
    match miss_probability {
        Some(m) if m < DEFAULT_MAX_MISS => format!("passes ({passed} of {attempts}; a fault as frequent as this finding's would be missed with p ≤ {m:.3})"),
        Some(m) => format!(
            "not proven ({passed} pass{}; need {} for {:.0}%)",
            if passed == 1 { "" } else { "es" },
            needed_passes(passed, m),
            100.0 * (1.0 - DEFAULT_MAX_MISS)
        ),
        None => format!("passes ({passed} of {attempts})"),
    }
}

/// The passes that prove what `passed` passes with miss probability `miss` do not: the rate
/// bound they were held to is `1 - miss^(1/passed)` (`miss = (1 - bound)^passed`), and
/// [`attempts_needed`] at [`DEFAULT_MAX_MISS`] follows from it. No pass: unknown (shown as 0).
pub fn needed_passes(passed: u32, miss: f64) -> u32 {
    if passed == 0 {
        return 0;
    }
    let bound = 1.0 - miss.clamp(0.0, 1.0).powf(1.0 / passed as f64);
    attempts_needed(bound, DEFAULT_MAX_MISS, 10_000)
}

/// Attempts a pass needs so that a fault of rate at least `p` would have shown with probability
/// above `1 - max_miss` (`(1 - p)^n < max_miss`), capped at `cap`; `cap` when `p` is 0.
pub fn attempts_needed(p: f64, max_miss: f64, cap: u32) -> u32 {
    if p >= 1.0 {
        return 1;
    }
    if p <= 0.0 {
        return cap;
    }
    let mut n = (max_miss.ln() / (1.0 - p).ln()).ceil().max(1.0) as u32;
    // ceil() lands on equality when the ratio is whole; the rule is strict.
    while miss(p, n) >= max_miss {
        n += 1;
    }
    n.min(cap)
}

/// The one-sided Clopper–Pearson upper bound on the fault rate of `k` faults in `n` attempts, at
/// confidence `1 - alpha`: the `p` at which `k` or fewer faults have probability `alpha`
/// (`1 - cp_lower(n - k, n, alpha)` by symmetry; 1 when `k = n`).
pub fn cp_upper(k: u32, n: u32, alpha: f64) -> f64 {
    if n == 0 || k >= n {
        return 1.0;
    }
    1.0 - cp_lower(n - k, n, alpha)
}

/// Fisher's exact test, one-sided: the chance that `k` or more of the `n` attempts of a run fault
/// when its attempts and `n0` earlier ones (`k0` faulted) share one fault rate — given the
/// `k + k0` faults, how they fall is hypergeometric. Small: the run's rate rose.
pub fn fisher_greater(k: u32, n: u32, k0: u32, n0: u32) -> f64 {
    let (total, faults) = (n + n0, k + k0);
    let ln_choose = |a: u32, b: u32| -> f64 {
        if b > a {
            return f64::NEG_INFINITY;
        }
        let b = b.min(a - b);
        (0..b).map(|i| ((a - i) as f64).ln() - ((i + 1) as f64).ln()).sum()
    };
    let denom = ln_choose(total, n);
    let top = faults.min(n);
    let p: f64 = (k..=top)
        .map(|j| (ln_choose(faults, j) + ln_choose(total - faults, n - j) - denom).exp())
        .sum();
    p.min(1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn upper_bounds_and_fishers_test_meet_their_closed_forms() {
        // k = 0: 1 - alpha^(1/n); the 95% bound of 1 of 8 ≈ 0.4707 (P(X <= 1) = 0.05 there).
        assert!((cp_upper(0, 8, 0.05) - (1.0 - 0.05f64.powf(1.0 / 8.0))).abs() < 1e-9);
        let p = cp_upper(1, 8, 0.05);
        assert!((1.0 - binomial_tail(2, 8, p) - 0.05).abs() < 1e-9 && (0.47..0.471).contains(&p));
        assert_eq!(cp_upper(3, 3, 0.05), 1.0);
        // 6 faults of 6 against 1 of 8: all 7 faults in the 6-attempt group of 14 has chance
        // C(7, 6)·C(7, 0) / C(14, 6) = 7/3003.
        assert!((fisher_greater(6, 6, 1, 8) - 7.0 / 3003.0).abs() < 1e-12);
        assert!((fisher_greater(0, 5, 2, 5) - 1.0).abs() < 1e-12);
        // The same rate twice is no evidence of a rise.
        assert!(fisher_greater(3, 8, 3, 8) > 0.3);
    }

    #[test]
    fn a_pass_against_a_flaky_finding_carries_its_miss_probability() {
        // 3 of 10: bound ≈ 0.087, so 2 passes miss it with p ≈ 0.83 — the text says so.
        let m = pass_miss(3, 10, 2);
        assert!((m - (1.0 - rate_bound(3, 10)).powi(2)).abs() < 1e-12 && m > 0.5, "{m}");
        // Not proven: as many passes as attempts_needed says for the finding's bound.
        let need = attempts_needed(rate_bound(3, 10), DEFAULT_MAX_MISS, 10_000);
        assert_eq!(
            passes_text(2, 2, Some(m)),
            format!("not proven (2 passes; need {need} for 99%)")
        );
        assert_eq!(needed_passes(2, m), need);
        // With that many passes it is proven, and the text says the miss probability.
        let proven = pass_miss(3, 10, need);
        assert!(proven < DEFAULT_MAX_MISS);
        assert!(passes_text(need, need, Some(proven)).starts_with(&format!(
            "passes ({need} of {need}; a fault as frequent as this finding's would be missed with p ≤ 0.0"
        )));
        // One pass less is not.
        assert!(passes_text(need - 1, need - 1, Some(pass_miss(3, 10, need - 1)))
            .starts_with("not proven"));
        // 2 of 2 faulted: the bound is sqrt(0.05) ≈ 0.22, so 2 passes (p ≈ 0.60) need 19.
        assert_eq!(
            passes_text(2, 2, Some(pass_miss(2, 2, 2))),
            "not proven (2 passes; need 19 for 99%)"
        );
        assert_eq!(
            passes_text(1, 1, Some(pass_miss(2, 2, 1))),
            "not proven (1 pass; need 19 for 99%)"
        );
        // More passes, smaller miss; a finding that always faulted needs fewer.
        assert!(pass_miss(3, 10, 40) < 0.05 && pass_miss(10, 10, 2) < m);
        assert_eq!(passes_text(2, 2, None), "passes (2 of 2)");
    }

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol
    }

    #[test]
    fn closed_forms_hold() {
        for n in 1..=40 {
            assert!(close(cp_lower(n, n, 0.05), 0.05f64.powf(1.0 / n as f64), 1e-15));
            assert_eq!(cp_lower(0, n, 0.05), 0.0);
            // k = 1: P(X >= 1) = 1 - (1 - p)^n = alpha. (n = 1 is the k = n form.)
            if n > 1 {
                assert!(
                    close(cp_lower(1, n, 0.05), 1.0 - 0.95f64.powf(1.0 / n as f64), 1e-12),
                    "1 of {n}"
                );
            }
        }
    }

    #[test]
    fn published_values() {
        // 5 of 10: the two-sided 95% Clopper–Pearson interval is (0.1871, 0.8129), so the
        // one-sided 97.5% lower bound is 0.1871; the two-sided 90% interval starts at 0.2224.
        assert!(close(cp_lower(5, 10, 0.025), 0.1871, 5e-5), "{}", cp_lower(5, 10, 0.025));
        assert!(close(cp_lower(5, 10, 0.05), 0.2224, 5e-5), "{}", cp_lower(5, 10, 0.05));
        // 1 of 10, two-sided 95%: the interval starts at 0.0025.
        assert!(close(cp_lower(1, 10, 0.025), 0.0025, 5e-5));
    }

    #[test]
    fn every_k_of_a_table_meets_the_defining_equation() {
        // The k = 0..n table: the bound's tail is alpha, it rises with k, and it stays below k/n.
        for n in [1u32, 2, 6, 10, 25, 50] {
            let mut last = -1.0;
            for k in 0..=n {
                let p = rate_bound(k, n);
                if k > 0 {
                    assert!(
                        close(binomial_tail(k, n, p), 0.05, 1e-9),
                        "{k} of {n}: tail {}",
                        binomial_tail(k, n, p)
                    );
                }
                assert!(p > last, "{k} of {n}: {p} after {last}");
                assert!(p <= k as f64 / n as f64, "{k} of {n}: {p}");
                last = p;
            }
        }
    }

    #[test]
    fn the_beta_quantile_is_symmetric() {
        // Beta(a, b) at alpha mirrors Beta(b, a) at 1 - alpha.
        for (a, b) in [(1, 1), (2, 5), (7, 3), (10, 10)] {
            assert!(
                close(beta_quantile_int(0.05, a, b), 1.0 - beta_quantile_int(0.95, b, a), 1e-9),
                "{a},{b}"
            );
        }
        // Beta(1, 1) is uniform.
        assert!(close(beta_quantile_int(0.3, 1, 1), 0.3, 1e-12));
    }

    #[test]
    fn binomial_tail_sums_the_mass() {
        assert!(close(binomial_tail(1, 3, 0.5), 7.0 / 8.0, 1e-15));
        assert!(close(binomial_tail(2, 4, 0.5), 11.0 / 16.0, 1e-15));
        assert_eq!(binomial_tail(5, 4, 0.5), 0.0);
        assert_eq!(binomial_tail(0, 4, 0.1), 1.0);
    }

    #[test]
    fn attempts_needed_is_the_first_n_below_the_threshold() {
        for p in [0.05, 0.2224, 0.5, 0.5493, 0.9] {
            let n = attempts_needed(p, 0.01, 1000);
            assert!(miss(p, n) < 0.01 && miss(p, n - 1) >= 0.01 || n == 1, "{p}: {n}");
        }
        // The rule is strict: 0.5^2 = 0.25 is not below 0.25.
        assert_eq!(attempts_needed(0.5, 0.25, 50), 3);
        assert_eq!(attempts_needed(1.0, 0.01, 50), 1);
        assert_eq!(attempts_needed(0.0, 0.01, 50), 50);
        assert_eq!(attempts_needed(0.01, 0.01, 50), 50);
    }
}
