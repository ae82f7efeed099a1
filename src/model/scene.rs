//! Scene parameters: part of every report (the same parameters give the same scene).
use serde::{Deserialize, Serialize};

/// Scene parameters (part of every report: the same parameters give the same scene).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SceneParams {
    pub seed: u64,
    pub width: u32,
    pub height: u32,
    /// Number of TLAS instances (at least 16).
    pub instances: u32,
    /// Grid resolution of the largest mesh: meshes are detail/4, detail/2 and detail quads a
    /// side, two triangles a quad.
    pub mesh_detail: u32,
}

/// Scene parameters out of the range rtprobe builds scenes for.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SceneError {
    #[error("instances must be 16..=4096, got {0}")]
    Instances(u32),
    #[error("image size must be a multiple of 8 in 8..=4096, got {width}x{height}")]
    ImageSize { width: u32, height: u32 },
    #[error("mesh detail must be a multiple of 4 in 4..=256, got {0}")]
    MeshDetail(u32),
}

impl Default for SceneParams {
    fn default() -> Self {
        Self { seed: 1, width: 64, height: 64, instances: 16, mesh_detail: 16 }
    }
}

impl SceneParams {
    pub fn validate(&self) -> Result<(), SceneError> {
        if self.instances < 16 || self.instances > 4096 {
            return Err(SceneError::Instances(self.instances));
        }
        if self.width < 8
            || self.height < 8
            || self.width % 8 != 0
            || self.height % 8 != 0
            || self.width > 4096
            || self.height > 4096
        {
            return Err(SceneError::ImageSize { width: self.width, height: self.height });
        }
        if self.mesh_detail < 4 || self.mesh_detail > 256 || self.mesh_detail % 4 != 0 {
            return Err(SceneError::MeshDetail(self.mesh_detail));
        }
        Ok(())
    }

    pub fn pixels(&self) -> usize {
        (self.width * self.height) as usize
    }
}
