//! Scene parameters: part of every report (the same parameters give the same scene).
use serde::{Deserialize, Serialize};

/// Scene parameters (part of every report: the same parameters give the same scene).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SceneParams {
    pub seed: u64,
    pub width: u32,
    pub height: u32,
    /// Number of TLAS instances (at least 16).
    pub instances: u32,
    /// Grid resolution of the largest mesh: meshes are detail/4, detail/2 and detail quads a
    /// side, two triangles a quad.
    pub mesh_detail: u32,
    /// `run --scene FILE`: the glTF scene the cells trace instead of the procedural one (absent
    /// in reports of procedural scenes, and before `--scene`). Then `instances` is the file's
    /// instance count and `seed` and `mesh_detail` make nothing.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub file: Option<SceneFile>,
}

/// A glTF scene file a run traced: where it was and what it held.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct SceneFile {
    /// The path as given (made absolute), which workers and re-runs load.
    pub path: String,
    /// FNV-1a 128, hex, of the file's bytes and the geometry read from its buffers: two runs
    /// of the same path with other contents are different runs.
    pub hash: String,
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
    #[error("the scene file has {0} instances; rtprobe's probes take 1..=4096 (the AS probe's custom indices hold 8192 per TLAS variant): give a scene with fewer nodes")]
    FileInstances(u32),
}

impl Default for SceneParams {
    fn default() -> Self {
        Self { seed: 1, width: 64, height: 64, instances: 16, mesh_detail: 16, file: None }
    }
}

impl SceneParams {
    pub fn validate(&self) -> Result<(), SceneError> {
        match &self.file {
            Some(_) if self.instances == 0 || self.instances > 4096 => {
                return Err(SceneError::FileInstances(self.instances))
            }
            Some(_) => {}
            None if self.instances < 16 || self.instances > 4096 => {
                return Err(SceneError::Instances(self.instances))
            }
            None => {}
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

/// Cells a scene cannot discriminate (`run --scene`: a loaded scene may break what the probe
/// contract assumes of the procedural one), with why; their verdicts stand, but a pass there
/// proves less. In the report's scene summary and the terminal summary.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SceneLimit {
    /// What the scene lacks or breaks, in words.
    pub why: String,
    /// Share of the cells' probe pixels (non-ambiguous primary rays) where it holds: 1 when a
    /// cell's probe cannot discriminate anywhere.
    pub share: f64,
    /// The cell ids, in plan order.
    pub cells: Vec<String>,
}

/// What the run's scene cost on the CPU before any cell: load (a `--scene` file read and fitted,
/// or the procedural scene built), the CPU reference's traces, and the process's peak memory
/// after both. The acceleration structures are built by each worker: `TimingSummary`'s
/// `as_build_ms_mean` and `as_build_ms_max`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct SceneCost {
    pub load_ms: f64,
    pub reference_ms: f64,
    /// VmHWM of the CLI process (MiB), when the system says.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub peak_mib: Option<u64>,
}
