//! The `scene_layout` cells' buffers (`scene::layout`), made the first time a planned cell reads
//! them and only the layout it reads: `shared_buffers`' positions, indices, `PrimMeshInfo` table,
//! mesh-slot table and the `SceneDesc` of their addresses; `per_mesh`'s one buffer per mesh slot,
//! bound at binding 2.
use super::error::CellError;
use super::resources::Target;
use crate::scene::layout::{LayoutData, LayoutError};
use crate::scene::Scene;
use crate::vk::memory::Buffer;
use crate::vk::Gpu;
use ash::vk;

const USAGE: vk::BufferUsageFlags = vk::BufferUsageFlags::from_raw(
    vk::BufferUsageFlags::STORAGE_BUFFER.as_raw()
        | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS.as_raw(),
);

/// A scene whose custom indices mix meshes in one slot cannot run a layout cell: rtprobe keeps no
/// layout for it (not the device's fault).
impl From<LayoutError> for CellError {
    fn from(e: LayoutError) -> Self {
        CellError::NotImplemented(e.to_string())
    }
}

/// `shared_buffers` on the device: the four buffers, then the `SceneDesc` of their addresses.
pub struct SharedBuffers {
    parts: Vec<Buffer>,
    pub desc: Buffer,
}

impl SharedBuffers {
    pub fn create(gpu: &Gpu, scene: &Scene) -> Result<Self, CellError> {
        let d = LayoutData::new(scene)?;
        let mut parts = Vec::new();
        for (bytes, what) in [
            (d.positions(scene), "scene positions"),
            (d.indices(scene), "scene indices"),
            (d.prim_info(scene), "scene prim_info"),
            (d.mesh_first(scene), "scene mesh slots"),
        ] {
            parts.push(Buffer::with_data(gpu, &bytes, USAGE, what)?);
        }
        // The fifth address, the material table's, stays 0 until a texture cell needs it
        // (`layout_textures`).
        let addrs: Vec<u8> =
            parts.iter().map(|b| b.address).chain([0]).flat_map(u64::to_le_bytes).collect();
        let desc = Buffer::with_data(gpu, &addrs, USAGE, "scene description")?;
        Ok(SharedBuffers { parts, desc })
    }

    pub fn destroy(&self, gpu: &Gpu) {
        self.parts.iter().chain([&self.desc]).for_each(|b| b.destroy(gpu));
    }
}

/// `per_mesh` on the device: one storage buffer per mesh slot.
pub struct MeshBuffers {
    buffers: Vec<Buffer>,
}

impl MeshBuffers {
    pub fn create(gpu: &Gpu, scene: &Scene) -> Result<Self, CellError> {
        let d = LayoutData::new(scene)?;
        let mut buffers = Vec::new();
        for slot in 0..d.slot_mesh.len() {
            let bytes: Vec<u8> =
                d.mesh_words(scene, slot).into_iter().flat_map(u32::to_le_bytes).collect();
            buffers.push(Buffer::with_data(gpu, &bytes, USAGE, "per-mesh buffer")?);
        }
        Ok(MeshBuffers { buffers })
    }

    /// Binding 2's descriptors: slot k's buffer, whole.
    pub fn targets(&self) -> Vec<Target> {
        self.buffers
            .iter()
            .map(|b| Target::Buffer { raw: b.raw, address: b.address, range: b.size })
            .collect()
    }

    pub fn destroy(&self, gpu: &Gpu) {
        self.buffers.iter().for_each(|b| b.destroy(gpu));
    }
}
