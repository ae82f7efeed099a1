//! What the f64 reference can say about one ray, and how sure it is: the primitives the ray may
//! cross ([`candidates`]), each with its *ambiguity margins* measured in ray space, and how many
//! distinct surfaces those are ([`crossings`]).
//!
//! The margin (issue 22): an f32 traversal evaluates the edge functions in ray space — the 2D
//! frame across the ray, after translating the vertices to the ray origin (Woop et al. 2013 §3).
//! Its coordinates there carry an absolute error of a few ulp(S), S the largest coordinate of
//! the object-space ray origin and the triangle (plus, under an instance transform, the world
//! origin's and hit point's mapped to object space), and its products a relative error of a few
//! f32 epsilons. Depth comes from the ray's dominant axis alone (ulp of the largest coordinate
//! on that axis over |d| on it). [`ULPS_OF_SCALE`] = 64 of each (6 bits over Woop et al.'s §4 bound) is the
//! position error allowed; `PlaneHit::edge_margins` turns it into a barycentric margin per edge,
//! `(abs·(|B| + |C|) + rel·|B|·|C|) / |det|` — near an edge, `abs / h` with h the vertex's
//! altitude *in ray space*. The previous margin divided by the triangle's 3D altitude, which
//! for a sliver seen edge-on (the split square's near-vertical triangles: 3D altitude ~0.01,
//! ray-space altitude 5e-9 … 1e-7) is up to 10^7 too narrow, so a correct answer on a ray 1.3e-9
//! (0.04 ulp) from a shared edge was called a wrong hit. A weight error δb moves t by
//! `Σ δb_k·(t_k − t)` (t_k: the t of each vertex's depth), added to the t margins: on a steep
//! triangle the hit's depth is as uncertain as its position across the ray.
use super::index::Index;
use super::{Part, Ray};
pub use crate::reference::watertight::ulp_f32;
use crate::reference::watertight::{self, PlaneHit};
use glam::DVec3;

/// Relative t part of the ambiguity margin (≈16 f32 ulps).
pub const T_EPS: f64 = 2e-6;
/// Barycentric distance from an edge below which a ray passes through it (the f64 shear's own
/// rounding, far below an f32 ulp).
pub const ON_EDGE_EPS: f64 = 1e-12;
/// Error allowed, in f32 ulps: of the coordinates (ulp(S)) and of the products (f32 epsilon).
pub const ULPS_OF_SCALE: f64 = 64.0;
/// Relative t tolerance (CTS `direction_length`, the matrix's).
pub const T_REL_TOL: f64 = 1e-3;
/// Barycentric tolerance (CTS `barycentric_coordinates`, the matrix's).
pub const BARY_TOL: f64 = 1e-3;

/// A triangle of the scene in object space (f64) and the ray taken into object space in f64.
pub(super) struct Resolved {
    pub v: [DVec3; 3],
    pub o: DVec3,
    pub d: DVec3,
    /// The instance's transform is not the identity.
    pub transformed: bool,
}

pub(super) fn resolve(part: &Part, instance: u32, primitive: u32, ray: &Ray) -> Option<Resolved> {
    let inst = part.scene.instances.get(instance as usize)?;
    let mesh = &part.scene.meshes[inst.mesh];
    let tri = mesh.indices.get(primitive as usize)?;
    let (o, d) = watertight::object_ray(
        &inst.transform,
        watertight::to_f64(ray.origin),
        watertight::to_f64(ray.dir),
    );
    let v = tri.map(|i| watertight::to_f64(mesh.positions[i as usize]));
    Some(Resolved { v, o, d, transformed: inst.transform != super::IDENTITY })
}

/// Margins for one ray/triangle pair: per weight (ambiguity: a weight within `edge[k]` of 0 may
/// fall either way), and for t (ambiguity and tolerance), and the barycentric tolerance.
pub(super) struct Margins {
    /// The ray-space position error allowed (`ULPS_OF_SCALE` ulps of the coordinates' scale).
    pub abs: f64,
    /// The ray-space distance within which the triangle is in reach at all (`PlaneHit::gap`).
    pub reach: f64,
    pub edge: [f64; 3],
    pub t_amb: f64,
    pub t_tol: f64,
    pub bary_tol: f64,
    /// The t range a hit on this triangle can report: its vertices' depths along the ray,
    /// widened by the depth coordinate's error and T_EPS·t, and by as far as the reference's
    /// own crossing lies outside an edge (within its margin).
    pub t_range: [f64; 2],
    /// The lowest weight a hit on this triangle can report, per vertex: minus its edge margin
    /// and [`WEIGHT_EPS`].
    pub weight_floor: [f64; 3],
}

impl Margins {
    /// Out of reach, or outside an edge by more than its margin: the ray cannot cross this
    /// triangle.
    pub fn outside(&self, p: &PlaneHit) -> bool {
        p.gap > self.reach || (0..3).any(|k| p.weights[k] < -self.edge[k])
    }
    /// Inside every edge by more than its margin.
    pub fn inside(&self, p: &PlaneHit) -> bool {
        (0..3).all(|k| p.weights[k] > self.edge[k])
    }
    /// A reported hit that is not on this triangle: its t outside `t_range`, or a weight
    /// (1 − u − v, u, v) below its floor. A watertight f32 test reports t as the weights' mean
    /// of the vertices' f32 depths (Woop et al. §3: `t = (U·Az + V·Bz + W·Cz)/det`, U, V, W of
    /// one sign), so it cannot leave their range; the relative t tolerance (1e-3·t) and the
    /// barycentric one (1e-3 + Σ margins) are far wider on a sliver and let a hit off the
    /// triangle pass (issue 22). NaN is left to the tolerance check (an infinite error).
    pub fn off_triangle(&self, t: f32, bary: [f32; 2]) -> bool {
        let (u, v) = (bary[0] as f64, bary[1] as f64);
        let w = [1.0 - u - v, u, v];
        let t = t as f64;
        t < self.t_range[0] || t > self.t_range[1] || (0..3).any(|k| w[k] < self.weight_floor[k])
    }
}

/// What f32 rounding of the reported barycentrics themselves may add below 0 (4 ulps of 1).
pub const WEIGHT_EPS: f64 = 4.0 * f32::EPSILON as f64;

pub(super) fn margins(r: &Resolved, ray: &Ray, p: &PlaneHit) -> Margins {
    let o = watertight::to_f64(ray.origin);
    let d = watertight::to_f64(ray.dir);
    let object = r.v.iter().fold(r.o.abs().max_element(), |m, v| m.max(v.abs().max_element()));
    // An instance transform takes the ray to object space in f32: the world coordinates' error
    // (mapped by the ratio of the direction lengths) joins the object space's own. Without one
    // (the identity) the object ray is the world ray, exactly.
    let world = if r.transformed {
        let s = o.abs().max_element().max((o + d * p.t).abs().max_element());
        ulp_f32(s) * r.d.length() / d.length().max(f64::MIN_POSITIVE)
    } else {
        0.0
    };
    let abs = ULPS_OF_SCALE * (ulp_f32(object) + world);
    let rel = ULPS_OF_SCALE * f32::EPSILON as f64;
    let edge = p.edge_margins(abs, rel).map(|m| if m.is_nan() { f64::INFINITY } else { m });
    // Depth: the dominant axis's coordinates, then the weights' error across the triangle's
    // depth range (large on a steep triangle).
    let along =
        ULPS_OF_SCALE * (ulp_f32(p.depth_scale) + world) / p.depth_dir.max(f64::MIN_POSITIVE);
    let depth: f64 = (0..3).map(|k| edge[k] * (p.vertex_t[k] - p.t).abs()).sum();
    let (lo, hi) = p
        .vertex_t
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &t| (lo.min(t), hi.max(t)));
    let outside: f64 = p.weights.iter().map(|w| (-w).max(0.0)).sum();
    let slack = T_EPS * p.t.abs() + along + outside * (hi - lo);
    Margins {
        abs,
        reach: abs + rel * p.reach_max,
        edge,
        t_amb: T_EPS * p.t.abs() + along + depth,
        t_tol: T_REL_TOL * p.t.abs() + along + depth,
        bary_tol: BARY_TOL + edge.iter().sum::<f64>(),
        t_range: [lo - slack, hi + slack],
        weight_floor: edge.map(|e| -e - WEIGHT_EPS),
    }
}

/// A primitive the ray may cross.
pub(super) struct Candidate {
    pub instance: u32,
    pub primitive: u32,
    pub hit: PlaneHit,
    /// Inside every edge and tmin/tmax by more than the margins: the ray crosses it.
    pub certain: bool,
    /// Within the ambiguity margin of an edge: may share the crossing with a neighbour.
    pub near_edge: bool,
    pub t_amb: f64,
    /// The margin of the weight nearest 0 (for the examples).
    pub edge_margin: f64,
}

pub(super) fn candidates(part: &Part, index: &Index, ray: &Ray) -> Vec<Candidate> {
    let mut out = Vec::new();
    for (k, p) in index.query(ray) {
        let Some(r) = resolve(part, k, p, ray) else {
            continue;
        };
        let Some(hit) = watertight::plane(r.o, r.d, r.v) else {
            continue;
        };
        let m = margins(&r, ray, &hit);
        let (tmin, tmax) = (ray.tmin as f64, ray.tmax as f64);
        let possible = !m.outside(&hit) && hit.t >= tmin - m.t_amb && hit.t <= tmax + m.t_amb;
        if possible {
            let nearest = (0..3).min_by(|&a, &b| hit.weights[a].total_cmp(&hit.weights[b]));
            out.push(Candidate {
                instance: k,
                primitive: p,
                hit,
                certain: m.inside(&hit) && hit.t > tmin + m.t_amb && hit.t < tmax - m.t_amb,
                near_edge: !m.inside(&hit),
                t_amb: m.t_amb,
                edge_margin: nearest.map_or(0.0, |k| m.edge[k]),
            });
        }
    }
    out
}

/// Distinct crossings among the candidates. Two candidates are one crossing when the ray comes
/// from the same side of both (determinant sign), their t values lie within either's margin and
/// both are near an edge: the ray passes through the edge (or vertex) they share. At a fold (a
/// silhouette edge seen from the ray) the sides differ and the ray really crosses twice.
pub(super) fn crossings(cands: &[Candidate]) -> u32 {
    let mut n = 0;
    for side in [false, true] {
        let mut cs: Vec<&Candidate> = cands.iter().filter(|c| c.hit.det_positive == side).collect();
        cs.sort_by(|a, b| a.hit.t.total_cmp(&b.hit.t));
        let mut last: Option<&Candidate> = None;
        for c in cs {
            let same = last.is_some_and(|l| {
                let reach = (T_EPS * c.hit.t.abs().max(1.0) * 8.0).max(l.t_amb).max(c.t_amb);
                l.near_edge && c.near_edge && c.hit.t - l.hit.t <= reach
            });
            if !same {
                n += 1;
            }
            last = Some(c);
        }
    }
    n
}
