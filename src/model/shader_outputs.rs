//! The output data a `run --shader` report carries for `--compare`: each variant's first
//! attempt's read-back outputs (storage images, written storage buffers), base64 in the report
//! up to [`EMBED_CAP`] bytes, with the units its own attempts did not agree on; and what a run
//! compared itself with.
use serde::{Deserialize, Serialize};

/// Output bytes a report embeds at most, over every variant (a 64×64 RGBA32F image is 64 KiB);
/// a variant whose outputs would pass it embeds none and the report's notes say so.
pub const EMBED_CAP: usize = 16 << 20;

/// What an output is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum OutputKind {
    Image,
    Buffer,
}

/// One read-back output of a variant's first attempt that ran.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct OutputData {
    /// As the attempt's `outputs` label it (`set 0 binding 1[0]`).
    pub label: String,
    pub kind: OutputKind,
    /// Bytes per unit: per texel (images), 4 (buffer words).
    pub texel: u32,
    /// The bytes, base64.
    pub bytes: String,
    /// A buffer's bytes before the trace (the harness's fill), base64: units left as filled
    /// were not written and are not compared.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub initial: Option<String>,
    /// Written through atomics (an append queue: its records compared as a multiset).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub scheduled: bool,
    /// The trailing array's byte offset and stride.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub records: Option<(u32, u32)>,
    /// Units (texels, words) in which a later attempt of the variant differed from this one:
    /// unstable on this device, left out of a comparison with it.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub unstable: Vec<u32>,
}

/// What `--compare` held the run against.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CompareInfo {
    /// The other report's path, as given.
    pub report: String,
    /// Its device.
    pub device: String,
    /// `--tolerance`: differences beyond it are findings; `None`: every difference is a note.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tolerance: Option<f32>,
    /// Outputs that differed (notes, or findings beyond the tolerance).
    pub differences: usize,
}
