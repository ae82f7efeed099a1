//! A glTF mesh's triangle primitives read into one vertex and index list per mesh: each primitive
//! a range of triangles (a BLAS geometry of the mesh's BLAS, as the glTF ray tracing tutorial
//! builds one BLAS per mesh), with its vertex offset, first triangle and material — the
//! tutorial's `PrimMeshInfo {indexOffset, vertexOffset, materialIndex}`. Indices stay relative
//! to the primitive's first vertex (the tutorial adds `vertexOffset` in the shader); [`LoadedMesh::triangle`]
//! adds it back.
use super::accessor;
use super::doc::{self, Root};
use super::error::LoadError;
use std::path::Path;

/// One primitive of a mesh.
#[derive(Clone, Debug, PartialEq)]
pub struct Primitive {
    /// First vertex of the primitive in the mesh's vertex lists.
    pub vertex_offset: u32,
    /// First triangle of the primitive in the mesh's triangle list.
    pub first_triangle: u32,
    pub triangles: u32,
    /// Index into [`super::Loaded::materials`]; `None`: glTF's default material.
    pub material: Option<usize>,
}

/// One glTF mesh: every primitive's vertices, one after the other.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LoadedMesh {
    pub name: String,
    /// No node of the default scene uses it: not read (a mesh of lines or points that no node
    /// places does not refuse the file), every list empty.
    pub unused: bool,
    pub positions: Vec<[f32; 3]>,
    /// Empty when a primitive has no normals (none then has them here).
    pub normals: Vec<[f32; 3]>,
    /// TEXCOORD_0; empty when a primitive has none.
    pub uvs: Vec<[f32; 2]>,
    /// Per primitive, relative to its `vertex_offset`.
    pub indices: Vec<[u32; 3]>,
    pub primitives: Vec<Primitive>,
}

impl LoadedMesh {
    /// Triangle `t`'s vertex indices into the mesh's vertex lists.
    pub fn triangle(&self, t: u32) -> [u32; 3] {
        let p = self
            .primitives
            .iter()
            .find(|p| (p.first_triangle..p.first_triangle + p.triangles).contains(&t))
            .expect("t is a triangle of the mesh");
        self.indices[t as usize].map(|i| i + p.vertex_offset)
    }

    pub fn triangle_count(&self) -> u32 {
        self.indices.len() as u32
    }
}

/// What one primitive read.
struct Read {
    positions: Vec<[f32; 3]>,
    normals: Option<Vec<[f32; 3]>>,
    uvs: Option<Vec<[f32; 2]>>,
    indices: Vec<[u32; 3]>,
}

/// glTF 2.0's primitive modes ("Meshes", `mesh.primitive.mode`), by number.
const MODES: [&str; 7] =
    ["Points", "Lines", "LineLoop", "LineStrip", "Triangles", "TriangleStrip", "TriangleFan"];

/// `mesh N` or `mesh N (name)`.
fn name(root: &Root, index: usize) -> String {
    root.meshes[index]
        .name
        .as_ref()
        .map_or_else(|| format!("mesh {index}"), |n| format!("mesh {index} ({n})"))
}

/// Mesh `index`, which no node uses: named, nothing read.
pub(super) fn unused(root: &Root, index: usize) -> LoadedMesh {
    LoadedMesh { name: name(root, index), unused: true, ..Default::default() }
}

/// Mesh `index` of `root`, validated ([`super::validate`]), read from `buffers`.
pub(super) fn read(
    path: &Path,
    root: &Root,
    index: usize,
    buffers: &[Vec<u8>],
) -> Result<LoadedMesh, LoadError> {
    let mesh = &root.meshes[index];
    let name = name(root, index);
    let mut out = LoadedMesh { name: name.clone(), ..Default::default() };
    let (mut all_normals, mut all_uvs) = (true, true);
    let mut reads = Vec::new();
    for (k, p) in mesh.primitives.iter().enumerate() {
        let part = format!("{name}, primitive {k}");
        let r = read_primitive(path, &part, root, p, buffers)?;
        all_normals &= r.normals.is_some();
        all_uvs &= r.uvs.is_some();
        reads.push((r, p.material));
    }
    for (r, material) in reads {
        out.primitives.push(Primitive {
            vertex_offset: out.positions.len() as u32,
            first_triangle: out.indices.len() as u32,
            triangles: r.indices.len() as u32,
            material,
        });
        out.positions.extend(r.positions);
        if all_normals {
            out.normals.extend(r.normals.unwrap_or_default());
        }
        if all_uvs {
            out.uvs.extend(r.uvs.unwrap_or_default());
        }
        out.indices.extend(r.indices);
    }
    Ok(out)
}

/// One triangle primitive's vertices and indices; NORMAL and TEXCOORD_0 kept only when they have
/// one element per position (glTF 2.0, "Meshes": all attribute accessors MUST have the same
/// count; one that does not is dropped, not read past), zeros where they have no bufferView.
fn read_primitive(
    path: &Path,
    part: &str,
    root: &Root,
    p: &doc::Primitive,
    buffers: &[Vec<u8>],
) -> Result<Read, LoadError> {
    if p.mode != 4 {
        let mode = MODES.get(p.mode as usize).copied().unwrap_or("unknown");
        return Err(LoadError::part(
            path,
            part,
            format!("mode {mode}, not triangles; triangulate it when exporting (ray tracing needs triangles)"),
        ));
    }
    let fail = |what: String| LoadError::part(path, part, what);
    let a = &p.attributes;
    let pos = a.position.ok_or_else(|| {
        fail("no POSITION attribute; export the mesh again with positions".into())
    })?;
    // An accessor without a bufferView is zeros (valid glTF 2.0): positions or indices of zeros
    // make no triangle, and their count would bound no read by the file's size.
    let viewless = |k: usize| root.accessors.get(k).is_some_and(|a| a.buffer_view.is_none());
    if viewless(pos) {
        return Err(fail(format!("POSITION accessor {pos} has no bufferView, so every vertex is zero (valid glTF 2.0, no triangle to trace); export the mesh with its positions")));
    }
    if let Some(i) = p.indices.filter(|&i| viewless(i)) {
        return Err(fail(format!("indices accessor {i} has no bufferView, so every index is zero (valid glTF 2.0, no triangle to trace); export the mesh with its indices")));
    }
    let positions = accessor::vec3(root, buffers, pos).map_err(fail)?;
    let n = positions.len() as u32;
    let flat: Vec<u32> = match p.indices {
        Some(i) => accessor::indices(root, buffers, i).map_err(fail)?,
        None => (0..n).collect(),
    };
    if flat.len() % 3 != 0 {
        return Err(fail(format!("{} indices, not a multiple of 3", flat.len())));
    }
    if let Some(bad) = flat.iter().find(|i| **i >= n) {
        return Err(fail(format!("index {bad} past its {n} vertices")));
    }
    // Counted before reading: a NORMAL or TEXCOORD_0 without a bufferView (zeros) is then never
    // longer than the positions the file holds.
    let same =
        |k: &usize| root.accessors.get(*k).is_some_and(|a| a.count == positions.len() as u64);
    let normals = match a.normal.filter(same) {
        Some(k) => Some(accessor::vec3(root, buffers, k).map_err(fail)?),
        None => None,
    };
    let uvs = match a.texcoord0.filter(same) {
        Some(k) => Some(accessor::vec2(root, buffers, k).map_err(fail)?),
        None => None,
    };
    let indices = flat.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
    Ok(Read { positions, normals, uvs, indices })
}
