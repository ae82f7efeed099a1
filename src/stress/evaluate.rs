//! Traced rays against the f64 watertight reference: per ray the expectation (must hit, must
//! miss, either way: `margin`), then leaks, false hits, wrong hits, double hits, and the t and
//! barycentric error of every hit measured on the primitive the device reported.
//!
//! What fails and what warns (Vulkan 1.4.360, `chapters/raytraversal.adoc`,
//! [[ray-traversal-watertight]]): "Implementations should not double-hit or miss when a ray
//! intersects a shared edge, or a shared vertex of a closed fan", and its note: "the language
//! above does not list a must requirement but it is expected and tested that implementations
//! will perform watertight intersection tests" — the CTS (`watertightness` tests) counts misses.
//! So:
//! - fail: a leak (a ray that must hit misses: a certain hit, or a ray through the interior of a
//!   closed surface), a wrong hit (a primitive the ray does not cross, one behind a certain
//!   closer hit, or a reported hit off the triangle: t outside its vertices' depth range or a
//!   weight below 0 by more than its margin, `Margins::off_triangle`), a false hit (a ray that must miss hits, or an inactive primitive is hit:
//!   `acceleration-structure-inactive-prims`, "An inactive object is considered invisible to all
//!   rays"), a duplicate any-hit (`VK_GEOMETRY_NO_DUPLICATE_ANY_HIT_INVOCATION_BIT_KHR`: "the
//!   implementation must only call the any-hit shader a single time for each primitive"), a
//!   hit outside the t / barycentric tolerance, a facing error;
//! - warn: a double hit outside every ambiguity margin ("should not double-hit"); a double hit
//!   within the margin of an edge is counted (`double_hits_in_margin`) but not warned: there an
//!   edge-inclusive test reports both triangles and f32 rounding can make any test do so.
//!
//! Tolerances (the spec gives none): |Δt| ≤ 1e-3·t + the ray-space position error mapped to t,
//! |Δb| ≤ 1e-3 + the sum of the edges' ray-space margins (`margin`). The relative 1e-3 terms are
//! the CTS rules (`direction_length`, `barycentric_coordinates`) and the matrix tolerances; the
//! ray-space terms only matter far from the origin and on triangles seen edge-on, where a
//! relative rule cannot hold for any f32 implementation.
use super::index::Index;
use super::margin::{candidates, crossings, margins, resolve, Candidate, Margins, Resolved};
pub use super::margin::{ulp_f32, BARY_TOL, ON_EDGE_EPS, T_EPS, T_REL_TOL, ULPS_OF_SCALE};
pub use super::result::{CaseResult, Example, Metrics, PartResult, Verdict, EXAMPLES_PER_KIND};
use super::{CaseKind, Part, Traced, Work};
use crate::reference::watertight::{self, PlaneHit};

/// Object-space built-ins (CTS `builtin`: ≈3.8e-6).
pub const BUILTIN_TOL: f64 = 4e-6;

#[derive(Default)]
struct Acc {
    m: Metrics,
    t_ulps: Vec<f64>,
    examples: Vec<Example>,
}

impl Acc {
    /// Keep ray `i` as an example of `kind` (at most [`EXAMPLES_PER_KIND`] per kind and part:
    /// an `Acc` holds one part).
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
        self.examples.push(super::examples::build(kind, part, i, tr, cands));
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
            if !must_hit && !culled {
                self.m.excluded += 1;
            }
        }
        if tr.candidates >= 2
            && tr.first_candidates[0] != 0
            && tr.first_candidates[0] == tr.first_candidates[1]
        {
            self.m.duplicate_any_hits += 1;
            self.example("duplicate_any_hit", part, i, tr, &cands);
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
        let m = margins(&r, ray, &p);
        let closer = cands.iter().any(|c| {
            c.certain
                && c.hit.t < p.t - m.t_amb
                && (c.instance, c.primitive) != (h.instance, h.primitive)
        });
        if m.outside(&p) || closer || m.off_triangle(h.t, h.bary) {
            self.m.wrong_hits += 1;
            self.m.disagreements += 1;
            self.example("wrong_hit", part, i, tr, &cands);
            return;
        }
        self.errors(part, i, tr, &cands, &r, &p, &m);
    }

    /// The ray reported more hits (any-hit calls) than it has crossings: a warning unless the
    /// ray is within the ambiguity margin of an edge.
    fn double_hit(&mut self, part: &Part, i: usize, tr: &Traced, cands: &[Candidate]) {
        self.m.double_hits += 1;
        if !cands.iter().any(|c| c.near_edge) {
            self.m.double_hit_warnings += 1;
            self.example("double_hit", part, i, tr, cands);
            return;
        }
        self.m.double_hits_in_margin += 1;
        // A ray through a shared edge or vertex is the spec's own case: implementations "should
        // not double-hit" there (Watertightness, Vulkan 1.4.360), so it is a warning; a ray only
        // near the edge, inside the ambiguity margin, is counted.
        if cands.iter().any(|c| c.hit.inside.abs() <= ON_EDGE_EPS) {
            self.m.double_hits_on_edge += 1;
            self.m.double_hit_warnings += 1;
            self.example("double_hit_on_edge", part, i, tr, cands);
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
        a.excluded += b.excluded;
        a.self_hits += b.self_hits;
        a.disagreements += b.disagreements;
        a.leaks += b.leaks;
        a.false_hits += b.false_hits;
        a.wrong_hits += b.wrong_hits;
        a.double_hits += b.double_hits;
        a.double_hit_warnings += b.double_hit_warnings;
        a.duplicate_any_hits += b.duplicate_any_hits;
        a.double_hits_on_edge += b.double_hits_on_edge;
        a.double_hits_in_margin += b.double_hits_in_margin;
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
        // Each part's examples are bounded per kind already.
        self.examples.extend_from_slice(&other.examples);
    }
}

/// Evaluate every part of a case: fail on a broken "must" (leaks, false and wrong hits,
/// duplicate any-hits, hits outside the tolerance, facing errors), warn on double hits outside
/// the ambiguity margin, pass otherwise.
pub fn evaluate(kind: CaseKind, parts: &[Part], traced: &[Vec<Traced>]) -> CaseResult {
    evaluate_counting(kind, parts, traced, &|_| {})
}

/// [`evaluate`], calling `on_work` after each triangle placed in a part's grid, each ray
/// judged and each ray's facing found (a worker's heartbeat counts them).
pub fn evaluate_counting(
    kind: CaseKind,
    parts: &[Part],
    traced: &[Vec<Traced>],
    on_work: &dyn Fn(Work),
) -> CaseResult {
    let mut total = Acc::default();
    let mut results = Vec::new();
    let mut indices = Vec::new();
    for (part, tr) in parts.iter().zip(traced) {
        let mut acc = Acc::default();
        let index = Index::build_reporting(part, &|| on_work(Work::Indexed));
        for (i, t) in tr.iter().enumerate() {
            acc.add(part, &index, i, t);
            on_work(Work::Judged);
        }
        total.merge(&acc);
        results.push(PartResult {
            label: part.label.clone(),
            distance: part.distance,
            metrics: acc.finish(),
        });
        indices.push(index);
    }
    let mut examples = std::mem::take(&mut total.examples);
    let mut metrics = total.finish();
    if kind == CaseKind::Transform {
        let errors = super::transform::facing_errors(parts, traced, &|| on_work(Work::Faced));
        metrics.facing_errors = errors.len();
        examples.extend(facing_examples(parts, &indices, traced, &errors));
    }
    let (verdict, detail) = verdict(&metrics);
    CaseResult {
        name: kind.as_str().into(),
        verdict,
        detail,
        metrics,
        ms: 0.0,
        parts: results,
        examples,
    }
}

/// Examples of facing errors (ray `i` of part `p`; `indices`: each part's grid), at most
/// [`EXAMPLES_PER_KIND`] per part.
fn facing_examples(
    parts: &[Part],
    indices: &[Index],
    traced: &[Vec<Traced>],
    errors: &[(usize, usize)],
) -> Vec<Example> {
    let mut out: Vec<Example> = Vec::new();
    for &(p, i) in errors {
        let part = &parts[p];
        if out.iter().filter(|e| e.part == part.label).count() >= EXAMPLES_PER_KIND {
            continue;
        }
        let cands = candidates(part, &indices[p], &part.rays[i]);
        out.push(super::examples::build("facing_error", part, i, &traced[p][i], &cands));
    }
    out
}

/// The verdict of a case's counts and what it rests on.
pub fn verdict(m: &Metrics) -> (Verdict, Option<String>) {
    let fail = m.disagreements > 0
        || m.duplicate_any_hits > 0
        || m.over_tolerance > 0
        || m.facing_errors > 0;
    // Warned: a double hit outside the ambiguity margin, or exactly on an edge (inside it).
    let outside = m.double_hit_warnings - m.double_hits_on_edge;
    let doubles = format!(
        "{} double hits warned (should not double-hit): {} outside the ambiguity margin, {} exactly on an edge; {} more within the margin, counted",
        m.double_hit_warnings,
        outside,
        m.double_hits_on_edge,
        m.double_hits_in_margin - m.double_hits_on_edge
    );
    if fail {
        let musts = format!(
            "{} leaks ({} with a subnormal ray component), {} false hits, {} wrong hits, {} duplicate any-hits, {} of {} hits outside the tolerance, {} facing errors",
            m.leaks,
            m.leaks_subnormal,
            m.false_hits,
            m.wrong_hits,
            m.duplicate_any_hits,
            m.over_tolerance,
            m.compared,
            m.facing_errors
        );
        (Verdict::Fail, Some(format!("{musts}; {doubles}")))
    } else if m.double_hit_warnings > 0 {
        (Verdict::Warn, Some(doubles))
    } else {
        (Verdict::Pass, None)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stress::{cases, one_mesh, Mesh, Ray, RayInfo, StressOptions, TracedHit};

    /// The hit of `ray` on `primitive` where the f64 reference crosses it (`p`), as f32.
    fn traced_on(ray: &Ray, primitive: u32, p: &PlaneHit) -> Traced {
        traced(ray, Some(primitive), p.t as f32, [p.bary[0] as f32, p.bary[1] as f32])
    }

    fn traced(ray: &Ray, primitive: Option<u32>, t: f32, bary: [f32; 2]) -> Traced {
        Traced {
            hit: primitive.map(|primitive| TracedHit {
                t,
                bary,
                primitive,
                instance: 0,
                hit_kind: 0,
                object_origin: ray.origin,
                object_dir: ray.dir,
            }),
            candidates: primitive.is_some() as u32,
            first_candidates: [primitive.map_or(0, |p| p + 1), 0],
        }
    }

    fn one(part: Part, tr: Vec<Traced>) -> CaseResult {
        evaluate(CaseKind::Watertight, &[part], &[tr])
    }

    fn bits3(b: [u32; 3]) -> [f32; 3] {
        b.map(f32::from_bits)
    }

    /// The rays lavapipe 26 was blamed for (FINDINGS #6 before issue 22: 3 wrong hits, 3 hits
    /// over tolerance in `square-1024`), with its answers: each passes within the ray-space
    /// margin of an edge of a near-vertical sliver, so each answer is legitimate.
    #[test]
    fn lavapipe_26s_answers_beside_slivers_are_neither_wrong_nor_over_tolerance() {
        let square = cases::watertight_part(false, "square-1024");
        // (origin bits, lavapipe's primitive, t, barycentrics) as reports/lavapipe-26/stress.json
        // printed them (each an f32 written out as f64: exact).
        let answers: [([u32; 3], u32, f64, [f64; 2]); 6] = [
            ([0x3e9e958f, 0x3f111102, 0xbf7dfdab], 222, 1.0, [0.5000042915344238, -0.0]),
            (
                [0x3e9e958e, 0x3f111103, 0xbf7dfdab],
                193,
                0.9895004630088806,
                [-0.0, 0.5517241358757019],
            ),
            (
                [0x3e09b798, 0x3df2182d, 0xbf7f1bb2],
                267,
                0.9949780702590942,
                [0.2527472674846649, -0.0],
            ),
            (
                [0x3e9e958e, 0x3f111102, 0xbf7dfdab],
                193,
                0.9949524402618408,
                [0.2666666805744171, 0.2666666805744171],
            ),
            (
                [0x3e9e958b, 0x3f111102, 0xbf7dfdab],
                865,
                0.990367591381073,
                [0.4313725531101227, 0.44117647409439087],
            ),
            (
                [0x3e9e958d, 0x3f111102, 0xbf7dfdab],
                193,
                0.9899048209190369,
                [0.03333333507180214, 0.5333333611488342],
            ),
        ];
        let rays: Vec<Ray> = answers
            .iter()
            .map(|a| Ray {
                origin: bits3(a.0),
                tmin: 0.0,
                dir: [0.0, 0.0, 1.0],
                tmax: f32::from_bits(0x7149f2ca),
            })
            .collect();
        let tr = rays
            .iter()
            .zip(&answers)
            .map(|(r, a)| traced(r, Some(a.1), a.2 as f32, a.3.map(|b| b as f32)))
            .collect();
        let part = Part {
            label: square.label.clone(),
            distance: None,
            scene: square.scene.clone(),
            info: vec![RayInfo { must_hit: true }; rays.len()],
            rays: rays.clone(),
            ray_flags: 0,
        };
        let r = one(part, tr);
        assert_eq!((r.metrics.wrong_hits, r.metrics.over_tolerance), (0, 0), "{:?}", r.detail);
        assert_eq!(r.metrics.ambiguous, rays.len());
        assert_eq!(r.verdict, Verdict::Pass, "{:?}", r.detail);
        // The first: 193's nearest edge is 0.013 away in barycentrics but 1.3e-9 in ray space
        // (0.04 ulp of 0.3), the sliver being ~1e-7 wide as the ray sees it.
        let (index, ray) = (Index::build(&square), rays[0]);
        let c = candidates(&square, &index, &ray).into_iter().find(|c| c.primitive == 193).unwrap();
        let k = (0..3).min_by(|&a, &b| c.hit.weights[a].total_cmp(&c.hit.weights[b])).unwrap();
        let (w, d) = (c.hit.weights[k], c.hit.edge_distance(k));
        assert!((0.013..0.014).contains(&w) && (1e-9..2e-9).contains(&d), "{w} {d}");
        assert!(!c.certain && c.edge_margin > w);
    }

    /// Sliver 193 of `square-1024` and the ray lavapipe 26 hit it with (a legitimate answer):
    /// the part holding only that ray, and the reference's hit and margins on 193.
    fn sliver_193() -> (Part, PlaneHit, Margins) {
        let mut part = cases::watertight_part(false, "square-1024");
        let ray = Ray {
            origin: bits3([0x3e9e958e, 0x3f111103, 0xbf7dfdab]),
            tmin: 0.0,
            dir: [0.0, 0.0, 1.0],
            tmax: f32::from_bits(0x7149f2ca),
        };
        part.rays = vec![ray];
        part.info = vec![RayInfo { must_hit: true }];
        let r = resolve(&part, 0, 193, &ray).unwrap();
        let p = watertight::plane(r.o, r.d, r.v).unwrap();
        let m = margins(&r, &ray, &p);
        (part, p, m)
    }

    /// Issue 22: on a sliver the t tolerance (1e-3·t + Σ margin·depth) and the barycentric one
    /// (1e-3 + Σ margins) are wide; a hit off the triangle — t outside its vertices' depth range,
    /// or a weight below 0 beyond its margin — is a wrong hit even inside them.
    #[test]
    fn a_wrong_t_or_off_triangle_barycentrics_on_a_sliver_are_wrong_hits() {
        let (part, p, m) = sliver_193();
        let ray = part.rays[0];
        let judge = |t: f64, w: [f64; 3]| {
            let mut p2 = sliver_193().0;
            p2.rays = vec![ray];
            one(p2, vec![traced(&ray, Some(193), t as f32, [w[1] as f32, w[2] as f32])]).metrics
        };
        // The reference's own answer passes.
        let ok = judge(p.t, p.weights);
        assert_eq!((ok.wrong_hits, ok.over_tolerance), (0, 0));
        // t just past the depth range, on the side nearer the crossing: inside the old tolerance.
        let (lo, hi) = (m.t_range[0], m.t_range[1]);
        let bad_t = if hi - p.t < p.t - lo { hi + 2e-5 } else { lo - 2e-5 };
        assert!((bad_t - p.t).abs() <= m.t_tol, "the old tolerance accepts it");
        let inside_t = if hi - p.t < p.t - lo { hi - 1e-7 } else { lo + 1e-7 };
        assert_eq!(judge(inside_t, p.weights).wrong_hits, 0, "inside the range");
        let r = judge(bad_t, p.weights);
        assert_eq!(r.wrong_hits, 1, "t {bad_t} outside [{lo}, {hi}]");
        // The weight with the widest margin planted just below its floor, another raised to keep
        // the sum: inside the old barycentric tolerance, off the triangle.
        let k = (0..3).max_by(|&a, &b| m.edge[a].total_cmp(&m.edge[b])).unwrap();
        let j = (0..3).filter(|&j| j != k).max_by(|&a, &b| p.weights[a].total_cmp(&p.weights[b]));
        let plant = |wk: f64| {
            let mut w = p.weights;
            w[j.unwrap()] += w[k] - wk;
            w[k] = wk;
            w
        };
        let floor = m.weight_floor[k];
        let bad = plant(floor - 1e-3 * floor.abs() - 1e-6);
        let db = (1..3).map(|i| (bad[i] - p.weights[i]).abs()).fold(0.0, f64::max);
        assert!(db <= m.bary_tol, "the old tolerance accepts it: {db} {}", m.bary_tol);
        assert_eq!(judge(p.t, plant(floor * 0.9)).wrong_hits, 0, "inside the margin");
        assert_eq!(judge(p.t, bad).wrong_hits, 1, "weight {k} at {} < {floor}", bad[k]);
    }

    /// A steep quad (its plane y = 1e-3·z) seen along +z: ray-space altitudes ~7e-4 against
    /// 3D ones ~0.7, so a barycentric margin from the 3D shape is 1000× too narrow.
    fn steep_pair() -> Part {
        let h = 1e-3;
        let mesh = Mesh {
            positions: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, h, 1.0], [0.0, h, 1.0]],
            // A below the diagonal (seen along +z), B above it; they share (0, 2).
            indices: vec![[0, 1, 2], [0, 2, 3]],
            inactive: vec![false, false],
        };
        Part {
            label: "steep".into(),
            distance: None,
            scene: one_mesh(mesh),
            rays: vec![],
            info: vec![],
            ray_flags: 0,
        }
    }

    /// The ray `f` ray-space margins inside A from the midpoint of the shared diagonal, and how
    /// far inside it really is (its f32 origin rounded), in margins.
    fn beside_the_diagonal(part: &Part, f: f64) -> (Ray, f64) {
        let at = |x: f64, y: f64| Ray {
            origin: [x as f32, y as f32, -1.0],
            tmin: 0.0,
            dir: [0.0, 0.0, 1.0],
            tmax: 1e30,
        };
        let index = Index::build(part);
        let on = at(0.5, 0.5e-3);
        let a = candidates(part, &index, &on).into_iter().find(|c| c.primitive == 0).unwrap();
        // v1 (index 1 of A) is opposite the diagonal; its margin is the diagonal's.
        let margin = a.hit.edge_margins(0.0, 0.0);
        assert_eq!(margin, [0.0; 3]);
        let m = {
            let r = resolve(part, 0, 0, &on).unwrap();
            margins(&r, &on, &a.hit).edge[1]
        };
        let dist = m * a.hit.det_abs / a.hit.edge_len[1];
        let n = (1e-3f64, -1.0f64);
        let len = n.0.hypot(n.1);
        let ray = at(0.5 + f * dist * n.0 / len, 0.5e-3 + f * dist * n.1 / len);
        let c = candidates(part, &index, &ray).into_iter().find(|c| c.primitive == 0).unwrap();
        (ray, c.hit.weights[1] / c.edge_margin.max(f64::MIN_POSITIVE))
    }

    #[test]
    fn inside_the_ray_space_margin_the_neighbour_is_accepted() {
        let part = steep_pair();
        let (ray, f) = beside_the_diagonal(&part, 0.6);
        assert!((0.4..0.8).contains(&f), "{f}");
        let b = resolve(&part, 0, 1, &ray).unwrap();
        let pb = watertight::plane(b.o, b.d, b.v).unwrap();
        // Inside A by ~0.6 of the margin: 0.0x in barycentrics, far beyond the 3D-altitude
        // margin (~2e-5) that called this a wrong hit.
        assert!(pb.inside < -1e-3, "{}", pb.inside);
        let tb = traced_on(&ray, 1, &pb);
        let with = |tr: Traced| {
            let mut p = steep_pair();
            p.rays = vec![ray];
            p.info = vec![RayInfo { must_hit: false }];
            one(p, vec![tr])
        };
        let r = with(tb);
        assert_eq!((r.metrics.wrong_hits, r.metrics.ambiguous), (0, 1), "{:?}", r.detail);
        let r = with(traced(&ray, None, 0.0, [0.0; 2]));
        assert_eq!(r.metrics.leaks, 0, "an ambiguous miss of an open quad is no leak");
    }

    /// The twin: just outside the margin, the neighbour is a wrong hit and a miss is a leak.
    #[test]
    fn just_outside_the_ray_space_margin_a_wrong_hit_and_a_miss_are_counted() {
        let part = steep_pair();
        let (ray, f) = beside_the_diagonal(&part, 1.3);
        assert!((1.1..1.5).contains(&f), "{f}");
        let b = resolve(&part, 0, 1, &ray).unwrap();
        let pb = watertight::plane(b.o, b.d, b.v).unwrap();
        let with = |tr: Traced| {
            let mut p = steep_pair();
            p.rays = vec![ray];
            p.info = vec![RayInfo { must_hit: false }];
            one(p, vec![tr])
        };
        let r = with(traced_on(&ray, 1, &pb));
        assert_eq!((r.metrics.wrong_hits, r.metrics.ambiguous), (1, 0), "{:?}", r.detail);
        assert_eq!(r.verdict, Verdict::Fail);
        let r = with(traced(&ray, None, 0.0, [0.0; 2]));
        assert_eq!(r.metrics.leaks, 1, "{:?}", r.detail);
        assert_eq!(r.verdict, Verdict::Fail);
    }

    #[test]
    fn double_hits_warn_outside_the_margin_and_through_a_shared_vertex() {
        let part = steep_pair();
        let (inside, _) = beside_the_diagonal(&part, 0.5);
        let (outside, _) = beside_the_diagonal(&part, 3.0);
        let both = |ray: &Ray| Traced {
            candidates: 2,
            first_candidates: [1, 2],
            ..traced(ray, None, 0.0, [0.0; 2])
        };
        let mut p = steep_pair();
        p.rays = vec![inside, outside];
        p.info = vec![RayInfo { must_hit: false }; 2];
        let a = |ray: &Ray| {
            let r = resolve(&part, 0, 0, ray).unwrap();
            let h = watertight::plane(r.o, r.d, r.v).unwrap();
            Traced {
                hit: traced(ray, Some(0), h.t as f32, [h.bary[0] as f32, h.bary[1] as f32]).hit,
                ..both(ray)
            }
        };
        // Through the shared vertex (0, 0): the spec's own case ("should not double-hit" on a
        // shared edge or vertex), a warning even inside the margin.
        let vertex = Ray { origin: [0.0, 0.0, -1.0], tmin: 0.0, dir: [0.0, 0.0, 1.0], tmax: 1e30 };
        p.rays.push(vertex);
        p.info.push(RayInfo { must_hit: false });
        let on = Traced { hit: traced(&vertex, Some(0), 1.0, [0.0, 0.0]).hit, ..both(&vertex) };
        let r = one(p, vec![a(&inside), a(&outside), on]);
        assert_eq!(r.metrics.double_hits, 3);
        assert_eq!((r.metrics.double_hits_in_margin, r.metrics.double_hits_on_edge), (2, 1));
        assert_eq!(r.metrics.double_hit_warnings, 2, "outside the margin, and on the vertex");
        assert_eq!(r.verdict, Verdict::Warn, "{:?}", r.detail);
        assert!(super::super::report::all_passed(std::slice::from_ref(&r)), "a warning passes");
        // The same primitive twice breaks NO_DUPLICATE_ANY_HIT_INVOCATION's "must": a failure.
        let mut p = steep_pair();
        p.rays = vec![outside];
        p.info = vec![RayInfo { must_hit: false }];
        let dup = Traced { first_candidates: [1, 1], ..a(&outside) };
        let r = one(p, vec![dup]);
        assert_eq!((r.metrics.duplicate_any_hits, r.verdict), (1, Verdict::Fail));
    }

    /// A part of the steep pair with `rays` (none must hit: the pair is an open quad).
    fn steep_with(rays: Vec<Ray>) -> Part {
        let mut p = steep_pair();
        p.info = vec![RayInfo { must_hit: false }; rays.len()];
        p.rays = rays;
        p
    }

    /// Twin of the examples: a planted leak and a planted wrong hit, each 1.3 margins inside
    /// triangle A, are listed with their ray (f32 bits) and A (vertices as bits, the crossing
    /// beyond the margin from its nearest edge); the wrong hit with B, the triangle reported.
    #[test]
    fn a_planted_leak_and_wrong_hit_are_examples_with_their_ray_and_triangle() {
        let (ray, _) = beside_the_diagonal(&steep_pair(), 1.3);
        let b = resolve(&steep_pair(), 0, 1, &ray).unwrap();
        let pb = watertight::plane(b.o, b.d, b.v).unwrap();
        let wrong = traced_on(&ray, 1, &pb);
        let r = one(steep_with(vec![ray, ray]), vec![traced(&ray, None, 0.0, [0.0; 2]), wrong]);
        assert_eq!(r.examples.len(), 2, "{:?}", r.examples);
        let bits = format!(
            "{:08x} {:08x} {:08x} 00000000",
            ray.origin[0].to_bits(),
            ray.origin[1].to_bits(),
            ray.origin[2].to_bits()
        );
        for (e, kind, ray_index) in [(&r.examples[0], "leak", 0), (&r.examples[1], "wrong_hit", 1)]
        {
            assert_eq!((e.kind.as_str(), e.part.as_str(), e.ray), (kind, "steep", Some(ray_index)));
            assert_eq!(e.bits[0], bits);
            let a = &e.triangles[0];
            assert_eq!((a.primitive, a.role), (0, super::super::result::TriangleRole::Expected));
            assert_eq!(e.reference.map(|r| r.0), Some(0), "{e:?}");
            assert_eq!(a.vertex_bits[2], "3f800000 3a83126f 3f800000", "{a:?}");
            assert!(a.edge_distance > a.margin && a.margin > 0.0, "{a:?}");
            assert!((1.0..2.0).contains(&a.t), "{a:?}");
        }
        assert_eq!(r.examples[0].hit, None);
        assert_eq!(r.examples[1].hit.map(|h| h.0), Some(1));
        let b = r.examples[1].triangles.iter().find(|t| t.primitive == 1).expect("B listed");
        assert!(b.edge_distance < -b.margin, "{b:?}");
        let text = super::super::examples::text(&r.examples);
        assert!(text.contains(&bits) && text.contains("3f800000 3a83126f 3f800000"), "{text}");
        assert!(text.contains("leak — steep ray 0") && text.contains("wrong_hit — steep ray 1"));
    }

    /// The other twin: a passing part has no examples; a failing one keeps at most
    /// EXAMPLES_PER_KIND per kind and part.
    #[test]
    fn a_passing_part_has_no_examples_and_a_failing_one_at_most_eight_per_kind() {
        let (ray, _) = beside_the_diagonal(&steep_pair(), 1.3);
        let a = resolve(&steep_pair(), 0, 0, &ray).unwrap();
        let pa = watertight::plane(a.o, a.d, a.v).unwrap();
        let right = traced_on(&ray, 0, &pa);
        let r = one(steep_with(vec![ray; 3]), vec![right; 3]);
        assert_eq!((r.verdict, r.examples.len()), (Verdict::Pass, 0), "{:?}", r.examples);
        let miss = traced(&ray, None, 0.0, [0.0; 2]);
        let parts = [steep_with(vec![ray; 10]), steep_with(vec![ray; 10])];
        let r = evaluate(CaseKind::Watertight, &parts, &[vec![miss; 10], vec![miss; 10]]);
        assert_eq!(r.metrics.leaks, 20);
        assert_eq!(r.examples.len(), 2 * EXAMPLES_PER_KIND);
    }

    /// lavapipe 26.2.6's two `--full` leaks (FINDINGS #6): each ray's f64 crossing lies inside
    /// exactly one triangle of `square-65536` (a valid tiling seen along z: no gap), 3.85e-10 and
    /// 7.0e-11 from its nearest edge — far inside the ray-space margin (~3.8e-6), so which
    /// triangle an f32 traversal reports is open, but that it reports one is the tiling's.
    #[test]
    fn lavapipe_26s_full_leaks_lie_inside_the_square_within_the_margin() {
        let opts = StressOptions { cases: vec![], seed: 1, full: true };
        let parts = cases::build(CaseKind::Watertight, &opts).unwrap();
        let part = parts.iter().find(|p| p.label == "square-65536").unwrap();
        assert!(crate::stress::mesh::tiling_faults(&part.scene.meshes[0]).is_valid());
        let index = Index::build(part);
        for (i, origin, inside, dist) in [
            (1_641_585, [0x3ed6d0ef, 0x3ea415c6, 0xbf7ed3eb], 14156, 3.85e-10),
            (1_677_750, [0x3f70f723, 0x3f67ce4f, 0xbf7dfc36], 6687, 7.0e-11),
        ] {
            let ray = part.rays[i];
            assert_eq!((ray.origin, ray.dir), (bits3(origin), [0.0, 0.0, 1.0]));
            assert!(part.info[i].must_hit);
            let cands = candidates(part, &index, &ray);
            let holding: Vec<&Candidate> = cands.iter().filter(|c| c.hit.inside >= 0.0).collect();
            assert_eq!(holding.len(), 1, "ray {i}");
            let c = holding[0];
            assert_eq!(c.primitive, inside);
            assert!(!c.certain, "ray {i}: within the margin of an edge");
            let k = (0..3).min_by(|&a, &b| c.hit.weights[a].total_cmp(&c.hit.weights[b])).unwrap();
            let d = c.hit.edge_distance(k);
            assert!((d / dist - 1.0).abs() < 0.02, "ray {i}: {d:e}");
            let r = resolve(part, 0, c.primitive, &ray).unwrap();
            assert!(d * 1e3 < margins(&r, &ray, &c.hit).abs, "ray {i}");
        }
    }
}
