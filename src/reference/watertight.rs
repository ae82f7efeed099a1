//! Watertight ray/triangle intersection in f64 (Woop, Benthin & Wald, "Watertight Ray/Triangle
//! Intersection", JCGT 2(1), 2013): translate the vertices to the ray origin, shear them so the
//! ray runs along +z, and evaluate the three 2D edge functions. A point on a shared edge gets the
//! same edge value (with opposite sign) from both triangles, so a closed mesh has no cracks: the
//! test is inclusive on edges (U, V, W all ≥ 0 or all ≤ 0). The f32 inputs are exact in f64 and
//! the shear adds at most a few f64 ulps, 2^-29 below f32 resolution, so this is the reference
//! the driver's f32 traversal is measured against.
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
    let (b0, b1, b2) = (u / det, vv / det, w / det);
    Some(PlaneHit { t, bary: [b1, b2], inside: b0.min(b1).min(b2), det_positive: det > 0.0 })
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
