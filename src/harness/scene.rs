//! The harness's scene: rtprobe's seeded scene at a smaller mesh detail, with custom indices
//! small enough to index a descriptor array with. Engine shaders index bindless arrays with
//! `gl_InstanceCustomIndexEXT`, `gl_InstanceID`, `gl_GeometryIndexEXT` or `gl_PrimitiveID`; the
//! probe scene's custom indices reach 2^24 − 1 (and the AS probe's variants `variant · 8192 + k`),
//! far past any array the harness can make, so a runtime array indexed by one read out of bounds
//! and crashed the driver. Here every index the scene can produce is below [`INDEX_BOUND`], and
//! the harness gives runtime arrays that many elements (`reflect::RUNTIME_ELEMENTS`).
use crate::model::SceneParams;
use crate::scene::{Geometry, Scene};

/// Width and height of the traced image: a per-pixel index reaches `TRACE_SIZE² − 1`.
pub const TRACE_SIZE: u32 = 64;

/// Every index the harness scene produces (custom index, instance index, geometry index,
/// primitive index within its geometry) is below this.
pub const INDEX_BOUND: u32 = 64;

/// The scene parameters: 16 instances, meshes of at most 8×8 quads (128 triangles, in three
/// geometries of at most 43), traced at `size`×`size`.
fn params(size: u32) -> SceneParams {
    SceneParams { width: size, height: size, mesh_detail: 8, ..SceneParams::default() }
}

/// The custom index of scene instance `k` of `n`: a permutation of 0..n without fixed points
/// (`5k + 3 mod n`, `n` a power of two), so the custom index is never the instance index.
fn scene_custom(k: u32, n: u32) -> u32 {
    (5 * k + 3) % n
}

/// The custom index of instance `k` in probe TLAS variant `v`: unlike the scene TLAS's and the
/// other variants' (for most instances), below [`INDEX_BOUND`] / 2.
pub fn variant_custom(v: u32, k: u32) -> u32 {
    (7 * v + 3 * k + 1) % (INDEX_BOUND / 2)
}

/// The harness scene, `size`×`size`.
pub fn build(size: u32) -> Scene {
    let mut s = Scene::build(&params(size));
    let n = s.instances.len() as u32;
    for (k, i) in s.instances.iter_mut().enumerate() {
        i.custom_index = scene_custom(k as u32, n);
    }
    s
}

/// A `--scene` file's scene as the harness traces it: fitted into the view at `size`×`size`
/// (`scene::gltf::fit`), then one BLAS per primitive and one instance per (node, primitive),
/// custom index the primitive's global index, as the glTF ray tracing tutorial
/// (`per_primitive::flatten`).
pub fn loaded(l: &crate::scene::gltf::Loaded, size: u32) -> Scene {
    super::per_primitive::flatten(crate::scene::gltf::fit::to_scene(l, &params(size)))
}

/// The runtime array elements a `--scene` file needs: one more than every index its hit
/// shaders can see (custom index, instance, geometry, primitive within a geometry, and the
/// probe TLAS variants' custom indices), at least [`INDEX_BOUND`].
pub fn loaded_bound(l: &crate::scene::gltf::Loaded) -> u32 {
    let s = loaded(l, TRACE_SIZE);
    let variants = crate::probe::as_variants(s.instances.len() as u32);
    index_bound(&s, variants, variant_custom).max(INDEX_BOUND)
}

/// One more than the largest index `scene` can produce in a hit shader, with its probe TLAS
/// variants' custom indices from `custom` (over `variants` variants).
pub fn index_bound(scene: &Scene, variants: u32, custom: fn(u32, u32) -> u32) -> u32 {
    let n = scene.instances.len() as u32;
    let customs = scene.instances.iter().map(|i| i.custom_index);
    let variant_customs = (0..variants).flat_map(|v| (0..=n).map(move |k| custom(v, k)));
    let primitives = scene.meshes.iter().flat_map(|m| m.geometries.iter().map(|g| g.len() as u32));
    let geometries = scene.meshes.iter().map(|m| m.geometries.len() as u32 - 1);
    let sphere = scene.instances.iter().any(|i| i.geometry == Geometry::Sphere) as u32;
    customs
        .chain(variant_customs)
        .chain(primitives.map(|p| p.saturating_sub(1)))
        .chain(geometries)
        .chain([n, sphere])
        .max()
        .unwrap_or(0)
        + 1
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::harness::reflect::{RUNTIME_ELEMENTS, RUNTIME_MEMBERS};

    /// A loaded scene's bound covers its largest primitive index: the test scene's ground has
    /// 128 triangles in one geometry, more than the harness scene's bound.
    #[test]
    fn a_loaded_scenes_bound_covers_its_primitives() {
        let d = crate::tempdir::tempdir().unwrap();
        let o = crate::scene::gltf::make::MakeOptions { triangles: 0, glb: false };
        let l =
            crate::scene::gltf::Loaded::load(&crate::scene::gltf::make::make(d.path(), o).unwrap())
                .unwrap();
        let most = l.meshes.iter().flat_map(|m| m.primitives.iter().map(|p| p.triangles)).max();
        assert!(loaded_bound(&l) >= most.unwrap(), "{}", loaded_bound(&l));
        assert!(most.unwrap() > INDEX_BOUND, "the twin: the default bound would not cover it");
    }

    #[test]
    fn runtime_arrays_cover_every_index_the_harness_scene_produces() {
        let s = build(64);
        let variants = crate::probe::as_variants(s.instances.len() as u32);
        let bound = index_bound(&s, variants, variant_custom);
        assert!(bound <= INDEX_BOUND, "{bound}");
        const { assert!(RUNTIME_ELEMENTS >= INDEX_BOUND) };
        // A block's runtime array covers four words per index (`v[3 * gl_PrimitiveID + 2]`).
        const { assert!(RUNTIME_MEMBERS >= 4 * INDEX_BOUND) };
        // …and one element per traced pixel (a per-pixel index reaches width × height − 1).
        const { assert!(RUNTIME_MEMBERS >= TRACE_SIZE * TRACE_SIZE) };
        // The custom index is a permutation unlike the instance index.
        let mut c: Vec<u32> = s.instances.iter().map(|i| i.custom_index).collect();
        assert!(c.iter().enumerate().all(|(k, x)| *x != k as u32), "{c:?}");
        c.sort_unstable();
        assert_eq!(c, (0..s.instances.len() as u32).collect::<Vec<_>>());
        // Twin: the probe scene's custom indices (and its AS variants') are far out of range.
        let probe = Scene::build(&SceneParams::default());
        assert!(index_bound(&probe, 0, crate::probe::as_custom) > 1 << 20);
        assert!(index_bound(&s, variants, crate::probe::as_custom) > INDEX_BOUND);
    }
}
