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
        assert_eq!(read_per_mesh(&d, &scene, (slot, g, p)), Some(truth));
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
        Some(read_per_mesh(&d, &scene, (n, g, p)).expect("padded: in bounds"))
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

/// A mutant's wrong descriptor reads another slot's buffer: for a hit on any mesh's (geometry,
/// primitive), every slot's buffer holds every word the fetch reads (the padding), and the
/// indices it reads are vertices of the buffer's own mesh; the twin: the unpadded words (the
/// mesh's own data only) leave some such read outside.
#[test]
fn every_slots_buffer_holds_every_hits_reads() {
    let scene = Scene::build(&SceneParams::default());
    let d = LayoutData::new(&scene).unwrap();
    let (mut reads, mut outside_unpadded) = (0, 0);
    for slot in 0..d.slot_mesh.len() {
        let w = d.mesh_words(&scene, slot);
        let own = &scene.meshes[d.held(&scene, slot)];
        let unpadded = unpadded_words(&scene, &d, slot);
        for mesh in &scene.meshes {
            for (g, r) in mesh.geometries.iter().enumerate() {
                for p in 0..r.end - r.start {
                    let f = read_mesh_words(&w, g as u32, p);
                    let f = f.unwrap_or_else(|| panic!("slot {slot}: ({g}, {p}) read outside"));
                    assert!(f.indices.iter().all(|&i| (i as usize) < own.positions.len()));
                    reads += 1;
                    outside_unpadded += read_mesh_words(&unpadded, g as u32, p).is_none() as usize;
                }
            }
        }
    }
    assert!(reads > 1000 && outside_unpadded > 0, "{reads} reads, {outside_unpadded} need padding");
}

/// Slot `slot`'s buffer without the padding: header, the mesh's indices, table, positions.
fn unpadded_words(scene: &Scene, d: &LayoutData, slot: usize) -> Vec<u32> {
    let mesh = &scene.meshes[d.held(scene, slot)];
    let table = 2 + 3 * mesh.indices.len() as u32;
    let mut w = vec![table + 2 * mesh.geometries.len() as u32, table];
    w.extend(mesh.indices.iter().flatten());
    let padded = d.mesh_words(scene, slot);
    let (t, pos) = (padded[1] as usize, padded[0] as usize);
    w.extend(&padded[t..t + 2 * mesh.geometries.len()]);
    w.extend(&padded[pos..]);
    w
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
