//! The host contract of a patched pipeline (`rtprobe.patch-contract/1`, written beside
//! `rtprobe patch`'s output): what the application must change on its side for the patched
//! modules to read what the originals read — the push-constant bytes to add and for which stages,
//! which device address goes at which offset (an acceleration structure's, or a table's whose
//! entry `i` is array element `i`'s), the spec constants that pin indices, and the device features
//! the patched modules need. A user cannot apply an address patch without it; the patch harness
//! feeds a patched pipeline from it.
//!
//! The push range is said as bytes to *cover*, not a range to add, because of two rules (Vulkan
//! 1.4.360): VUID-VkPipelineLayoutCreateInfo-pPushConstantRanges-00292 "Any two elements of
//! pPushConstantRanges must not include the same stage in stageFlags", and
//! VUID-VkRayTracingPipelineCreateInfoKHR-layout-10069 "the block must be contained inside the
//! push constant range in layout that matches the stage": a stage that already has a range must
//! have it widened.
use serde::{Deserialize, Serialize};

pub const SCHEMA: &str = "rtprobe.patch-contract/1";

/// One input module.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ContractModule {
    /// The input file, as given.
    pub file: String,
    /// Its stage: raygen, closest_hit, any_hit, miss, intersection, callable, compute, …
    pub stage: String,
    /// Its entry point's name.
    pub entry: String,
    /// The bytes of its own push-constant block, [start, end) (none: no block).
    pub push_block: Option<[u32; 2]>,
    /// The patches that changed it.
    pub patched: Vec<String>,
}

/// The push-constant bytes the patched modules read beyond their own blocks.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct PushRange {
    pub offset: u32,
    pub size: u32,
    /// The stages that read them.
    pub stages: Vec<String>,
}

/// What an address in push constants is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AddressKind {
    /// The device address of the acceleration structure bound at (set, binding).
    AccelerationStructure,
    /// The address of a table of 8-byte acceleration-structure addresses: entry `i` is element
    /// `i` of the array at (set, binding).
    AccelerationStructureTable,
    /// The address of a table of 8-byte buffer device addresses: entry `i` is the buffer bound
    /// as element `i` of the array at (set, binding).
    BufferTable,
}

/// One 8-byte address the host writes into push constants.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct AddressEntry {
    pub offset: u32,
    pub kind: AddressKind,
    pub set: u32,
    pub binding: u32,
    /// The array's length, when known (tables).
    #[serde(default)]
    pub elements: Option<u32>,
    pub stages: Vec<String>,
}

/// A spec constant that now holds a descriptor array's index.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SpecEntry {
    pub spec_id: u32,
    pub set: u32,
    pub binding: u32,
    /// Its default value (what the index is when the host does not specialize it).
    pub value: u32,
    pub stages: Vec<String>,
}

/// The host contract of one `rtprobe patch` run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct HostContract {
    pub schema: String,
    pub modules: Vec<ContractModule>,
    /// The push-constant bytes to add (none when no address was placed).
    #[serde(default)]
    pub push_range: Option<PushRange>,
    /// The end of the pipeline's push constants after the patch.
    #[serde(default)]
    pub push_end: u32,
    #[serde(default)]
    pub addresses: Vec<AddressEntry>,
    #[serde(default)]
    pub specialization: Vec<SpecEntry>,
    /// Device features and extensions the patched modules need beyond the originals'.
    #[serde(default)]
    pub requires: Vec<String>,
}

impl Default for HostContract {
    fn default() -> Self {
        HostContract {
            schema: SCHEMA.into(),
            modules: Vec::new(),
            push_range: None,
            push_end: 0,
            addresses: Vec::new(),
            specialization: Vec::new(),
            requires: Vec::new(),
        }
    }
}

/// `VK_SHADER_STAGE_RAYGEN_BIT_KHR` for "raygen".
pub fn stage_flag_name(stage: &str) -> String {
    let core = matches!(stage, "vertex" | "fragment" | "compute");
    let suffix = if core { "" } else { "_KHR" };
    format!("VK_SHADER_STAGE_{}_BIT{suffix}", stage.to_uppercase())
}

impl HostContract {
    /// Whether the host has anything to do.
    pub fn is_empty(&self) -> bool {
        self.addresses.is_empty() && self.specialization.is_empty() && self.requires.is_empty()
    }

    /// What the host must do, in sentences.
    pub fn sentence(&self) -> String {
        let mut out = Vec::new();
        if let Some(r) = &self.push_range {
            let stages: Vec<String> = r.stages.iter().map(|s| stage_flag_name(s)).collect();
            out.push(format!(
                "Host side: push constants must now cover bytes {}..{} for {} (widen the existing \
                 range of a stage that has one: a stage may appear in only one range).",
                r.offset,
                r.offset + r.size,
                stages.join("|"),
            ));
        }
        for a in &self.addresses {
            let what = match a.kind {
                AddressKind::AccelerationStructure => format!(
                    "the device address (vkGetAccelerationStructureDeviceAddressKHR) of the \
                     acceleration structure bound at set {} binding {}",
                    a.set, a.binding
                ),
                AddressKind::AccelerationStructureTable => format!(
                    "the address of a buffer of {} 8-byte acceleration-structure addresses, \
                     entry i for element i of set {} binding {}",
                    count(a.elements),
                    a.set,
                    a.binding
                ),
                AddressKind::BufferTable => format!(
                    "the address of a buffer of {} 8-byte buffer device addresses, entry i for \
                     the buffer bound as element i of set {} binding {}",
                    count(a.elements),
                    a.set,
                    a.binding
                ),
            };
            out.push(format!("At byte {}: {what}.", a.offset));
        }
        for s in &self.specialization {
            out.push(format!(
                "SpecId {} is the index into set {} binding {} (default {}).",
                s.spec_id, s.set, s.binding, s.value
            ));
        }
        if !self.requires.is_empty() {
            out.push(format!("Enable: {}.", self.requires.join(", ")));
        }
        out.join(" ")
    }
}

fn count(n: Option<u32>) -> String {
    n.map_or("N (the array's bound length)".into(), |n| n.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_sentence_names_every_address_and_stage() {
        let c = HostContract {
            push_range: Some(PushRange {
                offset: 24,
                size: 16,
                stages: vec!["raygen".into(), "closest_hit".into()],
            }),
            addresses: vec![
                AddressEntry {
                    offset: 24,
                    kind: AddressKind::AccelerationStructure,
                    set: 2,
                    binding: 0,
                    elements: None,
                    stages: vec!["raygen".into()],
                },
                AddressEntry {
                    offset: 32,
                    kind: AddressKind::BufferTable,
                    set: 1,
                    binding: 3,
                    elements: Some(3),
                    stages: vec!["closest_hit".into()],
                },
            ],
            requires: vec!["shaderInt64".into()],
            ..HostContract::default()
        };
        let s = c.sentence();
        assert!(s.contains("bytes 24..40"), "{s}");
        assert!(
            s.contains("VK_SHADER_STAGE_RAYGEN_BIT_KHR|VK_SHADER_STAGE_CLOSEST_HIT_BIT_KHR"),
            "{s}"
        );
        assert!(
            s.contains("At byte 24: the device address") && s.contains("set 2 binding 0"),
            "{s}"
        );
        assert!(
            s.contains("At byte 32: the address of a buffer of 3 8-byte buffer device addresses"),
            "{s}"
        );
        let back: HostContract = serde_json::from_str(&serde_json::to_string(&c).unwrap()).unwrap();
        assert_eq!(back, c);
        assert_eq!(stage_flag_name("compute"), "VK_SHADER_STAGE_COMPUTE_BIT");
    }
}
