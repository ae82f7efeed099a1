//! A uniform 2D grid (world xy) over the triangles of a part, so the reference does not test
//! every triangle for every ray of a large scene (`--full`: 65,536 triangles). Each triangle's
//! world box is padded by more than the ambiguity margin can reach (1e-4 of its size and of the
//! coordinate magnitude: the margin is at most 1e-5 of the size plus 64 ulp(S) ≈ 7.6e-6·S);
//! a ray's candidates are the triangles in the cells under its segment clipped to the scene box.
//! Small parts (≤ [`BRUTE_FORCE`] triangles) are searched exhaustively.
use super::{Part, Ray};
use crate::reference::watertight;
use glam::DVec3;

pub const BRUTE_FORCE: usize = 512;

pub struct Index {
    /// (instance, primitive) of every active triangle.
    all: Vec<(u32, u32)>,
    grid: Option<Grid>,
}

struct Grid {
    lo: DVec3,
    hi: DVec3,
    n: usize,
    cells: Vec<Vec<u32>>,
}

impl Grid {
    fn cell(&self, x: f64, axis: usize) -> usize {
        let f = (x - self.lo[axis]) / (self.hi[axis] - self.lo[axis]).max(f64::MIN_POSITIVE);
        ((f * self.n as f64).floor().max(0.0) as usize).min(self.n - 1)
    }
}

impl Index {
    pub fn build(part: &Part) -> Index {
        let mut all = Vec::new();
        let mut boxes = Vec::new();
        for (k, inst) in part.scene.instances.iter().enumerate() {
            let mesh = &part.scene.meshes[inst.mesh];
            let m = inst.transform;
            let world = |p: [f32; 3]| {
                let v = watertight::to_f64(p);
                DVec3::from_array(std::array::from_fn(|r| {
                    m[r][0] as f64 * v.x
                        + m[r][1] as f64 * v.y
                        + m[r][2] as f64 * v.z
                        + m[r][3] as f64
                }))
            };
            for (p, tri) in mesh.indices.iter().enumerate() {
                if mesh.inactive[p] {
                    continue;
                }
                let v = tri.map(|i| world(mesh.positions[i as usize]));
                let (lo, hi) = (v[0].min(v[1]).min(v[2]), v[0].max(v[1]).max(v[2]));
                if !(lo.is_finite() && hi.is_finite()) {
                    continue;
                }
                let pad =
                    1e-4 * ((hi - lo).max_element() + lo.abs().max(hi.abs()).max_element()) + 1e-30;
                all.push((k as u32, p as u32));
                boxes.push((lo - DVec3::splat(pad), hi + DVec3::splat(pad)));
            }
        }
        if all.len() <= BRUTE_FORCE {
            return Index { all, grid: None };
        }
        let lo = boxes.iter().fold(DVec3::splat(f64::MAX), |a, b| a.min(b.0));
        let hi = boxes.iter().fold(DVec3::splat(f64::MIN), |a, b| a.max(b.1));
        let n = ((all.len() as f64 / 2.0).sqrt() as usize).clamp(1, 512);
        let mut grid = Grid { lo, hi, n, cells: vec![Vec::new(); n * n] };
        for (i, (blo, bhi)) in boxes.iter().enumerate() {
            for y in grid.cell(blo.y, 1)..=grid.cell(bhi.y, 1) {
                for x in grid.cell(blo.x, 0)..=grid.cell(bhi.x, 0) {
                    grid.cells[y * n + x].push(i as u32);
                }
            }
        }
        Index { all, grid: Some(grid) }
    }

    /// The triangles the ray may reach: (instance, primitive).
    pub fn query(&self, ray: &Ray) -> Vec<(u32, u32)> {
        let Some(g) = &self.grid else {
            return self.all.clone();
        };
        let o = watertight::to_f64(ray.origin);
        let d = watertight::to_f64(ray.dir);
        let (mut t0, mut t1) = (ray.tmin as f64, (ray.tmax as f64).min(f64::MAX));
        for a in 0..3 {
            if d[a] == 0.0 {
                if o[a] < g.lo[a] || o[a] > g.hi[a] {
                    return vec![];
                }
                continue;
            }
            let (ta, tb) = ((g.lo[a] - o[a]) / d[a], (g.hi[a] - o[a]) / d[a]);
            t0 = t0.max(ta.min(tb));
            t1 = t1.min(ta.max(tb));
        }
        if t0 > t1 {
            return vec![];
        }
        let (p, q) = (o + d * t0, o + d * t1);
        let (lo, hi) = (p.min(q), p.max(q));
        let mut out: Vec<u32> = Vec::new();
        for y in g.cell(lo.y, 1)..=g.cell(hi.y, 1) {
            for x in g.cell(lo.x, 0)..=g.cell(hi.x, 0) {
                out.extend(&g.cells[y * g.n + x]);
            }
        }
        out.sort_unstable();
        out.dedup();
        out.into_iter().map(|i| self.all[i as usize]).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stress::{cases, CaseKind, StressOptions};

    #[test]
    fn the_grid_finds_every_candidate_brute_force_finds() {
        let opts = StressOptions { cases: vec![], seed: 2, full: false };
        let parts = cases::build(CaseKind::Watertight, &opts).unwrap();
        let big = parts.iter().find(|p| p.scene.meshes[0].indices.len() > BRUTE_FORCE).unwrap();
        let index = Index::build(big);
        assert!(index.grid.is_some());
        let brute = Index { all: index.all.clone(), grid: None };
        for r in big.rays.iter().step_by(7) {
            let got = index.query(r);
            let hits = |list: &[(u32, u32)]| {
                list.iter()
                    .filter(|(_, p)| {
                        let tri = big.scene.meshes[0].indices[*p as usize]
                            .map(|i| watertight::to_f64(big.scene.meshes[0].positions[i as usize]));
                        watertight::plane(
                            watertight::to_f64(r.origin),
                            watertight::to_f64(r.dir),
                            tri,
                        )
                        .is_some_and(|h| h.inside > -1e-3)
                    })
                    .copied()
                    .collect::<Vec<_>>()
            };
            let want = hits(&brute.query(r));
            let found = hits(&got);
            assert_eq!(found.len(), want.len(), "ray {r:?}");
            assert!(got.len() * 4 < index.all.len(), "the grid prunes");
        }
    }
}
