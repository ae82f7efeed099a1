//! What loading a glTF scene can fail with: each one line naming the part of the file (a mesh, a
//! primitive, a buffer, an image, a required extension) and what to do.
use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    #[error("cannot read scene {path}: {message}; give a .gltf or .glb file that exists")]
    Read { path: PathBuf, message: String },
    #[error(
        "scene {path} is not glTF 2.0: {message}; export it again as glTF 2.0 (.gltf or .glb)"
    )]
    Parse { path: PathBuf, message: String },
    #[error(
        "scene {path} requires extension {extension}, which rtprobe does not read; {}",
        remedy(extension)
    )]
    Extension { path: PathBuf, extension: String },
    #[error("scene {path}: {part}: {message}")]
    Part { path: PathBuf, part: String, message: String },
    #[error("scene {path} has no triangles: give a scene whose default scene has triangle meshes")]
    Empty { path: PathBuf },
    #[error("scene {path} changed since the run began (content hash {now}, the report's {was}): put the run's scene file back, or start a new run")]
    Changed { path: PathBuf, was: String, now: String },
}

/// What to do about a required extension, by what it changes.
fn remedy(extension: &str) -> String {
    match extension {
        "KHR_draco_mesh_compression" | "EXT_meshopt_compression" => {
            "export it with mesh compression off (Draco, meshopt), or decompress it with a glTF tool".into()
        }
        "KHR_mesh_quantization" => "export it with float positions (no quantization), or dequantize it with a glTF tool".into(),
        "KHR_texture_basisu" | "EXT_texture_webp" => {
            "export its textures as PNG or JPEG".into()
        }
        other => format!("export it without {other}, or with the extension baked into the data"),
    }
}

impl LoadError {
    pub(super) fn part(
        path: &std::path::Path,
        part: impl Into<String>,
        message: impl Into<String>,
    ) -> Self {
        LoadError::Part { path: path.to_path_buf(), part: part.into(), message: message.into() }
    }
}
