//! Both layouts' bytes, read as the shaders read them, give the scene's own triangles; each
//! twin (another mesh's buffer, the next primitive, another table entry) gives other data.
use super::*;
use crate::model::SceneParams;

/// Every (slot, mesh, geometry, primitive) a primary ray can hit on a triangle instance.
fn hits(scene: &Scene) -> Vec<(u32, usize, u32, u32)> {
    let mut out = vec![];
    for inst in &scene.instances {
        let Geometry::Mesh(m) = inst.geometry else { continue };
        let slot = slot_of(scene, inst.custom_index);
        for (g, r) in scene.meshes[m].geometries.iter().enumerate() {
            out.extend((0..r.end - r.start).map(|p| (slot, m, g as u32, p)));
        }
    }
    out
}

#[test]
fn both_layouts_read_the_scenes_own_triangles() {
    let scene = Scene::build(&SceneParams::default());
    let d = LayoutData::new(&scene).unwrap();
    let all = hits(&scene);
    assert!(all.len() > 1000);
    for &(slot, m, g, p) in &all {
        let truth = fetch(&scene, m, g, p);
        assert_eq!(read_shared(&d, &scene, (slot, g, p)), truth);
        assert_eq!(read_per_mesh(&d, &scene, (slot, g, p)), truth);
    }
}

#[test]
fn twins_read_other_data() {
    let scene = Scene::build(&SceneParams::default());
    let d = LayoutData::new(&scene).unwrap();
    let all = hits(&scene);
    let differs = |f: &dyn Fn(u32, usize, u32, u32) -> Option<Fetched>| {
        all.iter()
            .filter(|&&(s, m, g, p)| f(s, m, g, p).is_some_and(|x| x != fetch(&scene, m, g, p)))
            .count()
    };
    let slots = d.slot_mesh.len() as u32;
    // The wrong mesh's descriptor: the next slot.
    let next_slot = differs(&|s, _, g, p| {
        let n = (s + 1) % slots;
        (p < 3).then(|| read_per_mesh(&d, &scene, (n, g, p)))
    });
    // The wrong element: the next primitive of the same geometry.
    let next_prim = differs(&|s, m, g, p| {
        let r = &scene.meshes[m].geometries[g as usize];
        (p + 1 < r.end - r.start).then(|| read_shared(&d, &scene, (s, g, p + 1)))
    });
    // The wrong table entry: the geometry's neighbour's PrimMeshInfo.
    let next_entry = differs(&|s, m, g, p| {
        let n = scene.meshes[m].geometries.len() as u32;
        let r = &scene.meshes[m].geometries[((g + 1) % n) as usize];
        (p < r.end - r.start).then(|| read_shared(&d, &scene, (s, (g + 1) % n, p)))
    });
    assert!(
        next_slot > 0 && next_prim > 0 && next_entry > 0,
        "{next_slot} {next_prim} {next_entry}"
    );
}

#[test]
fn custom_indices_that_mix_meshes_in_one_slot_are_refused() {
    let mut scene = Scene::build(&SceneParams::default());
    let meshes: Vec<usize> = scene
        .instances
        .iter()
        .map(|i| match i.geometry {
            Geometry::Mesh(m) => m,
            Geometry::Sphere => usize::MAX,
        })
        .collect();
    let a = (0..meshes.len()).find(|&k| meshes[k] == 0).unwrap();
    let b = (0..meshes.len()).find(|&k| meshes[k] == 1).unwrap();
    scene.instances[b].custom_index = scene.instances[a].custom_index;
    assert!(matches!(LayoutData::new(&scene), Err(LayoutError::SlotClash { .. })));
}
