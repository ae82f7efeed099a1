//! The document checked before anything is read from it, each failure one line naming the
//! property as a JSON path (`meshes[0].primitives[1].indices: accessor 9 of 4`): the asset
//! version (glTF 2.0, "Asset", "Versioning"), every index into another array ("Indices and
//! Names"), every accessor's types and its last element inside its buffer view, every buffer view
//! inside its buffer, strides ("Data Alignment"; the `bufferView.byteStride` schema: 4 to 252, a
//! multiple of 4), the accessor types of the attributes rtprobe reads ("Meshes": POSITION and
//! NORMAL VEC3 float, TEXCOORD_n VEC2 float or normalized unsigned byte or short; indices
//! SCALAR unsigned byte, short or int; POSITION with `min` and `max`), enumerations (`mode`,
//! `alphaMode`, camera `type`) and images (a `uri` or a `bufferView` with a `mimeType`). Every
//! byte range is computed with checked arithmetic: a file's numbers cannot overflow it, and
//! after it every count × size of a read lies inside a buffer whose bytes are checked at load.
use super::accessor::{component_size, element_size, F32, U16, U32, U8};
use super::doc::{Accessor, Asset, Primitive, Root};

/// How a sparse accessor's refusal ends: valid glTF 2.0 that rtprobe does not read, so the
/// loader names it as a part of the file, not as a file that is not glTF (`open`).
pub(super) const SPARSE: &str =
    "sparse, which rtprobe does not read; export it without sparse accessors";

/// `invalid at {at}: {what}`.
fn bad(at: impl std::fmt::Display, what: impl std::fmt::Display) -> String {
    format!("invalid at {at}: {what}")
}

/// `i` indexes an array of `n` `what`s.
fn index(at: impl Fn() -> String, what: &str, i: usize, n: usize) -> Result<(), String> {
    match i < n {
        true => Ok(()),
        false => Err(bad(at(), format!("{what} {i} of {n}"))),
    }
}

/// glTF 2.0, "Asset": `version` "2.x" (minor versions are forward compatible, "Versioning"), and
/// a `minVersion`, if any, that rtprobe's 2.0 reader supports (MUST not load otherwise).
pub(super) fn version(asset: Option<&Asset>) -> Result<(), String> {
    let asset = asset.ok_or_else(|| bad("asset", "missing (every glTF has one)"))?;
    let parse = |v: &str| {
        let (major, minor) = v.split_once('.')?;
        let digits =
            |s: &str| !s.is_empty() && s.len() <= 9 && s.bytes().all(|b| b.is_ascii_digit());
        (digits(major) && digits(minor))
            .then(|| (major.parse::<u32>().ok(), minor.parse::<u32>().ok()))
    };
    match parse(&asset.version) {
        Some((Some(2), Some(_))) => {}
        _ => return Err(bad("asset.version", format!("\"{}\", not 2.x", asset.version))),
    }
    match asset.min_version.as_deref().map(parse) {
        None | Some(Some((Some(2), Some(0)))) => Ok(()),
        Some(_) => Err(bad(
            "asset.minVersion",
            format!("\"{}\": rtprobe reads glTF 2.0", asset.min_version.as_deref().unwrap_or("")),
        )),
    }
}

/// Every check below, in the order the parts are read.
pub(super) fn check(root: &Root) -> Result<(), String> {
    buffers(root)?;
    accessors(root)?;
    meshes(root)?;
    hierarchy(root)?;
    materials(root)?;
    images(root)
}

/// Buffer views inside their buffers, strides valid.
fn buffers(root: &Root) -> Result<(), String> {
    for (i, v) in root.buffer_views.iter().enumerate() {
        let at = || format!("bufferViews[{i}]");
        index(|| format!("{}.buffer", at()), "buffer", v.buffer, root.buffers.len())?;
        let length = root.buffers[v.buffer].byte_length;
        if v.byte_offset.checked_add(v.byte_length).is_none_or(|end| end > length) {
            let what = format!(
                "bytes {} + {} past buffer {} of {length} bytes",
                v.byte_offset, v.byte_length, v.buffer
            );
            return Err(bad(at(), what));
        }
        if let Some(s) = v.byte_stride.filter(|s| !(4..=252).contains(s) || s % 4 != 0) {
            return Err(bad(
                format!("{}.byteStride", at()),
                format!("{s}, not 4 to 252 in steps of 4"),
            ));
        }
    }
    Ok(())
}

/// Each accessor's types known, its count at least 1, its view (where it names one) there and its
/// last element inside that view.
fn accessors(root: &Root) -> Result<(), String> {
    for (i, a) in root.accessors.iter().enumerate() {
        let at = |field: &str| format!("accessors[{i}].{field}");
        if component_size(a.component_type).is_none() {
            return Err(bad(
                at("componentType"),
                format!("{}, not a glTF 2.0 component type", a.component_type),
            ));
        }
        let size = element_size(a.component_type, &a.kind)
            .ok_or_else(|| bad(at("type"), format!("\"{}\", not SCALAR, VECn or MATn", a.kind)))?;
        if a.count == 0 {
            return Err(bad(at("count"), "0 (at least 1)"));
        }
        // No bufferView: zeros (the `accessor.bufferView` schema), nothing to hold to a view.
        let Some(v) = a.buffer_view else {
            continue;
        };
        index(|| at("bufferView"), "bufferView", v, root.buffer_views.len())?;
        let view = &root.buffer_views[v];
        let stride = view.byte_stride.unwrap_or(size);
        if stride < size {
            return Err(bad(
                format!("bufferViews[{v}].byteStride"),
                format!("{stride}, less than accessor {i}'s {size}-byte element"),
            ));
        }
        let end = (a.count - 1)
            .checked_mul(stride)
            .and_then(|s| s.checked_add(size))
            .and_then(|s| s.checked_add(a.byte_offset));
        if end.is_none_or(|e| e > view.byte_length) {
            let what = format!(
                "{} elements of {size} bytes, stride {stride}, from byte {}: past bufferView {v} of {} bytes",
                a.count, a.byte_offset, view.byte_length
            );
            return Err(bad(format!("accessors[{i}]"), what));
        }
    }
    Ok(())
}

/// Each primitive's accessors and material named, of the types their semantics allow.
fn meshes(root: &Root) -> Result<(), String> {
    // A sparse accessor (valid glTF 2.0) refuses only a mesh some node names: one no node names
    // is never read (`Loaded::load`), so it cannot refuse the file.
    let named: std::collections::HashSet<usize> =
        root.nodes.iter().filter_map(|n| n.mesh).collect();
    for (m, mesh) in root.meshes.iter().enumerate() {
        // (the `mesh.primitives` schema: at least one; none would be a BLAS of no geometry)
        if mesh.primitives.is_empty() {
            return Err(bad(format!("meshes[{m}].primitives"), "empty (at least 1)"));
        }
        for (p, prim) in mesh.primitives.iter().enumerate() {
            let at = |field: &str| format!("meshes[{m}].primitives[{p}].{field}");
            if prim.mode > 6 {
                return Err(bad(at("mode"), format!("{}, not 0 to 6", prim.mode)));
            }
            if let Some(k) = prim.material {
                index(|| at("material"), "material", k, root.materials.len())?;
            }
            primitive(root, prim, &at, named.contains(&m))?;
        }
    }
    Ok(())
}

/// What an accessor read as one semantic may be: its `type`, component types, and whether an
/// integer one must be normalized.
struct Allowed {
    kind: &'static str,
    types: &'static [u32],
    normalized_ints: bool,
}

const FLOAT_VEC3: Allowed = Allowed { kind: "VEC3", types: &[F32], normalized_ints: false };
const TEXCOORD: Allowed = Allowed { kind: "VEC2", types: &[F32, U8, U16], normalized_ints: true };
const INDICES: Allowed = Allowed { kind: "SCALAR", types: &[U8, U16, U32], normalized_ints: false };

/// `read`: whether the loader may read the primitive (its mesh named by a node): only then is a
/// sparse accessor refused.
fn primitive(
    root: &Root,
    prim: &Primitive,
    at: &dyn Fn(&str) -> String,
    read: bool,
) -> Result<(), String> {
    let n = root.accessors.len();
    let attrs = &prim.attributes;
    let semantics = [
        ("attributes.POSITION", attrs.position, &FLOAT_VEC3),
        ("attributes.NORMAL", attrs.normal, &FLOAT_VEC3),
        ("attributes.TEXCOORD_0", attrs.texcoord0, &TEXCOORD),
        ("indices", prim.indices, &INDICES),
    ];
    for (field, a, allowed) in semantics {
        let Some(a) = a else { continue };
        index(|| at(field), "accessor", a, n)?;
        semantic(&root.accessors[a], allowed, read)
            .map_err(|what| bad(at(field), format!("accessor {a}: {what}")))?;
    }
    if let Some(a) = prim.indices.and_then(|a| root.accessors[a].buffer_view) {
        if root.buffer_views[a].byte_stride.is_some() {
            return Err(bad(at("indices"), format!("bufferView {a} has a byteStride; index data is tightly packed (glTF 2.0, Accessors: MUST NOT)")));
        }
    }
    if let Some(a) = attrs.position {
        let acc = &root.accessors[a];
        let three = |b: &Option<Vec<f64>>| b.as_ref().is_some_and(|v| v.len() == 3);
        if !three(&acc.min) || !three(&acc.max) {
            let what = format!("accessor {a} lacks a 3-component min and max (glTF 2.0, Meshes: POSITION MUST have them)");
            return Err(bad(at("attributes.POSITION"), what));
        }
    }
    Ok(())
}

/// `a` is of a type `allowed`, and dense where it is `read` (rtprobe does not read sparse
/// accessors).
fn semantic(a: &Accessor, allowed: &Allowed, read: bool) -> Result<(), String> {
    let int = a.component_type != F32;
    if a.kind != allowed.kind
        || !allowed.types.contains(&a.component_type)
        || (int && allowed.normalized_ints && !a.normalized)
    {
        let norm = if a.normalized { " normalized" } else { "" };
        return Err(format!(
            "{} of componentType {}{norm}, not a type glTF 2.0 allows here (Meshes)",
            a.kind, a.component_type
        ));
    }
    if read && a.sparse.is_some() {
        return Err(SPARSE.into());
    }
    Ok(())
}

/// The default scene, scenes' roots, nodes' meshes, cameras and children named; cameras typed.
fn hierarchy(root: &Root) -> Result<(), String> {
    let nodes = root.nodes.len();
    if let Some(s) = root.scene {
        index(|| "scene".into(), "scene", s, root.scenes.len())?;
    }
    for (s, scene) in root.scenes.iter().enumerate() {
        for (k, &n) in scene.nodes.iter().enumerate() {
            index(|| format!("scenes[{s}].nodes[{k}]"), "node", n, nodes)?;
        }
    }
    for (i, node) in root.nodes.iter().enumerate() {
        let at = |f: &str| format!("nodes[{i}].{f}");
        if let Some(m) = node.mesh {
            index(|| at("mesh"), "mesh", m, root.meshes.len())?;
        }
        if let Some(c) = node.camera {
            index(|| at("camera"), "camera", c, root.cameras.len())?;
        }
        for (k, &c) in node.children.iter().enumerate() {
            index(|| format!("nodes[{i}].children[{k}]"), "node", c, nodes)?;
        }
    }
    for (i, c) in root.cameras.iter().enumerate() {
        let given = match c.kind.as_str() {
            "perspective" => c.perspective.is_some(),
            "orthographic" => c.orthographic.is_some(),
            other => {
                return Err(bad(
                    format!("cameras[{i}].type"),
                    format!("\"{other}\", not perspective or orthographic"),
                ))
            }
        };
        if !given {
            return Err(bad(
                format!("cameras[{i}]"),
                format!("type {} without its {} object", c.kind, c.kind),
            ));
        }
    }
    Ok(())
}

/// Materials' alpha modes and textures, textures' images and samplers.
fn materials(root: &Root) -> Result<(), String> {
    for (i, m) in root.materials.iter().enumerate() {
        if !matches!(m.alpha_mode.as_str(), "OPAQUE" | "MASK" | "BLEND") {
            return Err(bad(
                format!("materials[{i}].alphaMode"),
                format!("\"{}\", not OPAQUE, MASK or BLEND", m.alpha_mode),
            ));
        }
        if let Some(t) = &m.pbr_metallic_roughness.base_color_texture {
            let at = || format!("materials[{i}].pbrMetallicRoughness.baseColorTexture.index");
            index(at, "texture", t.index, root.textures.len())?;
        }
    }
    for (i, t) in root.textures.iter().enumerate() {
        if let Some(s) = t.source {
            index(|| format!("textures[{i}].source"), "image", s, root.images.len())?;
        }
        if let Some(s) = t.sampler {
            index(|| format!("textures[{i}].sampler"), "sampler", s, root.samplers.len())?;
        }
    }
    Ok(())
}

/// Each image a `uri` or a `bufferView` with its `mimeType` (glTF 2.0, Images: MUST).
fn images(root: &Root) -> Result<(), String> {
    for (i, image) in root.images.iter().enumerate() {
        let at = |f: &str| format!("images[{i}].{f}");
        match (&image.uri, image.buffer_view, &image.mime_type) {
            (Some(_), None, _) => {}
            (None, Some(v), Some(_)) => {
                index(|| at("bufferView"), "bufferView", v, root.buffer_views.len())?
            }
            (None, Some(_), None) => {
                return Err(bad(at("mimeType"), "missing (an image in a bufferView must have one)"))
            }
            (Some(_), Some(_), _) => {
                return Err(bad(
                    format!("images[{i}]"),
                    "both uri and bufferView (one or the other)",
                ))
            }
            (None, None, _) => {
                return Err(bad(format!("images[{i}]"), "neither uri nor bufferView"))
            }
        }
    }
    Ok(())
}

#[cfg(test)]
#[path = "validate_tests.rs"]
mod tests;
