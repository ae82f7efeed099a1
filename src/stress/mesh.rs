//! The closed surfaces of the watertight case — the CTS-like split unit square and closed
//! fans — and the check that a split square is what the spec's watertightness rule needs: a
//! tiling of the unit square seen along z (every triangle counter-clockwise with area, the areas
//! summing to the square, every inner edge shared by exactly two triangles in opposite
//! directions), so that every shared vertex has a closed fan and a ray through the interior
//! must hit it ([[ray-traversal-watertight]]).
use super::Mesh;
use crate::scene::rng::Rng;
use glam::DVec3;

/// Twice the smallest area (seen along z) a split may leave. The f64 orientation of f32 points
/// of the unit square errs by at most a few 1e-16, so a triangle above this is certainly
/// counter-clockwise; below it a point rounded to f32 may sit on or across an edge.
pub const MIN_AREA2: f64 = 1e-13;

fn dv(p: [f32; 3]) -> DVec3 {
    crate::reference::watertight::to_f64(p)
}

/// Twice the signed area of (a, b, c) seen along z (counter-clockwise positive).
pub fn area2_xy(a: [f32; 3], b: [f32; 3], c: [f32; 3]) -> f64 {
    let (a, b, c) = (dv(a), dv(b), dv(c));
    (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x)
}

/// The CTS-like unit square: two triangles, then random interior points each splitting the
/// triangle that holds it into three (same winding), z jittered by ±`jitter`. The point is
/// computed in f64 and rounded to f32 (the device's coordinates); a rounded point that would
/// leave one of the three triangles below [`MIN_AREA2`] — on or across an edge: unchecked, that
/// left 8,634 of 65,536 triangles inverted and 318 flat — is drawn again, so the tiling stays
/// valid ([`tiling_faults`] finds nothing).
pub fn split_square(rng: &mut Rng, triangles: usize, jitter: f32) -> Mesh {
    let mut positions: Vec<[f32; 3]> = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]
        .iter()
        .map(|p| [p[0], p[1], rng.range(-jitter, jitter)])
        .collect();
    let mut indices = vec![[0u32, 1, 2], [0, 2, 3]];
    // Draws are bounded: a square this fine (below f32 resolution) ends short of `triangles`.
    let mut draws = triangles * 64;
    while indices.len() + 2 <= triangles && draws > 0 {
        draws -= 1;
        let k = (rng.next_u64() % indices.len() as u64) as usize;
        let [a, b, c] = indices[k];
        // Barycentrics of the new point, each at least 0.05: strictly inside (a, b, c).
        let w1 = rng.range(0.05, 0.9);
        let w2 = rng.range(0.05, 0.95 - w1);
        let (w1, w2) = (w1 as f64, w2 as f64);
        let [pa, pb, pc] = [a, b, c].map(|i| positions[i as usize]);
        let p = dv(pa) * (1.0 - w1 - w2) + dv(pb) * w1 + dv(pc) * w2;
        let q = [p.x as f32, p.y as f32, rng.range(-jitter, jitter)];
        if [area2_xy(pa, pb, q), area2_xy(pb, pc, q), area2_xy(pc, pa, q)]
            .iter()
            .any(|&s| s.is_nan() || s <= MIN_AREA2)
        {
            continue;
        }
        let i = positions.len() as u32;
        positions.push(q);
        indices[k] = [a, b, i];
        indices.push([b, c, i]);
        indices.push([c, a, i]);
    }
    let inactive = vec![false; indices.len()];
    Mesh { positions, indices, inactive }
}

/// A closed fan: centre vertex 0 and `n` ring vertices on the unit circle, z jittered.
pub fn closed_fan(rng: &mut Rng, n: u32, jitter: f32) -> Mesh {
    let mut positions = vec![[0.0, 0.0, rng.range(-jitter, jitter)]];
    for i in 0..n {
        let a = std::f64::consts::TAU * i as f64 / n as f64;
        positions.push([a.cos() as f32, a.sin() as f32, rng.range(-jitter, jitter)]);
    }
    let indices = (0..n).map(|i| [0, 1 + i, 1 + (i + 1) % n]).collect::<Vec<_>>();
    Mesh { positions, inactive: vec![false; indices.len()], indices }
}

/// Interior edges (shared by two triangles) of a mesh, as vertex pairs.
pub fn shared_edges(mesh: &Mesh) -> Vec<(u32, u32)> {
    let mut edges: Vec<(u32, u32)> = mesh
        .indices
        .iter()
        .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
        .map(|(a, b)| (a.min(b), a.max(b)))
        .collect();
    edges.sort_unstable();
    let mut shared: Vec<(u32, u32)> =
        edges.windows(2).filter(|w| w[0] == w[1]).map(|w| w[0]).collect();
    shared.dedup();
    shared
}

/// How a split square fails to tile the unit square seen along z.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TilingFaults {
    /// Clockwise triangles (negative area).
    pub inverted: usize,
    /// Triangles of no area.
    pub flat: usize,
    /// Triangles with area below [`MIN_AREA2`] / 2 (their orientation is not certain).
    pub thin: usize,
    /// |sum of the areas − 1|.
    pub area_error: f64,
    /// Directed edges without their opposite (not shared in opposite directions) off the
    /// square's boundary.
    pub open_edges: usize,
}

impl TilingFaults {
    pub fn is_valid(&self) -> bool {
        self.inverted == 0
            && self.flat == 0
            && self.thin == 0
            && self.area_error < 1e-9
            && self.open_edges == 0
    }
}

/// What keeps `mesh` (a split square) from being a tiling of the unit square.
pub fn tiling_faults(mesh: &Mesh) -> TilingFaults {
    let mut f = TilingFaults::default();
    let mut area = 0.0;
    let mut directed = std::collections::HashSet::new();
    for t in &mesh.indices {
        let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
        let s = area2_xy(a, b, c);
        if s < 0.0 {
            f.inverted += 1;
        } else if s == 0.0 {
            f.flat += 1;
        } else if s <= MIN_AREA2 {
            f.thin += 1;
        }
        area += s * 0.5;
        directed.extend([(t[0], t[1]), (t[1], t[2]), (t[2], t[0])]);
    }
    f.area_error = (area - 1.0).abs();
    let on_boundary = |a: u32, b: u32| {
        let (p, q) = (mesh.positions[a as usize], mesh.positions[b as usize]);
        (0..2).any(|k| p[k] == q[k] && (p[k] == 0.0 || p[k] == 1.0))
    };
    f.open_edges = directed
        .iter()
        .filter(|&&(a, b)| !directed.contains(&(b, a)) && !on_boundary(a, b))
        .count();
    f
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn split_squares_tile_the_unit_square_at_every_size() {
        // 65,536 is --full's square: f64 points rounded to f32 used to invert 8,634 of its
        // triangles and flatten 318.
        for (seed, n) in [(3, 64), (1, 1024), (1, 65_536), (7, 65_536)] {
            let m = split_square(&mut Rng::new(seed), n, 0.01);
            assert_eq!(m.indices.len(), n, "seed {seed}");
            let f = tiling_faults(&m);
            assert!(f.is_valid(), "seed {seed}, {n} triangles: {f:?}");
            assert!(shared_edges(&m).len() > n);
        }
    }

    #[test]
    fn the_check_finds_an_inverted_a_flat_and_an_open_triangle() {
        let m = split_square(&mut Rng::new(3), 64, 0.01);
        let mut inverted = m.clone();
        inverted.indices[5].swap(0, 1);
        let f = tiling_faults(&inverted);
        assert_eq!(f.inverted, 1);
        assert!(f.area_error > 1e-6 && f.open_edges > 0, "{f:?}");
        let mut flat = m.clone();
        flat.indices[9][2] = flat.indices[9][1];
        assert_eq!(tiling_faults(&flat).flat, 1);
        let mut gap = m;
        gap.indices.remove(0);
        let f = tiling_faults(&gap);
        assert!(!f.is_valid() && f.open_edges > 0, "{f:?}");
    }
}
