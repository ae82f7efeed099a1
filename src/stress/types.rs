//! What every stress case shares: rays, meshes, scenes and their parts, what a tracer returns,
//! the cases and the run's options.
use serde::Serialize;

/// One ray as the shaders read it (two vec4: origin, tmin; direction, tmax).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    pub origin: [f32; 3],
    pub tmin: f32,
    pub dir: [f32; 3],
    pub tmax: f32,
}

/// A triangle mesh of one BLAS (one non-opaque geometry). `inactive` primitives (degenerate or
/// NaN-X) must never be hit; the reference skips them.
#[derive(Clone, Debug, Default)]
pub struct Mesh {
    pub positions: Vec<[f32; 3]>,
    pub indices: Vec<[u32; 3]>,
    pub inactive: Vec<bool>,
}

#[derive(Clone, Debug)]
pub struct Instance {
    /// Row-major 3x4 object-to-world matrix (`VkTransformMatrixKHR`).
    pub transform: [[f32; 4]; 3],
    pub mesh: usize,
}

pub const IDENTITY: [[f32; 4]; 3] =
    [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]];

#[derive(Clone, Debug, Default)]
pub struct Scene {
    pub meshes: Vec<Mesh>,
    /// Instance k has `instanceCustomIndex` k.
    pub instances: Vec<Instance>,
}

/// What the case knows about a ray beyond the reference: a ray through the interior of a closed
/// surface must hit it (a miss is a leak even where the reference hit lies on an edge).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayInfo {
    pub must_hit: bool,
}

/// One scene with its rays: a case has one or more parts (sizes, distances, modes).
pub struct Part {
    pub label: String,
    /// `far`: the distance the scene was moved to (the x axis of the SVG).
    pub distance: Option<f64>,
    pub scene: Scene,
    pub rays: Vec<Ray>,
    pub info: Vec<RayInfo>,
    /// Ray flags of both traces (culling; the second trace adds gl_RayFlagsOpaqueEXT).
    pub ray_flags: u32,
}

/// What a tracer returns for one ray.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Traced {
    pub hit: Option<TracedHit>,
    /// Candidate triangle hits the any-hit shader counted (every candidate is ignored there,
    /// so each intersected primitive is counted once: NO_DUPLICATE_ANY_HIT_INVOCATION).
    pub candidates: u32,
    /// (instance << 24 | primitive) + 1 of the first two candidates counted; 0 where none.
    pub first_candidates: [u32; 2],
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TracedHit {
    pub t: f32,
    pub bary: [f32; 2],
    pub primitive: u32,
    pub instance: u32,
    /// gl_HitKindEXT (0xFE front, 0xFF back); 0 from CPU tracers.
    pub hit_kind: u32,
    /// gl_ObjectRayOriginEXT and gl_ObjectRayDirectionEXT in the closest-hit shader.
    pub object_origin: [f32; 3],
    pub object_dir: [f32; 3],
}

#[derive(Debug, thiserror::Error)]
pub enum TraceError {
    #[error("the device was lost: {0}")]
    DeviceLost(String),
    #[error("the trace did not finish within {0:?}")]
    Timeout(std::time::Duration),
    #[error("{0}")]
    Failed(String),
    /// The shader compiler could not start, or refused the stress shaders.
    #[error("{0}")]
    Compile(#[source] crate::shadergen::compile::CompileError),
}

/// One unit of the CPU's judging of a case, reported as it is done: a worker's heartbeat counts
/// them, so that every long step of the check shows progress (issue 22).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Work {
    /// One triangle placed in the reference's spatial grid (`index::Index::build`).
    Indexed,
    /// One ray judged against the reference (`evaluate`).
    Judged,
    /// One ray's facing found (`transform::facing_errors`).
    Faced,
}

/// Traces every ray of a part: the device, or a CPU intersector.
pub trait Tracer {
    fn name(&self) -> String;
    fn trace(&mut self, part: &Part) -> Result<Vec<Traced>, TraceError>;
}

/// The stress cases, in report order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum CaseKind {
    Watertight,
    Far,
    Grazing,
    Degenerate,
    Tmin,
    Transform,
    SelfHit,
}

impl CaseKind {
    pub const ALL: [CaseKind; 7] = [
        CaseKind::Watertight,
        CaseKind::Far,
        CaseKind::Grazing,
        CaseKind::Degenerate,
        CaseKind::Tmin,
        CaseKind::Transform,
        CaseKind::SelfHit,
    ];

    pub fn as_str(self) -> &'static str {
        match self {
            CaseKind::Watertight => "watertight",
            CaseKind::Far => "far",
            CaseKind::Grazing => "grazing",
            CaseKind::Degenerate => "degenerate",
            CaseKind::Tmin => "tmin",
            CaseKind::Transform => "transform",
            CaseKind::SelfHit => "self",
        }
    }

    pub fn parse(s: &str) -> Option<CaseKind> {
        Self::ALL.into_iter().find(|c| c.as_str() == s)
    }
}

/// Options of a stress run (parsed by the CLI).
#[derive(Clone, Debug)]
pub struct StressOptions {
    pub cases: Vec<CaseKind>,
    pub seed: u64,
    /// CTS-sized ray and triangle counts (65,536 triangles, 256×256 rays) instead of CI sizes.
    pub full: bool,
}

/// A scene of one mesh at the identity transform.
pub(crate) fn one_mesh(mesh: Mesh) -> Scene {
    Scene { meshes: vec![mesh], instances: vec![Instance { transform: IDENTITY, mesh: 0 }] }
}
