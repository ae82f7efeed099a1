//! The CPU reference: the scene traced in f64 ([`intersect`]), the record every cell should
//! produce per pixel ([`expected`]), and the comparison with documented tolerances ([`compare`]).
//!
//! Tolerances: flags, instance, primitive and slot must match exactly; probe values exactly (they
//! are small integers and quarters, exact in f32); `t` within 1e-3 relative (f32 traversal vs f64,
//! inverse transforms computed on both sides); barycentrics within 1e-3. Pixels whose hit lies
//! within 1e-4 (barycentric) of an edge or silhouette, or within 1e-4 relative distance of another
//! surface, are counted as `ambiguous` and skipped: there the GPU may pick either surface.
//!
//! `index=dynamic` without `nonuniform` indexes with a value that differs between invocations but
//! carries no `NonUniform` decoration: the Vulkan spec then leaves undefined *which* array element
//! is read (drivers commonly read one lane's element for the whole group). There the value must be
//! the value of *some* element of the array ([`ValueRule::AnyElement`]), which still catches
//! garbage reads, device losses and crashes; the slot the shader computed is still exact.
pub mod intersect;
pub mod watertight;

use crate::matrix::{Cell, IndexSource, Resource, Stage};
use crate::probe::{self, Record, FLAG_HIT, FLAG_PROBE};
use crate::scene::Scene;
use intersect::TraceRef;
use serde::{Deserialize, Serialize};

pub const T_REL_TOL: f64 = 1e-3;
pub const BARY_TOL: f64 = 1e-3;

/// Primary rays of every pixel traced through both TLASes the probes use.
pub struct SceneReference {
    /// Through the whole scene (TLAS 0).
    pub full: Vec<TraceRef>,
    /// Through the instances with an even custom index (TLAS 1).
    pub even: Vec<TraceRef>,
}

impl SceneReference {
    pub fn compute(scene: &Scene) -> Self {
        let (w, h) = (scene.params.width, scene.params.height);
        let mut full = Vec::with_capacity(scene.params.pixels());
        let mut even = Vec::with_capacity(scene.params.pixels());
        for y in 0..h {
            for x in 0..w {
                let (o, d) = scene.primary_ray(x, y);
                full.push(intersect::trace(scene, o, d, |_| true));
                even.push(intersect::trace(scene, o, d, |i| i.custom_index % 2 == 0));
            }
        }
        Self { full, even }
    }

    pub fn ambiguous_pixels(&self) -> usize {
        self.full.iter().filter(|t| t.ambiguous).count()
    }
}

/// How the probed value is checked.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ValueRule {
    Exact,
    /// Any element of the probed array is allowed (non-uniform index without NonUniform).
    AnyElement { resource: Resource, slots: u32, alternatives: [[f32; 4]; 2] },
}

#[derive(Clone, Copy, Debug)]
pub struct Expected {
    pub record: Record,
    pub ambiguous: bool,
    pub rule: ValueRule,
}

impl ValueRule {
    fn allows(&self, v: [f32; 4]) -> bool {
        match *self {
            ValueRule::Exact => false,
            ValueRule::AnyElement { resource: Resource::AccelerationStructure, alternatives, .. } => alternatives.contains(&v),
            ValueRule::AnyElement { resource, slots, .. } => {
                let s = v[0] - 1.0;
                s >= 0.0 && s.fract() == 0.0 && (s as u32) < slots && probe::resource_value(resource, s as u32) == v
            }
        }
    }
}

/// What `cell` must write for every pixel. `corrupt` (tests only) perturbs every probed value and
/// checks it exactly, so that a correct GPU result must be reported as a mismatch.
pub fn expected(cell: &Cell, scene: &Scene, sref: &SceneReference, corrupt: bool) -> Vec<Expected> {
    let (w, h) = (scene.params.width, scene.params.height);
    let slots = probe::slot_count(scene.params.instances);
    let mut out = Vec::with_capacity(scene.params.pixels());
    for y in 0..h {
        for x in 0..w {
            let p = (y * w + x) as usize;
            let mut rec = Record::default();
            let mut ambiguous = false;
            let traced = cell.stage.is_ray_tracing();
            let primary = sref.full[p];
            if traced {
                ambiguous = primary.ambiguous;
                if let Some(hit) = primary.hit {
                    rec.flags |= FLAG_HIT;
                    rec.instance = hit.instance;
                    rec.primitive = hit.primitive;
                    rec.t = hit.t as f32;
                    rec.bary = [hit.bary[0] as f32, hit.bary[1] as f32];
                }
            }
            let hit = primary.hit;
            let mut rule = ValueRule::Exact;
            let probe_runs = match cell.stage {
                Stage::Raygen | Stage::Callable | Stage::Fragment | Stage::Compute => true,
                Stage::ClosestHit | Stage::AnyHit => hit.is_some(),
                Stage::Intersection => hit.is_some_and(|h| h.sphere),
                Stage::Miss => hit.is_none(),
            };
            if probe_runs {
                let slot = match cell.index {
                    IndexSource::Literal => probe::LITERAL_SLOT,
                    IndexSource::SpecConstant => probe::SPEC_SLOT,
                    IndexSource::PushConstant => probe::PUSH_SLOT,
                    IndexSource::Dynamic => probe::dynamic_slot(cell.stage, x, y, w, hit.map(|h| h.instance).unwrap_or(0), slots),
                };
                rec.flags |= FLAG_PROBE;
                rec.slot = slot;
                // pin-index: the shader still records its computed slot, but reads the pinned one.
                let pinned = cell.patch == Some(crate::matrix::cell::Workaround::PinIndex);
                let slot = if pinned { probe::SPEC_SLOT } else { slot };
                let as_value = |t: &TraceRef| [if t.hit.is_some() { 1.0 } else { 0.0 }, 0.0, 0.0, 1.0];
                rec.value = if cell.resource == Resource::AccelerationStructure {
                    let t = if probe::as_slot_tlas(slot) == 0 { sref.full[p] } else { sref.even[p] };
                    ambiguous |= t.ambiguous;
                    as_value(&t)
                } else {
                    probe::resource_value(cell.resource, slot)
                };
                let made_uniform = matches!(cell.patch, Some(crate::matrix::cell::Workaround::Nonuniform | crate::matrix::cell::Workaround::PinIndex));
                if cell.index == IndexSource::Dynamic && !cell.nonuniform && !made_uniform && !corrupt {
                    if cell.resource == Resource::AccelerationStructure {
                        ambiguous |= sref.full[p].ambiguous || sref.even[p].ambiguous;
                    }
                    rule = ValueRule::AnyElement {
                        resource: cell.resource,
                        slots,
                        alternatives: [as_value(&sref.full[p]), as_value(&sref.even[p])],
                    };
                }
                if corrupt {
                    rec.value[0] += 1.0;
                }
            }
            out.push(Expected { record: rec, ambiguous, rule });
        }
    }
    out
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Mismatch {
    pub pixel: [u32; 2],
    pub field: String,
    pub expected: String,
    pub actual: String,
}

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Comparison {
    pub pixels: usize,
    pub compared: usize,
    pub ambiguous: usize,
    pub mismatched_pixels: usize,
    /// Mismatch counts per field (stable order).
    pub by_field: std::collections::BTreeMap<String, usize>,
    /// Largest relative `t` error and absolute barycentric / value error seen on compared pixels.
    pub worst_t_rel: f64,
    pub worst_bary: f64,
    pub worst_value: f64,
    /// Pixels whose value was checked against every element of the array (see [`ValueRule`]).
    #[serde(default)]
    pub any_element_values: usize,
    /// The first few mismatches, for the report.
    pub examples: Vec<Mismatch>,
    /// Pictures of a mismatching comparison (expected, actual, diff PNGs; `run --dump`).
    #[serde(skip_serializing_if = "Vec::is_empty", default)]
    pub pictures: Vec<String>,
}

impl Comparison {
    pub fn passed(&self) -> bool {
        self.mismatched_pixels == 0
    }
}

pub fn compare(expected: &[Expected], actual: &[Record], width: u32) -> Comparison {
    let mut c = Comparison { pixels: expected.len(), ..Default::default() };
    for (i, (e, a)) in expected.iter().zip(actual).enumerate() {
        if e.ambiguous {
            c.ambiguous += 1;
            continue;
        }
        c.compared += 1;
        let r = &e.record;
        let mut bad: Vec<(&str, String, String)> = Vec::new();
        if r.flags != a.flags {
            bad.push(("flags", r.flags.to_string(), a.flags.to_string()));
        } else {
            if r.flags & FLAG_HIT != 0 {
                if (r.instance, r.primitive) != (a.instance, a.primitive) {
                    bad.push(("instance_primitive", format!("{}/{}", r.instance, r.primitive), format!("{}/{}", a.instance, a.primitive)));
                } else {
                    let te = ((a.t as f64 - r.t as f64) / (r.t as f64).abs().max(1.0)).abs();
                    c.worst_t_rel = c.worst_t_rel.max(te);
                    if te > T_REL_TOL || !a.t.is_finite() {
                        bad.push(("t", r.t.to_string(), a.t.to_string()));
                    }
                    let be = (a.bary[0] as f64 - r.bary[0] as f64).abs().max((a.bary[1] as f64 - r.bary[1] as f64).abs());
                    c.worst_bary = c.worst_bary.max(be);
                    if be > BARY_TOL || !be.is_finite() {
                        bad.push(("bary", format!("{:?}", r.bary), format!("{:?}", a.bary)));
                    }
                }
            }
            if r.flags & FLAG_PROBE != 0 {
                if r.slot != a.slot {
                    bad.push(("slot", r.slot.to_string(), a.slot.to_string()));
                }
                let ve = r.value.iter().zip(a.value).map(|(x, y)| (*x as f64 - y as f64).abs()).fold(0.0, f64::max);
                let allowed = ve != 0.0 && e.rule.allows(a.value);
                if e.rule != ValueRule::Exact {
                    c.any_element_values += 1;
                }
                if !allowed {
                    c.worst_value = c.worst_value.max(if ve.is_nan() { f64::INFINITY } else { ve });
                }
                if ve != 0.0 && !allowed {
                    bad.push(("value", format!("{:?}", r.value), format!("{:?}", a.value)));
                }
            }
        }
        if !bad.is_empty() {
            c.mismatched_pixels += 1;
            for (field, exp, act) in bad {
                *c.by_field.entry(field.to_string()).or_default() += 1;
                if c.examples.len() < 8 {
                    let pixel = [i as u32 % width, i as u32 / width];
                    c.examples.push(Mismatch { pixel, field: field.into(), expected: exp, actual: act });
                }
            }
        }
    }
    c
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::matrix::{DescriptorModel, Resource};
    use crate::scene::SceneParams;

    fn cell(stage: Stage, index: IndexSource) -> Cell {
        Cell { stage, resource: Resource::StorageBuffer, index, nonuniform: false, as_access: None, descriptor_model: DescriptorModel::DescriptorIndexing, canary: None, patch: None, reorder: None }
    }

    #[test]
    fn default_scene_has_hits_misses_spheres_and_few_ambiguous_pixels() {
        let scene = Scene::build(&SceneParams::default());
        let r = SceneReference::compute(&scene);
        let hits = r.full.iter().filter(|t| t.hit.is_some()).count();
        let spheres = r.full.iter().filter(|t| t.hit.is_some_and(|h| h.sphere)).count();
        let n = r.full.len();
        assert!(hits > n / 5 && hits < n, "hits {hits} of {n}");
        assert!(spheres > 50, "spheres {spheres}");
        assert!(r.ambiguous_pixels() < n / 20, "ambiguous {}", r.ambiguous_pixels());
        let even_hits = r.even.iter().filter(|t| t.hit.is_some()).count();
        assert!(even_hits < hits && even_hits > 0);
    }

    #[test]
    fn expected_records_compare_equal_to_themselves_and_corruption_is_caught() {
        let scene = Scene::build(&SceneParams::default());
        let r = SceneReference::compute(&scene);
        let c = cell(Stage::ClosestHit, IndexSource::Dynamic);
        let e = expected(&c, &scene, &r, false);
        let actual: Vec<Record> = e.iter().map(|x| x.record).collect();
        let cmp = compare(&e, &actual, 64);
        assert!(cmp.passed() && cmp.compared > 0);
        let bad = expected(&c, &scene, &r, true);
        let cmp = compare(&bad, &actual, 64);
        assert!(!cmp.passed());
        assert_eq!(cmp.by_field.keys().collect::<Vec<_>>(), vec!["value"]);
        assert!(cmp.worst_value >= 1.0);
    }

    #[test]
    fn nonuniform_index_without_qualifier_accepts_any_element_but_not_garbage() {
        let scene = Scene::build(&SceneParams::default());
        let r = SceneReference::compute(&scene);
        let c = Cell { resource: Resource::UniformBuffer, ..cell(Stage::Raygen, IndexSource::Dynamic) };
        let e = expected(&c, &scene, &r, false);
        let mut actual: Vec<Record> = e.iter().map(|x| x.record).collect();
        // Another element's value (as a driver reading one lane's descriptor would return): fine.
        actual[10].value = crate::probe::resource_value(Resource::UniformBuffer, 0);
        let cmp = compare(&e, &actual, 64);
        assert!(cmp.passed(), "{cmp:?}");
        assert_eq!(cmp.any_element_values, cmp.compared);
        // Garbage is not.
        actual[11].value = [7.5, 0.0, 0.0, 0.0];
        assert!(!compare(&e, &actual, 64).passed());
        // With nonuniformEXT the element must be exact.
        let nu = Cell { nonuniform: true, ..c };
        let e = expected(&nu, &scene, &r, false);
        assert!(!compare(&e, &actual, 64).passed());
    }

    #[test]
    fn miss_probes_only_run_on_misses() {
        let scene = Scene::build(&SceneParams::default());
        let r = SceneReference::compute(&scene);
        let e = expected(&cell(Stage::Miss, IndexSource::Literal), &scene, &r, false);
        for (x, t) in e.iter().zip(&r.full) {
            assert_eq!(x.record.flags & FLAG_PROBE != 0, t.hit.is_none());
        }
    }
}
