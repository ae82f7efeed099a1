//! Watertight ray/triangle intersection in f64 (Woop, Benthin & Wald, "Watertight Ray/Triangle
//! Intersection", JCGT 2(1), 2013): translate the vertices to the ray origin, shear them so the
//! ray runs along +z, and evaluate the three 2D edge functions. A point on a shared edge gets the
//! same edge value (with opposite sign) from both triangles, so a closed mesh has no cracks: the
//! test is inclusive on edges (U, V, W all ≥ 0 or all ≤ 0). The f32 inputs are exact in f64 and
//! the shear adds at most a few f64 ulps, 2^-29 below f32 resolution, so this is the reference
//! the driver's f32 traversal is measured against.
//!
//! How close to an edge a ray may pass before an f32 traversal can legitimately decide the other
//! way is a question of *ray space*, the 2D frame the edge functions are evaluated in, not of the
//! triangle's 3D shape: a triangle seen nearly edge-on (a near-vertical sliver under a +z ray)
//! has a 3D altitude of 0.01 and a ray-space altitude of 1e-7. [`PlaneHit::edge_margins`] turns
//! an error in ray space into a barycentric margin per edge (Woop et al. §4 bound the f32 edge
//! functions the same way: the error of `U = Cx·By − Cy·Bx` is the coordinates' error times
//! `|B| + |C|` plus the products' relative error times `|B|·|C|`).
use glam::{DMat3, DVec3};

/// One ray/triangle intersection: distance, the weights of v1 and v2 (as `hitAttributeEXT vec2`
/// holds them), and how far inside the nearest edge the hit is (smallest barycentric, ≥ 0 when
/// the triangle is hit).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlaneHit {
    pub t: f64,
    pub bary: [f64; 2],
    pub inside: f64,
    /// Sign of the determinant: which side of the triangle the ray comes from. Two triangles of
    /// a surface crossed at one point share it; at a fold (silhouette) they differ.
    pub det_positive: bool,
    /// All three barycentrics: the weights of v0, v1 and v2 (`inside` is the smallest).
    pub weights: [f64; 3],
    /// The t at which the ray reaches each vertex's depth: `t` is their mean by `weights`, so a
    /// barycentric error `δb` moves t by `Σ δb_k·(vertex_t_k − t)` (large on a steep triangle).
    pub vertex_t: [f64; 3],
    /// |det|: twice the triangle's area in ray space.
    pub det_abs: f64,
    /// Per vertex k, the edge opposite it in ray space: its endpoints' distances from the ray
    /// `|B| + |C|`, their product `|B|·|C|`, and its length `|B − C|`.
    pub edge_reach: [f64; 3],
    pub edge_span: [f64; 3],
    pub edge_len: [f64; 3],
    /// How far the ray passes from the triangle in ray space (0 through it). Per-edge margins
    /// say which side of each edge's *line* rounding may put the ray; a triangle farther than
    /// the position error is out of reach whatever its edge lines do (a 1e-6 triangle seen from
    /// 3e5 away has lines that rounding can turn any way).
    pub gap: f64,
    /// The largest distance of a vertex from the ray in ray space.
    pub reach_max: f64,
    /// Depth in f32 comes from the ray's dominant axis alone (`t_k = (v_k − o)[kz] / d[kz]`):
    /// the largest |coordinate| on that axis of the origin and the vertices, and |d[kz]|.
    pub depth_scale: f64,
    pub depth_dir: f64,
}

impl PlaneHit {
    /// The barycentric margin of each weight (vertex k: the edge opposite it) for an absolute
    /// error `abs` of the ray-space coordinates and a relative error `rel` of the edge
    /// functions' products: `(abs·(|B| + |C|) + rel·|B|·|C|) / |det|`. For a ray near the edge
    /// (|B| + |C| ≈ |B − C|) the first term is `abs / h_k`, h_k the ray-space altitude of vertex k.
    pub fn edge_margins(&self, abs: f64, rel: f64) -> [f64; 3] {
        std::array::from_fn(|k| (abs * self.edge_reach[k] + rel * self.edge_span[k]) / self.det_abs)
    }

    /// The ray's signed distance from the line of the edge opposite vertex k in ray space
    /// (positive inside).
    pub fn edge_distance(&self, k: usize) -> f64 {
        self.weights[k] * self.det_abs / self.edge_len[k]
    }
}

fn axes(d: DVec3) -> (usize, usize, usize) {
    let a = d.abs();
    let kz = if a.x >= a.y && a.x >= a.z {
        0
    } else if a.y >= a.z {
        1
    } else {
        2
    };
    let (mut kx, mut ky) = ((kz + 1) % 3, (kz + 2) % 3);
    // Keep the winding: swap kx and ky when the dominant direction is negative.
    if d[kz] < 0.0 {
        std::mem::swap(&mut kx, &mut ky);
    }
    (kx, ky, kz)
}

/// Where the ray crosses the triangle's plane, with unclipped barycentrics (outside the triangle
/// some are negative). `None` when the ray is parallel to the plane or the triangle is degenerate
/// (all edge functions zero) or any input is NaN.
pub fn plane(o: DVec3, d: DVec3, v: [DVec3; 3]) -> Option<PlaneHit> {
    let (kx, ky, kz) = axes(d);
    let (sx, sy, sz) = (d[kx] / d[kz], d[ky] / d[kz], 1.0 / d[kz]);
    let rel = |p: DVec3| {
        let q = p - o;
        (q[kx] - sx * q[kz], q[ky] - sy * q[kz], sz * q[kz])
    };
    let (a, b, c) = (rel(v[0]), rel(v[1]), rel(v[2]));
    // Edge functions: U for the edge opposite v0 (weight of v0), V of v1, W of v2.
    let u = c.0 * b.1 - c.1 * b.0;
    let vv = a.0 * c.1 - a.1 * c.0;
    let w = b.0 * a.1 - b.1 * a.0;
    let det = u + vv + w;
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let t = (u * a.2 + vv * b.2 + w * c.2) / det;
    // The edge opposite each vertex: (v1, v2), (v2, v0), (v0, v1).
    let p = [(a.0, a.1), (b.0, b.1), (c.0, c.1)];
    let len = |q: (f64, f64)| (q.0 * q.0 + q.1 * q.1).sqrt();
    let edge = |i: usize, j: usize| {
        let (bi, cj) = (len(p[i]), len(p[j]));
        (bi + cj, bi * cj, len((p[i].0 - p[j].0, p[i].1 - p[j].1)))
    };
    let e = [edge(1, 2), edge(2, 0), edge(0, 1)];
    let (b0, b1, b2) = (u / det, vv / det, w / det);
    let gap = if b0 >= 0.0 && b1 >= 0.0 && b2 >= 0.0 {
        0.0
    } else {
        [(1, 2), (2, 0), (0, 1)]
            .iter()
            .map(|&(i, j)| segment_gap(p[i], p[j]))
            .fold(f64::MAX, f64::min)
    };
    Some(PlaneHit {
        t,
        bary: [b1, b2],
        inside: b0.min(b1).min(b2),
        det_positive: det > 0.0,
        weights: [b0, b1, b2],
        vertex_t: [a.2, b.2, c.2],
        det_abs: det.abs(),
        edge_reach: e.map(|x| x.0),
        edge_span: e.map(|x| x.1),
        edge_len: e.map(|x| x.2),
        gap,
        reach_max: p.iter().map(|&q| len(q)).fold(0.0, f64::max),
        depth_scale: v.iter().fold(o[kz].abs(), |m, q| m.max(q[kz].abs())),
        depth_dir: d[kz].abs(),
    })
}

/// Distance from the ray (the origin of ray space) to the segment p–q.
fn segment_gap(p: (f64, f64), q: (f64, f64)) -> f64 {
    let (dx, dy) = (q.0 - p.0, q.1 - p.1);
    let l2 = dx * dx + dy * dy;
    let s = if l2 > 0.0 { (-(p.0 * dx + p.1 * dy) / l2).clamp(0.0, 1.0) } else { 0.0 };
    let (x, y) = (p.0 + s * dx, p.1 + s * dy);
    (x * x + y * y).sqrt()
}

/// The watertight test: the plane crossing when it lies inside the triangle or on its edges.
pub fn intersect(o: DVec3, d: DVec3, v: [DVec3; 3]) -> Option<PlaneHit> {
    plane(o, d, v).filter(|h| h.inside >= 0.0)
}

/// The ray in an instance's object space: the row-major 3x4 object-to-world `transform`
/// (`VkTransformMatrixKHR`) inverted in f64.
pub fn object_ray(transform: &[[f32; 4]; 3], o: DVec3, d: DVec3) -> (DVec3, DVec3) {
    let m = transform;
    let a = DMat3::from_cols(
        DVec3::new(m[0][0] as f64, m[1][0] as f64, m[2][0] as f64),
        DVec3::new(m[0][1] as f64, m[1][1] as f64, m[2][1] as f64),
        DVec3::new(m[0][2] as f64, m[1][2] as f64, m[2][2] as f64),
    );
    let t = DVec3::new(m[0][3] as f64, m[1][3] as f64, m[2][3] as f64);
    let inv = a.inverse();
    (inv * (o - t), inv * d)
}

/// f32 ulp of |x| (of the smallest normal below it).
pub fn ulp_f32(x: f64) -> f64 {
    let x = (x.abs() as f32).max(f32::MIN_POSITIVE);
    let e = (x.to_bits() >> 23) as i32 - 127;
    2f64.powi(e - 23)
}

/// Vertex of an f32 mesh as f64 (exact).
pub fn to_f64(p: [f32; 3]) -> DVec3 {
    DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    const TRI: [DVec3; 3] = [DVec3::ZERO, DVec3::X, DVec3::Y];

    #[test]
    fn hits_inside_with_barycentrics_of_v1_and_v2() {
        let h = intersect(DVec3::new(0.25, 0.5, -2.0), DVec3::Z, TRI).unwrap();
        assert_eq!(h.t, 2.0);
        assert_eq!(h.bary, [0.25, 0.5]);
        assert!((h.inside - 0.25).abs() < 1e-15);
        assert!(intersect(DVec3::new(0.75, 0.5, -2.0), DVec3::Z, TRI).is_none());
        let back = intersect(DVec3::new(0.25, 0.25, 2.0), -DVec3::Z, TRI).unwrap();
        assert_eq!(back.t, 2.0, "both sides are hit (culling is the tracer's business)");
    }

    #[test]
    fn shared_edge_is_hit_by_both_triangles() {
        // Two triangles sharing the diagonal (1,0)-(0,1), same winding.
        let t2 = [DVec3::X, DVec3::new(1.0, 1.0, 0.0), DVec3::Y];
        let o = DVec3::new(0.5, 0.5, -1.0);
        let a = intersect(o, DVec3::Z, TRI).unwrap();
        let b = intersect(o, DVec3::Z, t2).unwrap();
        assert_eq!(a.inside, 0.0);
        assert_eq!(b.inside, 0.0);
        assert_eq!(a.t, b.t);
    }

    #[test]
    fn degenerate_and_nan_never_hit() {
        let line = [DVec3::ZERO, DVec3::X, DVec3::new(2.0, 0.0, 0.0)];
        assert!(intersect(DVec3::new(0.5, 0.0, -1.0), DVec3::Z, line).is_none());
        let dup = [DVec3::ZERO, DVec3::ZERO, DVec3::Y];
        assert!(intersect(DVec3::new(0.0, 0.5, -1.0), DVec3::Z, dup).is_none());
        let nan = [DVec3::new(f64::NAN, 0.0, 0.0), DVec3::X, DVec3::Y];
        assert!(intersect(DVec3::new(0.25, 0.25, -1.0), DVec3::Z, nan).is_none());
    }

    #[test]
    fn ulps_of_f32() {
        assert_eq!(ulp_f32(1.0), 2f64.powi(-23));
        assert_eq!(ulp_f32(1e7), 1.0);
        assert_eq!(ulp_f32(-3.0), 2f64.powi(-22));
    }

    #[test]
    fn margins_are_measured_in_ray_space() {
        // A unit right triangle seen face-on: at the hypotenuse's midpoint a ray-space error of
        // 1e-6 is 1e-6 / h = √2·1e-6 in v0's weight (|B| + |C| = √2, |det| = 1, h = 1/√2).
        let h = intersect(DVec3::new(0.5, 0.5, -1.0), DVec3::Z, TRI).unwrap();
        let m = h.edge_margins(1e-6, 0.0);
        assert!((m[0] - 2f64.sqrt() * 1e-6).abs() < 1e-15, "{m:?}");
        assert!((h.edge_distance(0)).abs() < 1e-15);
        // The same triangle tilted until it is seen nearly edge-on from the ray: its 3D
        // altitudes stay near 1, its ray-space altitude toward v2 shrinks to 1e-6, so the same
        // ray-space error is a barycentric margin a million times wider.
        let steep = [DVec3::ZERO, DVec3::X, DVec3::new(0.0, 1e-6, 1.0)];
        let o = DVec3::new(0.25, 0.25e-6, -1.0);
        let s = intersect(o, DVec3::Z, steep).unwrap();
        let m = s.edge_margins(1e-6, 0.0);
        assert!(m[2] > 0.9 && m[2] < 2.1, "{m:?}");
        assert!((s.edge_distance(2) - 0.25e-6).abs() < 1e-15, "{}", s.edge_distance(2));
        // t moves with the weights on a steep triangle: v2 is a whole unit deeper.
        assert!((s.vertex_t[2] - 2.0).abs() < 1e-12 && (s.vertex_t[0] - 1.0).abs() < 1e-12);
        // Through the triangle the gap is 0; 3 units beside the hypotenuse's midpoint, 3.
        assert_eq!(s.gap, 0.0);
        let off = 3.0 / 2f64.sqrt();
        let g = plane(DVec3::new(0.5 + off, 0.5 + off, -1.0), DVec3::Z, TRI).unwrap();
        assert!((g.gap - 3.0).abs() < 1e-12, "{}", g.gap);
    }

    #[test]
    fn oblique_rays_agree_with_the_plane_equation() {
        let tri = [DVec3::new(0.0, 0.0, 1.0), DVec3::new(2.0, 0.0, 1.5), DVec3::new(0.0, 2.0, 0.5)];
        let o = DVec3::new(-1.0, -0.5, -3.0);
        let d = DVec3::new(0.3, 0.2, 1.0);
        let h = intersect(o, d, tri).unwrap();
        let p = o + d * h.t;
        let q = tri[0] * (1.0 - h.bary[0] - h.bary[1]) + tri[1] * h.bary[0] + tri[2] * h.bary[1];
        assert!((p - q).length() < 1e-12, "{p} vs {q}");
    }
}
