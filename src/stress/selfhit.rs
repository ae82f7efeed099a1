//! The `self` case: secondary rays from the device's own hit points (Wächter & Binder, "A Fast
//! and Robust Method for Avoiding Self-Intersection", Ray Tracing Gems ch. 6). Primary rays hit
//! a split square moved 1000 units away (so ulp(hit point) ≈ 6e-5); from each hit point,
//! computed in f32 as a shader would (o + t·d), a ray leaves along the reflection, once from the
//! raw point and once from the point offset along the geometric normal by W&B's integer-ulp
//! rule. The reference judges each secondary ray on its exact f32 origin, so a hit where the
//! raw point lies below the surface is not the driver's fault; `self_hits` counts secondary hits
//! closer than [`SELF_T`]: expected for raw origins, none allowed with the offset.
use super::mesh::split_square;
use super::{
    Instance, Mesh, Part, Ray, RayInfo, Scene, StressOptions, TraceError, Traced, Tracer, IDENTITY,
};
use crate::scene::rng::Rng;

/// A secondary hit closer than this is a self-hit.
pub const SELF_T: f32 = 1e-3;
const OFFSET: f32 = 1000.0;

fn scene(rng: &mut Rng) -> Scene {
    let m = split_square(rng, 1024, 0.01);
    let positions = m
        .positions
        .iter()
        .map(|p| [p[0] * 4.0 + OFFSET, p[1] * 4.0 + OFFSET, p[2] * 4.0 + OFFSET])
        .collect();
    Scene {
        meshes: vec![Mesh { positions, ..m }],
        instances: vec![Instance { transform: IDENTITY, mesh: 0 }],
    }
}

fn sub(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Wächter & Binder's offset: move `p` along `n` by 256 ulps (integer arithmetic on the bits),
/// or by 1/65536 absolute near the origin (|p| < 1/32).
pub fn offset_ray(p: [f32; 3], n: [f32; 3]) -> [f32; 3] {
    const ORIGIN: f32 = 1.0 / 32.0;
    const FLOAT_SCALE: f32 = 1.0 / 65536.0;
    const INT_SCALE: f32 = 256.0;
    std::array::from_fn(|k| {
        let of = (INT_SCALE * n[k]) as i32;
        let pi =
            f32::from_bits(
                (p[k].to_bits() as i32).wrapping_add(if p[k] < 0.0 { -of } else { of }) as u32
            );
        if p[k].abs() < ORIGIN {
            p[k] + FLOAT_SCALE * n[k]
        } else {
            pi
        }
    })
}

/// Secondary rays (raw origin, offset origin) from the primary hits.
fn secondaries(primary: &Part, traced: &[Traced]) -> (Part, Part) {
    let mesh = &primary.scene.meshes[0];
    let mut raw = Part { label: "secondary-raw".into(), ..primary.clone_empty() };
    let mut off = Part { label: "secondary-offset".into(), ..raw.clone_empty() };
    for (ray, tr) in primary.rays.iter().zip(traced) {
        let Some(h) = tr.hit else { continue };
        let Some(tri) = mesh.indices.get(h.primitive as usize) else {
            continue;
        };
        let v = tri.map(|i| mesh.positions[i as usize]);
        let (e1, e2) = (sub(v[1], v[0]), sub(v[2], v[0]));
        let mut n = [
            e1[1] * e2[2] - e1[2] * e2[1],
            e1[2] * e2[0] - e1[0] * e2[2],
            e1[0] * e2[1] - e1[1] * e2[0],
        ];
        let len = dot(n, n).sqrt();
        if len == 0.0 {
            continue;
        }
        n = n.map(|x| x / len);
        if dot(n, ray.dir) > 0.0 {
            n = n.map(|x| -x);
        }
        let d = ray.dir;
        let p = std::array::from_fn(|k| ray.origin[k] + h.t * d[k]);
        let k = 2.0 * dot(d, n);
        let r = std::array::from_fn(|i| d[i] - k * n[i]);
        let push = |part: &mut Part, origin| {
            part.rays.push(Ray { origin, tmin: 0.0, dir: r, tmax: 1e30 });
            part.info.push(RayInfo { must_hit: false });
        };
        push(&mut raw, p);
        push(&mut off, offset_ray(p, n));
    }
    (raw, off)
}

impl Part {
    fn clone_empty(&self) -> Part {
        Part {
            label: self.label.clone(),
            distance: self.distance,
            scene: self.scene.clone(),
            rays: vec![],
            info: vec![],
            ray_flags: self.ray_flags,
        }
    }
}

/// Build and trace the three parts (primary, secondary raw, secondary offset). On a trace
/// failure, the parts built so far and the error.
/// The self case's parts with what the tracer returned for each, or the parts and the failure.
pub type SelfHitRun = Result<(Vec<Part>, Vec<Vec<Traced>>), (Vec<Part>, TraceError)>;

pub fn run(tracer: &mut dyn Tracer, opts: &StressOptions) -> SelfHitRun {
    let mut rng = Rng::new(opts.seed ^ 0x5e1f);
    let g = if opts.full { 256 } else { 48 };
    let mut primary = Part {
        label: "primary".into(),
        distance: None,
        scene: scene(&mut rng),
        rays: vec![],
        info: vec![],
        ray_flags: 0,
    };
    for j in 0..g {
        for i in 0..g {
            let x = OFFSET + 4.0 * (0.03 + 0.94 * (i as f32 + 0.5) / g as f32);
            let y = OFFSET + 4.0 * (0.03 + 0.94 * (j as f32 + 0.5) / g as f32);
            let d = [rng.range(-0.3, 0.3), rng.range(-0.3, 0.3), -1.0];
            primary.rays.push(Ray {
                origin: [x - 3.0 * d[0], y - 3.0 * d[1], OFFSET + 3.0],
                tmin: 0.0,
                dir: d,
                tmax: 1e30,
            });
            primary.info.push(RayInfo { must_hit: false });
        }
    }
    let t0 = match tracer.trace(&primary) {
        Ok(t) => t,
        Err(e) => return Err((vec![primary], e)),
    };
    let (raw, off) = secondaries(&primary, &t0);
    let mut traced = vec![t0];
    let mut parts = vec![primary];
    for p in [raw, off] {
        match tracer.trace(&p) {
            Ok(t) => traced.push(t),
            Err(e) => {
                parts.push(p);
                return Err((parts, e));
            }
        }
        parts.push(p);
    }
    Ok((parts, traced))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offset_moves_by_integer_ulps_away_from_the_surface() {
        let p = [1000.0f32, -1000.0, 0.001];
        let o = offset_ray(p, [0.0, 0.0, 1.0]);
        assert_eq!(o[0], 1000.0);
        assert_eq!(o[1], -1000.0);
        assert_eq!(o[2], 0.001 + 1.0 / 65536.0, "near the origin: absolute offset");
        let o = offset_ray(p, [1.0, -1.0, 0.0]);
        assert_eq!(o[0].to_bits(), 1000.0f32.to_bits() + 256);
        assert!(o[1] < -1000.0 && o[1].to_bits() == (-1000.0f32).to_bits() + 256);
    }
}
