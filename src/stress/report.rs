//! The stress report: a table per case on the terminal, and the JSON document
//! (`"schema": "rtprobe.stress/2"`) with the tolerances it was judged by. Schema 2 (issue 22):
//! margins in ray space, `ambiguous` rays counted, double hits split into warnings (outside
//! the margin) and `double_hits_in_margin`, verdict `warn`; `excluded` (column `excl`): the
//! ambiguous rays where a miss would be no leak. Schema 3 (issue 22's leftovers): an example's
//! `reference` is the reference's answer (the closest triangle holding the f64 crossing, with
//! `reference_instance`), not the candidate with the smallest t; its triangles' `vertices` are
//! in world space (under a transform with `object_vertex_bits` and `transform_bits`), and role
//! `expected` labels the answer.
use super::evaluate::{self, CaseResult, Metrics, Verdict};
use serde_json::{json, Value};

fn opt(x: Option<f64>) -> String {
    match x {
        None => "-".into(),
        Some(0.0) => "0".into(),
        Some(v) if (1e-3..1e4).contains(&v.abs()) => format!("{v:.3}"),
        Some(v) => format!("{v:.2e}"),
    }
}

fn row(label: &str, m: &Metrics) -> String {
    format!(
        "  {:<18} {:>6} {:>6} {:>6} {:>6} {:>5} {:>5} {:>5} {:>6} {:>6} {:>5} {:>10} {:>10} {:>10} {:>10}\n",
        label,
        m.rays,
        m.hits,
        m.ambiguous,
        m.excluded,
        m.leaks,
        m.false_hits,
        m.wrong_hits,
        m.double_hits,
        m.over_tolerance,
        m.self_hits,
        opt(m.t_err_max_ulps),
        opt(m.t_err_p99),
        opt(m.t_rel_err_max),
        opt(m.bary_err_max)
    )
}

/// The terminal tables: one per case, one row per part and a total row.
pub fn text(device: &str, cases: &[CaseResult]) -> String {
    let mut s = format!("rtprobe stress on {device}\n");
    for c in cases {
        s.push_str(&format!("\n{} — {}", c.name, c.verdict.as_str()));
        if let Some(d) = &c.detail {
            s.push_str(&format!(": {d}"));
        }
        s.push_str(&format!(" ({:.0} ms)\n", c.ms));
        if c.parts.is_empty() {
            continue;
        }
        s.push_str(&format!(
            "  {:<18} {:>6} {:>6} {:>6} {:>6} {:>5} {:>5} {:>5} {:>6} {:>6} {:>5} {:>10} {:>10} {:>10} {:>10}\n",
            "part", "rays", "hits", "ambig", "excl", "leak", "false", "wrong", "double", "overtol", "self", "t_ulps_max", "t_ulps_p99", "t_rel_max", "bary_max"
        ));
        for p in &c.parts {
            s.push_str(&row(&p.label, &p.metrics));
        }
        s.push_str(&row("total", &c.metrics));
        if !c.examples.is_empty() {
            s.push_str(&format!("  examples ({}):\n", c.examples.len()));
            s.push_str(&super::examples::text(&c.examples));
        }
    }
    let failed = cases.iter().filter(|c| !c.verdict.passed()).count();
    let warned = cases.iter().filter(|c| c.verdict == Verdict::Warn).count();
    let missing: Vec<&str> = cases
        .iter()
        .filter(|c| c.verdict == Verdict::NotImplemented)
        .map(|c| c.name.as_str())
        .collect();
    s.push_str(&format!(
        "\n{} cases, {} not passed, {} with warnings",
        cases.len(),
        failed,
        warned
    ));
    if !missing.is_empty() {
        s.push_str(&format!(", not implemented: {}", missing.join(", ")));
    }
    s.push('\n');
    s
}

/// The JSON report; `validation` is (layer active, errors it reported during the run).
pub fn json(
    device: &Value,
    tracer: &str,
    seed: u64,
    full: bool,
    validation: (bool, u64),
    cases: &[CaseResult],
) -> Value {
    json!({
        "schema": "rtprobe.stress/3",
        "rtprobe_version": env!("CARGO_PKG_VERSION"),
        "device": device,
        "tracer": tracer,
        "seed": seed,
        "full": full,
        "validation": { "active": validation.0, "errors": validation.1 },
        "tolerances": {
            "t_rel": evaluate::T_REL_TOL,
            "bary": evaluate::BARY_TOL,
            "ulps_of_scale": evaluate::ULPS_OF_SCALE,
            "t_eps": evaluate::T_EPS,
            "rule": "ray space: position error abs = ulps_of_scale*(ulp(S_object) + ulp(S_world)*|d_object|/|d_world|), product error rel = ulps_of_scale*f32_epsilon; margin of weight k = (abs*(|B|+|C|) + rel*|B||C|)/|det| for the edge (B, C) opposite vertex k in ray space (≈ abs/h_k, h_k its ray-space altitude); |db| <= bary + sum of the margins, |dt| <= t_rel*t + abs/|d_object| + sum_k margin_k*|t_k - t|; a hit off the triangle is a wrong hit: t outside [min t_k, max t_k] widened by t_eps*t + abs/|d_object| (+ the reference's own outside weights times the range), or a weight below -(margin_k + 4 f32 eps); S = max |coordinate| of ray origin, hit point and triangle; fail: leaks, false/wrong hits, duplicate any-hits, over tolerance, facing errors; warn: double hits outside the margins",
        },
        "cases": cases,
    })
}

/// Exit status of the command: every implemented case passed (warnings pass).
pub fn all_passed(cases: &[CaseResult]) -> bool {
    cases.iter().all(|c| c.verdict.passed())
}
