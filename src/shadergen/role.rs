//! The role a shader plays in a cell's pipeline: its shaderc kind and its file name.

/// The role a shader plays in a cell's pipeline.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Role {
    Raygen,
    Miss,
    /// Miss shader 1: clears the probe ray's payload (AS probes that trace).
    ProbeMiss,
    ClosestHitTriangles,
    ClosestHitProcedural,
    Intersection,
    AnyHit,
    Callable,
    Vertex,
    Fragment,
    Compute,
}

impl Role {
    /// The role of the shader that does the probed read of `stage` (closest-hit: the triangle
    /// one; the procedural one probes too).
    pub fn probed(stage: crate::model::Stage) -> Role {
        use crate::model::Stage;
        match stage {
            Stage::Raygen => Role::Raygen,
            Stage::ClosestHit => Role::ClosestHitTriangles,
            Stage::AnyHit => Role::AnyHit,
            Stage::Miss => Role::Miss,
            Stage::Intersection => Role::Intersection,
            Stage::Callable => Role::Callable,
            Stage::Fragment => Role::Fragment,
            Stage::Compute => Role::Compute,
        }
    }

    pub fn kind(self) -> shaderc::ShaderKind {
        use shaderc::ShaderKind as K;
        match self {
            Role::Raygen => K::RayGeneration,
            Role::Miss | Role::ProbeMiss => K::Miss,
            Role::ClosestHitTriangles | Role::ClosestHitProcedural => K::ClosestHit,
            Role::Intersection => K::Intersection,
            Role::AnyHit => K::AnyHit,
            Role::Callable => K::Callable,
            Role::Vertex => K::Vertex,
            Role::Fragment => K::Fragment,
            Role::Compute => K::Compute,
        }
    }

    pub fn file_name(self) -> &'static str {
        match self {
            Role::Raygen => "raygen.rgen",
            Role::Miss => "miss.rmiss",
            Role::ProbeMiss => "probe_miss.rmiss",
            Role::ClosestHitTriangles => "closest_hit_triangles.rchit",
            Role::ClosestHitProcedural => "closest_hit_procedural.rchit",
            Role::Intersection => "intersection.rint",
            Role::AnyHit => "any_hit.rahit",
            Role::Callable => "callable.rcall",
            Role::Vertex => "tiles.vert",
            Role::Fragment => "probe.frag",
            Role::Compute => "probe.comp",
        }
    }
}
