//! The `far` case's plot: maximum relative t error and maximum barycentric error (log scale)
//! against the distance the scene was moved to (log scale), one colour per mode (instance
//! transform, baked vertices, rays from the origin), drawn with [`crate::report::chart`].
use super::evaluate::CaseResult;
use crate::report::chart::{Axis, LineChart, Series, Style};

/// Errors below this are drawn at it (a log axis has no 0).
const FLOOR: f64 = 1e-10;

fn series(far: &CaseResult) -> Vec<Series> {
    let mut out = Vec::new();
    for (k, mode) in super::far::FAR_MODES.into_iter().enumerate() {
        let pts = |f: &dyn Fn(&super::evaluate::Metrics) -> Option<f64>| -> Vec<(f64, f64)> {
            far.parts
                .iter()
                .filter(|p| p.label.starts_with(mode))
                .filter_map(|p| Some((p.distance?.max(1.0), f(&p.metrics)?.max(FLOOR))))
                .collect()
        };
        out.push(Series {
            name: format!("{mode}: t rel."),
            points: pts(&|m| m.t_rel_err_max),
            style: Style::Line,
            colour: k,
        });
        out.push(Series {
            name: format!("{mode}: bary"),
            points: pts(&|m| m.bary_err_max),
            style: Style::Dashed,
            colour: k,
        });
    }
    out
}

/// The SVG document, or `None` when `far` has no compared hits.
pub fn far_plot(far: &CaseResult, device: &str) -> Option<String> {
    let series = series(far);
    if series.iter().all(|s| s.points.is_empty()) {
        return None;
    }
    let chart = LineChart {
        title: format!("rtprobe stress far: error vs distance — {device}"),
        x: Axis {
            label: "distance of the scene from the origin (distance 0 drawn at 1)".into(),
            log: true,
            range: Some((1.0, 1e7)),
        },
        y: Axis {
            label: "max error (relative t, absolute barycentric; log)".into(),
            log: true,
            range: None,
        },
        series,
        // The matrix tolerance (1e-3, relative t and barycentrics).
        hlines: vec![(1e-3, "tolerance 1e-3".into())],
        vlines: vec![],
    };
    Some(chart.svg())
}
