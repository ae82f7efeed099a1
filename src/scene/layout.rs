//! The `scene_layout` cells' scene data: the hit triangle's data as the scene holds it
//! ([`fetch`], what the CPU reference expects), and the bytes of the two layouts engines keep it
//! in, which the closest-hit reads on the GPU ([`LayoutData`]).
//!
//! `shared_buffers` is the glTF ray tracing tutorial's layout (`harness::scene_data`'s for `run
//! --shader`, made here from the matrix's [`Scene`] rather than from a glTF document): every
//! mesh's positions in one tightly packed `vec3` buffer, every mesh's indices (relative to the
//! mesh's first vertex) in one `uint` buffer, one `PrimMeshInfo {indexOffset, vertexOffset,
//! materialIndex}` per (mesh, BLAS geometry) — the tutorial's primitive —, and per mesh slot the
//! mesh's first `PrimMeshInfo`; a `SceneDesc` holds the four buffers' device addresses, then the
//! material table's (`scene::textures`; 0 until a texture cell needs it).
//! `per_mesh` keeps one storage buffer per mesh slot in a descriptor array (binding 2), each
//! with the mesh's own header, indices, primitive table and positions ([`LayoutData::mesh_words`]),
//! padded so that a hit on any mesh's (geometry, primitive) reads inside every slot's buffer: a
//! mutant's wrong buffer (`run --mutants`: index-zero, -next, -broadcast, stride-double) reads
//! another mesh's data in bounds, which the reference predicts ([`read_mesh_words`]).
//!
//! Both are selected by the hit's custom index as the matrix's dynamic cells select a slot:
//! slot `DYNAMIC_BASE + (custom & dyn_mask)` ([`crate::probe::dynamic_slot`]). The matrix's
//! scenes carry no materials, so primitive entry `k`'s material index is [`material`]`(k)`:
//! distinct per primitive, so that a wrong table entry shows.
use super::{Geometry, Scene};
use crate::model::{Resource, Stage};
use crate::probe;

/// Words of one `PrimMeshInfo` (`indexOffset`, `vertexOffset`, `materialIndex`).
pub const PRIM_INFO_WORDS: usize = 3;
/// The material index of primitive entry 0 (so that materials are unlike small vertex indices).
const MATERIAL_BASE: u32 = super::textures::FIRST_MATERIAL;
/// Words before a `per_mesh` buffer's indices: the positions' word offset, the primitive table's.
const MESH_HEADER_WORDS: u32 = 2;
/// Words of one `per_mesh` primitive-table entry: its first index (in words after the header)
/// and its material.
const MESH_PRIM_WORDS: u32 = 2;

/// What a scene-layout closest-hit fetches for its hit triangle: the three vertex indices (relative
/// to the mesh's first vertex), x of the first vertex, y of the second, z of the third (copied, not
/// interpolated), and the material index. The record holds them as `element`, `pad`, `pad2` and
/// `value` ([`Fetched::value`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fetched {
    pub indices: [u32; 3],
    pub coords: [f32; 3],
    pub material: u32,
}

impl Fetched {
    /// The record's `value`: the three coordinates, then the material index as a float (exact:
    /// material indices stay far below 2^24).
    pub fn value(&self) -> [f32; 4] {
        [self.coords[0], self.coords[1], self.coords[2], self.material as f32]
    }
}

/// Primitive entry `entry`'s material index.
pub fn material(entry: u32) -> u32 {
    MATERIAL_BASE + entry
}

/// Per mesh, its first primitive entry (its geometries are entries `first..first + geometries`).
fn first_entries(scene: &Scene) -> Vec<u32> {
    let mut next = 0u32;
    scene
        .meshes
        .iter()
        .map(|m| {
            let at = next;
            next += m.geometries.len() as u32;
            at
        })
        .collect()
}

/// What the closest-hit must fetch for primitive `primitive` of geometry `geometry` of mesh `mesh`:
/// the scene's own triangle.
pub fn fetch(scene: &Scene, mesh: usize, geometry: u32, primitive: u32) -> Fetched {
    let m = &scene.meshes[mesh];
    let tri = m.geometries[geometry as usize].start + primitive;
    let indices = m.indices[tri as usize];
    let coords = [0, 1, 2].map(|k| m.positions[indices[k] as usize][k]);
    Fetched { indices, coords, material: material(first_entries(scene)[mesh] + geometry) }
}

/// The mesh slot a custom index selects (the slot of `index=dynamic` closest-hit cells).
pub fn slot_of(scene: &Scene, custom: u32) -> u32 {
    let i = scene.params.instances;
    let slots = (
        probe::slot_count(Resource::StorageBuffer, i),
        probe::dyn_mask(Resource::StorageBuffer, i),
    );
    probe::dynamic_slot(Stage::ClosestHit, (0, 0, 0), custom, probe::DYNAMIC_BASE, slots)
}

/// A scene whose custom indices cannot select its meshes.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum LayoutError {
    #[error("instances {first} and {second} select mesh slot {slot} by their custom indices but hold different meshes, so no mesh layout can serve both; scene_layout cells need custom indices that tell meshes apart in their low bits (leave them out with --filter scene_layout=none)")]
    SlotClash { first: usize, second: usize, slot: u32 },
}

/// The two layouts' bytes for one scene.
pub struct LayoutData {
    /// Per mesh slot, the mesh its slot holds (the mesh of every triangle instance whose custom
    /// index selects it); `None` where no triangle instance selects it.
    pub slot_mesh: Vec<Option<usize>>,
    first_entry: Vec<u32>,
    first_vertex: Vec<u32>,
    first_index: Vec<u32>,
    /// The most BLAS geometries of any mesh, and the most triangles of any geometry: what a hit
    /// read through another slot's buffer can index ([`LayoutData::mesh_words`]'s padding).
    most_geometries: u32,
    most_triangles: u32,
}

fn words_bytes(words: impl IntoIterator<Item = u32>) -> Vec<u8> {
    words.into_iter().flat_map(u32::to_le_bytes).collect()
}

impl LayoutData {
    /// The slots' meshes and every mesh's offsets; refused where two instances of different
    /// meshes select one slot.
    pub fn new(scene: &Scene) -> Result<LayoutData, LayoutError> {
        let slots = probe::slot_count(Resource::StorageBuffer, scene.params.instances);
        let mut slot_mesh: Vec<Option<(usize, usize)>> = vec![None; slots as usize];
        for (k, inst) in scene.instances.iter().enumerate() {
            let Geometry::Mesh(m) = inst.geometry else { continue };
            let slot = slot_of(scene, inst.custom_index);
            match slot_mesh[slot as usize] {
                Some((first, held)) if held != m => {
                    return Err(LayoutError::SlotClash { first, second: k, slot })
                }
                Some(_) => {}
                None => slot_mesh[slot as usize] = Some((k, m)),
            }
        }
        let (mut v, mut i) = (0u32, 0u32);
        let (mut first_vertex, mut first_index) = (vec![], vec![]);
        for m in &scene.meshes {
            first_vertex.push(v);
            first_index.push(i);
            v += m.positions.len() as u32;
            i += 3 * m.indices.len() as u32;
        }
        let geometries = scene.meshes.iter().flat_map(|m| m.geometries.iter());
        Ok(LayoutData {
            slot_mesh: slot_mesh.into_iter().map(|s| s.map(|(_, m)| m)).collect(),
            first_entry: first_entries(scene),
            first_vertex,
            first_index,
            most_geometries: scene
                .meshes
                .iter()
                .map(|m| m.geometries.len() as u32)
                .max()
                .unwrap_or(0),
            most_triangles: geometries.map(|r| r.end - r.start).max().unwrap_or(0),
        })
    }

    /// The mesh a slot's buffer holds: its own, or for a slot no instance selects the largest
    /// mesh (a decoy that a wrong slot reads in bounds, unlike the right one's data).
    fn held(&self, scene: &Scene, slot: usize) -> usize {
        self.slot_mesh[slot].unwrap_or_else(|| {
            (0..scene.meshes.len()).max_by_key(|&m| scene.meshes[m].indices.len()).unwrap_or(0)
        })
    }

    /// `shared_buffers`' positions: every mesh's, `vec3` tightly packed.
    pub fn positions(&self, scene: &Scene) -> Vec<u8> {
        let all = scene.meshes.iter().flat_map(|m| m.positions.iter().flatten());
        words_bytes(all.map(|f| f.to_bits()))
    }

    /// `shared_buffers`' indices: every mesh's triangles, relative to the mesh's first vertex.
    pub fn indices(&self, scene: &Scene) -> Vec<u8> {
        words_bytes(scene.meshes.iter().flat_map(|m| m.indices.iter().flatten().copied()))
    }

    /// `shared_buffers`' `PrimMeshInfo` table, entry by entry (mesh by mesh, geometry by geometry).
    pub fn prim_info(&self, scene: &Scene) -> Vec<u8> {
        let mut words = Vec::new();
        for (m, mesh) in scene.meshes.iter().enumerate() {
            for (g, range) in mesh.geometries.iter().enumerate() {
                words.push(self.first_index[m] + 3 * range.start);
                words.push(self.first_vertex[m]);
                words.push(material(self.first_entry[m] + g as u32));
            }
        }
        words_bytes(words)
    }

    /// `shared_buffers`' first `PrimMeshInfo` entry of each slot's mesh.
    pub fn mesh_first(&self, scene: &Scene) -> Vec<u8> {
        words_bytes((0..self.slot_mesh.len()).map(|s| self.first_entry[self.held(scene, s)]))
    }

    /// `per_mesh`'s buffer of slot `slot`, as words: `[positions offset, primitive table offset]`,
    /// the mesh's indices, its primitive table (`[first index after the header, material]` per
    /// geometry), its positions' bits. Padded for a hit on another mesh read through this buffer
    /// (a mutant's wrong descriptor): the table up to the most geometries of any mesh (entries
    /// `[0, material of the mesh's first entry]`), the indices with zeros up to the last
    /// geometry's start plus the most triangles of any geometry, so every word such a hit reads
    /// lies inside the buffer and every index read is a vertex of this mesh.
    pub fn mesh_words(&self, scene: &Scene, slot: usize) -> Vec<u32> {
        let m = self.held(scene, slot);
        let mesh = &scene.meshes[m];
        let last_start = mesh.geometries.iter().map(|r| r.start).max().unwrap_or(0);
        let index_words = 3 * (mesh.indices.len() as u32).max(last_start + self.most_triangles);
        let table = MESH_HEADER_WORDS + index_words;
        let entries = self.most_geometries.max(mesh.geometries.len() as u32);
        let positions = table + MESH_PRIM_WORDS * entries;
        let mut w = vec![positions, table];
        w.extend(mesh.indices.iter().flatten());
        w.resize(table as usize, 0);
        for (g, range) in mesh.geometries.iter().enumerate() {
            w.extend([3 * range.start, material(self.first_entry[m] + g as u32)]);
        }
        while w.len() < positions as usize {
            w.extend([0, material(self.first_entry[m])]);
        }
        w.extend(mesh.positions.iter().flatten().map(|f| f.to_bits()));
        w
    }
}

/// The GLSL of a `shared_buffers` fetch: declarations, and statements that read the hit
/// triangle through `pc.sceneDesc` for mesh slot `probeSlot`, defining `uvec3 probeTri` and
/// `vec4 probeValue` (the CPU twin: [`read_shared`]).
pub const SHARED_DECLS: &str = "layout(buffer_reference, std430, buffer_reference_align = 8) readonly buffer SceneDesc { uvec2 positions; uvec2 indices; uvec2 primInfo; uvec2 meshFirst; uvec2 materials; };\n\
layout(buffer_reference, std430, buffer_reference_align = 4) readonly buffer SceneWords { uint w[]; };\n\
layout(buffer_reference, std430, buffer_reference_align = 4) readonly buffer ScenePositions { float p[]; };\n";

pub const SHARED_BODY: &str = "    SceneDesc sceneDesc = SceneDesc(pc.sceneDesc);\n    \
uint primEntry = SceneWords(sceneDesc.meshFirst).w[probeSlot] + uint(gl_GeometryIndexEXT);\n    \
SceneWords primInfo = SceneWords(sceneDesc.primInfo);\n    \
uint indexOffset = primInfo.w[3u * primEntry];\n    uint vertexOffset = primInfo.w[3u * primEntry + 1u];\n    uint materialIndex = primInfo.w[3u * primEntry + 2u];\n    \
SceneWords sceneIndices = SceneWords(sceneDesc.indices);\n    uint firstIndex = indexOffset + 3u * uint(gl_PrimitiveID);\n    \
uvec3 probeTri = uvec3(sceneIndices.w[firstIndex], sceneIndices.w[firstIndex + 1u], sceneIndices.w[firstIndex + 2u]);\n    \
ScenePositions scenePositions = ScenePositions(sceneDesc.positions);\n    \
vec4 probeValue = vec4(scenePositions.p[3u * (vertexOffset + probeTri.x)], scenePositions.p[3u * (vertexOffset + probeTri.y) + 1u], scenePositions.p[3u * (vertexOffset + probeTri.z) + 2u], float(materialIndex));\n";

/// The GLSL of a `per_mesh` fetch: declarations (the mesh buffers at `binding`: 2, or 3 in a
/// texture cell, whose textures are at 2), and statements that read the hit triangle from mesh
/// buffer `meshes[SUB]` (`SUB`: the descriptor index expression), defining `uvec3 probeTri`,
/// `uint materialIndex` and `vec4 probeValue` (the CPU twin: [`read_per_mesh`]).
pub fn per_mesh_decls(binding: u32) -> String {
    format!("layout(set = 0, binding = {binding}, std430) readonly buffer MeshData {{ uint w[]; }} meshes[];\n")
}

/// The binding of a texture cell's mesh buffers (`per_mesh`): after the textures at 2.
pub const TEXTURE_CELL_MESH_BINDING: u32 = 3;

pub fn per_mesh_body(sub: &str) -> String {
    format!(
        "    uint meshPrim = meshes[{sub}].w[1u] + {MESH_PRIM_WORDS}u * uint(gl_GeometryIndexEXT);\n    \
uint firstIndex = {MESH_HEADER_WORDS}u + meshes[{sub}].w[meshPrim] + 3u * uint(gl_PrimitiveID);\n    uint materialIndex = meshes[{sub}].w[meshPrim + 1u];\n    \
uvec3 probeTri = uvec3(meshes[{sub}].w[firstIndex], meshes[{sub}].w[firstIndex + 1u], meshes[{sub}].w[firstIndex + 2u]);\n    \
uint meshPositions = meshes[{sub}].w[0u];\n    \
vec4 probeValue = vec4(uintBitsToFloat(meshes[{sub}].w[meshPositions + 3u * probeTri.x]), uintBitsToFloat(meshes[{sub}].w[meshPositions + 3u * probeTri.y + 1u]), uintBitsToFloat(meshes[{sub}].w[meshPositions + 3u * probeTri.z + 2u]), float(materialIndex));\n"
    )
}

/// Words of `bytes` (little-endian).
fn words(bytes: &[u8]) -> Vec<u32> {
    bytes.chunks_exact(4).map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect()
}

/// What [`SHARED_BODY`] reads for a hit on (slot, geometry, primitive), emulated on the CPU.
pub fn read_shared(
    d: &LayoutData,
    scene: &Scene,
    (slot, geometry, primitive): (u32, u32, u32),
) -> Fetched {
    let first = words(&d.mesh_first(scene));
    let info = words(&d.prim_info(scene));
    let ind = words(&d.indices(scene));
    let pos = words(&d.positions(scene));
    let entry = (first[slot as usize] + geometry) as usize * PRIM_INFO_WORDS;
    let (index_offset, vertex_offset, material) = (info[entry], info[entry + 1], info[entry + 2]);
    let at = (index_offset + 3 * primitive) as usize;
    let indices = [ind[at], ind[at + 1], ind[at + 2]];
    let coords =
        [0, 1, 2].map(|k| f32::from_bits(pos[(3 * (vertex_offset + indices[k])) as usize + k]));
    Fetched { indices, coords, material }
}

/// What [`per_mesh_body`] reads from slot `slot`'s buffer for a hit on (geometry, primitive),
/// emulated on the CPU (`None`: a read outside the buffer, [`read_mesh_words`]).
pub fn read_per_mesh(
    d: &LayoutData,
    scene: &Scene,
    (slot, geometry, primitive): (u32, u32, u32),
) -> Option<Fetched> {
    read_mesh_words(&d.mesh_words(scene, slot as usize), geometry, primitive)
}

/// What [`per_mesh_body`] reads from a mesh buffer's words `w` ([`LayoutData::mesh_words`]) for
/// a hit on (geometry, primitive); `None` where a word it reads lies outside `w` (never for a
/// hit on one of the scene's meshes: the buffers are padded for it).
pub fn read_mesh_words(w: &[u32], geometry: u32, primitive: u32) -> Option<Fetched> {
    let at = |k: u32| w.get(k as usize).copied();
    let prim = at(1)? + MESH_PRIM_WORDS * geometry;
    let first = MESH_HEADER_WORDS + at(prim)? + 3 * primitive;
    let indices = [at(first)?, at(first + 1)?, at(first + 2)?];
    let positions = at(0)?;
    let mut coords = [0.0; 3];
    for k in 0..3 {
        coords[k] = f32::from_bits(at(positions + 3 * indices[k] + k as u32)?);
    }
    Some(Fetched { indices, coords, material: at(prim + 1)? })
}

#[cfg(test)]
mod tests;
