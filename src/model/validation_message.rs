//! What a validation-layer message is about ([`kind`]), and a child's message counts by kind
//! ([`MessageCounts`]): `run --shader --validate=gpu-av` turns a fault into the harness's
//! `error` only on a GPU-AV error that reports an **invalid access** by the shader.
//!
//! The rule: GPU-AV instruments the shader and, when an access breaks one of the rules below,
//! reports it as an error naming the rule's VUID (or, in layers before those VUIDs existed, a
//! fixed `UNASSIGNED-…` id). Those accesses are undefined behaviour by the spec, so a fault
//! after one is the shader's (or the harness's bindings'), not the driver's. Every other
//! message — GPU-AV's setup problems (`UNASSIGNED-GPU-Assisted Validation Error/Warning`,
//! `WARNING-GPU-Assisted-Validation…`: a descriptor slot it could not reserve, memory it could
//! not allocate), warnings, API-usage errors not about the access — says nothing about the
//! access that faulted: counted and shown, never the verdict. Rules (Vulkan 1.4.360,
//! `chapters/commonvalidity/draw_dispatch_common.adoc` and `appendices/spirvenv.adoc`):
//! - `VUID-{cmd}-None-10068`: array indices must be less than the binding's descriptor count
//!   (layers before it: `UNASSIGNED-Descriptor index out of bounds`, `… Buffer index out of
//!   bounds`, `… Texel Buffer index out of bounds`);
//! - `VUID-{cmd}-None-08114`: accessed descriptors must be valid (layers before it:
//!   `UNASSIGNED-Descriptor uninitialized`, `UNASSIGNED-Descriptor destroyed`);
//! - `VUID-{cmd}-uniformBuffers-06935`, `-storageBuffers-06936` (shader objects: `-None-08612`,
//!   `-None-08613`): buffer accesses within the bound range (`UNASSIGNED-Descriptor Texel
//!   Buffer texel out of bounds` for texel buffers);
//! - `VUID-RuntimeSpirv-PhysicalStorageBuffer64-11819`: a buffer-address access must reference
//!   a buffer with device-address usage (layers before it: `UNASSIGNED-Device address out of
//!   bounds`);
//! - `VUID-RuntimeSpirv-OpTraceRayKHR-*` (06355–06360, 06552–06554, 06892, 06893, 11855): a
//!   traced ray's origin and direction finite, no NaN, `0 ≤ tMin ≤ tMax`, its flags not
//!   contradicting each other or the pipeline's, its TLAS a top-level one. The harness's data
//!   can make a user's raygen compute such a ray (a camera matrix of arbitrary floats), so a
//!   fault after one is no driver finding either.
use serde::{Deserialize, Serialize};

/// What one message is about.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MessageKind {
    /// GPU-AV reports the shader's invalid access (an out-of-bounds index, an uninitialised
    /// descriptor, an address no buffer holds).
    InvalidAccess,
    /// GPU-AV's own setup (it could not instrument or reserve what it needs).
    GpuAvSetup,
    /// Anything else (API usage, warnings not about the access).
    Other,
}

/// The ids (VUIDs, or the layer's `UNASSIGNED-` ids) GPU-AV reports an invalid access with (the
/// module doc has their rules), matched against the message's id only (never its prose): one
/// starting with `-` is a VUID's command-independent tail (`VUID-{cmd}-None-10068`), any other
/// a prefix of the id. Checked against the strings of the layers rtprobe runs with (`strings
/// libVkLayer_khronos_validation.so`): 1.3.239 (Debian 12) holds `-None-08114`, `-06935`,
/// `-06936` and the `UNASSIGNED-Descriptor index out of bounds` / `uninitialized` / `Device
/// address out of bounds` ids; 1.4.363 (the sid root) holds every VUID below and the
/// `UNASSIGNED-Descriptor Texel Buffer texel out of bounds` / `Descriptor destroyed` ids.
pub const INVALID_ACCESS_IDS: &[&str] = &[
    "-None-10068",
    "-None-08114",
    "-uniformBuffers-06935",
    "-storageBuffers-06936",
    "-None-08612",
    "-None-08613",
    "VUID-RuntimeSpirv-PhysicalStorageBuffer64-11819",
    "VUID-RuntimeSpirv-OpTraceRayKHR-",
    "UNASSIGNED-Descriptor index out of bounds",
    "UNASSIGNED-Descriptor uninitialized",
    "UNASSIGNED-Descriptor destroyed",
    "UNASSIGNED-Descriptor Buffer index out of bounds",
    "UNASSIGNED-Descriptor Texel Buffer",
    "UNASSIGNED-Device address out of bounds",
];

/// How GPU-AV's own messages name themselves: ids (1.3.239: `UNASSIGNED-GPU-Assisted Validation
/// Setup Error.`, `… Warning`, `UNASSIGNED-GPU-Assisted-Validation`; 1.4.363:
/// `WARNING-GPU-Assisted-Validation`, `WARNING-GPU-AV-…`) and, where a message has none, its
/// prose (`… Aborting GPU-AV`, `GPU-Assisted validation requires …`). Matched anywhere: a
/// setup message makes a verdict `inconclusive`, never lenient.
const SETUP_MARKERS: &[&str] = &["GPU-Assisted", "GPU-AV", "GPU Assisted"];

/// The message's id: the first `[ ID ]` of the text (the layer writes it there, and the
/// messenger callback puts `pMessageIdName` there where the layer did not).
fn message_id(text: &str) -> Option<&str> {
    let start = text.find("[ ")? + 2;
    let len = text[start..].find(" ]")?;
    Some(text[start..start + len].trim())
}

/// Whether `id` is one of [`INVALID_ACCESS_IDS`].
fn is_access_id(id: &str) -> bool {
    INVALID_ACCESS_IDS.iter().any(|rule| match rule.strip_prefix('-') {
        Some(_) => id.starts_with("VUID-") && id.ends_with(rule),
        None => id.starts_with(rule),
    })
}

/// What `text` (a message as the layer wrote it, its id leading) is about; an invalid-access id
/// wins over a setup marker.
pub fn kind(text: &str) -> MessageKind {
    if message_id(text).is_some_and(is_access_id) {
        MessageKind::InvalidAccess
    } else if SETUP_MARKERS.iter().any(|m| text.contains(m)) {
        MessageKind::GpuAvSetup
    } else {
        MessageKind::Other
    }
}

/// Messages counted by severity and kind (the messenger's counters, or a difference of them).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct MessageCounts {
    /// Error-severity messages, every kind.
    pub errors: u64,
    /// Error-severity messages that report an invalid access ([`MessageKind::InvalidAccess`]).
    pub invalid_access: u64,
    /// Warning-severity messages.
    pub warnings: u64,
}

impl MessageCounts {
    /// The messages since `before` (counters only grow; a smaller one counts 0).
    pub fn since(self, before: MessageCounts) -> MessageCounts {
        MessageCounts {
            errors: self.errors.saturating_sub(before.errors),
            invalid_access: self.invalid_access.saturating_sub(before.invalid_access),
            warnings: self.warnings.saturating_sub(before.warnings),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gpu_av_access_reports_are_told_from_setup_and_other_messages() {
        // Bookworm's 1.3.239 layer on an index past the array's length.
        let oob = "Validation Error: [ UNASSIGNED-Descriptor index out of bounds ] Object 0: … | Index of 63 used to index descriptor array of length 2.";
        assert_eq!(kind(oob), MessageKind::InvalidAccess);
        let new = "Validation Error: [ VUID-vkCmdTraceRaysKHR-None-10068 ] (set = 0, binding = 1) Index of 63 …";
        assert_eq!(kind(new), MessageKind::InvalidAccess);
        let bda = "Validation Error: [ VUID-RuntimeSpirv-PhysicalStorageBuffer64-11819 ] vkCmdTraceRaysKHR(): Out of bounds: trying to read 4 bytes";
        assert_eq!(kind(bda), MessageKind::InvalidAccess);
        let uninit = "Validation Error: [ VUID-vkCmdTraceRaysKHR-None-08114 ] Descriptor index 5 is uninitialized.";
        assert_eq!(kind(uninit), MessageKind::InvalidAccess);
        let nan_ray = "Validation Error: [ VUID-RuntimeSpirv-OpTraceRayKHR-06355 ] vkCmdTraceRaysKHR(): OpTraceRayKHR ray origin is not finite";
        assert_eq!(kind(nan_ray), MessageKind::InvalidAccess);
        let setup = "Validation Error: [ UNASSIGNED-GPU-Assisted Validation Error. ] Unable to reserve descriptor binding slot";
        assert_eq!(kind(setup), MessageKind::GpuAvSetup);
        let warn = "Validation Warning: [ WARNING-GPU-Assisted-Validation-Setup ] Internal pipeline layout";
        assert_eq!(kind(warn), MessageKind::GpuAvSetup);
        let other =
            "Validation Error: [ VUID-vkDestroyBuffer-buffer-00922 ] Cannot free buffer in use";
        assert_eq!(kind(other), MessageKind::Other);
        // "out of bounds" in prose is not the id: it does not decide.
        assert_eq!(kind("Validation Warning: a copy may be out of bounds"), MessageKind::Other);
        // An access VUID in another message's prose is not its id.
        let prose = "Validation Error: [ VUID-vkCmdTraceRaysKHR-None-08600 ] layout incompatible; see also VUID-vkCmdTraceRaysKHR-None-10068";
        assert_eq!(kind(prose), MessageKind::Other);
        // A rule's number under another rule's name is not the rule.
        assert_eq!(kind("[ VUID-vkCmdTraceRaysKHR-None-100689 ] x"), MessageKind::Other);
        assert_eq!(kind("[ VUID-vkCmdDraw-None-10068 ] Index of 9"), MessageKind::InvalidAccess);
        // Setup messages as 1.3.239 names them, and one without an id.
        let old_setup = "Validation Error: [ UNASSIGNED-GPU-Assisted Validation Setup Error. ] Unable to allocate descriptor set.  Aborting GPU-AV";
        assert_eq!(kind(old_setup), MessageKind::GpuAvSetup);
        assert_eq!(
            kind("Unable to create shader module.  Aborting GPU-AV"),
            MessageKind::GpuAvSetup
        );
    }

    #[test]
    fn counts_since_a_snapshot() {
        let before = MessageCounts { errors: 2, invalid_access: 1, warnings: 5 };
        let now = MessageCounts { errors: 5, invalid_access: 1, warnings: 9 };
        assert_eq!(now.since(before), MessageCounts { errors: 3, invalid_access: 0, warnings: 4 });
        assert_eq!(before.since(now), MessageCounts::default());
    }
}
