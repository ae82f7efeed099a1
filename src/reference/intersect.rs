//! CPU ray/scene intersection in f64: Möller–Trumbore for triangles, the analytic sphere for the
//! procedural geometry, instance transforms inverted in f64. Hits within a margin of an edge, of
//! the sphere's silhouette, or of another hit's distance are flagged `ambiguous`: there f32 GPU
//! traversal may legitimately pick the other surface, so those pixels are not compared.
//! [`candidates`] collects every instance's hits of one ray once; [`resolve`] picks the closest
//! among the instances a TLAS holds, so the AS probe's TLAS variants cost one traversal.
use super::boxes::{box_pads, may_hit_padded};
use super::bvh::Bvh;
use crate::scene::{Geometry, Instance, Scene, RAY_TMAX, RAY_TMIN, SPHERE_RADIUS};
use glam::DVec3;

/// Barycentric margin inside which a hit is marginal, at least (a floor for triangles seen
/// face-on; [`RAY_SPACE_ULPS`] widens it where the triangle is seen edge-on).
pub const EPS_BARY: f64 = 1e-4;
/// The f32 position error the GPU may make across the ray, in ulps of the largest coordinate
/// (and f32 epsilons of the edge functions' products): measured in ray space, where a triangle
/// seen nearly edge-on has a tiny altitude, so a barycentric margin alone is far too narrow
/// there (issue 22: the same root as `stress`'s sliver "wrong hits"; `watertight::PlaneHit::edge_margins`).
pub const RAY_SPACE_ULPS: f64 = 64.0;
/// Relative distance margin for two hits to be too close to order.
pub const EPS_T: f64 = 1e-4;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// The instance's custom index in the scene TLAS.
    pub instance: u32,
    /// The instance's position in `Scene::instances` (`Scene::instances.len()`: the floor).
    pub instance_id: u32,
    pub geometry: u32,
    /// Within its geometry.
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

#[derive(Clone, Copy, Debug)]
pub struct Candidate {
    pub hit: Hit,
    marginal: bool,
}

fn object_ray(inst: &Instance, o: DVec3, d: DVec3) -> (DVec3, DVec3) {
    super::watertight::object_ray(&inst.transform, o, d)
}

/// Whether the object-space ray can come within a margin of the object-space box `lo..hi`
/// inside the ray's t range (a conservative quick reject).
pub(super) fn may_hit_box(o: DVec3, d: DVec3, lo: [f64; 3], hi: [f64; 3]) -> bool {
    may_hit_padded(o, d, (lo, hi), box_pads(lo, hi))
}

pub(super) fn triangle(
    o: DVec3,
    d: DVec3,
    v0: DVec3,
    v1: DVec3,
    v2: DVec3,
) -> Option<(f64, f64, f64, bool)> {
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
    // Each weight's margin: EPS_BARY, or its ray-space margin where that is wider.
    let margin = ray_space_margins(o, d, [v0, v1, v2]).map(|m| m.max(EPS_BARY));
    let weights = [w, u, v];
    if (0..3).any(|k| weights[k] < -margin[k]) || t <= RAY_TMIN as f64 || t >= RAY_TMAX as f64 {
        return None;
    }
    Some((t, u, v, (0..3).any(|k| weights[k] < margin[k])))
}

/// The barycentric margin of each vertex's weight for [`RAY_SPACE_ULPS`] of position error in
/// ray space (∞ where the triangle has no area in ray space; 0 where it is farther from the ray
/// than that error).
fn ray_space_margins(o: DVec3, d: DVec3, v: [DVec3; 3]) -> [f64; 3] {
    let s = v.iter().fold(o.abs().max_element(), |m, p| m.max(p.abs().max_element()));
    let abs = RAY_SPACE_ULPS * super::watertight::ulp_f32(s);
    let rel = RAY_SPACE_ULPS * f32::EPSILON as f64;
    match super::watertight::plane(o, d, v) {
        // Out of reach in ray space: no margin can bring the ray onto it.
        Some(h) if h.gap > abs + rel * h.reach_max => [0.0; 3],
        Some(h) => h.edge_margins(abs, rel).map(|m| if m.is_nan() { f64::INFINITY } else { m }),
        None => [f64::INFINITY; 3],
    }
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
    let t = if t0 >= tmin && t0 <= tmax {
        t0
    } else if t1 >= tmin && t1 <= tmax {
        t1
    } else {
        return None;
    };
    Some((t, marginal))
}

/// Meshes with more triangles than this are traversed through their [`Bvh`].
pub const BVH_ABOVE: usize = 256;

/// What culls a scene's triangles, built once per scene: each mesh's box (for the whole-mesh
/// quick reject) and, for meshes above [`BVH_ABOVE`] triangles, its BVH. Computing the boxes per
/// ray cost a pass over every vertex of the scene for every ray.
pub struct Culling {
    bounds: Vec<([f64; 3], [f64; 3])>,
    bvhs: Vec<Option<Bvh>>,
}

impl Culling {
    pub fn of(scene: &Scene) -> Culling {
        let bounds = scene
            .meshes
            .iter()
            .map(|mesh| {
                let (mut lo, mut hi) = ([f64::MAX; 3], [f64::MIN; 3]);
                for v in &mesh.positions {
                    for a in 0..3 {
                        lo[a] = lo[a].min(v[a] as f64);
                        hi[a] = hi[a].max(v[a] as f64);
                    }
                }
                (lo, hi)
            })
            .collect();
        let bvhs = scene
            .meshes
            .iter()
            .map(|m| (m.indices.len() > BVH_ABOVE).then(|| Bvh::build(m)))
            .collect();
        Culling { bounds, bvhs }
    }

    /// Without BVHs: every triangle of a mesh the quick reject keeps is tested.
    #[cfg(test)]
    fn brute(scene: &Scene) -> Culling {
        Culling { bvhs: scene.meshes.iter().map(|_| None).collect(), ..Culling::of(scene) }
    }
}

/// The triangles of mesh `m` the object-space ray may hit, in index order: every one, or those
/// its BVH does not cull (the same candidates: `bvh`'s tests).
fn triangles_to_test(scene: &Scene, cull: &Culling, m: usize, (o, d): (DVec3, DVec3)) -> Vec<u32> {
    match &cull.bvhs[m] {
        Some(bvh) => {
            let mut tris = Vec::new();
            bvh.visit(o, d, |t| tris.push(t));
            // Index order, as without the BVH: `resolve` keeps the first of equally close hits.
            tris.sort_unstable();
            tris
        }
        None => (0..scene.meshes[m].indices.len() as u32).collect(),
    }
}

fn mesh_candidates(
    scene: &Scene,
    cull: &Culling,
    (id, inst, m): (u32, &Instance, usize),
    (oo, od): (DVec3, DVec3),
    cands: &mut Vec<Candidate>,
) {
    let mesh = &scene.meshes[m];
    if !may_hit_box(oo, od, cull.bounds[m].0, cull.bounds[m].1) {
        return;
    }
    let p = |i: u32| {
        let v = mesh.positions[i as usize];
        DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64)
    };
    for tri_index in triangles_to_test(scene, cull, m, (oo, od)) {
        let tri = mesh.indices[tri_index as usize];
        if let Some((t, u, v, marginal)) = triangle(oo, od, p(tri[0]), p(tri[1]), p(tri[2])) {
            let (geometry, primitive) = mesh.geometry_of(tri_index);
            let hit = Hit {
                instance: inst.custom_index,
                instance_id: id,
                geometry,
                primitive,
                t,
                bary: [u, v],
                sphere: false,
            };
            cands.push(Candidate { hit, marginal });
        }
    }
}

/// Every hit of the ray with `instances` (each with its instance id), marginal ones included.
pub fn candidates<'a>(
    (scene, cull): (&Scene, &Culling),
    origin: [f32; 3],
    dir: [f32; 3],
    instances: impl Iterator<Item = (u32, &'a Instance)>,
) -> Vec<Candidate> {
    let o = DVec3::new(origin[0] as f64, origin[1] as f64, origin[2] as f64);
    let d = DVec3::new(dir[0] as f64, dir[1] as f64, dir[2] as f64);
    let mut cands: Vec<Candidate> = Vec::new();
    for (id, inst) in instances {
        let (oo, od) = object_ray(inst, o, d);
        match inst.geometry {
            Geometry::Mesh(m) => mesh_candidates(scene, cull, (id, inst, m), (oo, od), &mut cands),
            Geometry::Sphere => {
                if let Some((t, marginal)) = sphere(oo, od) {
                    let hit = Hit {
                        instance: inst.custom_index,
                        instance_id: id,
                        geometry: 0,
                        primitive: 0,
                        t,
                        bary: [0.0, 0.0],
                        sphere: true,
                    };
                    cands.push(Candidate { hit, marginal });
                }
            }
        }
    }
    cands
}

/// The closest of the `cands` that `include` accepts, and whether the GPU may pick another.
pub fn resolve(cands: &[Candidate], include: impl Fn(&Hit) -> bool) -> TraceRef {
    let kept: Vec<&Candidate> = cands.iter().filter(|c| include(&c.hit)).collect();
    // The GPU commits the closest certain-or-marginal hit it finds; a marginal candidate may or
    // may not be found, so it only makes the pixel ambiguous when it could be the closest.
    let best = kept.iter().filter(|c| !c.marginal).min_by(|a, b| a.hit.t.total_cmp(&b.hit.t));
    let ambiguous_near = |t: f64| t * (1.0 + EPS_T) + EPS_T;
    let key = |h: &Hit| (h.instance_id, h.geometry, h.primitive);
    match best {
        None => TraceRef { hit: None, ambiguous: !kept.is_empty() },
        Some(b) => {
            let bound = ambiguous_near(b.hit.t);
            let ambiguous = kept.iter().any(|c| {
                !std::ptr::eq(*c, *b)
                    && c.hit.t <= bound
                    && (c.marginal || key(&c.hit) != key(&b.hit))
            });
            TraceRef { hit: Some(b.hit), ambiguous }
        }
    }
}

/// Closest hit of the ray among the scene instances `include` accepts.
pub fn trace(
    (scene, cull): (&Scene, &Culling),
    origin: [f32; 3],
    dir: [f32; 3],
    include: impl Fn(&Instance) -> bool,
) -> TraceRef {
    let insts =
        scene.instances.iter().enumerate().map(|(k, i)| (k as u32, i)).filter(|&(_, i)| include(i));
    resolve(&candidates((scene, cull), origin, dir, insts), |_| true)
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
        assert!(
            (t - 1.0).abs() < 1e-12
                && (u - 0.25).abs() < 1e-12
                && (v - 0.25).abs() < 1e-12
                && !marginal
        );
        let edge = triangle(DVec3::new(0.5, 0.5 - 1e-6, -1.0), d, v0, v1, v2).unwrap();
        assert!(edge.3, "near the hypotenuse is marginal");
        assert!(triangle(DVec3::new(0.9, 0.9, -1.0), d, v0, v1, v2).is_none());
    }

    #[test]
    fn a_triangle_seen_edge_on_is_marginal_by_its_ray_space_margin() {
        // Steep: its projection along +z is 1e-4 high, its 3D altitudes near 1. A ray 1e-6
        // (≈ 8 ulps at this scale) inside its long edge is 0.01 inside in barycentrics: far
        // beyond EPS_BARY, well within the ray-space margin (64 ulps ≈ 8e-6 across the ray).
        let (v0, v1, v2) = (DVec3::ZERO, DVec3::X, DVec3::new(0.0, 1e-4, 1.0));
        let near = triangle(DVec3::new(0.5, 1e-6, -1.0), DVec3::Z, v0, v1, v2).unwrap();
        assert!(near.2 > 50.0 * EPS_BARY, "{near:?}");
        assert!(near.3, "marginal in ray space");
        // Just outside it the ray is a possible hit, marginal; well inside it is certain.
        let out = triangle(DVec3::new(0.5, -1e-6, -1.0), DVec3::Z, v0, v1, v2).unwrap();
        assert!(out.3);
        let inside = triangle(DVec3::new(0.25, 5e-5, -1.0), DVec3::Z, v0, v1, v2).unwrap();
        assert!(!inside.3, "{inside:?}");
        // Face-on, the floor still holds: 1e-6 inside a unit triangle's edge is marginal.
        assert!(triangle(DVec3::new(0.5, 1e-6, -1.0), DVec3::Z, v0, v1, DVec3::Y).unwrap().3);
    }

    #[test]
    fn every_pixel_traces_the_same_through_the_bvh_as_through_every_triangle() {
        let p = crate::model::SceneParams { mesh_detail: 32, ..Default::default() };
        let scene = Scene::build(&p);
        assert!(scene.meshes.iter().any(|m| m.indices.len() > BVH_ABOVE));
        let (bvh, brute) = (Culling::of(&scene), Culling::brute(&scene));
        let mut ambiguous = 0;
        for y in 0..p.height {
            for x in 0..p.width {
                let (o, d) = scene.primary_ray(x, y);
                let want = trace((&scene, &brute), o, d, |_| true);
                assert_eq!(trace((&scene, &bvh), o, d, |_| true), want, "pixel {x},{y}");
                ambiguous += want.ambiguous as u32;
            }
        }
        assert!(ambiguous > 0, "ambiguous pixels compared too");
    }

    #[test]
    fn sphere_front_hit() {
        let (t, marginal) = sphere(DVec3::new(0.0, 0.0, -2.0), DVec3::Z).unwrap();
        assert!((t - 1.5).abs() < 1e-12 && !marginal);
        assert!(sphere(DVec3::new(0.6, 0.0, -2.0), DVec3::Z).is_none());
    }
}
