//! The `far` case: an 8×8 height field moved away from the origin three ways (by the instance
//! transform, by its vertices, or with the camera at the origin), traced at distances 0 … 1e7.
//!
//! Leaks stay detectable at every distance (issue 22). A ray through the interior of the field's
//! footprint that crosses the whole slab of its heights must hit it (the field covers its
//! footprint without gaps: a closed surface over it), unless rounding can put the crossing
//! outside the footprint. With unit cells that rounding (the ray-space margin, 64 ulps of the
//! coordinates) covered every ray from 1e5 on (64·ulp(1e5) = 0.5 of a cell), so no ray could
//! leak there: the `far` case reported all of them ambiguous. The cells now grow with the
//! distance ([`cell`]: at least 2^11 ulps of it), so the margin stays 1/32 of a cell and the
//! rays keep their place in it: the same scene in units of the coordinates' precision.
use super::margin::{ulp_f32, ULPS_OF_SCALE};
use super::{Instance, Mesh, Part, Ray, RayInfo, Scene};
use crate::reference::watertight;
use crate::scene::rng::Rng;
use glam::DVec3;

/// Distances `far` moves the scene to (exact in f32, below 2^24 so integer vertices stay exact).
pub const FAR_DISTANCES: [f64; 8] = [0.0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7];

/// How `far` moves the scene: by the instance transform (rays start 2 cells below the hit), by
/// the vertices themselves (same rays), or by the instance transform with the rays starting near
/// the world origin (the hit is the distance away).
pub const FAR_MODES: [&str; 3] = ["instance", "baked", "camera"];

/// Cells of the height field per side.
const CELLS: u32 = 8;

/// The grid's cell size at distance `d`: 1, or 2^11 ulps of `d` where that is larger (a power
/// of two, so the vertices stay exact: 2 at 1e4, 16 at 1e5, 128 at 1e6, 2048 at 1e7).
pub fn cell(d: f64) -> f64 {
    (2048.0 * ulp_f32(d)).max(1.0)
}

/// An n×n height field of cells of size `c` (heights ±c/4), its heights from `heights`.
fn grid(heights: &[f32], n: u32, c: f32) -> Mesh {
    let mut positions = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let h = heights[(j * (n + 1) + i) as usize];
            positions.push([i as f32 * c, j as f32 * c, h * c]);
        }
    }
    let row = n + 1;
    let mut indices = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let a = j * row + i;
            indices.push([a, a + 1, a + row]);
            indices.push([a + 1, a + row + 1, a + row]);
        }
    }
    Mesh { positions, inactive: vec![false; indices.len()], indices }
}

fn ray_through(p: DVec3, d: [f32; 3], back: f64) -> Ray {
    let o = p - watertight::to_f64(d) * back;
    Ray { origin: [o.x as f32, o.y as f32, o.z as f32], tmin: 0.0, dir: d, tmax: 1e30 }
}

/// The scene of `mode` at distance `d` with cells of size `c`.
fn scene(mode: &str, heights: &[f32], d: f64, c: f64) -> Scene {
    let base = grid(heights, CELLS, c as f32);
    let t = d as f32;
    match mode {
        "instance" | "camera" => Scene {
            meshes: vec![base],
            instances: vec![Instance {
                transform: [[1.0, 0.0, 0.0, t], [0.0, 1.0, 0.0, t], [0.0, 0.0, 1.0, t]],
                mesh: 0,
            }],
        },
        _ => super::one_mesh(Mesh {
            positions: base.positions.iter().map(|p| [p[0] + t, p[1] + t, p[2] + t]).collect(),
            ..base
        }),
    }
}

pub fn parts(rng: &mut Rng, full: bool) -> Vec<Part> {
    let heights: Vec<f32> =
        (0..(CELLS + 1) * (CELLS + 1)).map(|_| rng.range(-0.25, 0.25)).collect();
    let count = if full { 4096 } else { 512 };
    let targets: Vec<([f64; 2], [f32; 3])> = (0..count)
        .map(|_| {
            let p = [rng.range(0.25, 7.75) as f64, rng.range(0.25, 7.75) as f64];
            (p, [rng.range(-0.5, 0.5), rng.range(-0.5, 0.5), 1.0])
        })
        .collect();
    let mut parts = Vec::new();
    for mode in FAR_MODES {
        for d in FAR_DISTANCES {
            let c = cell(d);
            let scene = scene(mode, &heights, d, c);
            let mut part = Part {
                label: format!("{mode}-{d:e}"),
                distance: Some(d),
                scene,
                rays: Vec::new(),
                info: Vec::new(),
                ray_flags: 0,
            };
            for (p, dir) in &targets {
                let at = DVec3::new(p[0] * c + d, p[1] * c + d, d);
                let ray = if mode == "camera" {
                    // From near the origin along ≈(1, 1, 1): the hit is `d` away.
                    let dir = [1.0 + dir[0] * 0.1, 1.0 + dir[1] * 0.1, 1.0];
                    ray_through(at, dir, d.max(2.0 * c))
                } else {
                    ray_through(at, *dir, 2.0 * c)
                };
                let must_hit = crosses_inside(&part.scene, &ray);
                part.rays.push(ray);
                part.info.push(RayInfo { must_hit });
            }
            parts.push(part);
        }
    }
    parts
}

/// Whether `ray` (its f32 values, exactly) crosses the whole slab of the field's heights inside
/// its footprint by more than twice the ray-space margin (2·64 ulps of the largest coordinate):
/// the field covers its footprint without gaps and its height is continuous, so the ray crosses
/// it there, and a miss is a leak whatever rounding does.
pub fn crosses_inside(scene: &Scene, ray: &Ray) -> bool {
    let inst = &scene.instances[0];
    let m = inst.transform;
    let world: Vec<DVec3> = scene.meshes[inst.mesh]
        .positions
        .iter()
        .map(|&p| {
            let v = watertight::to_f64(p);
            DVec3::from_array(std::array::from_fn(|r| {
                m[r][0] as f64 * v.x + m[r][1] as f64 * v.y + m[r][2] as f64 * v.z + m[r][3] as f64
            }))
        })
        .collect();
    let lo = world.iter().fold(DVec3::splat(f64::INFINITY), |a, &b| a.min(b));
    let hi = world.iter().fold(DVec3::splat(f64::NEG_INFINITY), |a, &b| a.max(b));
    let (o, d) = (watertight::to_f64(ray.origin), watertight::to_f64(ray.dir));
    if d.z <= 0.0 {
        return false;
    }
    let (ta, tb) = ((lo.z - o.z) / d.z, (hi.z - o.z) / d.z);
    let (a, b) = (o + d * ta, o + d * tb);
    let scale =
        [lo.abs(), hi.abs(), o.abs(), b.abs()].iter().fold(0.0f64, |s, v| s.max(v.max_element()));
    let slack =
        2.0 * ULPS_OF_SCALE * (ulp_f32(scale) + f32::EPSILON as f64 * (hi - lo).max_element());
    let inside = |p: DVec3| (0..2).all(|k| p[k] > lo[k] + slack && p[k] < hi[k] - slack);
    ta > ray.tmin as f64 + slack / d.z && tb < ray.tmax as f64 && inside(a) && inside(b)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stress::cpu::{watertight_f64, CpuTracer};
    use crate::stress::evaluate::evaluate;
    use crate::stress::{CaseKind, Traced, Tracer};

    /// At every distance and mode most rays must hit (a leak counts), and the f64 reference as
    /// the device never misses one of them (the must-hit claim holds).
    #[test]
    fn far_rays_must_hit_at_every_distance_and_the_reference_hits_them() {
        let parts = parts(&mut Rng::new(7), false);
        let mut cpu = CpuTracer { name: "watertight f64", intersect: watertight_f64 };
        for p in &parts {
            let must = p.info.iter().filter(|i| i.must_hit).count();
            assert!(must * 100 >= p.rays.len() * 90, "{}: {must} of {}", p.label, p.rays.len());
            let r = evaluate(CaseKind::Far, std::slice::from_ref(p), &[cpu.trace(p).unwrap()]);
            assert_eq!(r.metrics.leaks, 0, "{}: {:?}", p.label, r.detail);
            assert!(r.metrics.excluded * 100 <= p.rays.len() * 10, "{}", p.label);
        }
    }

    /// The twin: a miss planted on a must-hit ray at the farthest distance is a leak, in every
    /// mode (before issue 22's fix no ray at ≥ 1e5 was must-hit, so it passed).
    #[test]
    fn a_leak_planted_at_the_farthest_distance_is_counted() {
        let far = *FAR_DISTANCES.last().unwrap();
        let parts = parts(&mut Rng::new(7), false);
        let mut cpu = CpuTracer { name: "watertight f64", intersect: watertight_f64 };
        for p in parts.iter().filter(|p| p.distance == Some(far)) {
            let mut tr = cpu.trace(p).unwrap();
            let i = p.info.iter().position(|i| i.must_hit).unwrap();
            assert!(tr[i].hit.is_some());
            tr[i] = Traced::default();
            let r = evaluate(CaseKind::Far, std::slice::from_ref(p), &[tr]);
            assert_eq!(r.metrics.leaks, 1, "{}: {:?}", p.label, r.detail);
            assert!(!r.verdict.passed(), "{}", p.label);
        }
    }

    #[test]
    fn cells_stay_exact_powers_of_two() {
        assert_eq!(cell(0.0), 1.0);
        assert_eq!(cell(1e3), 1.0);
        assert_eq!([cell(1e4), cell(1e5), cell(1e6), cell(1e7)], [2.0, 16.0, 128.0, 2048.0]);
    }
}
