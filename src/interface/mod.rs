//! A pipeline's SPIR-V modules against what the pipeline provides them ([`check`]): every
//! set/binding resource variable backed by a binding of its descriptor kind, with enough
//! descriptors, seen by its stage; the push-constant block inside the push range its stage sees;
//! every incoming ray payload and callable data the structure some stage of the pipeline sends;
//! every hit attribute within the device's limit and the one its hit group's intersection shader
//! writes (two floats for triangles). A mismatch is typed and names the binding, stage or block
//! ([`Mismatch`]): for rtprobe an `error` of the cell (a bundle or user shader that does not fit
//! the cell's layout), never a driver finding.
//!
//! The rules (Vulkan 1.4.360, checked against Vulkan-Docs): `VUID-{pipeline}-layout-07988` (a
//! resource variable's set must match its stage), `-07990` (its descriptor type), `-07991` (an
//! array's `descriptorCount` at least its length), `-07987` / `-10069` (a push-constant block
//! inside a range of its stage) — the rules `VUID-VkRayTracingPipelineCreateInfoKHR-layout-03427`
//! stated as one until 1.3.244; "Ray Tracing Pipeline Interface" (payloads, callable data and hit
//! attributes must match between the stages using them; without an intersection shader the hit
//! attribute is two 32-bit floats); `maxRayHitAttributeSize` (block sizes at scalar alignment, as
//! `maxPipelineRayHitAttributeSize` counts them).
//!
//! Files: the checks' view of a module's interface (`view`, read by `crate::reflect`), the
//! pipeline's description
//! (`layout`), the checks (`check`), what they fail with (`error`).
mod check;
mod error;
pub mod layout;
pub mod view;

pub use check::{check, check_read, read};
pub use error::{InterfaceError, Mismatch};
pub use layout::{BindingDesc, DescriptorKind, HitGroup, PipelineDesc, PushRange};
pub use view::ModuleInterface;

#[cfg(test)]
mod tests;
