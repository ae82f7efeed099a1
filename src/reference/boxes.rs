//! The conservative ray/box test the reference culls with — a box widened by a margin per axis,
//! met anywhere in the ray's t range — shared by the whole-mesh quick reject (`intersect`) and
//! the per-mesh BVH (`bvh`).
use crate::scene::{RAY_TMAX, RAY_TMIN};
use glam::DVec3;

/// The margin per axis the quick reject widens a mesh's box by.
pub fn box_pads(lo: [f64; 3], hi: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|a| 1e-3 * (hi[a] - lo[a]).max(1.0))
}

/// Whether the ray can meet the box `lo..hi` widened by `pad` per axis inside the ray's t range.
pub fn may_hit_padded(o: DVec3, d: DVec3, (lo, hi): ([f64; 3], [f64; 3]), pad: [f64; 3]) -> bool {
    let (mut t0, mut t1) = (RAY_TMIN as f64 * 0.5, RAY_TMAX as f64 * 1.01);
    for a in 0..3 {
        let (l, h) = (lo[a] - pad[a], hi[a] + pad[a]);
        if d[a] == 0.0 {
            if o[a] < l || o[a] > h {
                return false;
            }
            continue;
        }
        let (ta, tb) = ((l - o[a]) / d[a], (h - o[a]) / d[a]);
        t0 = t0.max(ta.min(tb));
        t1 = t1.min(ta.max(tb));
    }
    t0 <= t1 * (1.0 + 1e-6) + 1e-6
}
