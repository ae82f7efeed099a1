//! glTF 2.0 scenes (`.gltf` with its `.bin` files and images, or `.glb`), read by rtprobe's own
//! reader over `serde_json` — the container (`glb`), the document as far as rtprobe reads it
//! (`doc`), checked before use (`validate`), accessors read (`accessor`) — into what rtprobe
//! builds acceleration structures and buffers from: each mesh's triangle
//! primitives (`mesh`), the default scene's nodes as instances with world transforms and the
//! first camera (`nodes`), materials with `alphaMode` and base colour textures, each image
//! decoded only when asked (`material`), and the scene fitted into the probes' orthographic view
//! (`fit`). Every failure is one line naming the part of the file (`error`). `make` writes the
//! test scene and the large scene for measurements.
mod accessor;
mod doc;
pub mod error;
pub mod fit;
mod glb;
pub mod make;
pub mod material;
pub mod mesh;
pub mod nodes;
mod open;
mod pixels;
mod uri;
mod validate;

pub use error::LoadError;
pub use material::{Alpha, Material, Texture};
pub use mesh::{LoadedMesh, Primitive};
pub use nodes::{Camera, NodeInstance};

use std::path::{Path, PathBuf};

/// A loaded glTF scene.
pub struct Loaded {
    pub path: PathBuf,
    pub meshes: Vec<LoadedMesh>,
    /// One per node with a mesh, depth first from the default scene's roots.
    pub instances: Vec<NodeInstance>,
    pub materials: Vec<Material>,
    pub camera: Option<Camera>,
    /// Images in the document (decoded only by [`Loaded::decode_image`]).
    pub images: usize,
    root: doc::Root,
    buffers: Vec<Vec<u8>>,
}

impl Loaded {
    /// Read `path`: the document, validated, its buffers, nodes, the meshes they use (the others
    /// [`LoadedMesh::unused`]) and materials; no image is decoded.
    pub fn load(path: &Path) -> Result<Loaded, LoadError> {
        let open::Opened { root, buffers } = open::open(path)?;
        let (instances, camera) = nodes::walk(&root).map_err(|n| {
            LoadError::part(path, format!("node {n}"), "reached twice: the node hierarchy must be disjoint trees (glTF 2.0, nodes); fix the exporter's children lists")
        })?;
        // Only the meshes a node places are read: one no node uses cannot refuse the file.
        let used: std::collections::HashSet<usize> = instances.iter().map(|i| i.mesh).collect();
        let meshes = (0..root.meshes.len())
            .map(|m| match used.contains(&m) {
                true => mesh::read(path, &root, m, &buffers),
                false => Ok(mesh::unused(&root, m)),
            })
            .collect::<Result<Vec<_>, _>>()?;
        if instances.iter().all(|i| meshes[i.mesh].indices.is_empty()) {
            return Err(LoadError::Empty { path: path.to_path_buf() });
        }
        let materials = (0..root.materials.len()).map(|m| material::read(&root, m)).collect();
        let images = root.images.len();
        Ok(Loaded {
            path: path.to_path_buf(),
            meshes,
            instances,
            materials,
            camera,
            images,
            root,
            buffers,
        })
    }

    /// Image `index` decoded to RGBA8 (a material's `base_color_image`).
    pub fn decode_image(&self, index: usize) -> Result<Texture, LoadError> {
        material::decode(&self.path, &self.root, &self.buffers, index)
    }

    /// Image `index`'s width and height from its header (no texel decoded).
    pub fn image_size(&self, index: usize) -> Result<(u32, u32), LoadError> {
        material::size(&self.path, &self.root, &self.buffers, index)
    }

    /// How the file names image `index`: `images[N]` and its URI or buffer view.
    pub fn image_name(&self, index: usize) -> String {
        self.root
            .images
            .get(index)
            .map_or_else(|| format!("images[{index}]"), |i| material::describe(i, index))
    }

    /// Triangles of every instance (a mesh instanced by two nodes counts twice).
    pub fn triangles(&self) -> u64 {
        self.instances.iter().map(|i| self.meshes[i.mesh].indices.len() as u64).sum()
    }

    /// Bytes of the tutorial's shared geometry buffers: positions, normals, UVs, indices and the
    /// per-primitive table (12 bytes a primitive), each mesh once.
    pub fn geometry_bytes(&self) -> u64 {
        self.meshes
            .iter()
            .map(|m| {
                (m.positions.len() * 12
                    + m.normals.len() * 12
                    + m.uvs.len() * 8
                    + m.indices.len() * 12) as u64
                    + 12 * m.primitives.len() as u64
            })
            .sum()
    }

    /// Whether primitive `p` of mesh `m` is opaque (its material's `alphaMode` is OPAQUE).
    pub fn opaque(&self, m: usize, p: usize) -> bool {
        self.meshes[m].primitives[p].material.is_none_or(|k| self.materials[k].alpha.opaque())
    }
}

#[cfg(test)]
mod tests;
