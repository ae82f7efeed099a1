//! `run --shader --scene`'s scene laid out as the glTF ray tracing tutorial (nvpro's
//! `ray_tracing_gltf`) lays it out: one BLAS per primitive ("primMesh"), one TLAS instance per
//! (node, primitive), `instanceCustomIndex` the primitive's global index — primitives numbered
//! mesh by mesh, in the order of `scene_data`'s flat `PrimMeshInfo` table — so that
//! `primInfo[gl_InstanceCustomIndexEXT]` (the tutorial) and
//! `primInfo[gl_InstanceCustomIndexEXT + gl_GeometryIndexEXT]` (engines with multi-geometry
//! BLASes; the geometry index is 0 here) both read the hit primitive's entry. Only the harness's
//! scene is flattened; the generated matrix's `--scene` keeps one BLAS per mesh.
use crate::scene::{Geometry, Instance, Mesh, Scene};

/// One geometry of `m` as a mesh of its own: its triangles, with only the vertices they use
/// (indices renumbered from the lowest one used).
fn geometry_mesh(m: &Mesh, g: &std::ops::Range<u32>) -> Mesh {
    let tris = &m.indices[g.start as usize..g.end as usize];
    let lo = tris.iter().flatten().copied().min().unwrap_or(0);
    let hi = tris.iter().flatten().copied().max().map_or(lo, |h| h + 1);
    let indices: Vec<[u32; 3]> = tris.iter().map(|t| t.map(|i| i - lo)).collect();
    Mesh {
        positions: m.positions[lo as usize..hi as usize].to_vec(),
        geometries: std::iter::once(0..indices.len() as u32).collect(),
        indices,
    }
}

/// `scene` with each mesh's geometries made meshes of their own and each instance of a mesh
/// made one instance per geometry (same transform), custom index the geometry's global index
/// (its mesh's first global index plus the geometry index). The floor stays one mesh (last);
/// spheres stay as they are. Parameters and `no_opaque` carry over.
pub fn flatten(scene: Scene) -> Scene {
    let floor_mesh = match scene.floor.geometry {
        Geometry::Mesh(k) => Some(k),
        Geometry::Sphere => None,
    };
    let mut meshes = Vec::new();
    // Per old mesh: its first new mesh, its first global primitive index, its geometries.
    let mut first = Vec::with_capacity(scene.meshes.len());
    let mut global = 0u32;
    for (k, m) in scene.meshes.into_iter().enumerate() {
        let n = m.geometries.len();
        first.push((meshes.len(), global, n));
        if Some(k) == floor_mesh {
            meshes.push(m);
            continue;
        }
        meshes.extend(m.geometries.iter().map(|g| geometry_mesh(&m, g)));
        global += n as u32;
    }
    let mut instances = Vec::new();
    for i in &scene.instances {
        match i.geometry {
            Geometry::Mesh(k) => {
                let (at, prim, n) = first[k];
                instances.extend((0..n).map(|g| Instance {
                    transform: i.transform,
                    custom_index: prim + g as u32,
                    geometry: Geometry::Mesh(at + g),
                }));
            }
            Geometry::Sphere => instances.push(Instance { ..*i }),
        }
    }
    let floor = Instance {
        geometry: floor_mesh.map_or(Geometry::Sphere, |k| Geometry::Mesh(first[k].0)),
        ..scene.floor
    };
    let params = crate::model::SceneParams { instances: instances.len() as u32, ..scene.params };
    let procedural_sbt_offset = scene.procedural_sbt_offset;
    // The matrix's scene-layout texture cells never run on a flattened scene: its own synthetic
    // textures, per geometry of the new meshes.
    let geometries: Vec<usize> = meshes.iter().map(|m| m.geometries.len()).collect();
    let textures = crate::scene::textures::SceneTextures::synthetic(&geometries, params.seed);
    Scene {
        params,
        meshes,
        instances,
        floor,
        no_opaque: scene.no_opaque,
        procedural_sbt_offset,
        textures,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::SceneParams;

    fn quad(z: f32) -> Vec<[f32; 3]> {
        vec![[0.0, 0.0, z], [1.0, 0.0, z], [0.0, 1.0, z], [1.0, 1.0, z]]
    }

    /// Two meshes (two geometries, then one), instanced three times: every (instance,
    /// geometry) becomes an instance whose mesh holds exactly that geometry's triangles, its
    /// custom index the geometry's global index; the floor stays last and unsplit.
    #[test]
    fn each_primitive_becomes_a_blas_and_each_node_primitive_an_instance() {
        let a = Mesh {
            positions: [quad(0.0), quad(1.0)].concat(),
            indices: vec![[0, 1, 2], [1, 3, 2], [4, 5, 6]],
            geometries: vec![0..2, 2..3],
        };
        let b = Mesh {
            positions: quad(2.0),
            indices: vec![[0, 1, 2]],
            geometries: std::iter::once(0..1).collect(),
        };
        let inst = |m, x| Instance {
            transform: [[1.0, 0.0, 0.0, x], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]],
            custom_index: 99,
            geometry: Geometry::Mesh(m),
        };
        let params = SceneParams::default();
        let s =
            Scene::with_meshes(&params, vec![a, b], vec![inst(0, 0.0), inst(1, 1.0), inst(0, 2.0)]);
        let old: Vec<[[f32; 3]; 3]> = s.meshes[0]
            .indices
            .iter()
            .map(|t| t.map(|i| s.meshes[0].positions[i as usize]))
            .collect();
        let f = flatten(s);
        assert_eq!(f.meshes.len(), 4, "three primitives and the floor");
        let customs: Vec<u32> = f.instances.iter().map(|i| i.custom_index).collect();
        assert_eq!(customs, vec![0, 1, 2, 0, 1]);
        let meshes: Vec<Geometry> = f.instances.iter().map(|i| i.geometry).collect();
        let m = Geometry::Mesh;
        assert_eq!(meshes, vec![m(0), m(1), m(2), m(0), m(1)]);
        assert_eq!(f.instances[4].transform[0][3], 2.0);
        assert_eq!(f.params.instances, 5);
        assert_eq!(f.floor.geometry, m(3));
        assert_eq!(f.meshes[3].indices.len(), 2);
        // The second primitive's mesh holds its own triangle, renumbered, one geometry.
        let tri =
            |k: usize, t: usize| f.meshes[k].indices[t].map(|i| f.meshes[k].positions[i as usize]);
        assert_eq!(tri(0, 0), old[0]);
        assert_eq!(tri(0, 1), old[1]);
        assert_eq!(tri(1, 0), old[2]);
        assert_eq!(f.meshes[1].positions.len(), 3);
        assert!(f.meshes[..3]
            .iter()
            .all(|m| m.geometries.len() == 1 && m.geometries[0] == (0..m.indices.len() as u32)));
    }
}
