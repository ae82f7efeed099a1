//! What reading a module ([`InterfaceError`]) and checking it against its pipeline
//! ([`Mismatch`]) fail with; each mismatch names the binding, stage or block, and the rule.
use ash::vk;

/// A module that cannot be read.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum InterfaceError {
    #[error("not a SPIR-V module: {0}")]
    NotSpirv(String),
}

/// How a module does not fit its pipeline.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum Mismatch {
    #[error("module {module} ({stage:?}): {source}")]
    Unreadable { module: usize, stage: vk::ShaderStageFlags, source: InterfaceError },
    #[error("set {set} binding {binding}: the {stage:?} shader declares a {shader} the pipeline does not provide (VUID-VkRayTracingPipelineCreateInfoKHR-layout-07988)")]
    NoBinding { set: u32, binding: u32, stage: vk::ShaderStageFlags, shader: &'static str },
    #[error("set {set} binding {binding}: the {stage:?} shader declares it but the binding is not visible to that stage (layout-07988)")]
    NotVisible { set: u32, binding: u32, stage: vk::ShaderStageFlags },
    #[error("set {set} binding {binding}: the {stage:?} shader declares a {shader}, the pipeline provides a {layout} (layout-07990)")]
    Kind {
        set: u32,
        binding: u32,
        stage: vk::ShaderStageFlags,
        shader: &'static str,
        layout: &'static str,
    },
    #[error("set {set} binding {binding}: the {stage:?} shader declares an array of {shader}, the pipeline provides {layout} descriptors (layout-07991)")]
    Count { set: u32, binding: u32, stage: vk::ShaderStageFlags, shader: u32, layout: u32 },
    #[error("push constants: the {stage:?} shader's block spans bytes {start}..{end}, the pipeline's range for it is {range} (layout-07987 / layout-10069)")]
    Push { stage: vk::ShaderStageFlags, start: u32, end: u32, range: String },
    /// `got`, `sent`: [`super::view::IoShape`]s as text (structure and size).
    #[error("ray payload: the {stage:?} shader receives {got}, no stage sends that structure (sent: {sent}); the payload must be the same structure in every stage using it (Ray Tracing Pipeline Interface)")]
    Payload { stage: vk::ShaderStageFlags, got: String, sent: String },
    #[error("callable data: the {stage:?} shader receives {got}, no stage passes that structure (passed: {sent}); it must be the same structure (Ray Tracing Pipeline Interface)")]
    CallableData { stage: vk::ShaderStageFlags, got: String, sent: String },
    #[error("hit attribute: the {stage:?} shader's is {got}, {expected} (Ray Tracing Pipeline Interface, maxRayHitAttributeSize)")]
    HitAttribute { stage: vk::ShaderStageFlags, got: String, expected: String },
}
