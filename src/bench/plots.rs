//! The plots of `rtprobe bench`, drawn from its `bench.json` value with [`crate::report::chart`]:
//! detection against size (measured points, binomial curves), matrix time against size,
//! detection against repeats of flaky faults, and the per-phase time of each sweep entry.
use crate::report::chart::{Axis, LineChart, Series, StackedBars, Style};
use serde_json::Value;

fn f(v: &Value) -> f64 {
    v.as_f64().unwrap_or(f64::NAN)
}

fn arr(v: &Value) -> &[Value] {
    v.as_array().map(|a| a.as_slice()).unwrap_or(&[])
}

/// Every plot: (file name, SVG).
pub fn all(bench: &Value) -> Vec<(String, String)> {
    let device = bench["device"]["name"].as_str().unwrap_or("device");
    if bench.get("cells").is_some() {
        return vec![("time-vs-cells.svg".into(), cells(bench, device))];
    }
    let default_px = bench["default"]["size"].as_f64().map(|s| s * s);
    vec![
        ("detection-vs-size.svg".into(), detection(bench, device, default_px)),
        ("time-vs-size.svg".into(), time(bench, device, default_px)),
        ("flaky-repeats.svg".into(), flaky(bench, device)),
        ("sweep-phases.svg".into(), sweep(bench, device)),
        ("mutants-kills.svg".into(), mutants(bench, device)),
    ]
}

/// Time against distinct cells: each series' points and its fitted line.
fn cells(b: &Value, device: &str) -> String {
    let pts = arr(&b["cells"]["points"]);
    let mut series = vec![];
    for (k, (key, fit, name)) in [
        (
            "first_wall_s",
            "fit_first",
            if b["cells"]["cold"] == true { "first run (cold caches)" } else { "first run" },
        ),
        ("again_wall_s", "fit_again", "again (warm)"),
    ]
    .into_iter()
    .enumerate()
    {
        let points: Vec<(f64, f64)> = pts.iter().map(|p| (f(&p["cells"]), f(&p[key]))).collect();
        let fitted = &b["cells"][fit];
        let (ms, fixed, r2) = (f(&fitted["per_cell_ms"]), f(&fitted["fixed_s"]), f(&fitted["r2"]));
        let line = points.iter().map(|&(x, _)| (x, fixed + ms / 1e3 * x)).collect();
        series.push(Series { name: name.into(), points, style: Style::Points, colour: k });
        series.push(Series {
            name: format!("{ms:.2} ms/cell + {fixed:.2} s, R² {r2:.4}"),
            points: line,
            style: Style::Dashed,
            colour: k,
        });
    }
    LineChart {
        title: format!("rtprobe run: time against distinct cells (--cells-scale) — {device}"),
        x: Axis { label: "cells run, each with its own pipeline".into(), log: false, range: None },
        y: Axis { label: "wall time of the run (s)".into(), log: false, range: None },
        series,
        hlines: vec![],
        vlines: vec![],
    }
    .svg()
}

fn default_line(px: Option<f64>) -> Vec<(f64, String)> {
    px.map(|p| vec![(p, format!("default {}×{}", p.sqrt(), p.sqrt()))]).unwrap_or_default()
}

fn detection(b: &Value, device: &str, default_px: Option<f64>) -> String {
    let pooled = arr(&b["detection"]["pooled"]);
    let mut series = vec![];
    for (k, fr) in arr(&b["detection"]["fractions"]).iter().enumerate() {
        let pts = |key: &str| {
            pooled
                .iter()
                .filter(|p| p["fraction"] == *fr)
                .map(|p| (f(&p["pixels"]), f(&p["detection"][key])))
                .collect::<Vec<_>>()
        };
        series.push(Series {
            name: format!("measured f={fr}"),
            points: pts("measured"),
            style: Style::Points,
            colour: k,
        });
        series.push(Series {
            name: format!("1-(1-f)^n, f={fr}"),
            points: pts("predicted"),
            style: Style::Dashed,
            colour: k,
        });
    }
    LineChart {
        title: format!("Detection of a wrong value on a fraction f of records — {device}"),
        x: Axis {
            label: "image size (pixels = rays per cell, log)".into(),
            log: true,
            range: None,
        },
        y: Axis {
            label: "share of injected cells caught".into(),
            log: false,
            range: Some((0.0, 1.0)),
        },
        series,
        hlines: vec![],
        vlines: default_line(default_px),
    }
    .svg()
}

fn time(b: &Value, device: &str, default_px: Option<f64>) -> String {
    let pts = arr(&b["size_time"]["points"]);
    let line = |name: &str, get: &dyn Fn(&Value) -> f64, k: usize, style: Style| Series {
        name: name.into(),
        points: pts.iter().map(|p| (f(&p["pixels"]), get(p))).collect(),
        style,
        colour: k,
    };
    let phase = |name: &'static str| move |p: &Value| f(&p["estimated"]["phases_ms"][name]) / 1e3;
    LineChart {
        title: format!("Matrix time against image size — {device}"),
        x: Axis { label: "image size (pixels, log)".into(), log: true, range: None },
        y: Axis {
            label: "time (s, log; sums over cells for phases)".into(),
            log: true,
            range: None,
        },
        series: vec![
            line("wall (estimated for samples)", &|p| f(&p["estimated"]["wall_s"]), 0, Style::Line),
            line("trace", &phase("trace"), 1, Style::Dashed),
            line("check (readback + compare)", &phase("check"), 2, Style::Dashed),
            line("pipeline", &phase("pipeline"), 3, Style::Dashed),
            line("compile", &phase("compile"), 4, Style::Dashed),
        ],
        hlines: vec![],
        vlines: default_line(default_px),
    }
    .svg()
}

fn flaky(b: &Value, device: &str) -> String {
    let mut series = vec![];
    for (k, p) in arr(&b["flaky"]["points"]).iter().enumerate() {
        let curve = |key: &str| {
            arr(&p[key]).iter().enumerate().map(|(i, v)| ((i + 1) as f64, f(v))).collect::<Vec<_>>()
        };
        series.push(Series {
            name: format!("measured P={}", p["probability"]),
            points: curve("measured"),
            style: Style::Line,
            colour: k,
        });
        series.push(Series {
            name: format!("1-(1-P)^r, P={}", p["probability"]),
            points: curve("predicted"),
            style: Style::Dashed,
            colour: k,
        });
    }
    LineChart {
        title: format!("Flaky faults: detection against attempts — {device}"),
        x: Axis { label: "attempts r (repeats)".into(), log: false, range: None },
        y: Axis {
            label: "share of cells that faulted within r attempts".into(),
            log: false,
            range: Some((0.0, 1.0)),
        },
        series,
        hlines: vec![(0.95, "95%".into()), (0.99, "99%".into())],
        vlines: vec![],
    }
    .svg()
}

fn sweep(b: &Value, device: &str) -> String {
    let ran: Vec<&Value> =
        arr(&b["sweep"]["entries"]).iter().filter(|e| e["skipped"].is_null()).collect();
    StackedBars {
        title: format!("Where the time goes, per run configuration — {device}"),
        y_label: "time summed over cells and workers (s)".into(),
        x_label: "extra run arguments (wall time)".into(),
        categories: ran
            .iter()
            .map(|e| format!("{} ({:.1} s)", e["args"].as_str().unwrap_or(""), f(&e["wall_s"])))
            .collect(),
        layers: super::PHASES
            .iter()
            .map(|ph| (ph.to_string(), ran.iter().map(|e| f(&e["phases_ms"][*ph]) / 1e3).collect()))
            .collect(),
    }
    .svg()
}

/// Part 4 at its largest size: per mutant, its applicable pairs killed, survived as the cell's
/// rule allows, survived as probe defects, and faults.
fn mutants(b: &Value, device: &str) -> String {
    let points = arr(&b["mutants"]["points"]);
    let last = points.iter().max_by_key(|p| p["size"].as_u64().unwrap_or(0));
    let per = last.and_then(|p| p["counts"]["per_mutant"].as_object()).cloned().unwrap_or_default();
    let count = |m: &Value, k: &str| m["counts"][k].as_f64().unwrap_or(0.0);
    let layer = |name: &str, key: &str| {
        (name.to_string(), per.values().map(|m| count(m, key)).collect::<Vec<f64>>())
    };
    StackedBars {
        title: format!(
            "Emulated driver bugs caught, per mutant ({}×{}) — {device}",
            last.map(|p| f(&p["size"])).unwrap_or(0.0),
            last.map(|p| f(&p["size"])).unwrap_or(0.0)
        ),
        y_label: "applicable (cell, mutant) pairs".into(),
        x_label: "mutant".into(),
        categories: per.keys().cloned().collect(),
        layers: vec![
            layer("killed", "killed"),
            layer("survived, allowed by the cell's rule", "allowed"),
            layer("survived: probe defect", "probe_defects"),
            layer("fault (not a kill)", "faults"),
        ],
    }
    .svg()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::report::chart::check_well_formed;
    use serde_json::json;

    #[test]
    fn plots_of_a_bench_value_are_well_formed_and_name_their_series() {
        let b = json!({
            "device": { "name": "llvmpipe" },
            "default": { "size": 64 },
            "detection": { "fractions": [0.01, 1.0], "pooled": [
                { "size": 8, "pixels": 64, "fraction": 0.01, "detection": { "measured": 0.5, "predicted": 0.47 } },
                { "size": 64, "pixels": 4096, "fraction": 0.01, "detection": { "measured": 1.0, "predicted": 1.0 } },
                { "size": 8, "pixels": 64, "fraction": 1.0, "detection": { "measured": 1.0, "predicted": 1.0 } } ] },
            "size_time": { "points": [ { "pixels": 64, "estimated": { "wall_s": 1.0, "phases_ms": { "trace": 300.0, "check": 1.0, "pipeline": 20.0, "compile": 5.0 } } } ] },
            "flaky": { "points": [ { "probability": 0.5, "measured": [0.4, 0.8], "predicted": [0.5, 0.75] } ] },
            "sweep": { "entries": [ { "args": "-j 1", "wall_s": 2.0, "phases_ms": { "trace": 1000.0 } }, { "args": "-j 1 --threads 2", "skipped": "unknown" } ] },
            "mutants": { "points": [ { "size": 16, "counts": { "per_mutant": { "index-next": { "counts": { "killed": 5, "allowed": 2, "probe_defects": 0, "faults": 1 } } } } } ] },
        });
        let plots = all(&b);
        assert_eq!(plots.len(), 5);
        assert!(plots[4].1.contains("index-next") && plots[4].1.contains("probe defect"));
        for (name, svg) in &plots {
            check_well_formed(svg).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert!(svg.contains("llvmpipe"), "{name}");
        }
        assert!(
            plots[0].1.contains("measured f=0.01")
                && plots[0].1.contains("1-(1-f)^n, f=1.0")
                && plots[0].1.contains("default 64×64")
        );
        assert!(plots[2].1.contains("measured P=0.5") && plots[2].1.contains("99%"));
        assert!(
            plots[3].1.contains("-j 1 (2.0 s)") && !plots[3].1.contains("--threads"),
            "skipped entries are not drawn"
        );
    }
}
