//! The glTF 2.0 JSON document as far as rtprobe reads it, deserialized with `serde`: unknown
//! properties are ignored (glTF 2.0, "JSON Encoding": extensions and extras add properties), each
//! property the spec gives a default has it here (`#[serde(default = …)]`), and nothing is checked
//! yet — [`super::validate`] checks every index, type and byte range before anything is read.
//! Names follow the spec's "Properties Reference" (camelCase in the file).
use serde::Deserialize;

/// The top-level `glTF` object (its `asset` read with [`Head`]).
#[derive(Debug, Default, Deserialize)]
#[serde(rename_all = "camelCase")]
pub(super) struct Root {
    pub scene: Option<usize>,
    #[serde(default)]
    pub scenes: Vec<Scene>,
    #[serde(default)]
    pub nodes: Vec<Node>,
    #[serde(default)]
    pub cameras: Vec<Camera>,
    #[serde(default)]
    pub meshes: Vec<Mesh>,
    #[serde(default)]
    pub accessors: Vec<Accessor>,
    #[serde(default)]
    pub buffer_views: Vec<BufferView>,
    #[serde(default)]
    pub buffers: Vec<Buffer>,
    #[serde(default)]
    pub materials: Vec<Material>,
    #[serde(default)]
    pub textures: Vec<Texture>,
    #[serde(default)]
    pub images: Vec<Image>,
    /// Only counted: a texture's `sampler` must name one (rtprobe samples with its own).
    #[serde(default)]
    pub samplers: Vec<serde::de::IgnoredAny>,
}

/// What is read before anything else: the required extensions (each refused: rtprobe reads
/// none) and the asset's version. Deserialized on its own, so that a file whose other properties
/// an extension changed is refused for the extension, not for what it changed.
#[derive(Debug, Default, Deserialize)]
#[serde(rename_all = "camelCase")]
pub(super) struct Head {
    #[serde(default)]
    pub extensions_required: Vec<String>,
    pub asset: Option<Asset>,
}

/// glTF 2.0, "Asset": `version` (required) and `minVersion`, both `"major.minor"`.
#[derive(Debug, Default, Deserialize)]
#[serde(rename_all = "camelCase")]
pub(super) struct Asset {
    pub version: String,
    pub min_version: Option<String>,
}

#[derive(Debug, Default, Deserialize)]
pub(super) struct Scene {
    #[serde(default)]
    pub nodes: Vec<usize>,
}

/// glTF 2.0, "Transformations": `matrix` (column-major) or TRS, whose defaults are the identity.
#[derive(Debug, Default, Deserialize)]
pub(super) struct Node {
    pub camera: Option<usize>,
    #[serde(default)]
    pub children: Vec<usize>,
    pub mesh: Option<usize>,
    pub matrix: Option<[f32; 16]>,
    #[serde(default)]
    pub translation: [f32; 3],
    /// XYZW, W the scalar.
    #[serde(default = "identity_rotation")]
    pub rotation: [f32; 4],
    #[serde(default = "unit_scale")]
    pub scale: [f32; 3],
}

fn identity_rotation() -> [f32; 4] {
    [0.0, 0.0, 0.0, 1.0]
}

fn unit_scale() -> [f32; 3] {
    [1.0; 3]
}

/// glTF 2.0, "Cameras": `type` names which of the two projections is given.
#[derive(Debug, Default, Deserialize)]
pub(super) struct Camera {
    #[serde(rename = "type")]
    pub kind: String,
    pub perspective: Option<serde::de::IgnoredAny>,
    pub orthographic: Option<serde::de::IgnoredAny>,
}

#[derive(Debug, Default, Deserialize)]
pub(super) struct Mesh {
    pub name: Option<String>,
    pub primitives: Vec<Primitive>,
}

/// glTF 2.0, "Meshes": `mode` defaults to 4 (triangles); the attributes rtprobe reads.
#[derive(Debug, Default, Deserialize)]
pub(super) struct Primitive {
    pub attributes: Attributes,
    pub indices: Option<usize>,
    pub material: Option<usize>,
    #[serde(default = "triangles")]
    pub mode: u32,
}

fn triangles() -> u32 {
    4
}

#[derive(Debug, Default, Deserialize)]
pub(super) struct Attributes {
    #[serde(rename = "POSITION")]
    pub position: Option<usize>,
    #[serde(rename = "NORMAL")]
    pub normal: Option<usize>,
    #[serde(rename = "TEXCOORD_0")]
    pub texcoord0: Option<usize>,
}

/// glTF 2.0, "Accessors": `byteOffset` defaults to 0, `normalized` to false.
#[derive(Debug, Default, Deserialize)]
#[serde(rename_all = "camelCase")]
pub(super) struct Accessor {
    pub buffer_view: Option<usize>,
    #[serde(default)]
    pub byte_offset: u64,
    pub component_type: u32,
    #[serde(default)]
    pub normalized: bool,
    pub count: u64,
    #[serde(rename = "type")]
    pub kind: String,
    pub min: Option<Vec<f64>>,
    pub max: Option<Vec<f64>>,
    /// Not read: an accessor rtprobe reads that has one is refused ([`super::validate`]).
    pub sparse: Option<serde::de::IgnoredAny>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(rename_all = "camelCase")]
pub(super) struct BufferView {
    pub buffer: usize,
    #[serde(default)]
    pub byte_offset: u64,
    pub byte_length: u64,
    pub byte_stride: Option<u64>,
}

/// glTF 2.0, "Buffers and Buffer Views": no `uri` is the GLB's BIN chunk (first buffer only).
#[derive(Debug, Default, Deserialize)]
#[serde(rename_all = "camelCase")]
pub(super) struct Buffer {
    pub uri: Option<String>,
    pub byte_length: u64,
}

/// glTF 2.0, "Materials": the defaults of the "Default Material" section.
#[derive(Debug, Deserialize)]
#[serde(rename_all = "camelCase")]
pub(super) struct Material {
    pub name: Option<String>,
    #[serde(default)]
    pub pbr_metallic_roughness: Pbr,
    #[serde(default)]
    pub emissive_factor: [f32; 3],
    #[serde(default = "opaque")]
    pub alpha_mode: String,
    pub alpha_cutoff: Option<f32>,
}

fn opaque() -> String {
    "OPAQUE".into()
}

#[derive(Debug, Deserialize)]
#[serde(rename_all = "camelCase")]
pub(super) struct Pbr {
    #[serde(default = "white")]
    pub base_color_factor: [f32; 4],
    pub base_color_texture: Option<TextureInfo>,
}

impl Default for Pbr {
    fn default() -> Self {
        Pbr { base_color_factor: white(), base_color_texture: None }
    }
}

fn white() -> [f32; 4] {
    [1.0; 4]
}

/// `textureInfo`: `texCoord` defaults to 0 (TEXCOORD_0, the one set rtprobe reads).
#[derive(Debug, Deserialize)]
#[serde(rename_all = "camelCase")]
pub(super) struct TextureInfo {
    pub index: usize,
    #[serde(default)]
    pub tex_coord: u32,
}

/// glTF 2.0, "Textures": `source` may be undefined (then an extension SHOULD supply the image;
/// rtprobe reads none, so the material is untextured).
#[derive(Debug, Default, Deserialize)]
pub(super) struct Texture {
    pub source: Option<usize>,
    pub sampler: Option<usize>,
}

/// glTF 2.0, "Images": a `uri`, or a `bufferView` with its `mimeType`.
#[derive(Debug, Default, Deserialize)]
#[serde(rename_all = "camelCase")]
pub(super) struct Image {
    pub uri: Option<String>,
    pub buffer_view: Option<usize>,
    pub mime_type: Option<String>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_the_specs_and_unknown_properties_are_ignored() {
        let r: Root = serde_json::from_str(
            r#"{"asset": {"version": "2.0", "generator": "x"}, "extras": 1,
                "nodes": [{}], "materials": [{"doubleSided": true}],
                "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "COLOR_0": 1}}]}]}"#,
        )
        .unwrap();
        let n = &r.nodes[0];
        assert_eq!(
            (n.translation, n.rotation, n.scale),
            ([0.0; 3], [0.0, 0.0, 0.0, 1.0], [1.0; 3])
        );
        assert_eq!(r.meshes[0].primitives[0].mode, 4);
        let m = &r.materials[0];
        assert_eq!(m.pbr_metallic_roughness.base_color_factor, [1.0; 4]);
        assert_eq!((m.alpha_mode.as_str(), m.alpha_cutoff), ("OPAQUE", None));
        let no_version = serde_json::from_str::<Head>(r#"{"asset": {"generator": "x"}}"#);
        assert!(no_version.is_err(), "asset.version is required");
    }
}
