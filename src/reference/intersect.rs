//! CPU ray/scene intersection in f64: Möller–Trumbore for triangles, the analytic sphere for the
//! procedural geometry, instance transforms inverted in f64. Hits within a margin of an edge, of
//! the sphere's silhouette, or of another hit's distance are flagged `ambiguous`: there f32 GPU
//! traversal may legitimately pick the other surface, so those pixels are not compared.
use crate::scene::{Geometry, Instance, Scene, RAY_TMAX, RAY_TMIN, SPHERE_RADIUS};
use glam::DVec3;

/// Barycentric margin inside which a hit is marginal.
pub const EPS_BARY: f64 = 1e-4;
/// Relative distance margin for two hits to be too close to order.
pub const EPS_T: f64 = 1e-4;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    pub instance: u32,
    pub primitive: u32,
    pub t: f64,
    /// (weight of v1, weight of v2), as `hitAttributeEXT vec2` holds them; (0, 0) for spheres.
    pub bary: [f64; 2],
    pub sphere: bool,
}

#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TraceRef {
    pub hit: Option<Hit>,
    pub ambiguous: bool,
}

struct Candidate {
    hit: Hit,
    marginal: bool,
}

fn object_ray(inst: &Instance, o: DVec3, d: DVec3) -> (DVec3, DVec3) {
    super::watertight::object_ray(&inst.transform, o, d)
}

/// World-space xy bounds of an instance's object-space box, for a quick reject of the
/// axis-aligned (+z) primary rays.
fn world_xy_bounds(inst: &Instance, lo: [f64; 3], hi: [f64; 3]) -> [f64; 4] {
    let m = inst.transform;
    let mut b = [f64::MAX, f64::MAX, f64::MIN, f64::MIN];
    for c in 0..8 {
        let p = [if c & 1 == 0 { lo[0] } else { hi[0] }, if c & 2 == 0 { lo[1] } else { hi[1] }, if c & 4 == 0 { lo[2] } else { hi[2] }];
        for (axis, row) in m.iter().take(2).enumerate() {
            let w = row[0] as f64 * p[0] + row[1] as f64 * p[1] + row[2] as f64 * p[2] + row[3] as f64;
            b[axis] = b[axis].min(w);
            b[axis + 2] = b[axis + 2].max(w);
        }
    }
    b
}

fn triangle(o: DVec3, d: DVec3, v0: DVec3, v1: DVec3, v2: DVec3) -> Option<(f64, f64, f64, bool)> {
    let e1 = v1 - v0;
    let e2 = v2 - v0;
    let p = d.cross(e2);
    let det = e1.dot(p);
    if det.abs() < 1e-14 {
        return None;
    }
    let inv = 1.0 / det;
    let s = o - v0;
    let u = s.dot(p) * inv;
    let q = s.cross(e1);
    let v = d.dot(q) * inv;
    let t = e2.dot(q) * inv;
    let w = 1.0 - u - v;
    let min = u.min(v).min(w);
    if min < -EPS_BARY || t <= RAY_TMIN as f64 || t >= RAY_TMAX as f64 {
        return None;
    }
    Some((t, u, v, min < EPS_BARY))
}

fn sphere(o: DVec3, d: DVec3) -> Option<(f64, bool)> {
    let r = SPHERE_RADIUS as f64;
    let a = d.dot(d);
    let b = 2.0 * o.dot(d);
    let c = o.dot(o) - r * r;
    let disc = b * b - 4.0 * a * c;
    let scale = (b * b).max(1e-30);
    if disc < -EPS_BARY * scale {
        return None;
    }
    let marginal = disc.abs() < EPS_BARY * scale;
    let sq = disc.max(0.0).sqrt();
    let t0 = (-b - sq) / (2.0 * a);
    let t1 = (-b + sq) / (2.0 * a);
    let (tmin, tmax) = (RAY_TMIN as f64, RAY_TMAX as f64);
    let t = if t0 >= tmin && t0 <= tmax { t0 } else if t1 >= tmin && t1 <= tmax { t1 } else { return None };
    Some((t, marginal))
}

/// Closest hit of the ray among the instances `include` accepts.
pub fn trace(scene: &Scene, origin: [f32; 3], dir: [f32; 3], include: impl Fn(&Instance) -> bool) -> TraceRef {
    let o = DVec3::new(origin[0] as f64, origin[1] as f64, origin[2] as f64);
    let d = DVec3::new(dir[0] as f64, dir[1] as f64, dir[2] as f64);
    let margin = 1e-3;
    let mut cands: Vec<Candidate> = Vec::new();
    for inst in scene.instances.iter().filter(|i| include(i)) {
        let (lo, hi) = match inst.geometry {
            Geometry::Mesh(_) => ([-1.0, -1.0, -0.25], [1.0, 1.0, 0.25]),
            Geometry::Sphere => ([-0.5; 3], [0.5; 3]),
        };
        if d.x == 0.0 && d.y == 0.0 {
            let b = world_xy_bounds(inst, lo, hi);
            if o.x < b[0] - margin || o.x > b[2] + margin || o.y < b[1] - margin || o.y > b[3] + margin {
                continue;
            }
        }
        let (oo, od) = object_ray(inst, o, d);
        match inst.geometry {
            Geometry::Mesh(m) => {
                let mesh = &scene.meshes[m];
                let p = |i: u32| {
                    let v = mesh.positions[i as usize];
                    DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64)
                };
                for (prim, tri) in mesh.indices.iter().enumerate() {
                    if let Some((t, u, v, marginal)) = triangle(oo, od, p(tri[0]), p(tri[1]), p(tri[2])) {
                        let hit = Hit { instance: inst.custom_index, primitive: prim as u32, t, bary: [u, v], sphere: false };
                        cands.push(Candidate { hit, marginal });
                    }
                }
            }
            Geometry::Sphere => {
                if let Some((t, marginal)) = sphere(oo, od) {
                    let hit = Hit { instance: inst.custom_index, primitive: 0, t, bary: [0.0, 0.0], sphere: true };
                    cands.push(Candidate { hit, marginal });
                }
            }
        }
    }
    // The GPU commits the closest certain-or-marginal hit it finds; a marginal candidate may or
    // may not be found, so it only makes the pixel ambiguous when it could be the closest.
    let best = cands.iter().filter(|c| !c.marginal).min_by(|a, b| a.hit.t.total_cmp(&b.hit.t));
    let ambiguous_near = |t: f64| t * (1.0 + EPS_T) + EPS_T;
    match best {
        None => TraceRef { hit: None, ambiguous: !cands.is_empty() },
        Some(b) => {
            let bound = ambiguous_near(b.hit.t);
            let ambiguous = cands.iter().any(|c| {
                !std::ptr::eq(c, b) && c.hit.t <= bound && (c.marginal || (c.hit.instance, c.hit.primitive) != (b.hit.instance, b.hit.primitive))
            });
            TraceRef { hit: Some(b.hit), ambiguous }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn triangle_hits_inside_and_flags_edges() {
        let o = DVec3::new(0.25, 0.25, -1.0);
        let d = DVec3::Z;
        let (v0, v1, v2) = (DVec3::ZERO, DVec3::X, DVec3::Y);
        let (t, u, v, marginal) = triangle(o, d, v0, v1, v2).unwrap();
        assert!((t - 1.0).abs() < 1e-12 && (u - 0.25).abs() < 1e-12 && (v - 0.25).abs() < 1e-12 && !marginal);
        let edge = triangle(DVec3::new(0.5, 0.5 - 1e-6, -1.0), d, v0, v1, v2).unwrap();
        assert!(edge.3, "near the hypotenuse is marginal");
        assert!(triangle(DVec3::new(0.9, 0.9, -1.0), d, v0, v1, v2).is_none());
    }

    #[test]
    fn sphere_front_hit() {
        let (t, marginal) = sphere(DVec3::new(0.0, 0.0, -2.0), DVec3::Z).unwrap();
        assert!((t - 1.5).abs() < 1e-12 && !marginal);
        assert!(sphere(DVec3::new(0.6, 0.0, -2.0), DVec3::Z).is_none());
    }
}
