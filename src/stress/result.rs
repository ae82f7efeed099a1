//! What a stress case reports: its verdict, the counts and errors per case and part, and
//! examples of the rays that failed a check.
use super::{CaseKind, Part, TraceError};
use serde::{Deserialize, Serialize};

/// A case's verdict. `Fail` is a broken "must" (or a "expected and tested" rule the CTS counts:
/// leaks); `Warn` a broken "should" only (double hits outside the ambiguity margin).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Verdict {
    Pass,
    Warn,
    Fail,
    DeviceLost,
    Timeout,
    /// The worker running the case died (a driver crash): that case's outcome only.
    Crash,
    Error,
    NotImplemented,
}

impl Verdict {
    pub fn as_str(self) -> &'static str {
        match self {
            Verdict::Pass => "pass",
            Verdict::Warn => "warn",
            Verdict::Fail => "fail",
            Verdict::DeviceLost => "device_lost",
            Verdict::Timeout => "timeout",
            Verdict::Crash => "crash",
            Verdict::Error => "error",
            Verdict::NotImplemented => "not_implemented",
        }
    }

    /// Whether the run's exit status stays 0 with this verdict.
    pub fn passed(self) -> bool {
        match self {
            Verdict::Pass | Verdict::Warn | Verdict::NotImplemented => true,
            Verdict::Fail
            | Verdict::DeviceLost
            | Verdict::Timeout
            | Verdict::Crash
            | Verdict::Error => false,
        }
    }
}

#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct Metrics {
    pub rays: usize,
    pub hits: usize,
    /// Rays the reference cannot judge strictly: some primitive they may hit lies within the
    /// ambiguity margin of an edge or of tmin/tmax (only a case's must-hit still holds there).
    pub ambiguous: usize,
    /// Of those, rays where a miss would be no leak (no must-hit from the case, not culled):
    /// the share of a case a leak could hide in (issue 22).
    #[serde(default)]
    pub excluded: usize,
    /// Hit/miss against an unambiguous reference, plus hits on the wrong primitive.
    pub disagreements: usize,
    /// Rays that must hit and missed.
    pub leaks: usize,
    /// Leaks of rays with a subnormal origin or direction component (flush-to-zero territory).
    pub leaks_subnormal: usize,
    /// Rays that must miss (or hit an inactive primitive) and hit.
    pub false_hits: usize,
    /// Hits on a primitive the ray does not cross, or behind a certain closer hit.
    pub wrong_hits: usize,
    /// Rays whose any-hit count exceeds their distinct crossings.
    pub double_hits: usize,
    /// Double hits of rays outside every ambiguity margin: the spec's "should not double-hit",
    /// broken where no rounding explains it (a warning each).
    pub double_hit_warnings: usize,
    /// Double hits of rays within the ambiguity margin of an edge: an edge-inclusive test
    /// reports both triangles there, and rounding may (not warned).
    pub double_hits_in_margin: usize,
    /// Of those, rays exactly through a shared edge or vertex (within `ON_EDGE_EPS`).
    pub double_hits_on_edge: usize,
    /// Rays where any-hit saw the same primitive twice: the geometry has
    /// NO_DUPLICATE_ANY_HIT_INVOCATION, whose "must" this breaks.
    pub duplicate_any_hits: usize,
    /// Largest error of gl_ObjectRayOriginEXT / gl_ObjectRayDirectionEXT against the f64
    /// inverse transform, relative to max(1, |world origin|, |object value|) (hits over
    /// `BUILTIN_TOL` count in `over_tolerance`).
    pub builtin_err_max: Option<f64>,
    /// `transform`: hits whose facing is not the one function of object-space winding, and culled
    /// traces that keep a culled facing or drop the other.
    pub facing_errors: usize,
    /// Hits closer than `selfhit::SELF_T` (the `self` case's false self-intersections).
    pub self_hits: usize,
    /// Hits whose t and barycentrics were compared.
    pub compared: usize,
    /// Compared hits outside the t or barycentric tolerance.
    pub over_tolerance: usize,
    /// |Δt| in f32 ulps of the reference t.
    pub t_err_max_ulps: Option<f64>,
    pub t_err_p99: Option<f64>,
    pub t_rel_err_max: Option<f64>,
    pub bary_err_max: Option<f64>,
}

/// One ray that failed a check, with what the reference and the tracer said (evidence a driver
/// engineer can replay: at most [`EXAMPLES_PER_KIND`] per kind and part).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Example {
    pub kind: String,
    pub part: String,
    /// The ray's index in its part (the order the tracer read them).
    #[serde(default)]
    pub ray: Option<usize>,
    pub origin: [f32; 3],
    pub dir: [f32; 3],
    pub tmin: f32,
    pub tmax: f32,
    /// The same four vectors as f32 bit patterns (exact reproduction).
    pub bits: [String; 2],
    /// The reference's answer (`examples::expected`): the closest triangle whose closed shadow
    /// holds the f64 crossing between tmin and tmax, as (primitive, t, smallest weight); the one
    /// a leak should have hit. `None` where the f64 ray crosses no triangle. (Schema 2 named the
    /// candidate with the smallest t, which could be one only within a margin.)
    pub reference: Option<(u32, f64, f64)>,
    /// The instance of that triangle.
    #[serde(default)]
    pub reference_instance: Option<u32>,
    /// That hit's ambiguity margin at its nearest edge (barycentric, measured in ray space).
    pub reference_margin: Option<f64>,
    /// Distinct crossings the reference counts.
    pub crossings: u32,
    /// The device's closest hit: (primitive, t, barycentrics (u, v)); `None` a miss.
    pub hit: Option<(u32, f32, [f32; 2])>,
    /// The instance of that hit.
    #[serde(default)]
    pub hit_instance: Option<u32>,
    pub candidates: u32,
    /// (instance << 24 | primitive) + 1 of the first two candidates any-hit counted.
    pub first_candidates: [u32; 2],
    /// The reference's triangles for this ray, each labelled with its role: its answer first,
    /// then the others whose closed shadow holds the f64 crossing, then the nearest the ray may
    /// hit within their margins, then the one the device reported where it is none of these (at
    /// most [`TRIANGLES_PER_EXAMPLE`] + 1).
    #[serde(default)]
    pub triangles: Vec<RefTriangle>,
}

/// Why a triangle is listed with an example.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TriangleRole {
    /// The reference's answer (`Example::reference`): the closest triangle holding the crossing.
    Expected,
    /// The f64 crossing lies inside or on its edges: exactly, the ray hits it.
    Contains,
    /// Outside it, but within an edge's ambiguity margin: an f32 traversal may report it.
    Near,
    /// The device reported it, and the reference has it neither way.
    Reported,
}

/// A triangle of an example as the f64 reference sees it along the ray.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct RefTriangle {
    pub role: TriangleRole,
    pub instance: u32,
    pub primitive: u32,
    /// Its vertices in world space, the space the ray is in, and their bit patterns: the BLAS's
    /// f32 vertices where the instance transform is the identity, else those under the transform
    /// (in f64) rounded to f32. (Schema 2 listed object space.)
    pub vertices: [[f32; 3]; 3],
    pub vertex_bits: [String; 3],
    /// Under an instance transform other than the identity: the vertices as the BLAS holds them
    /// (object space, f32 bits) and the transform's three rows (f32 bits), for exact replay.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub object_vertex_bits: Option<[String; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub transform_bits: Option<[String; 3]>,
    /// Where the ray crosses its plane: t and the weights of (v0, v1, v2) (f64).
    pub t: f64,
    pub weights: [f64; 3],
    /// The signed ray-space distance from the crossing to its nearest edge's line (positive
    /// inside; the edge nearest in ray space, not the smallest weight's), in object-space units.
    pub edge_distance: f64,
    /// The ray-space position error allowed (64 ulps of the coordinates' scale): a crossing
    /// closer to an edge than about this may fall either side in f32.
    pub margin: f64,
    /// The same margin as a weight at that edge (the barycentric margin).
    pub weight_margin: f64,
    /// Inside every edge and tmin/tmax by more than the margins.
    pub certain: bool,
}

pub const EXAMPLES_PER_KIND: usize = 8;
/// The reference's triangles listed per example (besides the one the device reported).
pub const TRIANGLES_PER_EXAMPLE: usize = 4;

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct PartResult {
    pub label: String,
    pub distance: Option<f64>,
    #[serde(flatten)]
    pub metrics: Metrics,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct CaseResult {
    pub name: String,
    pub verdict: Verdict,
    pub detail: Option<String>,
    #[serde(flatten)]
    pub metrics: Metrics,
    pub ms: f64,
    pub parts: Vec<PartResult>,
    pub examples: Vec<Example>,
}

impl CaseResult {
    pub fn not_implemented(kind: CaseKind) -> Self {
        let detail = format!("rtprobe does not implement the {} case yet", kind.as_str());
        Self::without_results(kind, Verdict::NotImplemented, detail, 0)
    }

    pub fn failed(kind: CaseKind, parts: &[Part], e: &TraceError) -> Self {
        let verdict = match e {
            TraceError::DeviceLost(_) => Verdict::DeviceLost,
            TraceError::Timeout(_) => Verdict::Timeout,
            TraceError::Failed(_) | TraceError::Compile(_) => Verdict::Error,
        };
        Self::without_results(
            kind,
            verdict,
            e.to_string(),
            parts.iter().map(|p| p.rays.len()).sum(),
        )
    }

    /// A case that produced no results: its verdict, why, and how many rays it would have traced.
    pub fn without_results(kind: CaseKind, verdict: Verdict, detail: String, rays: usize) -> Self {
        CaseResult {
            name: kind.as_str().into(),
            verdict,
            detail: Some(detail),
            metrics: Metrics { rays, ..Metrics::default() },
            ms: 0.0,
            parts: vec![],
            examples: vec![],
        }
    }
}
