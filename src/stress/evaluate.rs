//! Traced rays against the f64 watertight reference: per ray the expectation (must hit, must
//! miss, either way), then leaks, false hits, wrong hits, double hits, and the t and barycentric
//! error of every hit measured on the primitive the device reported.
//!
//! Tolerances (derived from the rules quoted in issue 11; the spec gives none):
//! - hit/miss: a ray through the interior of a closed surface must hit it (spec
//!   "ray-traversal-watertight"; CTS watertightness allows zero misses); a ray whose reference
//!   hit is farther than the *ambiguity margin* from every edge and from tmin/tmax must agree;
//!   inactive (degenerate, NaN-X) primitives must never be hit.
//! - ambiguity margin: an f32 traversal evaluates edge functions on coordinates of magnitude S
//!   (the larger of the ray origin and the hit point), each rounded to ½ulp(S); the edge value
//!   and t inherit a position error of a few ulp(S) (Woop et al. 2013 §4 bound their f32 test
//!   by a small multiple of the unit roundoff times the coordinate magnitude). We allow
//!   [`ULPS_OF_SCALE`] = 64 ulp(S) (6 bits over that bound): in barycentrics that is
//!   64·ulp(S)/h for a triangle of smallest altitude h, plus [`EDGE_EPS`]; in t it is
//!   64·ulp(S)/|d|, plus [`T_EPS`]·t.
//! - error verdict: |Δt| ≤ 1e-3·t + 64·ulp(S)/|d| and |Δb| ≤ 1e-3 + 64·ulp(S)/h. The relative
//!   1e-3 terms are the CTS rules (`direction_length`, `barycentric_coordinates`) and today's
//!   matrix tolerances; the ulp(S) terms only matter far from the origin, where a relative rule on
//!   t cannot hold for any f32 implementation (the ray origin itself is rounded to ulp(S)).
//! - double hits: the any-hit count may not exceed the number of distinct surfaces the reference
//!   crosses (candidates grouped by t within the margin): a shared edge or a fan's centre vertex
//!   is one crossing ("should not double-hit").
use super::index::Index;
use super::{CaseKind, Part, Ray, TraceError, Traced};
use crate::reference::watertight::{self, PlaneHit};
use glam::DVec3;
use serde::Serialize;

/// Barycentric part of the ambiguity margin.
pub const EDGE_EPS: f64 = 1e-5;
/// Relative t part of the ambiguity margin (≈16 f32 ulps).
pub const T_EPS: f64 = 2e-6;
/// Barycentric distance from an edge below which a ray passes through it (the f64 shear's own
/// rounding, far below an f32 ulp).
pub const ON_EDGE_EPS: f64 = 1e-12;
/// Absolute error allowed for coordinates of magnitude S, in f32 ulps of S.
pub const ULPS_OF_SCALE: f64 = 64.0;
/// Relative t tolerance (CTS `direction_length`, the matrix's).
pub const T_REL_TOL: f64 = 1e-3;
/// Object-space built-ins (CTS `builtin`: ≈3.8e-6).
pub const BUILTIN_TOL: f64 = 4e-6;
/// Barycentric tolerance (CTS `barycentric_coordinates`, the matrix's).
pub const BARY_TOL: f64 = 1e-3;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Verdict {
    Pass,
    Fail,
    DeviceLost,
    Timeout,
    Error,
    NotImplemented,
}

impl Verdict {
    pub fn as_str(self) -> &'static str {
        match self {
            Verdict::Pass => "pass",
            Verdict::Fail => "fail",
            Verdict::DeviceLost => "device_lost",
            Verdict::Timeout => "timeout",
            Verdict::Error => "error",
            Verdict::NotImplemented => "not_implemented",
        }
    }
}

#[derive(Clone, Debug, Default, Serialize)]
pub struct Metrics {
    pub rays: usize,
    pub hits: usize,
    /// Rays the reference cannot judge strictly: some primitive they may hit lies within the
    /// ambiguity margin of an edge or of tmin/tmax (only a case's must-hit still holds there).
    pub ambiguous: usize,
    /// Hit/miss against an unambiguous reference, plus hits on the wrong primitive.
    pub disagreements: usize,
    /// Rays that must hit and missed.
    pub leaks: usize,
    /// Leaks of rays with a subnormal origin or direction component (flush-to-zero territory).
    pub leaks_subnormal: usize,
    /// Rays that must miss (or hit an inactive primitive) and hit.
    pub false_hits: usize,
    /// Hits on a primitive the ray does not cross, or behind a certain closer hit.
    pub wrong_hits: usize,
    pub double_hits: usize,
    /// Double hits where any-hit saw the same primitive twice (the geometry has
    /// NO_DUPLICATE_ANY_HIT_INVOCATION: a violation on its own).
    pub duplicate_any_hits: usize,
    /// Double hits of rays that pass through a shared edge or vertex (within [`ON_EDGE_EPS`]): what an
    /// edge-inclusive watertight test (Woop et al.) reports; off-edge double hits are not that.
    pub double_hits_on_edge: usize,
    /// Double hits of rays within the ambiguity margin of an edge (includes `double_hits_on_edge`);
    /// a double hit away from every edge reports a surface twice where no rounding explains it.
    pub double_hits_near_edge: usize,
    /// Largest error of gl_ObjectRayOriginEXT / gl_ObjectRayDirectionEXT against the f64
    /// inverse transform, relative to max(1, |world origin|, |object value|) (hits over
    /// [`BUILTIN_TOL`] count in `over_tolerance`).
    pub builtin_err_max: Option<f64>,
    /// `transform`: hits whose facing is not the one function of object-space winding, and culled
    /// traces that keep a culled facing or drop the other.
    pub facing_errors: usize,
    /// Hits closer than `selfhit::SELF_T` (the `self` case's false self-intersections).
    pub self_hits: usize,
    /// Hits whose t and barycentrics were compared.
    pub compared: usize,
    /// Compared hits outside the t or barycentric tolerance.
    pub over_tolerance: usize,
    /// |Δt| in f32 ulps of the reference t.
    pub t_err_max_ulps: Option<f64>,
    pub t_err_p99: Option<f64>,
    pub t_rel_err_max: Option<f64>,
    pub bary_err_max: Option<f64>,
}

/// One ray that failed a check, with what the reference and the tracer said (evidence for a
/// write-up; at most [`EXAMPLES_PER_KIND`] per kind and case).
#[derive(Clone, Debug, Serialize)]
pub struct Example {
    pub kind: &'static str,
    pub part: String,
    pub origin: [f32; 3],
    pub dir: [f32; 3],
    pub tmin: f32,
    pub tmax: f32,
    /// The same four vectors as f32 bit patterns (exact reproduction).
    pub bits: [String; 2],
    /// The reference's closest possible hit: (primitive, t, smallest barycentric).
    pub reference: Option<(u32, f64, f64)>,
    /// Distinct crossings the reference counts.
    pub crossings: u32,
    pub hit: Option<(u32, f32, [f32; 2])>,
    pub candidates: u32,
    /// (instance << 24 | primitive) + 1 of the first two candidates any-hit counted.
    pub first_candidates: [u32; 2],
}

pub const EXAMPLES_PER_KIND: usize = 3;

#[derive(Clone, Debug, Serialize)]
pub struct PartResult {
    pub label: String,
    pub distance: Option<f64>,
    #[serde(flatten)]
    pub metrics: Metrics,
}

#[derive(Clone, Debug, Serialize)]
pub struct CaseResult {
    pub name: &'static str,
    pub verdict: Verdict,
    pub detail: Option<String>,
    #[serde(flatten)]
    pub metrics: Metrics,
    pub ms: f64,
    pub parts: Vec<PartResult>,
    pub examples: Vec<Example>,
}

impl CaseResult {
    pub fn not_implemented(kind: CaseKind) -> Self {
        let detail = Some(format!("rtprobe does not implement the {} case yet", kind.as_str()));
        CaseResult {
            name: kind.as_str(),
            verdict: Verdict::NotImplemented,
            detail,
            metrics: Metrics::default(),
            ms: 0.0,
            parts: vec![],
            examples: vec![],
        }
    }

    pub fn failed(kind: CaseKind, parts: &[Part], e: &TraceError) -> Self {
        let verdict = match e {
            TraceError::DeviceLost(_) => Verdict::DeviceLost,
            TraceError::Timeout(_) => Verdict::Timeout,
            TraceError::Failed(_) | TraceError::Compile(_) => Verdict::Error,
        };
        let metrics =
            Metrics { rays: parts.iter().map(|p| p.rays.len()).sum(), ..Metrics::default() };
        CaseResult {
            name: kind.as_str(),
            verdict,
            detail: Some(e.to_string()),
            metrics,
            ms: 0.0,
            parts: vec![],
            examples: vec![],
        }
    }
}

/// f32 ulp of |x| (of the smallest normal below it).
pub fn ulp_f32(x: f64) -> f64 {
    let x = (x.abs() as f32).max(f32::MIN_POSITIVE);
    let e = (x.to_bits() >> 23) as i32 - 127;
    2f64.powi(e - 23)
}

struct Candidate {
    instance: u32,
    primitive: u32,
    hit: PlaneHit,
    certain: bool,
    /// Within the ambiguity margin of an edge: may share the crossing with a neighbour.
    near_edge: bool,
}

/// A triangle of the scene in object space (f64) and the ray taken into object space in f64.
struct Resolved {
    v: [DVec3; 3],
    o: DVec3,
    d: DVec3,
}

fn resolve(part: &Part, instance: u32, primitive: u32, ray: &Ray) -> Option<Resolved> {
    let inst = part.scene.instances.get(instance as usize)?;
    let mesh = &part.scene.meshes[inst.mesh];
    let tri = mesh.indices.get(primitive as usize)?;
    let (o, d) = watertight::object_ray(
        &inst.transform,
        watertight::to_f64(ray.origin),
        watertight::to_f64(ray.dir),
    );
    let v = tri.map(|i| watertight::to_f64(mesh.positions[i as usize]));
    Some(Resolved { v, o, d })
}

/// Smallest altitude of a triangle (∞ for a degenerate one: no barycentric margin applies).
fn min_altitude(v: [DVec3; 3]) -> f64 {
    let area2 = (v[1] - v[0]).cross(v[2] - v[0]).length();
    let longest = (v[1] - v[0]).length().max((v[2] - v[1]).length()).max((v[0] - v[2]).length());
    if area2 == 0.0 || longest == 0.0 {
        f64::INFINITY
    } else {
        area2 / longest
    }
}

/// Margins for one ray/triangle pair: (barycentric, t), each for ambiguity and tolerance.
struct Margins {
    edge: f64,
    t_amb: f64,
    t_tol: f64,
    bary_tol: f64,
}

fn margins(r: &Resolved, ray: &Ray, t: f64) -> Margins {
    let o = watertight::to_f64(ray.origin);
    let d = watertight::to_f64(ray.dir);
    let p = o + d * t;
    let s = o.abs().max_element().max(p.abs().max_element());
    let abs = ULPS_OF_SCALE * ulp_f32(s);
    // Altitude in object space, mapped to world by the ratio of the direction lengths.
    let h = min_altitude(r.v) * d.length() / r.d.length().max(f64::MIN_POSITIVE);
    let bary_abs = if h.is_finite() { abs / h } else { 0.0 };
    let dl = d.length().max(f64::MIN_POSITIVE);
    Margins {
        edge: EDGE_EPS + bary_abs,
        t_amb: T_EPS * t.abs() + abs / dl,
        t_tol: T_REL_TOL * t.abs() + abs / dl,
        bary_tol: BARY_TOL + bary_abs,
    }
}

fn candidates(part: &Part, index: &Index, ray: &Ray) -> Vec<Candidate> {
    let mut out = Vec::new();
    for (k, p) in index.query(ray) {
        let Some(r) = resolve(part, k, p, ray) else {
            continue;
        };
        let Some(hit) = watertight::plane(r.o, r.d, r.v) else {
            continue;
        };
        let m = margins(&r, ray, hit.t);
        let (tmin, tmax) = (ray.tmin as f64, ray.tmax as f64);
        let possible = hit.inside >= -m.edge && hit.t >= tmin - m.t_amb && hit.t <= tmax + m.t_amb;
        if possible {
            let certain = hit.inside > m.edge && hit.t > tmin + m.t_amb && hit.t < tmax - m.t_amb;
            out.push(Candidate {
                instance: k,
                primitive: p,
                hit,
                certain,
                near_edge: hit.inside <= m.edge,
            });
        }
    }
    out
}

/// Distinct crossings among the candidates. Two candidates are one crossing when the ray comes
/// from the same side of both (determinant sign), their t values lie within the margin and both
/// are near an edge: the ray passes through the edge (or vertex) they share. At a fold (a
/// silhouette edge seen from the ray) the sides differ and the ray really crosses twice.
fn crossings(cands: &[Candidate]) -> u32 {
    let mut n = 0;
    for side in [false, true] {
        let mut cs: Vec<&Candidate> = cands.iter().filter(|c| c.hit.det_positive == side).collect();
        cs.sort_by(|a, b| a.hit.t.total_cmp(&b.hit.t));
        let mut last: Option<&Candidate> = None;
        for c in cs {
            let same = last.is_some_and(|l| {
                l.near_edge
                    && c.near_edge
                    && c.hit.t - l.hit.t <= T_EPS * c.hit.t.abs().max(1.0) * 8.0
            });
            if !same {
                n += 1;
            }
            last = Some(c);
        }
    }
    n
}

#[derive(Default)]
struct Acc {
    m: Metrics,
    t_ulps: Vec<f64>,
    examples: Vec<Example>,
}

fn bits(v: [f32; 4]) -> String {
    v.iter().map(|x| format!("{:08x}", x.to_bits())).collect::<Vec<_>>().join(" ")
}

impl Acc {
    fn example(
        &mut self,
        kind: &'static str,
        part: &Part,
        i: usize,
        tr: &Traced,
        cands: &[Candidate],
    ) {
        if self.examples.iter().filter(|e| e.kind == kind).count() >= EXAMPLES_PER_KIND {
            return;
        }
        let r = &part.rays[i];
        let closest = cands
            .iter()
            .min_by(|a, b| a.hit.t.total_cmp(&b.hit.t))
            .map(|c| (c.primitive, c.hit.t, c.hit.inside));
        self.examples.push(Example {
            kind,
            part: part.label.clone(),
            origin: r.origin,
            dir: r.dir,
            tmin: r.tmin,
            tmax: r.tmax,
            bits: [
                bits([r.origin[0], r.origin[1], r.origin[2], r.tmin]),
                bits([r.dir[0], r.dir[1], r.dir[2], r.tmax]),
            ],
            reference: closest,
            crossings: crossings(cands),
            hit: tr.hit.map(|h| (h.primitive, h.t, h.bary)),
            candidates: tr.candidates,
            first_candidates: tr.first_candidates,
        });
    }

    fn add(&mut self, part: &Part, index: &Index, i: usize, tr: &Traced) {
        let ray = &part.rays[i];
        let cands = candidates(part, index, ray);
        // Culled traces: the reference does not cull; `transform::facing_errors` judges them.
        let culled =
            part.ray_flags & (super::transform::CULL_BACK | super::transform::CULL_FRONT) != 0;
        let must_hit = !culled && (part.info[i].must_hit || cands.iter().any(|c| c.certain));
        let may_hit = !cands.is_empty();
        self.m.rays += 1;
        if cands.iter().any(|c| !c.certain) {
            self.m.ambiguous += 1;
        }
        if tr.candidates > crossings(&cands).max(1) {
            self.double_hit(part, i, tr, &cands);
        }
        let Some(h) = tr.hit else {
            if must_hit {
                self.m.leaks += 1;
                if ray.origin.iter().chain(&ray.dir).any(|x| x.is_subnormal()) {
                    self.m.leaks_subnormal += 1;
                }
                self.m.disagreements += 1;
                self.example("leak", part, i, tr, &cands);
            }
            return;
        };
        self.m.hits += 1;
        if h.t < super::selfhit::SELF_T {
            self.m.self_hits += 1;
        }
        let inactive = part
            .scene
            .instances
            .get(h.instance as usize)
            .and_then(|inst| part.scene.meshes[inst.mesh].inactive.get(h.primitive as usize))
            .copied();
        if !may_hit || inactive == Some(true) {
            self.m.false_hits += 1;
            self.m.disagreements += 1;
            self.example("false_hit", part, i, tr, &cands);
            return;
        }
        let plane = resolve(part, h.instance, h.primitive, ray)
            .and_then(|r| watertight::plane(r.o, r.d, r.v).map(|p| (r, p)));
        let Some((r, p)) = plane else {
            self.m.wrong_hits += 1;
            self.m.disagreements += 1;
            self.example("wrong_hit", part, i, tr, &cands);
            return;
        };
        let m = margins(&r, ray, p.t);
        let closer = cands.iter().any(|c| {
            c.certain
                && c.hit.t < p.t - m.t_amb
                && (c.instance, c.primitive) != (h.instance, h.primitive)
        });
        if p.inside < -m.edge || closer {
            self.m.wrong_hits += 1;
            self.m.disagreements += 1;
            self.example("wrong_hit", part, i, tr, &cands);
            return;
        }
        self.errors(part, i, tr, &cands, &r, &p, &m);
    }

    /// The ray reported more hits (any-hit calls) than it has crossings.
    fn double_hit(&mut self, part: &Part, i: usize, tr: &Traced, cands: &[Candidate]) {
        self.m.double_hits += 1;
        if tr.first_candidates[0] == tr.first_candidates[1] {
            self.m.duplicate_any_hits += 1;
        }
        if cands.iter().any(|c| c.near_edge) {
            self.m.double_hits_near_edge += 1;
        }
        if cands.iter().any(|c| c.hit.inside.abs() <= ON_EDGE_EPS) {
            self.m.double_hits_on_edge += 1;
            self.example("double_hit_on_edge", part, i, tr, cands);
        } else {
            self.example("double_hit", part, i, tr, cands);
        }
    }

    /// A right hit's errors against the reference: t (ulps and relative), barycentrics and the
    /// object-space built-ins (`r`: the hit triangle, `p`: the f64 hit, `m`: the margins).
    #[allow(clippy::too_many_arguments)]
    fn errors(
        &mut self,
        part: &Part,
        i: usize,
        tr: &Traced,
        cands: &[Candidate],
        r: &Resolved,
        p: &PlaneHit,
        m: &Margins,
    ) {
        let (ray, h) = (&part.rays[i], tr.hit.expect("a hit"));
        let dt = (h.t as f64 - p.t).abs();
        // f64::max drops a NaN operand: a NaN barycentric must count as an infinite error.
        let db = [h.bary[0] as f64 - p.bary[0], h.bary[1] as f64 - p.bary[1]]
            .iter()
            .map(|d| if d.is_nan() { f64::INFINITY } else { d.abs() })
            .fold(0.0, f64::max);
        self.m.compared += 1;
        let scale = watertight::to_f64(ray.origin)
            .abs()
            .max_element()
            .max(r.o.abs().max_element())
            .max(1.0);
        let obj = |v: [f32; 3]| watertight::to_f64(v);
        let be = ((obj(h.object_origin) - r.o).abs().max_element() / scale)
            .max((obj(h.object_dir) - r.d).abs().max_element() / r.d.abs().max_element().max(1.0));
        let be = if be.is_nan() { f64::INFINITY } else { be };
        self.m.builtin_err_max = Some(self.m.builtin_err_max.unwrap_or(0.0).max(be));
        if !(dt <= m.t_tol && db <= m.bary_tol && be <= BUILTIN_TOL) {
            self.m.over_tolerance += 1;
            self.example("over_tolerance", part, i, tr, cands);
        }
        let ulps = dt / ulp_f32(p.t);
        self.t_ulps.push(if ulps.is_nan() { f64::INFINITY } else { ulps });
        let rel = if p.t != 0.0 { dt / p.t.abs() } else { dt };
        self.m.t_rel_err_max = Some(self.m.t_rel_err_max.unwrap_or(0.0).max(if rel.is_nan() {
            f64::INFINITY
        } else {
            rel
        }));
        self.m.bary_err_max = Some(self.m.bary_err_max.unwrap_or(0.0).max(if db.is_nan() {
            f64::INFINITY
        } else {
            db
        }));
    }

    fn finish(mut self) -> Metrics {
        self.t_ulps.sort_by(f64::total_cmp);
        if let Some(&max) = self.t_ulps.last() {
            self.m.t_err_max_ulps = Some(max);
            let k =
                ((self.t_ulps.len() as f64 * 0.99).ceil() as usize).clamp(1, self.t_ulps.len()) - 1;
            self.m.t_err_p99 = Some(self.t_ulps[k]);
        }
        self.m
    }

    fn merge(&mut self, other: &Acc) {
        let (a, b) = (&mut self.m, &other.m);
        a.rays += b.rays;
        a.hits += b.hits;
        a.ambiguous += b.ambiguous;
        a.self_hits += b.self_hits;
        a.disagreements += b.disagreements;
        a.leaks += b.leaks;
        a.false_hits += b.false_hits;
        a.wrong_hits += b.wrong_hits;
        a.double_hits += b.double_hits;
        a.duplicate_any_hits += b.duplicate_any_hits;
        a.double_hits_on_edge += b.double_hits_on_edge;
        a.double_hits_near_edge += b.double_hits_near_edge;
        a.leaks_subnormal += b.leaks_subnormal;
        a.compared += b.compared;
        a.over_tolerance += b.over_tolerance;
        let max = |x: Option<f64>, y: Option<f64>| match (x, y) {
            (Some(x), Some(y)) => Some(x.max(y)),
            (x, None) => x,
            (None, y) => y,
        };
        a.t_rel_err_max = max(a.t_rel_err_max, b.t_rel_err_max);
        a.builtin_err_max = max(a.builtin_err_max, b.builtin_err_max);
        a.facing_errors += b.facing_errors;
        a.bary_err_max = max(a.bary_err_max, b.bary_err_max);
        self.t_ulps.extend_from_slice(&other.t_ulps);
        for e in &other.examples {
            if self.examples.iter().filter(|x| x.kind == e.kind).count() < EXAMPLES_PER_KIND {
                self.examples.push(e.clone());
            }
        }
    }
}

/// Evaluate every part of a case; the verdict fails on any leak, false or wrong hit, double hit,
/// or compared hit outside the tolerance.
pub fn evaluate(kind: CaseKind, parts: &[Part], traced: &[Vec<Traced>]) -> CaseResult {
    let mut total = Acc::default();
    let mut results = Vec::new();
    for (part, tr) in parts.iter().zip(traced) {
        let mut acc = Acc::default();
        let index = Index::build(part);
        for (i, t) in tr.iter().enumerate() {
            acc.add(part, &index, i, t);
        }
        total.merge(&acc);
        results.push(PartResult {
            label: part.label.clone(),
            distance: part.distance,
            metrics: acc.finish(),
        });
    }
    let examples = std::mem::take(&mut total.examples);
    let mut metrics = total.finish();
    if kind == CaseKind::Transform {
        metrics.facing_errors = super::transform::facing_errors(parts, traced);
    }
    let fail = metrics.disagreements > 0
        || metrics.double_hits > 0
        || metrics.over_tolerance > 0
        || metrics.facing_errors > 0;
    let verdict = if fail { Verdict::Fail } else { Verdict::Pass };
    let detail = fail.then(|| {
        format!(
            "{} leaks ({} with a subnormal ray component), {} false hits, {} wrong hits, {} double hits ({} exactly on an edge, {} near one), {} of {} hits outside the tolerance, {} facing errors",
            metrics.leaks,
            metrics.leaks_subnormal,
            metrics.false_hits,
            metrics.wrong_hits,
            metrics.double_hits,
            metrics.double_hits_on_edge,
            metrics.double_hits_near_edge,
            metrics.over_tolerance,
            metrics.compared,
            metrics.facing_errors
        )
    });
    CaseResult { name: kind.as_str(), verdict, detail, metrics, ms: 0.0, parts: results, examples }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ulps_of_f32() {
        assert_eq!(ulp_f32(1.0), 2f64.powi(-23));
        assert_eq!(ulp_f32(1e7), 1.0);
        assert_eq!(ulp_f32(-3.0), 2f64.powi(-22));
    }
}
