//! A bounding volume hierarchy over one mesh's triangles, for the CPU reference of large scenes
//! (a loaded glTF scene of a million triangles; the procedural meshes are small enough to test
//! every triangle). It only **culls**: a node is skipped when the ray misses its f64 box widened
//! by the mesh box's own margin (`intersect::box_pads`, the margin the whole-mesh quick reject
//! already uses), so every triangle the mesh-level reject would have tested and that can yield a
//! candidate — a hit or a marginal one, within its barycentric margins — is still tested, by the
//! same f64 test. The tests hold the BVH's candidates equal to testing every triangle, on rays
//! aimed at vertices and edges (the ambiguous hits) as well as at random. Built by median split
//! of the triangles' centroids on the widest axis; leaves of at most [`LEAF`] triangles.
use super::boxes::{box_pads, may_hit_padded};
use crate::scene::Mesh;
use glam::DVec3;

/// Triangles per leaf, at most.
pub const LEAF: usize = 4;

#[derive(Clone, Copy, Debug)]
struct Node {
    lo: [f64; 3],
    hi: [f64; 3],
    /// Leaf: its first triangle in `order`; inner: its second child (the first follows it).
    first: u32,
    /// Leaf: its triangle count.
    count: u32,
    leaf: bool,
}

pub struct Bvh {
    nodes: Vec<Node>,
    /// Triangle indices of the mesh, leaf by leaf.
    order: Vec<u32>,
    pads: [f64; 3],
}

fn bounds(mesh: &Mesh, tris: &[u32]) -> ([f64; 3], [f64; 3]) {
    let (mut lo, mut hi) = ([f64::MAX; 3], [f64::MIN; 3]);
    for &t in tris {
        for &v in &mesh.indices[t as usize] {
            let p = mesh.positions[v as usize];
            for a in 0..3 {
                lo[a] = lo[a].min(p[a] as f64);
                hi[a] = hi[a].max(p[a] as f64);
            }
        }
    }
    (lo, hi)
}

impl Bvh {
    pub fn build(mesh: &Mesh) -> Bvh {
        let mut order: Vec<u32> = (0..mesh.indices.len() as u32).collect();
        let (lo, hi) = bounds(mesh, &order);
        let mut bvh = Bvh { nodes: Vec::new(), order: Vec::new(), pads: box_pads(lo, hi) };
        let centroid = |t: u32| {
            let [a, b, c] = mesh.indices[t as usize].map(|v| mesh.positions[v as usize]);
            [0, 1, 2].map(|k| (a[k] as f64 + b[k] as f64 + c[k] as f64) / 3.0)
        };
        let centroids: Vec<[f64; 3]> = order.iter().map(|&t| centroid(t)).collect();
        bvh.split(mesh, (&mut order, 0), &centroids);
        bvh.order = order;
        bvh
    }

    /// Adds the node of `tris`, which start at `offset` in the order (and its subtree); returns
    /// its index.
    fn split(
        &mut self,
        mesh: &Mesh,
        (tris, offset): (&mut [u32], u32),
        centroids: &[[f64; 3]],
    ) -> usize {
        let (lo, hi) = bounds(mesh, tris);
        let me = self.nodes.len();
        let leaf = tris.len() <= LEAF;
        self.nodes.push(Node { lo, hi, first: offset, count: tris.len() as u32, leaf });
        if leaf {
            return me;
        }
        let c = |t: &u32| centroids[*t as usize];
        let extent = |k: usize| {
            let (mn, mx) = tris
                .iter()
                .fold((f64::MAX, f64::MIN), |(l, h), t| (l.min(c(t)[k]), h.max(c(t)[k])));
            mx - mn
        };
        let axis = (0..3).max_by(|&a, &b| extent(a).total_cmp(&extent(b))).unwrap_or(0);
        let mid = tris.len() / 2;
        tris.select_nth_unstable_by(mid, |x, y| c(x)[axis].total_cmp(&c(y)[axis]));
        let (left, right) = tris.split_at_mut(mid);
        self.split(mesh, (left, offset), centroids);
        let second = self.split(mesh, (right, offset + mid as u32), centroids);
        self.nodes[me].first = second as u32;
        me
    }

    /// Calls `f` with every triangle whose node box (widened by the mesh's margin) the
    /// object-space ray `o + t·d` can meet.
    pub fn visit(&self, o: DVec3, d: DVec3, mut f: impl FnMut(u32)) {
        let mut stack = vec![0usize];
        while let Some(k) = stack.pop() {
            let n = self.nodes[k];
            if !may_hit_padded(o, d, (n.lo, n.hi), self.pads) {
                continue;
            }
            if n.leaf {
                for &t in &self.order[n.first as usize..(n.first + n.count) as usize] {
                    f(t);
                }
            } else {
                stack.push(n.first as usize);
                stack.push(k + 1);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reference::intersect::{may_hit_box, triangle};
    use crate::scene::rng::Rng;

    fn p(mesh: &Mesh, v: u32) -> DVec3 {
        let q = mesh.positions[v as usize];
        DVec3::new(q[0] as f64, q[1] as f64, q[2] as f64)
    }

    /// Every candidate (triangle, marginal) of the ray: through the BVH, or testing every triangle
    /// behind the whole-mesh quick reject as `intersect::candidates` does.
    fn hits(mesh: &Mesh, bvh: Option<&Bvh>, o: DVec3, d: DVec3) -> Vec<(u32, bool)> {
        let test = |t: u32| {
            let [a, b, c] = mesh.indices[t as usize];
            triangle(o, d, p(mesh, a), p(mesh, b), p(mesh, c)).map(|h| (t, h.3))
        };
        let mut out = Vec::new();
        match bvh {
            Some(b) => b.visit(o, d, |t| out.extend(test(t))),
            None => {
                let all: Vec<u32> = (0..mesh.indices.len() as u32).collect();
                let (lo, hi) = bounds(mesh, &all);
                if may_hit_box(o, d, lo, hi) {
                    out.extend(all.into_iter().filter_map(test));
                }
            }
        }
        out.sort();
        out
    }

    /// A soup of random triangles, slivers and ones nearly parallel to z among them.
    fn soup(n: u32, rng: &mut Rng) -> Mesh {
        let mut positions = Vec::new();
        for k in 0..n {
            let c = [rng.range(-3.0, 3.0), rng.range(-3.0, 3.0), rng.range(-3.0, 3.0)];
            let s = if k % 5 == 0 { 0.001 } else { 0.4 };
            positions.push(c);
            positions.push([
                c[0] + rng.range(-0.5, 0.5),
                c[1] + s * rng.range(-1.0, 1.0),
                c[2] + rng.range(-0.5, 0.5),
            ]);
            positions.push([
                c[0] + rng.range(-0.5, 0.5),
                c[1] + rng.range(-0.5, 0.5),
                c[2] + rng.range(-0.5, 0.5),
            ]);
        }
        let indices: Vec<[u32; 3]> = (0..n).map(|k| [3 * k, 3 * k + 1, 3 * k + 2]).collect();
        Mesh { positions, indices, geometries: std::iter::once(0..n).collect() }
    }

    #[test]
    fn the_bvh_finds_every_candidate_testing_every_triangle_finds() {
        let mut rng = Rng::new(7);
        let mut big = crate::scene::Scene::build(&crate::model::SceneParams {
            mesh_detail: 64,
            ..Default::default()
        });
        let meshes = [soup(3000, &mut rng), big.meshes.swap_remove(2)];
        let (mut rays, mut marginal) = (0, 0);
        for mesh in &meshes {
            let bvh = Bvh::build(mesh);
            let mut check = |o: DVec3, d: DVec3| {
                let want = hits(mesh, None, o, d);
                assert_eq!(hits(mesh, Some(&bvh), o, d), want, "ray {o} {d}");
                rays += 1;
                marginal += want.iter().filter(|h| h.1).count();
            };
            for _ in 0..2000 {
                let o = DVec3::new(rng.range(-4.0, 4.0) as f64, rng.range(-4.0, 4.0) as f64, -10.0);
                let d = DVec3::new(rng.range(-0.3, 0.3) as f64, rng.range(-0.3, 0.3) as f64, 1.0);
                check(o, d);
            }
            // Aimed at vertices and edge midpoints: the ambiguous hits.
            for (k, tri) in mesh.indices.iter().enumerate().step_by(7) {
                let (a, b) = (p(mesh, tri[k % 3]), p(mesh, tri[(k + 1) % 3]));
                for target in [a, (a + b) / 2.0] {
                    let o = target - DVec3::new(0.1, -0.2, 10.0);
                    check(o, (target - o).normalize());
                }
            }
        }
        assert!(rays > 4000 && marginal > 100, "{rays} rays, {marginal} marginal candidates");
    }

    #[test]
    fn a_ray_that_misses_visits_nothing_and_an_empty_mesh_is_fine() {
        let mesh = soup(100, &mut Rng::new(3));
        let bvh = Bvh::build(&mesh);
        let mut n = 0;
        bvh.visit(DVec3::new(50.0, 50.0, -10.0), DVec3::Z, |_| n += 1);
        assert_eq!(n, 0);
        let empty = Mesh { positions: vec![], indices: vec![], geometries: vec![] };
        Bvh::build(&empty).visit(DVec3::ZERO, DVec3::Z, |_| n += 1);
        assert_eq!(n, 0);
    }
}
