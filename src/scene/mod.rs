//! Procedural, seeded ray tracing scenes on the CPU: triangle meshes of different sizes (height
//! fields, each split into several BLAS geometries so `gl_GeometryIndexEXT` varies), one procedural
//! (AABB + sphere) geometry, and a TLAS-like instance list with rotation and scale, each instance
//! carrying its own `instanceCustomIndex` that selects its resources, as an engine does. Custom
//! indices are unlike instance indices: their low bits are a permutation with no fixed point of
//! the instance indices, their high bits sparse (some near 2^24−1). A floor quad behind everything
//! exists only in the AS probe's TLASes. The camera is orthographic with exactly representable ray
//! origins, so the GPU and the CPU reference trace bit-identical rays. `gpu` uploads it and builds
//! BLAS/TLAS.
pub mod file;
pub mod gltf;
pub mod gpu;
pub mod layout;
pub mod rng;
pub mod texture_limits;
pub mod textures;

use crate::model::SceneParams;
use glam::{Mat3, Quat, Vec3};
use rng::Rng;

pub struct Mesh {
    pub positions: Vec<[f32; 3]>,
    pub indices: Vec<[u32; 3]>,
    /// The BLAS geometries: ranges of `indices` (geometry g holds triangles `geometries[g]`).
    pub geometries: Vec<std::ops::Range<u32>>,
}

impl Mesh {
    /// (geometry index, primitive index within it) of triangle `tri` of `indices`.
    pub fn geometry_of(&self, tri: u32) -> (u32, u32) {
        let g = self
            .geometries
            .iter()
            .position(|r| r.contains(&tri))
            .expect("geometries cover the mesh");
        (g as u32, tri - self.geometries[g].start)
    }
}

/// Height-field meshes are split into this many BLAS geometries.
pub const GEOMETRIES_PER_MESH: u32 = 3;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Geometry {
    /// Index into `Scene::meshes`.
    Mesh(usize),
    /// The procedural sphere of radius [`SPHERE_RADIUS`] inside the unit AABB.
    Sphere,
}

pub struct Instance {
    /// Row-major 3x4 object-to-world matrix, as `VkTransformMatrixKHR` holds it.
    pub transform: [[f32; 4]; 3],
    pub custom_index: u32,
    pub geometry: Geometry,
}

impl Instance {
    /// Hit group offset in the SBT: 0 triangles, 1 procedural.
    pub fn sbt_offset(&self) -> u32 {
        match self.geometry {
            Geometry::Mesh(_) => 0,
            Geometry::Sphere => 1,
        }
    }
}

pub const SPHERE_RADIUS: f32 = 0.5;
/// The AABB of the procedural geometry, in object space.
pub const SPHERE_AABB: [f32; 6] = [-0.5, -0.5, -0.5, 0.5, 0.5, 0.5];
/// Half extent of the orthographic view, and the z of every ray origin.
pub const VIEW_HALF: f32 = 6.0;
pub const RAY_Z: f32 = -10.0;
pub const RAY_TMIN: f32 = 0.001;
pub const RAY_TMAX: f32 = 100.0;

/// z of the floor quad of the AS probe's TLASes (behind every scene instance).
pub const FLOOR_Z: f32 = 6.0;
/// Half extent of the floor quad (covers every probe ray of the view).
pub const FLOOR_HALF: f32 = 16.0;

pub struct Scene {
    pub params: SceneParams,
    /// Height fields, then the floor quad (last).
    pub meshes: Vec<Mesh>,
    pub instances: Vec<Instance>,
    /// The floor: only in the AS probe's TLASes, as instance number `instances.len()`.
    pub floor: Instance,
    /// Every instance built with `FORCE_NO_OPAQUE`, so any-hit shaders run on every candidate
    /// (as an engine marks alpha-tested geometry): `run --shader` with a user's any-hit. The
    /// matrix's scene is opaque; its any-hit cells trace with `gl_RayFlagsNoOpaqueEXT`.
    pub no_opaque: bool,
    /// The sphere instances' `instanceShaderBindingTableRecordOffset`: 1 (after the triangle
    /// group), or past `run --shader`'s triangle records of every ray type (`harness::hit_table`).
    pub procedural_sbt_offset: u32,
    /// Per primitive entry, the base-colour image the `scene_layout` texture cells sample
    /// (`textures`): the procedural scene's synthetic ones, a glTF file's materials' images.
    pub textures: textures::SceneTextures,
}

/// Split `n` triangles into `parts` contiguous geometries.
fn split(n: u32, parts: u32) -> Vec<std::ops::Range<u32>> {
    (0..parts).map(|g| g * n / parts..(g + 1) * n / parts).collect()
}

fn floor_quad() -> Mesh {
    let positions = vec![[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [-1.0, 1.0, 0.0], [1.0, 1.0, 0.0]];
    // Two geometries of one triangle each.
    Mesh { positions, indices: vec![[0, 1, 2], [1, 3, 2]], geometries: split(2, 2) }
}

/// Custom indices of `n` instances: low bits (under `probe::instance_mask`) a seeded permutation of
/// 0..n without fixed points (so custom & mask != instance index), high bits sparse, every fourth
/// instance's all ones (custom near 2^24−1).
fn custom_indices(n: u32, seed: u64) -> Vec<u32> {
    let mut rng = Rng::new(seed ^ 0x6375_7374_6f6d);
    let mut perm: Vec<u32> = (0..n).collect();
    for i in (1..n as usize).rev() {
        let j = (rng.next_u64() % (i as u64 + 1)) as usize;
        perm.swap(i, j);
    }
    for i in 0..n as usize {
        if perm[i] == i as u32 {
            perm.swap(i, (i + 1) % n as usize);
        }
    }
    let bits = crate::probe::instance_mask(n).count_ones();
    let high_max = ((1u32 << 24) - 1) >> bits;
    perm.iter()
        .enumerate()
        .map(|(k, low)| {
            let high =
                if k % 4 == 1 { high_max } else { (rng.next_u64() % (high_max as u64 + 1)) as u32 };
            (high << bits) | low
        })
        .collect()
}

fn height_field(n: u32, rng: &mut Rng) -> Mesh {
    let mut positions = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let x = -1.0 + 2.0 * i as f32 / n as f32;
            let y = -1.0 + 2.0 * j as f32 / n as f32;
            positions.push([x, y, rng.range(-0.25, 0.25)]);
        }
    }
    let mut indices = Vec::new();
    let row = n + 1;
    for j in 0..n {
        for i in 0..n {
            let a = j * row + i;
            indices.push([a, a + 1, a + row]);
            indices.push([a + 1, a + row + 1, a + row]);
        }
    }
    let geometries = split(indices.len() as u32, GEOMETRIES_PER_MESH);
    Mesh { positions, indices, geometries }
}

impl Scene {
    pub fn build(params: &SceneParams) -> Scene {
        let mut rng = Rng::new(params.seed);
        let d = params.mesh_detail;
        let meshes = vec![
            height_field(d / 4, &mut rng),
            height_field(d / 2, &mut rng),
            height_field(d, &mut rng),
        ];
        let n = params.instances;
        let cols = (n as f32).sqrt().ceil() as u32;
        let spacing = 2.0 * VIEW_HALF / cols as f32;
        let mut instances = Vec::new();
        for k in 0..n {
            let (cx, cy) = (k % cols, k / cols);
            let centre = Vec3::new(
                -VIEW_HALF + spacing * (cx as f32 + 0.5) + rng.range(-0.1, 0.1) * spacing,
                -VIEW_HALF + spacing * (cy as f32 + 0.5) + rng.range(-0.1, 0.1) * spacing,
                rng.range(0.0, 2.0),
            );
            let axis = Vec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(0.2, 1.0))
                .normalize();
            let rot = Quat::from_axis_angle(axis, rng.range(-1.1, 1.1));
            let geometry =
                if k % 4 == 3 { Geometry::Sphere } else { Geometry::Mesh((k as usize) % 3) };
            let size = match geometry {
                Geometry::Sphere => spacing * rng.range(0.7, 1.1),
                Geometry::Mesh(_) => spacing * rng.range(0.35, 0.55),
            };
            let m = Mat3::from_quat(rot) * size;
            let c = m.to_cols_array_2d();
            let transform = [
                [c[0][0], c[1][0], c[2][0], centre.x],
                [c[0][1], c[1][1], c[2][1], centre.y],
                [c[0][2], c[1][2], c[2][2], centre.z],
            ];
            instances.push(Instance { transform, custom_index: 0, geometry });
        }
        for (i, c) in instances.iter_mut().zip(custom_indices(n, params.seed)) {
            i.custom_index = c;
        }
        Scene::with_meshes(params, meshes, instances)
    }

    /// A scene of the given meshes and instances (a loaded glTF scene's, or the procedural one's),
    /// with the AS probe's floor quad after the meshes; `params.instances` becomes the count.
    pub fn with_meshes(
        params: &SceneParams,
        mut meshes: Vec<Mesh>,
        instances: Vec<Instance>,
    ) -> Scene {
        let floor = Instance {
            transform: [
                [FLOOR_HALF, 0.0, 0.0, 0.0],
                [0.0, FLOOR_HALF, 0.0, 0.0],
                [0.0, 0.0, 1.0, FLOOR_Z],
            ],
            custom_index: 0,
            geometry: Geometry::Mesh(meshes.len()),
        };
        meshes.push(floor_quad());
        let params = SceneParams { instances: instances.len() as u32, ..params.clone() };
        let geometries: Vec<usize> = meshes.iter().map(|m| m.geometries.len()).collect();
        let textures = textures::SceneTextures::synthetic(&geometries, params.seed);
        Scene {
            params,
            meshes,
            instances,
            floor,
            no_opaque: false,
            procedural_sbt_offset: 1,
            textures,
        }
    }

    /// The primary ray of pixel (x, y): origin and direction, exactly as the shaders compute them.
    pub fn primary_ray(&self, x: u32, y: u32) -> ([f32; 3], [f32; 3]) {
        let sx = 2.0 * VIEW_HALF / self.params.width as f32;
        let sy = 2.0 * VIEW_HALF / self.params.height as f32;
        let ox = -VIEW_HALF + (x as f32 + 0.5) * sx;
        let oy = VIEW_HALF - (y as f32 + 0.5) * sy;
        ([ox, oy, RAY_Z], [0.0, 0.0, 1.0])
    }

    pub fn triangle_count(&self) -> usize {
        self.instances
            .iter()
            .map(|i| match i.geometry {
                Geometry::Mesh(m) => self.meshes[m].indices.len(),
                Geometry::Sphere => 0,
            })
            .sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scene_is_deterministic_and_has_what_the_issue_asks() {
        let p = SceneParams::default();
        let a = Scene::build(&p);
        let b = Scene::build(&p);
        assert_eq!(a.instances.len(), 16);
        assert_eq!(
            a.meshes.iter().map(|m| m.indices.len()).collect::<Vec<_>>(),
            vec![32, 128, 512, 2]
        );
        assert!(a.meshes.iter().all(|m| m.geometries.len() > 1
            && m.geometries.last().unwrap().end == m.indices.len() as u32));
        assert_eq!(a.meshes[0].geometry_of(31), (2, 31 - 21));
        assert!(a.instances.iter().any(|i| i.geometry == Geometry::Sphere));
        for (x, y) in a.instances.iter().zip(&b.instances) {
            assert_eq!(x.transform, y.transform);
        }
        let c = Scene::build(&SceneParams { seed: 2, ..p });
        assert_ne!(a.instances[0].transform, c.instances[0].transform);
        // custom indices are distinct, 24-bit, unlike the instance index (also under the mask),
        // and some are near 2^24-1
        let mask = crate::probe::instance_mask(16);
        let mut ids: Vec<u32> = a.instances.iter().map(|i| i.custom_index).collect();
        assert!(
            ids.iter().enumerate().all(|(k, c)| *c < 1 << 24 && c & mask != k as u32),
            "{ids:?}"
        );
        assert!(ids.iter().filter(|c| **c >= (1 << 24) - 16).count() >= 4, "{ids:?}");
        ids.sort();
        ids.dedup();
        assert_eq!(ids.len(), 16);
    }

    #[test]
    fn params_are_checked() {
        assert!(SceneParams { instances: 4, ..Default::default() }.validate().is_err());
        assert!(SceneParams { width: 60, ..Default::default() }.validate().is_err());
        assert!(SceneParams::default().validate().is_ok());
    }
}
