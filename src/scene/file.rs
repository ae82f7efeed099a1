//! `run --scene FILE`: the scene a run's [`SceneParams`] describe — the glTF file's, fitted into
//! the probes' view (`gltf::fit::to_scene`), or the procedural one — and the file's identity (its
//! content hash), which a report records so that another file, or the same path with other
//! contents, is another run (`--resume`, `merge`, baselines).
use super::gltf::{LoadError, Loaded};
use super::Scene;
use crate::model::{SceneFile, SceneParams};
use crate::stable_hash::StableHash;
use std::path::Path;

impl Scene {
    /// The scene `params` describe: the glTF file's (loaded, held to the content hash the run
    /// recorded, and fitted), else the procedural scene of `Scene::build`.
    pub fn of(params: &SceneParams) -> Result<Scene, LoadError> {
        match &params.file {
            Some(f) => {
                let loaded = load_same(f)?;
                let mut scene = super::gltf::fit::to_scene(&loaded, params);
                scene.textures = super::textures::SceneTextures::of_file(loaded);
                Ok(scene)
            }
            None => Ok(Scene::build(params)),
        }
    }
}

/// `f`'s file loaded, refused when its contents are not the ones the run recorded.
pub fn load_same(f: &SceneFile) -> Result<Loaded, LoadError> {
    let loaded = Loaded::load(Path::new(&f.path))?;
    let now = content_hash(&loaded)?;
    if now != f.hash {
        return Err(LoadError::Changed { path: f.path.clone().into(), was: f.hash.clone(), now });
    }
    Ok(loaded)
}

/// The identity of a loaded scene file: its absolute path and content hash.
pub fn identity(loaded: &Loaded) -> Result<SceneFile, LoadError> {
    let path = std::path::absolute(&loaded.path).unwrap_or_else(|_| loaded.path.clone());
    Ok(SceneFile { path: path.display().to_string(), hash: content_hash(loaded)? })
}

/// FNV-1a 128, hex, of the file's bytes and the geometry read from its buffers (a `.gltf`'s
/// `.bin` edited is another scene): positions, triangles and primitive ranges of every mesh, and
/// each instance's mesh and world matrix.
pub fn content_hash(loaded: &Loaded) -> Result<String, LoadError> {
    let bytes = std::fs::read(&loaded.path)
        .map_err(|e| LoadError::Read { path: loaded.path.clone(), message: e.to_string() })?;
    let mut h = StableHash::default();
    h.bytes(&bytes);
    for m in &loaded.meshes {
        h.u64(m.positions.len() as u64);
        m.positions.iter().flatten().for_each(|v| {
            h.u32(v.to_bits());
        });
        h.u64(m.indices.len() as u64);
        m.indices.iter().flatten().for_each(|i| {
            h.u32(*i);
        });
        for p in &m.primitives {
            h.u32(p.vertex_offset).u32(p.first_triangle).u32(p.triangles);
        }
    }
    for i in &loaded.instances {
        h.u64(i.mesh as u64);
        i.world.to_cols_array().iter().for_each(|v| {
            h.u32(v.to_bits());
        });
    }
    Ok(format!("{:032x}", h.finish()))
}
