//! Writes glTF scenes for tests and measurements (`rtprobe scene make`), so no scene is
//! downloaded: the **test scene** — three meshes (a textured ground height field, a pyramid whose
//! two primitives — two opposite sides, then the other two with the base — have different
//! materials, an alpha-masked leaf quad instanced by three nodes), a node hierarchy with
//! translations, rotations and scales, three materials (one with `alphaMode` MASK, one with an
//! `emissiveFactor`), two PNG textures and a camera — and, with `triangles`, a **large scene** of
//! height-field meshes with at least that many triangles. As `.gltf` + `.bin` + PNGs, or one
//! `.glb` with the images in buffer views. Every file is written atomically.
use serde_json::{json, Value};
use std::path::{Path, PathBuf};

#[derive(Clone, Copy, Debug, Default)]
pub struct MakeOptions {
    /// 0: the test scene; else a large scene of at least this many triangles.
    pub triangles: u64,
    pub glb: bool,
}

#[derive(Debug, thiserror::Error)]
pub enum MakeError {
    #[error("cannot write the scene: {0}")]
    Write(#[from] crate::atomic::WriteError),
    #[error("cannot encode a texture: {0}")]
    Png(#[from] png::EncodingError),
}

/// Geometry of one mesh, one or more primitives.
struct Prim {
    positions: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    uvs: Vec<[f32; 2]>,
    indices: Vec<u32>,
    material: usize,
}

/// The binary buffer and the JSON arrays that describe it.
#[derive(Default)]
struct Builder {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Builder {
    fn view(&mut self, bytes: &[u8], target: Option<u32>) -> usize {
        while self.bin.len() % 4 != 0 {
            self.bin.push(0);
        }
        let mut v = json!({"buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len()});
        if let Some(t) = target {
            v["target"] = json!(t);
        }
        self.bin.extend_from_slice(bytes);
        self.views.push(v);
        self.views.len() - 1
    }

    fn floats<const N: usize>(&mut self, data: &[[f32; N]], kind: &str, bounds: bool) -> usize {
        let bytes: Vec<u8> = data.iter().flatten().flat_map(|f| f.to_le_bytes()).collect();
        let view = self.view(&bytes, Some(34962));
        let mut a =
            json!({"bufferView": view, "componentType": 5126, "count": data.len(), "type": kind});
        if bounds {
            let lo: Vec<f32> =
                (0..N).map(|k| data.iter().map(|v| v[k]).fold(f32::INFINITY, f32::min)).collect();
            let hi: Vec<f32> = (0..N)
                .map(|k| data.iter().map(|v| v[k]).fold(f32::NEG_INFINITY, f32::max))
                .collect();
            a["min"] = json!(lo);
            a["max"] = json!(hi);
        }
        self.accessors.push(a);
        self.accessors.len() - 1
    }

    fn indices(&mut self, data: &[u32]) -> usize {
        let bytes: Vec<u8> = data.iter().flat_map(|i| i.to_le_bytes()).collect();
        let view = self.view(&bytes, Some(34963));
        self.accessors.push(json!({"bufferView": view, "componentType": 5125, "count": data.len(), "type": "SCALAR"}));
        self.accessors.len() - 1
    }

    fn mesh(&mut self, name: &str, prims: &[Prim]) -> Value {
        let primitives: Vec<Value> = prims
            .iter()
            .map(|p| {
                let pos = self.floats(&p.positions, "VEC3", true);
                let nor = self.floats(&p.normals, "VEC3", false);
                let uv = self.floats(&p.uvs, "VEC2", false);
                let idx = self.indices(&p.indices);
                json!({"attributes": {"POSITION": pos, "NORMAL": nor, "TEXCOORD_0": uv}, "indices": idx, "material": p.material, "mode": 4})
            })
            .collect();
        json!({"name": name, "primitives": primitives})
    }
}

/// An n×n-quad height field over [−1, 1]², heights from a fixed formula (two triangles a quad).
fn height_field(n: u32, material: usize, phase: f32) -> Prim {
    let (mut positions, mut normals, mut uvs, mut indices) = (vec![], vec![], vec![], vec![]);
    for j in 0..=n {
        for i in 0..=n {
            let (u, v) = (i as f32 / n as f32, j as f32 / n as f32);
            let h = 0.15 * ((7.0 * u + phase).sin() * (5.0 * v - phase).cos());
            positions.push([2.0 * u - 1.0, h, 2.0 * v - 1.0]);
            normals.push([0.0, 1.0, 0.0]);
            uvs.push([u, v]);
        }
    }
    for j in 0..n {
        for i in 0..n {
            let a = j * (n + 1) + i;
            indices.extend([a, a + n + 1, a + 1, a + 1, a + n + 1, a + n + 2]);
        }
    }
    Prim { positions, normals, uvs, indices, material }
}

/// A pyramid of two primitives: two opposite sides (red), then the other two sides with the base
/// (the leaf's material), so that from any side both primitives are in view.
fn pyramid() -> Vec<Prim> {
    let apex = [0.0, 1.0, 0.0];
    let b = [[-0.5, 0.0, -0.5], [0.5, 0.0, -0.5], [0.5, 0.0, 0.5], [-0.5, 0.0, 0.5]];
    let prim = |material| Prim {
        positions: vec![],
        normals: vec![],
        uvs: vec![],
        indices: vec![],
        material,
    };
    let mut sides = [prim(1), prim(2)];
    for k in 0..4 {
        let p = &mut sides[k % 2];
        let base = p.positions.len() as u32;
        p.positions.extend([b[k], b[(k + 1) % 4], apex]);
        p.normals.extend([[0.0, 0.45, 0.9]; 3]);
        p.uvs.extend([[0.0, 0.0], [1.0, 0.0], [0.5, 1.0]]);
        p.indices.extend([base, base + 2, base + 1]);
    }
    let [red, mut rest] = sides;
    let base = rest.positions.len() as u32;
    rest.positions.extend(b);
    rest.normals.extend([[0.0, -1.0, 0.0]; 4]);
    rest.uvs.extend([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]);
    rest.indices.extend([0, 1, 2, 0, 2, 3].map(|i| base + i));
    vec![red, rest]
}

fn leaf() -> Prim {
    Prim {
        positions: vec![[-0.5, -0.5, 0.0], [0.5, -0.5, 0.0], [0.5, 0.5, 0.0], [-0.5, 0.5, 0.0]],
        normals: vec![[0.0, 0.0, 1.0]; 4],
        uvs: vec![[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]],
        indices: vec![0, 1, 2, 0, 2, 3],
        material: 2,
    }
}

/// A 16×16 RGBA texture: a checker (`stripes` false) or alpha stripes (every other 4-texel
/// column transparent, so MASK discards it).
fn texture(stripes: bool) -> Result<Vec<u8>, png::EncodingError> {
    let mut rgba = Vec::with_capacity(16 * 16 * 4);
    for y in 0..16u32 {
        for x in 0..16u32 {
            rgba.extend(if stripes {
                [40, 200, 60, if (x / 4) % 2 == 0 { 255 } else { 0 }]
            } else if (x / 4 + y / 4) % 2 == 0 {
                [230, 230, 230, 255]
            } else {
                [30, 30, 160, 255]
            });
        }
    }
    let mut bytes = Vec::new();
    let mut enc = png::Encoder::new(&mut bytes, 16, 16);
    enc.set_color(png::ColorType::Rgba);
    enc.set_depth(png::BitDepth::Eight);
    enc.write_header()?.write_image_data(&rgba)?;
    Ok(bytes)
}

/// A quaternion `[x, y, z, w]` of `angle` radians about `axis` (unit).
fn quat(axis: [f32; 3], angle: f32) -> [f32; 4] {
    let (s, c) = (angle / 2.0).sin_cos();
    [axis[0] * s, axis[1] * s, axis[2] * s, c]
}

fn materials() -> Value {
    json!([
        {"name": "checker", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "baseColorFactor": [1.0, 1.0, 1.0, 1.0]}},
        {"name": "red", "emissiveFactor": [0.05, 0.0, 0.15], "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.1, 0.1, 1.0]}},
        {"name": "leaf", "alphaMode": "MASK", "alphaCutoff": 0.5, "doubleSided": true,
         "pbrMetallicRoughness": {"baseColorTexture": {"index": 1}}}
    ])
}

/// The test scene's meshes and nodes; the root nodes' indices last.
fn test_scene(b: &mut Builder) -> (Vec<Value>, Vec<Value>, Vec<usize>) {
    let meshes = vec![
        b.mesh("ground", &[height_field(8, 0, 0.3)]),
        b.mesh("pyramid", &pyramid()),
        b.mesh("leaf", &[leaf()]),
    ];
    let y = [0.0, 1.0, 0.0];
    let nodes = vec![
        json!({"name": "world", "translation": [0.0, -0.2, 0.0], "rotation": quat(y, 0.3), "children": [1, 2, 3]}),
        json!({"name": "ground", "mesh": 0, "scale": [3.0, 1.0, 3.0]}),
        json!({"name": "pyramid", "mesh": 1, "translation": [-1.0, 0.1, 0.5], "rotation": quat(y, 0.5), "scale": [1.2, 1.2, 1.2]}),
        json!({"name": "bush", "translation": [1.2, 0.3, -0.4], "rotation": quat(y, 0.8), "children": [4, 5, 6]}),
        json!({"name": "leaf a", "mesh": 2, "translation": [0.0, 0.5, 0.0]}),
        json!({"name": "leaf b", "mesh": 2, "translation": [0.4, 0.6, 0.2], "rotation": quat(y, 1.2)}),
        json!({"name": "leaf c", "mesh": 2, "translation": [-0.3, 0.4, -0.3], "rotation": quat([1.0, 0.0, 0.0], 0.4)}),
        camera_node(),
    ];
    (meshes, nodes, vec![0, 7])
}

fn camera_node() -> Value {
    json!({"name": "camera", "camera": 0, "translation": [0.0, 2.5, 6.0], "rotation": quat([1.0, 0.0, 0.0], -0.35)})
}

/// A 4×4 grid of height-field meshes with at least `triangles` triangles in all, each mesh
/// its own node.
fn large_scene(b: &mut Builder, triangles: u64) -> (Vec<Value>, Vec<Value>, Vec<usize>) {
    let per_mesh = triangles.div_ceil(16);
    let n = ((per_mesh as f64 / 2.0).sqrt().ceil() as u32).max(1);
    let mut meshes = Vec::new();
    let mut nodes = vec![json!({"name": "world", "children": (1..=16).collect::<Vec<_>>()})];
    for k in 0..16u32 {
        meshes.push(b.mesh(&format!("tile {k}"), &[height_field(n, (k % 2) as usize, k as f32)]));
        let (x, z) = ((k % 4) as f32 * 2.1 - 3.15, (k / 4) as f32 * 2.1 - 3.15);
        nodes.push(json!({"name": format!("tile {k}"), "mesh": k, "translation": [x, 0.0, z]}));
    }
    nodes.push(camera_node());
    (meshes, nodes, vec![0, 17])
}

/// Write the scene into `dir` (created if missing): `scene.gltf`, `scene.bin`, `checker.png`,
/// `stripes.png`, or `scene.glb`. Returns the scene file's path.
pub fn make(dir: &Path, o: MakeOptions) -> Result<PathBuf, MakeError> {
    let mut b = Builder::default();
    let (meshes, nodes, roots) =
        if o.triangles == 0 { test_scene(&mut b) } else { large_scene(&mut b, o.triangles) };
    let pngs = [("checker.png", texture(false)?), ("stripes.png", texture(true)?)];
    let images: Vec<Value> = if o.glb {
        pngs.iter()
            .map(|(_, png)| json!({"bufferView": b.view(png, None), "mimeType": "image/png"}))
            .collect()
    } else {
        pngs.iter().map(|(name, _)| json!({"uri": name})).collect()
    };
    while b.bin.len() % 4 != 0 {
        b.bin.push(0);
    }
    let mut buffer = json!({"byteLength": b.bin.len()});
    if !o.glb {
        buffer["uri"] = json!("scene.bin");
    }
    let doc = json!({
        "asset": {"version": "2.0", "generator": "rtprobe scene make"},
        "scene": 0,
        "scenes": [{"nodes": roots}],
        "nodes": nodes,
        "meshes": meshes,
        "materials": materials(),
        "textures": [{"source": 0, "sampler": 0}, {"source": 1, "sampler": 0}],
        "samplers": [{"magFilter": 9728, "minFilter": 9728}],
        "images": images,
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1, "aspectRatio": 1.0}}],
        "accessors": b.accessors,
        "bufferViews": b.views,
        "buffers": [buffer],
    });
    let text = serde_json::to_vec(&doc).expect("a JSON value serializes");
    if o.glb {
        let path = dir.join("scene.glb");
        crate::atomic::write_atomic(&path, &glb(text, &b.bin))?;
        return Ok(path);
    }
    crate::atomic::write_atomic(&dir.join("scene.bin"), &b.bin)?;
    for (name, png) in &pngs {
        crate::atomic::write_atomic(&dir.join(name), png)?;
    }
    let path = dir.join("scene.gltf");
    crate::atomic::write_atomic(&path, &text)?;
    Ok(path)
}

/// A binary glTF container: the 12-byte header, the JSON chunk padded with spaces, the BIN chunk
/// padded with zeros (glTF 2.0, "Binary glTF Layout").
/// A GLB of `json` and `bin`, each chunk padded to 4 bytes (glTF 2.0, "Chunks": JSON with
/// spaces, BIN with zeros).
pub(super) fn glb(mut json: Vec<u8>, bin: &[u8]) -> Vec<u8> {
    while json.len() % 4 != 0 {
        json.push(b' ');
    }
    let mut bin = bin.to_vec();
    while bin.len() % 4 != 0 {
        bin.push(0);
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = Vec::with_capacity(total);
    out.extend(b"glTF");
    out.extend(2u32.to_le_bytes());
    out.extend((total as u32).to_le_bytes());
    out.extend((json.len() as u32).to_le_bytes());
    out.extend(b"JSON");
    out.extend(json);
    out.extend((bin.len() as u32).to_le_bytes());
    out.extend(b"BIN\0");
    out.extend(bin);
    out
}
