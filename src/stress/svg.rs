//! A hand-written SVG of the `far` case: maximum relative t error and maximum barycentric error
//! (log scale) against the distance the scene was moved to (log scale), one line per mode
//! (instance transform, baked vertices, rays from the origin). No plotting dependency.
use super::evaluate::CaseResult;

const W: f64 = 640.0;
const H: f64 = 400.0;
const L: f64 = 70.0;
const R: f64 = 150.0;
const T: f64 = 30.0;
const B: f64 = 50.0;

/// (series name, colour, dash, [(distance, error)]).
type Series = (String, &'static str, &'static str, Vec<(f64, f64)>);

fn series(far: &CaseResult) -> Vec<Series> {
    let mut out: Vec<Series> = Vec::new();
    for (mode, colour) in super::cases::FAR_MODES.into_iter().zip(["#1f77b4", "#d62728", "#9467bd"]) {
        let pts = |f: &dyn Fn(&super::evaluate::Metrics) -> Option<f64>| -> Vec<(f64, f64)> {
            far.parts
                .iter()
                .filter(|p| p.label.starts_with(mode))
                .filter_map(|p| Some((p.distance?.max(1.0), f(&p.metrics)?)))
                .collect()
        };
        out.push((format!("{mode}: t rel."), colour, "", pts(&|m| m.t_rel_err_max)));
        out.push((format!("{mode}: bary"), colour, "6,4", pts(&|m| m.bary_err_max)));
    }
    out
}

/// The SVG document, or `None` when `far` has no compared hits.
pub fn far_plot(far: &CaseResult, device: &str) -> Option<String> {
    let all = series(far);
    let floor = 1e-10f64;
    let ys: Vec<f64> = all.iter().flat_map(|s| s.3.iter().map(|p| p.1.max(floor))).collect();
    if ys.is_empty() {
        return None;
    }
    let (ylo, yhi) = (ys.iter().cloned().fold(f64::MAX, f64::min).log10().floor(), ys.iter().cloned().fold(f64::MIN, f64::max).log10().ceil().max(-2.0));
    let ylo = ylo.min(yhi - 1.0);
    let (xlo, xhi) = (0.0f64, 7.0f64);
    let x = |d: f64| L + (d.log10() - xlo) / (xhi - xlo) * (W - L - R);
    let y = |v: f64| T + (yhi - v.max(floor).log10()) / (yhi - ylo) * (H - T - B);
    let mut s = format!("<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{W}\" height=\"{H}\" font-family=\"sans-serif\" font-size=\"11\">\n");
    s.push_str(&format!("<rect width=\"{W}\" height=\"{H}\" fill=\"white\"/>\n"));
    s.push_str(&format!("<text x=\"{L}\" y=\"18\" font-size=\"13\">rtprobe stress far: error vs distance — {}</text>\n", xml(device)));
    for e in 0..=7 {
        let px = x(10f64.powi(e));
        s.push_str(&format!("<line x1=\"{px:.1}\" y1=\"{T}\" x2=\"{px:.1}\" y2=\"{:.1}\" stroke=\"#ddd\"/>\n", H - B));
        s.push_str(&format!("<text x=\"{px:.1}\" y=\"{:.1}\" text-anchor=\"middle\">1e{e}</text>\n", H - B + 15.0));
    }
    let mut e = ylo as i32;
    while e <= yhi as i32 {
        let py = y(10f64.powi(e));
        s.push_str(&format!("<line x1=\"{L}\" y1=\"{py:.1}\" x2=\"{:.1}\" y2=\"{py:.1}\" stroke=\"#ddd\"/>\n", W - R));
        s.push_str(&format!("<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"end\">1e{e}</text>\n", L - 5.0, py + 4.0));
        e += 1;
    }
    // The matrix tolerance (1e-3, relative t and barycentrics).
    let tol = y(1e-3);
    s.push_str(&format!("<line x1=\"{L}\" y1=\"{tol:.1}\" x2=\"{:.1}\" y2=\"{tol:.1}\" stroke=\"#2ca02c\" stroke-dasharray=\"2,3\"/>\n", W - R));
    s.push_str(&format!("<text x=\"{:.1}\" y=\"{:.1}\" fill=\"#2ca02c\">tolerance 1e-3</text>\n", W - R + 5.0, tol + 4.0));
    s.push_str(&format!("<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\">distance of the scene from the origin (distance 0 drawn at 1)</text>\n", (L + W - R) / 2.0, H - 12.0));
    s.push_str(&format!("<text x=\"14\" y=\"{:.1}\" transform=\"rotate(-90 14 {:.1})\" text-anchor=\"middle\">max error (log)</text>\n", (T + H - B) / 2.0, (T + H - B) / 2.0));
    for (k, (name, colour, dash, pts)) in all.iter().enumerate() {
        let path: Vec<String> = pts.iter().map(|&(d, v)| format!("{:.1},{:.1}", x(d), y(v))).collect();
        s.push_str(&format!("<polyline fill=\"none\" stroke=\"{colour}\" stroke-width=\"2\" stroke-dasharray=\"{dash}\" points=\"{}\"/>\n", path.join(" ")));
        for &(d, v) in pts {
            s.push_str(&format!("<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"2.5\" fill=\"{colour}\"/>\n", x(d), y(v)));
        }
        let ly = T + 10.0 + 16.0 * k as f64;
        s.push_str(&format!("<line x1=\"{:.1}\" y1=\"{ly:.1}\" x2=\"{:.1}\" y2=\"{ly:.1}\" stroke=\"{colour}\" stroke-width=\"2\" stroke-dasharray=\"{dash}\"/>\n", W - R + 8.0, W - R + 30.0));
        s.push_str(&format!("<text x=\"{:.1}\" y=\"{:.1}\">{}</text>\n", W - R + 34.0, ly + 4.0, xml(name)));
    }
    s.push_str("</svg>\n");
    Some(s)
}

fn xml(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;")
}
