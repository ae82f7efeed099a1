//! `run --shader --scene FILE`'s data: the loaded glTF scene laid out the way the glTF ray
//! tracing tutorial lays it out, each mesh once, for `--fill TARGET=scene.NAME` ([`Item`]).
//! Positions and normals are tightly packed `vec3` (scalar layout), UVs `vec2`, indices `uint`
//! relative to their primitive's first vertex (the shader adds `vertexOffset`), a mesh without
//! normals or UVs holds zeros there so every vertex list stays aligned with the positions.
//! Materials are the tutorial's `GltfShadeMaterial` ([`MATERIAL_BYTES`] each, scalar layout:
//! `vec4 pbrBaseColorFactor; vec3 emissiveFactor; int pbrBaseColorTexture`, the texture a glTF
//! texture index or −1), the document's then glTF's default material (a primitive without one
//! points at it). `prim_info` is the tutorial's flat table: one
//! `PrimMeshInfo {indexOffset, vertexOffset, materialIndex}` per primitive, mesh by mesh, entry
//! `gl_InstanceCustomIndexEXT` (the harness traces one BLAS per primitive, custom index the
//! primitive's global index: `per_primitive`); offsets in the shared index and vertex lists.
//! `scene_desc` is the device addresses of the six buffers as `uint64`. The child makes the
//! buffers named by the fills ([`SceneBuffers`]); the parent sums their bytes first ([`bytes_needed`]).
use super::error::HarnessError;
use super::fill::{Fill, FillError, Fills, Request, Source, Target};
use super::module::UserModule;
pub use super::scene_item::{Item, ALL, DESC_ORDER};
use crate::scene::gltf::{Alpha, Loaded};
use crate::vk::memory::{Buffer, Location};
use crate::vk::Gpu;
use ash::vk;
use serde::{Deserialize, Serialize};

/// Bytes of one material: `vec4 pbrBaseColorFactor; vec3 emissiveFactor;
/// int pbrBaseColorTexture` (scalar layout: the texture index at byte 28).
pub const MATERIAL_BYTES: usize = 32;
/// Bytes of one `prim_info` entry (`PrimMeshInfo`).
pub const PRIM_INFO_BYTES: usize = 12;
/// Bytes of `scene_desc`: six device addresses.
pub const SCENE_DESC_BYTES: usize = 48;

fn floats<const N: usize>(out: &mut Vec<u8>, v: &[[f32; N]]) {
    out.extend(v.iter().flatten().flat_map(|f| f.to_le_bytes()));
}

/// Per mesh, its first vertex and first index in the shared lists.
fn mesh_bases(loaded: &Loaded) -> Vec<(u32, u32)> {
    let (mut v, mut i) = (0u32, 0u32);
    loaded
        .meshes
        .iter()
        .map(|m| {
            let at = (v, i);
            v += m.positions.len() as u32;
            i += 3 * m.indices.len() as u32;
            at
        })
        .collect()
}

/// The materials: the document's, then glTF's default (white, no emission, no texture).
fn materials(loaded: &Loaded) -> Vec<u8> {
    let mut out = Vec::new();
    let default = crate::scene::gltf::Material {
        name: "default".into(),
        base_color: [1.0; 4],
        base_color_image: None,
        base_color_texture: None,
        emissive: [0.0; 3],
        alpha: Alpha::Opaque,
    };
    for m in loaded.materials.iter().chain([&default]) {
        out.extend(m.base_color.iter().flat_map(|f| f.to_le_bytes()));
        out.extend(m.emissive.iter().flat_map(|f| f.to_le_bytes()));
        // The image index, so it selects the `scene.textures` element (element i = image i); it
        // is the glTF texture index where texture i's source is image i, as exporters write it.
        out.extend(m.base_color_image.map_or(-1, |i| i as i32).to_le_bytes());
    }
    out
}

/// Every primitive's `PrimMeshInfo`, mesh by mesh (entry k: global primitive k).
fn prim_info(loaded: &Loaded) -> Vec<u8> {
    let mut out = Vec::new();
    let default = loaded.materials.len() as i32;
    for (m, (v, i)) in loaded.meshes.iter().zip(mesh_bases(loaded)) {
        for p in &m.primitives {
            out.extend((i + 3 * p.first_triangle).to_le_bytes());
            out.extend((v + p.vertex_offset).to_le_bytes());
            out.extend(p.material.map_or(default, |k| k as i32).to_le_bytes());
        }
    }
    out
}

/// The bytes of `item` (`scene_desc` and `textures` are not bytes of the scene: empty).
pub fn bytes(loaded: &Loaded, item: Item) -> Vec<u8> {
    let mut out = Vec::new();
    for m in &loaded.meshes {
        let n = m.positions.len();
        match item {
            Item::Positions => floats(&mut out, &m.positions),
            Item::Normals if m.normals.len() == n => floats(&mut out, &m.normals),
            Item::Normals => out.resize(out.len() + 12 * n, 0),
            Item::Uvs if m.uvs.len() == n => floats(&mut out, &m.uvs),
            Item::Uvs => out.resize(out.len() + 8 * n, 0),
            Item::Indices => out.extend(m.indices.iter().flatten().flat_map(|i| i.to_le_bytes())),
            Item::Materials | Item::PrimInfo | Item::SceneDesc | Item::Textures => break,
        }
    }
    match item {
        Item::Materials => materials(loaded),
        Item::PrimInfo => prim_info(loaded),
        Item::Positions
        | Item::Normals
        | Item::Uvs
        | Item::Indices
        | Item::SceneDesc
        | Item::Textures => out,
    }
}

/// The buffers `items` need made: each named one, and all six behind a `scene_desc`.
fn buffers_for(items: &[Item]) -> Vec<Item> {
    let mut out: Vec<Item> = items.iter().copied().filter(|i| *i != Item::Textures).collect();
    if items.contains(&Item::SceneDesc) {
        out.extend(DESC_ORDER);
    }
    out.sort();
    out.dedup();
    out
}

/// The device memory `items` take on the device: their buffers' bytes, and for `textures`
/// each image's RGBA8 texels (`texture_bytes`, from the images' sizes).
pub fn bytes_needed(loaded: &Loaded, items: &[Item], texture_bytes: u64) -> u64 {
    let buffers: u64 = buffers_for(items)
        .into_iter()
        .map(|i| match i {
            Item::SceneDesc => SCENE_DESC_BYTES as u64,
            _ => bytes(loaded, i).len() as u64,
        })
        .sum();
    buffers + if items.contains(&Item::Textures) { texture_bytes } else { 0 }
}

/// The largest device-local heap of a device, in bytes.
pub fn largest_device_heap(memory: &vk::PhysicalDeviceMemoryProperties) -> u64 {
    memory.memory_heaps[..memory.memory_heap_count as usize]
        .iter()
        .filter(|h| h.flags.contains(vk::MemoryHeapFlags::DEVICE_LOCAL))
        .map(|h| h.size)
        .max()
        .unwrap_or(0)
}

/// One scene fill as the job carries it: its place among the fills, its target and item.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct SceneFill {
    /// Its index among `--fill`'s (a later fill over an earlier one where they meet).
    pub at: usize,
    pub target: Target,
    pub item: Item,
}

/// A `scene.NAME` fill held to `modules`: a buffer item into a buffer binding (the buffer is
/// then sized to the scene's bytes) or as an 8-byte address at a push or record offset;
/// `textures` only into a texture array binding with room for the scene's `images`
/// (`super::scene_textures::check`). `at`: its place among the run's fills.
pub fn resolve_scene(
    r: &Request,
    modules: &[UserModule],
    (at, images): (usize, usize),
) -> Result<SceneFill, FillError> {
    let Source::Scene(item) = r.source else {
        return Err(FillError::Syntax(r.text.clone(), "not a scene source".into()));
    };
    let refuse = |why: String| FillError::Target(r.text.clone(), why);
    if item == Item::Textures {
        super::scene_textures::check(r, modules, images)?;
        return Ok(SceneFill { at, target: r.target, item });
    }
    let room = super::fill::room(r, modules)?;
    if matches!(r.target, Target::Push(_) | Target::Record(_)) && room < 8 {
        return Err(refuse(format!("only {room} bytes from there to the block's end, where a device address takes 8; give an offset at least 8 bytes before the end")));
    }
    Ok(SceneFill { at, target: r.target, item })
}

/// The bindings the `scene.textures` fills target (`super::scene_textures`).
pub fn texture_targets(fills: &[SceneFill]) -> Vec<(u32, u32)> {
    let binding = |f: &SceneFill| match f.target {
        Target::Binding { set, binding, .. } => Some((set, binding)),
        Target::Push(_) | Target::Record(_) => None,
    };
    fills.iter().filter(|f| f.item == Item::Textures).filter_map(binding).collect()
}

/// The scene's buffers on the device, made for the fills that name them.
pub struct SceneBuffers {
    made: Vec<(Item, Buffer)>,
}

impl SceneBuffers {
    /// The buffers `fills` need, written from `loaded` (`scene_desc` after the others, from
    /// their addresses).
    pub fn new(gpu: &Gpu, loaded: &Loaded, fills: &[SceneFill]) -> Result<Self, HarnessError> {
        let items: Vec<Item> = fills.iter().map(|f| f.item).collect();
        let mut made: Vec<(Item, Buffer)> = Vec::new();
        let usage =
            vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS;
        for item in buffers_for(&items) {
            let data = match item {
                Item::SceneDesc => DESC_ORDER
                    .iter()
                    .flat_map(|d| {
                        made.iter()
                            .find(|(i, _)| i == d)
                            .map_or(0, |(_, b)| b.address)
                            .to_le_bytes()
                    })
                    .collect(),
                _ => bytes(loaded, item),
            };
            let what = "scene buffer";
            let buf = Buffer::new(gpu, data.len().max(16) as u64, usage, Location::Host, what)?;
            buf.write(0, &data);
            made.push((item, buf));
        }
        Ok(SceneBuffers { made })
    }

    /// `fills` with each scene fill put in its place: a binding gets its buffer's bytes, a
    /// push or record offset the buffer's 8-byte device address.
    pub fn placed(&self, loaded: &Loaded, fills: &Fills, scene: &[SceneFill]) -> Fills {
        let mut out = fills.0.clone();
        for f in scene.iter().filter(|f| f.item != Item::Textures) {
            let Some((_, buf)) = self.made.iter().find(|(i, _)| *i == f.item) else { continue };
            let bytes = match f.target {
                Target::Binding { .. } if f.item == Item::SceneDesc => {
                    let all = DESC_ORDER.iter().flat_map(|d| {
                        self.made
                            .iter()
                            .find(|(i, _)| i == d)
                            .map_or(0, |(_, b)| b.address)
                            .to_le_bytes()
                    });
                    all.collect()
                }
                Target::Binding { .. } => bytes(loaded, f.item),
                Target::Push(_) | Target::Record(_) => buf.address.to_le_bytes().to_vec(),
            };
            out.insert(f.at.min(out.len()), Fill { target: f.target, bytes });
        }
        Fills(out)
    }

    pub fn destroy(&self, gpu: &Gpu) {
        self.made.iter().for_each(|(_, b)| b.destroy(gpu));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn test_scene() -> (crate::tempdir::TempDir, Loaded) {
        let d = crate::tempdir::tempdir().unwrap();
        let o = crate::scene::gltf::make::MakeOptions { triangles: 0, glb: false };
        let path = crate::scene::gltf::make::make(d.path(), o).unwrap();
        let l = Loaded::load(&path).unwrap();
        (d, l)
    }

    fn words(b: &[u8]) -> Vec<u32> {
        b.chunks(4).map(|c| u32::from_le_bytes(c.try_into().unwrap())).collect()
    }

    /// Every `PrimMeshInfo` points at its primitive's triangles and vertices in the shared
    /// lists, entry k the k-th primitive mesh by mesh: the triangle the loader holds is the one
    /// the layout gives, and the flattened scene's custom index names that entry.
    #[test]
    fn prim_info_finds_every_primitives_triangles() {
        let (_d, l) = test_scene();
        let info = words(&bytes(&l, Item::PrimInfo));
        let idx = words(&bytes(&l, Item::Indices));
        let pos = bytes(&l, Item::Positions);
        let (mut bases_v, mut seen, mut entry) = (0usize, 0, 0usize);
        for (k, m) in l.meshes.iter().enumerate() {
            for (g, p) in m.primitives.iter().enumerate() {
                let e = &info[3 * entry..3 * entry + 3];
                for t in 0..p.triangles {
                    let want = m.triangle(p.first_triangle + t);
                    let got: Vec<u32> =
                        (0..3).map(|c| idx[(e[0] + 3 * t + c) as usize] + e[1]).collect();
                    for c in 0..3 {
                        let at = 12 * got[c] as usize;
                        let v = &pos[at..at + 12];
                        let w: Vec<u8> = m.positions[want[c] as usize]
                            .iter()
                            .flat_map(|f| f.to_le_bytes())
                            .collect();
                        assert_eq!(v, &w[..], "mesh {k} primitive {g} triangle {t}");
                        assert_eq!(got[c] as usize - bases_v, want[c] as usize);
                    }
                    seen += 1;
                }
                let mat = e[2] as usize;
                assert_eq!(Some(mat).filter(|m| *m < l.materials.len()), p.material);
                entry += 1;
            }
            bases_v += m.positions.len();
        }
        assert_eq!(info.len(), 3 * entry, "one entry per primitive, no header");
        assert_eq!(seen, l.meshes.iter().map(|m| m.indices.len()).sum::<usize>());
        // The flattened scene's custom indices are exactly the entries, each primitive's.
        let s = super::super::scene::loaded(&l, 64);
        let mut customs: Vec<u32> = s.instances.iter().map(|i| i.custom_index).collect();
        customs.sort_unstable();
        customs.dedup();
        assert_eq!(customs, (0..entry as u32).collect::<Vec<_>>());
    }

    /// The largest device-local heap: a host-only heap larger than it does not count (the
    /// twin: counting every heap would give the host heap).
    #[test]
    fn the_largest_heap_is_a_device_local_one() {
        let mut m =
            vk::PhysicalDeviceMemoryProperties { memory_heap_count: 3, ..Default::default() };
        m.memory_heaps[0] =
            vk::MemoryHeap { size: 8 << 30, flags: vk::MemoryHeapFlags::DEVICE_LOCAL };
        m.memory_heaps[1] = vk::MemoryHeap { size: 64 << 30, flags: vk::MemoryHeapFlags::empty() };
        m.memory_heaps[2] =
            vk::MemoryHeap { size: 256 << 20, flags: vk::MemoryHeapFlags::DEVICE_LOCAL };
        assert_eq!(largest_device_heap(&m), 8 << 30);
        m.memory_heap_count = 0;
        assert_eq!(largest_device_heap(&m), 0);
    }

    #[test]
    fn materials_and_vertex_lists_have_their_sizes() {
        let (_d, l) = test_scene();
        let verts: usize = l.meshes.iter().map(|m| m.positions.len()).sum();
        assert_eq!(bytes(&l, Item::Positions).len(), 12 * verts);
        assert_eq!(bytes(&l, Item::Normals).len(), 12 * verts);
        assert_eq!(bytes(&l, Item::Uvs).len(), 8 * verts);
        let m = bytes(&l, Item::Materials);
        assert_eq!(m.len(), MATERIAL_BYTES * (l.materials.len() + 1));
        let w = words(&m);
        assert_eq!(f32::from_bits(w[0]), l.materials[0].base_color[0]);
        // The tutorial's GltfShadeMaterial: emissive at bytes 16..28, the texture at 28.
        for (k, mat) in l.materials.iter().enumerate() {
            let e = &w[8 * k..8 * k + 8];
            assert_eq!(
                e[4..7].iter().map(|b| f32::from_bits(*b)).collect::<Vec<_>>(),
                mat.emissive
            );
            assert_eq!(e[7] as i32, mat.base_color_image.map_or(-1, |t| t as i32));
        }
        assert!(l.materials.iter().any(|m| m.emissive != [0.0; 3]), "the test scene emits");
        assert_eq!(w[8 * l.materials.len() + 7] as i32, -1, "the default has no texture");
        let needed = bytes_needed(&l, &[Item::SceneDesc], 0);
        let six: u64 = DESC_ORDER.iter().map(|i| bytes(&l, *i).len() as u64).sum();
        assert_eq!(needed, six + SCENE_DESC_BYTES as u64);
        assert_eq!(bytes_needed(&l, &[Item::Uvs], 100), 8 * verts as u64);
        assert_eq!(Item::parse("prim_info"), Some(Item::PrimInfo));
        assert_eq!(Item::parse("prims"), None);
    }
}
