//! A CPU "device" for the stress suite's own tests: brute-force traversal over every triangle
//! with a pluggable intersector. With the f64 watertight test it must pass every case; with a
//! deliberately sloppy f32 Möller–Trumbore (an epsilon that shrinks every triangle) the suite
//! must find leaks: the check can fail.
use super::{Part, TraceError, Traced, TracedHit, Tracer};
use crate::reference::watertight;
use glam::DVec3;

/// Object-space ray and triangle → (t, weight of v1, weight of v2).
pub type Intersector = fn([f32; 3], [f32; 3], [[f32; 3]; 3]) -> Option<(f32, f32, f32)>;

pub struct CpuTracer {
    pub name: &'static str,
    pub intersect: Intersector,
}

/// The reference test itself (inclusive edges, f64), rounded to f32 results.
pub fn watertight_f64(o: [f32; 3], d: [f32; 3], v: [[f32; 3]; 3]) -> Option<(f32, f32, f32)> {
    let h = watertight::intersect(
        watertight::to_f64(o),
        watertight::to_f64(d),
        v.map(watertight::to_f64),
    )?;
    Some((h.t as f32, h.bary[0] as f32, h.bary[1] as f32))
}

/// Möller–Trumbore in f32 with a barycentric epsilon (as some engines write it): not watertight.
pub fn sloppy_f32(o: [f32; 3], d: [f32; 3], v: [[f32; 3]; 3]) -> Option<(f32, f32, f32)> {
    const EPS: f32 = 1e-5;
    let sub = |a: [f32; 3], b: [f32; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let cross = |a: [f32; 3], b: [f32; 3]| {
        [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    };
    let dot = |a: [f32; 3], b: [f32; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let (e1, e2) = (sub(v[1], v[0]), sub(v[2], v[0]));
    let p = cross(d, e2);
    let det = dot(e1, p);
    if det.abs() < 1e-8 {
        return None;
    }
    let s = sub(o, v[0]);
    let u = dot(s, p) / det;
    let q = cross(s, e1);
    let w = dot(d, q) / det;
    if u < EPS || w < EPS || u + w > 1.0 - EPS {
        return None;
    }
    Some((dot(e2, q) / det, u, w))
}

fn object_ray(m: &[[f32; 4]; 3], o: [f32; 3], d: [f32; 3]) -> ([f32; 3], [f32; 3]) {
    let (o, d) = watertight::object_ray(m, watertight::to_f64(o), watertight::to_f64(d));
    let f = |v: DVec3| [v.x as f32, v.y as f32, v.z as f32];
    (f(o), f(d))
}

impl Tracer for CpuTracer {
    fn name(&self) -> String {
        format!("cpu ({})", self.name)
    }

    fn trace(&mut self, part: &Part) -> Result<Vec<Traced>, TraceError> {
        Ok(part
            .rays
            .iter()
            .map(|ray| {
                let mut out = Traced::default();
                for (k, inst) in part.scene.instances.iter().enumerate() {
                    let (o, d) = object_ray(&inst.transform, ray.origin, ray.dir);
                    let mesh = &part.scene.meshes[inst.mesh];
                    for (p, tri) in mesh.indices.iter().enumerate() {
                        let v = tri.map(|i| mesh.positions[i as usize]);
                        let Some((t, b1, b2)) = (self.intersect)(o, d, v) else {
                            continue;
                        };
                        if !(t > ray.tmin && t < ray.tmax) {
                            continue;
                        }
                        if out.candidates < 2 {
                            out.first_candidates[out.candidates as usize] =
                                ((k as u32) << 24 | p as u32) + 1;
                        }
                        out.candidates += 1;
                        if out.hit.is_none_or(|h| t < h.t) {
                            out.hit = Some(TracedHit {
                                t,
                                bary: [b1, b2],
                                primitive: p as u32,
                                instance: k as u32,
                                hit_kind: 0,
                                object_origin: o,
                                object_dir: d,
                            });
                        }
                    }
                }
                out
            })
            .collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stress::{run, CaseKind, StressOptions};

    fn case(tracer: &mut CpuTracer, kind: CaseKind) -> crate::stress::evaluate::CaseResult {
        let opts = StressOptions { cases: vec![kind], seed: 1, full: false };
        run(tracer, &opts).remove(0)
    }

    #[test]
    fn the_watertight_reference_as_device_has_no_leaks() {
        let mut t = CpuTracer { name: "watertight f64", intersect: watertight_f64 };
        let r = case(&mut t, CaseKind::Watertight);
        assert_eq!(r.metrics.leaks, 0, "{r:?}");
        assert_eq!(r.metrics.disagreements, 0, "{r:?}");
        assert!(r.metrics.rays > 1000);
        // An edge-inclusive test double-hits on shared edges (and at folds near them), only
        // there: within the ambiguity margin; those exactly on the edge are the spec's "should
        // not double-hit" case, so warnings, and the only ones.
        assert!(r.metrics.double_hits_on_edge > 0);
        assert_eq!(r.metrics.double_hits, r.metrics.double_hits_in_margin);
        assert_eq!(r.metrics.double_hit_warnings, r.metrics.double_hits_on_edge);
        assert_eq!(r.verdict, crate::stress::evaluate::Verdict::Warn, "{:?}", r.detail);
        for k in [CaseKind::Degenerate, CaseKind::Tmin, CaseKind::Far, CaseKind::Grazing] {
            let r = case(&mut t, k);
            assert_eq!(r.metrics.disagreements, 0, "{k:?}: {r:?}");
            assert_eq!(r.metrics.over_tolerance, 0, "{k:?}: {r:?}");
        }
    }

    /// A tracer that runs the reference and then breaks its answers with `f`.
    struct Broken(CpuTracer, fn(&mut Traced));

    impl Tracer for Broken {
        fn name(&self) -> String {
            "broken".into()
        }
        fn trace(&mut self, part: &Part) -> Result<Vec<Traced>, TraceError> {
            let mut v = self.0.trace(part)?;
            v.iter_mut().for_each(self.1);
            Ok(v)
        }
    }

    fn broken(f: fn(&mut Traced), kind: CaseKind) -> crate::stress::evaluate::CaseResult {
        let mut t = Broken(CpuTracer { name: "watertight f64", intersect: watertight_f64 }, f);
        run(&mut t, &StressOptions { cases: vec![kind], seed: 1, full: false }).remove(0)
    }

    #[test]
    fn wrong_t_garbage_bits_inactive_hits_and_duplicates_are_caught() {
        let r = broken(
            |t| {
                if let Some(h) = t.hit.as_mut() {
                    h.t *= 1.01
                }
            },
            CaseKind::Far,
        );
        assert!(r.metrics.over_tolerance > 0, "t off by 1%: {r:?}");
        let r = broken(
            |t| {
                if let Some(h) = t.hit.as_mut() {
                    h.bary[0] = f32::from_bits(0x7fc0_0001)
                }
            },
            CaseKind::Grazing,
        );
        assert_eq!(r.metrics.over_tolerance, r.metrics.compared, "NaN barycentrics");
        assert!(r.metrics.compared > 0);
        let r = broken(
            |t| {
                if let Some(h) = t.hit.as_mut() {
                    h.primitive = 3
                }
            },
            CaseKind::Degenerate,
        );
        assert!(r.metrics.false_hits > 0, "hits on the NaN-X triangle: {r:?}");
        let r = broken(
            |t| {
                t.candidates += 1;
                t.first_candidates[1] = t.first_candidates[0];
            },
            CaseKind::Tmin,
        );
        assert!(r.metrics.double_hits > 0 && r.metrics.duplicate_any_hits > 0);
        let r = broken(|t| t.hit = None, CaseKind::Tmin);
        assert!(r.metrics.leaks > 0, "certain hits dropped");
        {
            let r = broken(|t| t.hit = None, CaseKind::Watertight);
            assert_eq!(r.verdict, crate::stress::evaluate::Verdict::Fail);
        }
    }

    #[test]
    fn a_sloppy_intersector_leaks_and_fails() {
        let mut t = CpuTracer { name: "sloppy f32 Möller–Trumbore", intersect: sloppy_f32 };
        let r = case(&mut t, CaseKind::Watertight);
        assert!(r.metrics.leaks > 100, "{r:?}");
        assert_eq!(r.verdict, crate::stress::evaluate::Verdict::Fail);
    }
}
