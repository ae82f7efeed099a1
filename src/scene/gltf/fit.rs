//! A loaded scene as the probes trace it: every ray of rtprobe's cells is orthographic along +z
//! with exactly representable origins (the probe contract, `Scene::primary_ray`), so instead of a
//! perspective camera the scene is moved into that view. The view is the glTF camera's
//! orientation (its position and rotation, scale dropped), else glTF's front view (the viewer on
//! +z looking down −z); rotated half a turn about y (a rotation: triangle facing is kept) so the
//! rays' +z looks the same way, then scaled uniformly and moved so the bounds fill 90% of the
//! view in x and y (or less, for a deep scene) and lie between z = −9 and z = 5: after the rays'
//! origins at `RAY_Z` = −10 and in front of the AS probe's floor at `FLOOR_Z` = 6. Custom indices are the mesh's index, as the glTF ray tracing tutorial sets
//! `instanceCustomIndex`.
use super::Loaded;
use crate::model::SceneParams;
use crate::scene::{Geometry, Instance, Mesh, Scene, VIEW_HALF};
use glam::{Mat4, Vec3};

/// The fitted scene's far end, in front of the AS probe's floor at z = 6.
const FAR: f32 = 5.0;
/// Largest depth of the fitted scene: its near end 1 after the rays' origins at z = −10.
const DEPTH: f32 = 14.0;

/// The world-to-view transform of the fit.
pub fn view(loaded: &Loaded) -> Mat4 {
    let camera = loaded.camera.as_ref().map_or(Mat4::IDENTITY, |c| c.world.inverse());
    let turned = Mat4::from_rotation_y(std::f32::consts::PI) * camera;
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for i in &loaded.instances {
        let m = turned * i.world;
        for p in &loaded.meshes[i.mesh].positions {
            let q = m.transform_point3(Vec3::from(*p));
            lo = lo.min(q);
            hi = hi.max(q);
        }
    }
    let size = hi - lo;
    let across = size.x.max(size.y).max(f32::MIN_POSITIVE);
    let mut s = 0.9 * 2.0 * VIEW_HALF / across;
    if size.z * s > DEPTH {
        s = DEPTH / size.z;
    }
    let centre = Vec3::new((lo.x + hi.x) / 2.0, (lo.y + hi.y) / 2.0, hi.z);
    Mat4::from_translation(Vec3::new(0.0, 0.0, FAR))
        * Mat4::from_scale(Vec3::splat(s))
        * Mat4::from_translation(-centre)
        * turned
}

/// Row-major 3×4, as `VkTransformMatrixKHR` holds it.
fn rows(m: Mat4) -> [[f32; 4]; 3] {
    let c = m.to_cols_array_2d();
    [0, 1, 2].map(|r| [c[0][r], c[1][r], c[2][r], c[3][r]])
}

/// The loaded scene as a [`Scene`]: each glTF mesh one BLAS, its primitives the geometries; one
/// instance per node with a mesh, custom index the mesh's index; `params`' image size and seed.
pub fn to_scene(loaded: &Loaded, params: &SceneParams) -> Scene {
    // Only the meshes a node places: one no node uses (`LoadedMesh::unused`, empty) would be a
    // BLAS of no geometry. `slot[m]`: glTF mesh m's place among them.
    let mut slot = vec![usize::MAX; loaded.meshes.len()];
    let meshes = loaded
        .meshes
        .iter()
        .enumerate()
        .filter(|(_, m)| !m.unused)
        .enumerate()
        .map(|(k, (m, mesh))| {
            slot[m] = k;
            Mesh {
                positions: mesh.positions.clone(),
                indices: (0..mesh.triangle_count()).map(|t| mesh.triangle(t)).collect(),
                geometries: mesh
                    .primitives
                    .iter()
                    .map(|p| p.first_triangle..p.first_triangle + p.triangles)
                    .collect(),
            }
        })
        .collect();
    let v = view(loaded);
    let instances = loaded
        .instances
        .iter()
        .map(|i| Instance {
            transform: rows(v * i.world),
            // The file's mesh index, as the user knows it.
            custom_index: i.mesh as u32,
            geometry: Geometry::Mesh(slot[i.mesh]),
        })
        .collect();
    Scene::with_meshes(params, meshes, instances)
}
