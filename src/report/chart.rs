//! Hand-written SVG charts (no plotting dependency): line charts with linear or log axes
//! ([`LineChart`]) and stacked bars ([`StackedBars`]), each with a title, axis labels with units
//! and a legend. Used by `rtprobe bench` and `rtprobe stress --svg`.

const W: f64 = 720.0;
const H: f64 = 420.0;
const L: f64 = 72.0;
const R: f64 = 210.0;
const T: f64 = 34.0;
const B: f64 = 62.0;
const PALETTE: [&str; 10] = [
    "#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2", "#7f7f7f",
    "#bcbd22", "#17becf",
];

/// The colour of palette entry `k` (wraps).
pub fn colour(k: usize) -> &'static str {
    PALETTE[k % PALETTE.len()]
}

#[derive(Clone, Debug, Default)]
pub struct Axis {
    /// With its unit, e.g. `time (s)`.
    pub label: String,
    pub log: bool,
    /// Fixed range; `None`: from the data.
    pub range: Option<(f64, f64)>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Style {
    /// Points joined by a solid line, with markers.
    Line,
    /// A dashed line without markers (predictions).
    Dashed,
    /// Markers only.
    Points,
}

#[derive(Clone, Debug)]
pub struct Series {
    pub name: String,
    pub points: Vec<(f64, f64)>,
    pub style: Style,
    /// Palette index (measured and predicted series of one parameter share it).
    pub colour: usize,
}

#[derive(Clone, Debug, Default)]
pub struct LineChart {
    pub title: String,
    pub x: Axis,
    pub y: Axis,
    pub series: Vec<Series>,
    /// Horizontal reference lines: (y, label).
    pub hlines: Vec<(f64, String)>,
    /// Vertical reference lines: (x, label).
    pub vlines: Vec<(f64, String)>,
}

/// A mapping from data to pixels along one axis, and its ticks.
struct Scale {
    lo: f64,
    hi: f64,
    log: bool,
    p0: f64,
    p1: f64,
}

impl Scale {
    fn new(axis: &Axis, values: impl Iterator<Item = f64>, p0: f64, p1: f64) -> Scale {
        let vals: Vec<f64> = values.filter(|v| v.is_finite() && (!axis.log || *v > 0.0)).collect();
        let (mut lo, mut hi) = axis.range.unwrap_or_else(|| {
            (
                vals.iter().cloned().fold(f64::INFINITY, f64::min),
                vals.iter().cloned().fold(f64::NEG_INFINITY, f64::max),
            )
        });
        if !lo.is_finite() || !hi.is_finite() {
            (lo, hi) = if axis.log { (1.0, 10.0) } else { (0.0, 1.0) };
        }
        if axis.log {
            lo = lo.max(1e-300).log10().floor();
            hi = hi.max(1e-300).log10().ceil();
            if hi <= lo {
                hi = lo + 1.0;
            }
        } else {
            if axis.range.is_none() {
                lo = lo.min(0.0);
                let step = nice_step(hi - lo);
                hi = (hi / step).ceil() * step;
            }
            if hi <= lo {
                hi = lo + 1.0;
            }
        }
        Scale { lo, hi, log: axis.log, p0, p1 }
    }

    fn at(&self, v: f64) -> f64 {
        let v = if self.log { v.max(1e-300).log10() } else { v };
        self.p0 + (v - self.lo) / (self.hi - self.lo) * (self.p1 - self.p0)
    }

    /// (value, label) of each tick.
    fn ticks(&self) -> Vec<(f64, String)> {
        if self.log {
            let n = (self.hi - self.lo) as i32;
            let every = (n / 8).max(1);
            (self.lo as i32..=self.hi as i32)
                .step_by(every as usize)
                .map(|e| (10f64.powi(e), format_decade(e)))
                .collect()
        } else {
            let step = nice_step(self.hi - self.lo);
            let first = (self.lo / step).ceil() as i64;
            let last = (self.hi / step + 1e-9).floor() as i64;
            (first..=last).map(|k| (k as f64 * step, fmt_num(k as f64 * step))).collect()
        }
    }
}

fn format_decade(e: i32) -> String {
    match e {
        0 => "1".into(),
        1 => "10".into(),
        2 => "100".into(),
        3 => "1000".into(),
        -1 => "0.1".into(),
        -2 => "0.01".into(),
        -3 => "0.001".into(),
        e => format!("1e{e}"),
    }
}

/// A step of 1, 2 or 5 × 10^k giving 4 to 10 ticks over `span`.
fn nice_step(span: f64) -> f64 {
    let span = if span > 0.0 && span.is_finite() { span } else { 1.0 };
    let raw = span / 6.0;
    let mag = 10f64.powf(raw.log10().floor());
    [1.0, 2.0, 5.0, 10.0].iter().map(|m| m * mag).find(|s| *s >= raw).unwrap_or(10.0 * mag)
}

fn fmt_num(v: f64) -> String {
    let s = format!("{:.6}", v);
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" {
        "0".into()
    } else {
        s.into()
    }
}

pub fn xml(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

fn header(title: &str) -> String {
    let mut s = format!("<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{W}\" height=\"{H}\" viewBox=\"0 0 {W} {H}\" font-family=\"sans-serif\" font-size=\"11\">\n");
    s += &format!("<title>{}</title>\n", xml(title));
    s += &format!("<rect width=\"{W}\" height=\"{H}\" fill=\"white\"/>\n");
    s += &format!(
        "<text x=\"{L}\" y=\"20\" font-size=\"13\" font-weight=\"bold\">{}</text>\n",
        xml(title)
    );
    s
}

fn axis_labels(s: &mut String, x: &str, y: &str) {
    let (cx, cy) = ((L + W - R) / 2.0, (T + H - B) / 2.0);
    s.push_str(&format!(
        "<text x=\"{cx:.1}\" y=\"{:.1}\" text-anchor=\"middle\">{}</text>\n",
        H - 8.0,
        xml(x)
    ));
    s.push_str(&format!("<text x=\"16\" y=\"{cy:.1}\" transform=\"rotate(-90 16 {cy:.1})\" text-anchor=\"middle\">{}</text>\n", xml(y)));
    s.push_str(&format!("<rect x=\"{L}\" y=\"{T}\" width=\"{:.1}\" height=\"{:.1}\" fill=\"none\" stroke=\"#444\"/>\n", W - L - R, H - T - B));
}

/// One legend entry at row `k`: a line sample (dashed or not, with or without a marker) and the name.
fn legend(s: &mut String, k: usize, name: &str, colour: &str, style: Style) {
    let ly = T + 10.0 + 16.0 * k as f64;
    let (x0, x1) = (W - R + 10.0, W - R + 34.0);
    match style {
        Style::Line | Style::Dashed => {
            let dash = if style == Style::Dashed { " stroke-dasharray=\"6,4\"" } else { "" };
            s.push_str(&format!("<line x1=\"{x0:.1}\" y1=\"{ly:.1}\" x2=\"{x1:.1}\" y2=\"{ly:.1}\" stroke=\"{colour}\" stroke-width=\"2\"{dash}/>\n"));
        }
        Style::Points => {}
    }
    if style != Style::Dashed {
        s.push_str(&format!(
            "<circle cx=\"{:.1}\" cy=\"{ly:.1}\" r=\"3\" fill=\"{colour}\"/>\n",
            (x0 + x1) / 2.0
        ));
    }
    s.push_str(&format!(
        "<text x=\"{:.1}\" y=\"{:.1}\">{}</text>\n",
        x1 + 5.0,
        ly + 4.0,
        xml(name)
    ));
}

impl LineChart {
    pub fn svg(&self) -> String {
        let pts = || self.series.iter().flat_map(|s| s.points.iter());
        let xs = Scale::new(
            &self.x,
            pts().map(|p| p.0).chain(self.vlines.iter().map(|v| v.0)),
            L,
            W - R,
        );
        let ys = Scale::new(
            &self.y,
            pts().map(|p| p.1).chain(self.hlines.iter().map(|h| h.0)),
            H - B,
            T,
        );
        let mut s = header(&self.title);
        grid(&mut s, &xs, &ys);
        axis_labels(&mut s, &self.x.label, &self.y.label);
        self.reference_lines(&mut s, &xs, &ys);
        for (k, se) in self.series.iter().enumerate() {
            self.series_svg(&mut s, se, &xs, &ys);
            legend(&mut s, k, &se.name, colour(se.colour), se.style);
        }
        s + "</svg>\n"
    }

    /// The dotted horizontal and vertical reference lines, with their labels.
    fn reference_lines(&self, s: &mut String, xs: &Scale, ys: &Scale) {
        for (v, label) in &self.hlines {
            let py = ys.at(*v);
            *s += &format!("<line x1=\"{L}\" y1=\"{py:.1}\" x2=\"{:.1}\" y2=\"{py:.1}\" stroke=\"#555\" stroke-dasharray=\"2,3\"/>\n", W - R);
            *s += &format!(
                "<text x=\"{:.1}\" y=\"{:.1}\" fill=\"#555\" text-anchor=\"end\">{}</text>\n",
                W - R - 4.0,
                py - 3.0,
                xml(label)
            );
        }
        for (v, label) in &self.vlines {
            let px = xs.at(*v);
            *s += &format!("<line x1=\"{px:.1}\" y1=\"{T}\" x2=\"{px:.1}\" y2=\"{:.1}\" stroke=\"#555\" stroke-dasharray=\"2,3\"/>\n", H - B);
            *s += &format!(
                "<text x=\"{:.1}\" y=\"{:.1}\" fill=\"#555\">{}</text>\n",
                px + 3.0,
                T + 12.0,
                xml(label)
            );
        }
    }

    /// Series `se`: its line and markers, through the points both axes can show.
    fn series_svg(&self, s: &mut String, se: &Series, xs: &Scale, ys: &Scale) {
        let c = colour(se.colour);
        let visible: Vec<(f64, f64)> = se
            .points
            .iter()
            .copied()
            .filter(|&(x, y)| {
                x.is_finite()
                    && y.is_finite()
                    && (!self.x.log || x > 0.0)
                    && (!self.y.log || y > 0.0)
            })
            .collect();
        let path: Vec<String> =
            visible.iter().map(|&(x, y)| format!("{:.1},{:.1}", xs.at(x), ys.at(y))).collect();
        match se.style {
            Style::Line => *s += &format!("<polyline fill=\"none\" stroke=\"{c}\" stroke-width=\"2\" points=\"{}\"/>\n", path.join(" ")),
            Style::Dashed => *s += &format!("<polyline fill=\"none\" stroke=\"{c}\" stroke-width=\"1.5\" stroke-dasharray=\"6,4\" points=\"{}\"/>\n", path.join(" ")),
            Style::Points => {}
        }
        if se.style != Style::Dashed {
            for &(x, y) in &visible {
                *s += &format!(
                    "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"3\" fill=\"{c}\"/>\n",
                    xs.at(x),
                    ys.at(y)
                );
            }
        }
    }
}

/// The grid lines and tick labels of both axes.
fn grid(s: &mut String, xs: &Scale, ys: &Scale) {
    for (v, label) in xs.ticks() {
        let px = xs.at(v);
        *s += &format!(
            "<line x1=\"{px:.1}\" y1=\"{T}\" x2=\"{px:.1}\" y2=\"{:.1}\" stroke=\"#e4e4e4\"/>\n",
            H - B
        );
        *s += &format!(
            "<text x=\"{px:.1}\" y=\"{:.1}\" text-anchor=\"middle\">{label}</text>\n",
            H - B + 15.0
        );
    }
    for (v, label) in ys.ticks() {
        let py = ys.at(v);
        *s += &format!(
            "<line x1=\"{L}\" y1=\"{py:.1}\" x2=\"{:.1}\" y2=\"{py:.1}\" stroke=\"#e4e4e4\"/>\n",
            W - R
        );
        *s += &format!(
            "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"end\">{label}</text>\n",
            L - 5.0,
            py + 4.0
        );
    }
}

/// Bars per category, each stacked from its layers (e.g. time per phase per run configuration).
#[derive(Clone, Debug, Default)]
pub struct StackedBars {
    pub title: String,
    pub y_label: String,
    pub x_label: String,
    pub categories: Vec<String>,
    /// (layer name, value per category).
    pub layers: Vec<(String, Vec<f64>)>,
}

impl StackedBars {
    pub fn svg(&self) -> String {
        let n = self.categories.len().max(1);
        let totals: Vec<f64> = (0..n)
            .map(|i| self.layers.iter().map(|l| l.1.get(i).copied().unwrap_or(0.0).max(0.0)).sum())
            .collect();
        let ys = Scale::new(
            &Axis { label: String::new(), log: false, range: None },
            totals.iter().copied(),
            H - B,
            T,
        );
        let mut s = header(&self.title);
        for (v, label) in ys.ticks() {
            let py = ys.at(v);
            s += &format!("<line x1=\"{L}\" y1=\"{py:.1}\" x2=\"{:.1}\" y2=\"{py:.1}\" stroke=\"#e4e4e4\"/>\n", W - R);
            s += &format!(
                "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"end\">{label}</text>\n",
                L - 5.0,
                py + 4.0
            );
        }
        axis_labels(&mut s, &self.x_label, &self.y_label);
        let slot = (W - L - R) / n as f64;
        for (i, cat) in self.categories.iter().enumerate() {
            let x0 = L + slot * i as f64 + slot * 0.15;
            let bw = slot * 0.7;
            let mut acc = 0.0;
            for (k, (name, vals)) in self.layers.iter().enumerate() {
                let v = vals.get(i).copied().unwrap_or(0.0).max(0.0);
                let (top, bottom) = (ys.at(acc + v), ys.at(acc));
                acc += v;
                s += &format!("<rect x=\"{x0:.1}\" y=\"{top:.1}\" width=\"{bw:.1}\" height=\"{:.1}\" fill=\"{}\"><title>{}: {}</title></rect>\n", (bottom - top).max(0.0), colour(k), xml(name), fmt_num((v * 1000.0).round() / 1000.0));
            }
            s += &format!(
                "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\">{}</text>\n",
                x0 + bw / 2.0,
                ys.at(acc) - 4.0,
                fmt_num((acc * 100.0).round() / 100.0)
            );
            for (k, line) in wrap(cat, ((slot / 5.5) as usize).max(8)).iter().enumerate() {
                s += &format!("<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\" font-size=\"9\">{}</text>\n", x0 + bw / 2.0, H - B + 12.0 + 10.0 * k as f64, xml(line));
            }
        }
        for (k, (name, _)) in self.layers.iter().enumerate() {
            let ly = T + 10.0 + 16.0 * k as f64;
            s += &format!(
                "<rect x=\"{:.1}\" y=\"{:.1}\" width=\"14\" height=\"10\" fill=\"{}\"/>\n",
                W - R + 10.0,
                ly - 5.0,
                colour(k)
            );
            s += &format!(
                "<text x=\"{:.1}\" y=\"{:.1}\">{}</text>\n",
                W - R + 30.0,
                ly + 4.0,
                xml(name)
            );
        }
        s + "</svg>\n"
    }
}

/// `text` broken at spaces into lines of at most `width` characters (a longer word stays whole).
fn wrap(text: &str, width: usize) -> Vec<String> {
    let mut lines: Vec<String> = vec![];
    for word in text.split_whitespace() {
        match lines.last_mut() {
            Some(l) if l.chars().count() + 1 + word.chars().count() <= width => {
                l.push(' ');
                l.push_str(word);
            }
            _ => lines.push(word.to_string()),
        }
    }
    lines
}

/// What is wrong with an SVG document ([`check_well_formed`]).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SvgError {
    #[error("not an <svg> … </svg> document")]
    NotSvg,
    #[error("unterminated tag")]
    UnterminatedTag,
    /// A closing tag that does not close the element open there (`open`: that element, if any).
    #[error("</{name}> closes {open:?}")]
    Misnested { name: String, open: Option<String> },
    /// The elements left open, outermost first.
    #[error("unclosed: {0:?}")]
    Unclosed(Vec<String>),
}

/// A structural check of an SVG document for tests: it starts with `<svg`, ends with `</svg>`,
/// and every element opened is closed in order. Returns the first problem.
pub fn check_well_formed(doc: &str) -> Result<(), SvgError> {
    let doc = doc.trim();
    if !doc.starts_with("<svg") || !doc.ends_with("</svg>") {
        return Err(SvgError::NotSvg);
    }
    let mut stack: Vec<String> = Vec::new();
    let mut rest = doc;
    while let Some(i) = rest.find('<') {
        let after = &rest[i + 1..];
        let j = after.find('>').ok_or(SvgError::UnterminatedTag)?;
        let tag = &after[..j];
        rest = &after[j + 1..];
        if let Some(name) = tag.strip_prefix('/') {
            match stack.pop() {
                Some(open) if open == name.trim() => {}
                open => return Err(SvgError::Misnested { name: name.trim().into(), open }),
            }
        } else if !tag.ends_with('/') && !tag.starts_with('?') && !tag.starts_with('!') {
            stack.push(tag.split_whitespace().next().unwrap_or("").to_string());
        }
    }
    if stack.is_empty() {
        Ok(())
    } else {
        Err(SvgError::Unclosed(stack))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn chart(log: bool) -> LineChart {
        LineChart {
            title: "detection <vs> size".into(),
            x: Axis { label: "pixels".into(), log, range: None },
            y: Axis { label: "P(detect)".into(), log: false, range: Some((0.0, 1.0)) },
            series: vec![
                Series {
                    name: "measured f=0.01".into(),
                    points: vec![(64.0, 0.5), (256.0, 0.9), (0.0, 1.0)],
                    style: Style::Line,
                    colour: 0,
                },
                Series {
                    name: "predicted f=0.01".into(),
                    points: vec![(64.0, 0.47), (256.0, 0.92)],
                    style: Style::Dashed,
                    colour: 0,
                },
            ],
            hlines: vec![(0.95, "95%".into())],
            vlines: vec![(4096.0, "default".into())],
        }
    }

    #[test]
    fn line_charts_are_well_formed_and_name_their_series() {
        for log in [false, true] {
            let svg = chart(log).svg();
            check_well_formed(&svg).unwrap();
            for needle in [
                "measured f=0.01",
                "predicted f=0.01",
                "detection &lt;vs&gt; size",
                "pixels",
                "P(detect)",
                "95%",
                "default",
            ] {
                assert!(svg.contains(needle), "{needle} missing");
            }
        }
        // The point at x = 0 cannot be drawn on a log axis and is left out, not drawn at -inf.
        assert!(!chart(true).svg().contains("inf"));
    }

    #[test]
    fn stacked_bars_stack_and_label_totals() {
        let b = StackedBars {
            title: "time per phase".into(),
            y_label: "time (s)".into(),
            x_label: "run".into(),
            categories: vec!["-j 1".into(), "-j 2".into()],
            layers: vec![("trace".into(), vec![1.0, 0.5]), ("check".into(), vec![0.5, 0.25])],
        };
        let svg = b.svg();
        check_well_formed(&svg).unwrap();
        assert!(
            svg.contains(">1.5<")
                && svg.contains(">0.75<")
                && svg.contains("-j 2")
                && svg.contains("trace")
        );
        assert_eq!(
            wrap("-j 1 --isolation process-per-cell (29.1 s)", 18),
            vec!["-j 1 --isolation", "process-per-cell", "(29.1 s)"]
        );
    }

    #[test]
    fn the_well_formedness_check_catches_broken_documents() {
        assert!(check_well_formed("<svg><g></svg>").is_err());
        assert!(check_well_formed("<svg><g/></svg>").is_ok());
        assert!(check_well_formed("<html></html>").is_err());
        assert!(check_well_formed("<svg><text>a</g></svg>").is_err());
    }

    #[test]
    fn nice_steps() {
        assert_eq!(nice_step(1.0), 0.2);
        assert_eq!(nice_step(10.0), 2.0);
        assert_eq!(nice_step(30.0), 5.0);
        assert_eq!(fmt_num(0.30000000000000004), "0.3");
    }
}
