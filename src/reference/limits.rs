//! What a scene cannot discriminate (`run --scene`). The probe contract assumes what the
//! procedural scene guarantees: custom indices whose masked low bits are a permutation of the
//! instance indices without a fixed point (a driver handing `gl_InstanceID` for
//! `gl_InstanceCustomIndexEXT` reads another slot) and distinct per instance (a driver reading
//! another instance's custom index reads another slot), procedural geometry for the intersection
//! probe, and pixels that hit and pixels that miss. A loaded glTF scene's custom index is its
//! mesh's index, so it may equal the instance index or repeat across instances; the cells that
//! rely on what the scene breaks are named, with why and on what share of their pixels.
use super::SceneReference;
use crate::model::{Cell, SceneLimit, Stage};
use crate::probe::spec::{ElementMap, ProbeSpec, Sampler, SlotSource};
use crate::scene::{Geometry, Scene};

/// What the scene breaks, one entry per reason, each with the cells (of `cells`) it touches.
pub fn of(scene: &Scene, sref: &SceneReference, cells: &[Cell]) -> Vec<SceneLimit> {
    let facts = Facts::of(scene, sref);
    let mut out: Vec<SceneLimit> = Vec::new();
    for c in cells.iter().filter(|c| c.canary.is_none()) {
        let Some((why, share)) = facts.limit(c) else { continue };
        match out.iter_mut().find(|l| l.why == why) {
            Some(l) => l.cells.push(c.id()),
            None => out.push(SceneLimit { why, share, cells: vec![c.id()] }),
        }
    }
    out
}

/// What the scene's instances and primary rays show.
struct Facts {
    spheres: bool,
    hits: usize,
    misses: usize,
    /// Why custom indices do not tell instances apart, and the share of hit pixels it covers.
    custom: Option<(String, f64)>,
}

impl Facts {
    fn of(scene: &Scene, sref: &SceneReference) -> Facts {
        let clear = sref.full.iter().filter(|t| !t.ambiguous);
        let (hits, misses) =
            clear
                .clone()
                .fold((0, 0), |(h, m), t| if t.hit.is_some() { (h + 1, m) } else { (h, m + 1) });
        let spheres = scene.instances.iter().any(|i| i.geometry == Geometry::Sphere);
        let (why, aliased) = aliased_instances(scene);
        let on_aliased = clear
            .filter_map(|t| t.hit)
            .filter(|h| aliased.get(h.instance_id as usize).copied().unwrap_or(false))
            .count();
        let custom = why.map(|w| (w, on_aliased as f64 / hits.max(1) as f64));
        Facts { spheres, hits, misses, custom }
    }

    /// Why `c`'s probe cannot discriminate on this scene, and on what share of its pixels.
    fn limit(&self, c: &Cell) -> Option<(String, f64)> {
        let spec = ProbeSpec::of(c);
        match spec.stage {
            Stage::Intersection if !self.spheres => {
                return Some(("the scene has no procedural (AABB) geometry: the intersection probe never runs".into(), 1.0));
            }
            Stage::ClosestHit | Stage::AnyHit | Stage::Intersection if self.hits == 0 => {
                return Some((
                    "no primary ray hits the scene: the hit probes never run".into(),
                    1.0,
                ));
            }
            Stage::Miss if self.misses == 0 => {
                return Some((
                    "every primary ray hits the scene: the miss probe never runs".into(),
                    1.0,
                ));
            }
            Stage::ClosestHit | Stage::AnyHit | Stage::Intersection => {}
            Stage::Raygen | Stage::Miss | Stage::Callable | Stage::Fragment | Stage::Compute => {
                return None
            }
        }
        let reads_custom = spec.slot == SlotSource::Dynamic
            || matches!(spec.sampler, Sampler::Dynamic { .. })
            || matches!(spec.element, ElementMap::Packed | ElementMap::Layer);
        self.custom.clone().filter(|(_, share)| reads_custom && *share > 0.0)
    }
}

/// Which instances' masked custom index equals their instance index or another instance's, and
/// the sentence saying so (`None`: the scene keeps the contract).
fn aliased_instances(scene: &Scene) -> (Option<String>, Vec<bool>) {
    let mask = crate::probe::instance_mask(scene.instances.len() as u32);
    let masked: Vec<u32> = scene.instances.iter().map(|i| i.custom_index & mask).collect();
    let equal: Vec<usize> = (0..masked.len()).filter(|&k| masked[k] == k as u32 & mask).collect();
    let repeated: Vec<usize> = (0..masked.len())
        .filter(|&k| masked.iter().enumerate().any(|(j, m)| j != k && *m == masked[k]))
        .collect();
    let aliased: Vec<bool> =
        (0..masked.len()).map(|k| equal.contains(&k) || repeated.contains(&k)).collect();
    let list = |v: &[usize]| v.iter().map(usize::to_string).collect::<Vec<_>>().join(", ");
    let mut parts = Vec::new();
    if !equal.is_empty() {
        parts.push(format!("equals the instance index on instances {} (a driver returning gl_InstanceID reads the same slot there)", list(&equal)));
    }
    if !repeated.is_empty() {
        parts.push(format!("is shared by instances {} (a driver reading another instance's custom index reads the same slot there)", list(&repeated)));
    }
    let why = (!parts.is_empty())
        .then(|| format!("the scene's custom index (masked {mask:#x}) {}", parts.join(", and ")));
    (why, aliased)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::SceneParams;
    use crate::scene::gltf::make::{make, MakeOptions};

    fn cells() -> Vec<Cell> {
        crate::matrix::plan::all_cells().0
    }

    #[test]
    fn the_procedural_scene_keeps_the_contract() {
        let scene = Scene::build(&SceneParams::default());
        let sref = SceneReference::compute(&scene);
        assert_eq!(aliased_instances(&scene).0, None);
        assert!(of(&scene, &sref, &cells()).is_empty());
    }

    /// The test scene: custom indices 0, 1, 2, 2, 2 (the mesh's) on instances 0..5, no sphere.
    #[test]
    fn the_test_scene_names_what_it_breaks_and_where() {
        let dir = crate::tempdir::tempdir().unwrap();
        let path = make(dir.path(), MakeOptions { triangles: 0, glb: false }).unwrap();
        let loaded = crate::scene::gltf::Loaded::load(&path).unwrap();
        let scene = crate::scene::gltf::fit::to_scene(&loaded, &SceneParams::default());
        let sref = SceneReference::compute(&scene);
        let (why, aliased) = aliased_instances(&scene);
        assert_eq!(aliased, vec![true, true, true, true, true]);
        let why = why.unwrap();
        assert!(
            why.contains("instances 0, 1, 2 (") && why.contains("shared by instances 2, 3, 4"),
            "{why}"
        );
        let all = cells();
        let limits = of(&scene, &sref, &all);
        let named = |needle: &str| limits.iter().find(|l| l.why.contains(needle)).unwrap();
        let sphere = named("no procedural");
        assert_eq!(sphere.share, 1.0);
        let intersection = all.iter().filter(|c| c.stage == Stage::Intersection).count();
        assert_eq!(sphere.cells.len(), intersection);
        let custom = named("custom index");
        assert!(custom.share > 0.99, "every hit is on an aliased instance: {}", custom.share);
        assert!(custom.cells.iter().all(|id| id.contains("closest_hit") || id.contains("any_hit")));
        // Raygen cells read no custom index: never named.
        assert!(limits.iter().all(|l| l.cells.iter().all(|id| !id.contains("stage=raygen"))));
    }
}
