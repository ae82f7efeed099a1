//! `run --shader --profile FILE`: the device features an engine enables, read from a Khronos
//! Vulkan Profiles JSON (what `caps --profile` writes, or a hand-written one of its schema:
//! `capabilities.NAME.features.VkStruct.member: true`). Struct names promoted into the core
//! feature structs, or renamed when their extension went KHR, are read as the struct rtprobe
//! queries (`VkPhysicalDeviceDescriptorIndexingFeatures` → `VkPhysicalDeviceVulkan12Features`),
//! so a feature has one name. Also the harness's binding flags the profile implies, and what a
//! shader run records of it.
use serde::{Deserialize, Serialize};
use serde_json::Value;
use std::collections::BTreeSet;

/// What is wrong with a profile file, in one line.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ProfileError {
    #[error("not JSON ({0}); give a Vulkan Profiles JSON such as `rtprobe caps --profile` writes")]
    Json(String),
    #[error("no `capabilities` object; give a Vulkan Profiles JSON such as `rtprobe caps --profile` writes")]
    NoCapabilities,
    #[error("{0}: not an object; features are `\"VkStruct\": {{\"member\": true}}`")]
    NotObject(String),
    #[error("{0}: not true or false; a feature is a boolean")]
    NotBool(String),
}

/// One feature: the struct rtprobe queries it in and its member (Vulkan spelling).
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct Feature {
    pub structure: String,
    pub member: String,
}

impl Feature {
    pub fn new(structure: &str, member: &str) -> Feature {
        let structure = canonical(structure).to_string();
        Feature { structure, member: member.to_string() }
    }

    /// `VkStruct.member`.
    pub fn name(&self) -> String {
        format!("{}.{}", self.structure, self.member)
    }
}

/// Feature structs that were promoted to core (their members now in the VulkanXY struct) or
/// renamed: the name caps reads them by.
const ALIASES: &[(&str, &str)] = &[
    ("VkPhysicalDeviceFeatures2", "VkPhysicalDeviceFeatures"),
    ("VkPhysicalDeviceDescriptorIndexingFeatures", V12),
    ("VkPhysicalDeviceDescriptorIndexingFeaturesEXT", V12),
    ("VkPhysicalDeviceBufferDeviceAddressFeatures", V12),
    ("VkPhysicalDeviceBufferDeviceAddressFeaturesKHR", V12),
    ("VkPhysicalDeviceScalarBlockLayoutFeatures", V12),
    ("VkPhysicalDeviceScalarBlockLayoutFeaturesEXT", V12),
    ("VkPhysicalDeviceTimelineSemaphoreFeatures", V12),
    ("VkPhysicalDeviceVulkanMemoryModelFeatures", V12),
    ("VkPhysicalDeviceShaderFloat16Int8Features", V12),
    ("VkPhysicalDeviceImageRobustnessFeatures", V13),
    ("VkPhysicalDeviceImageRobustnessFeaturesEXT", V13),
    ("VkPhysicalDeviceDynamicRenderingFeatures", V13),
    ("VkPhysicalDeviceSynchronization2Features", V13),
    ("VkPhysicalDeviceMaintenance4Features", V13),
    ("VkPhysicalDeviceRobustness2FeaturesKHR", ROBUSTNESS2),
];
const V12: &str = "VkPhysicalDeviceVulkan12Features";
const V13: &str = "VkPhysicalDeviceVulkan13Features";
pub const ROBUSTNESS2: &str = "VkPhysicalDeviceRobustness2FeaturesEXT";
pub const CORE: &str = "VkPhysicalDeviceFeatures";

/// The struct rtprobe reads `structure`'s `member` in.
fn canonical(structure: &str) -> &str {
    ALIASES.iter().find(|(from, _)| *from == structure).map_or(structure, |(_, to)| to)
}

/// The features a profile enables (every member given `true`, over all its capabilities).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DeviceProfile {
    pub enabled: BTreeSet<Feature>,
}

impl DeviceProfile {
    /// Reads a Vulkan Profiles JSON; members given `false` enable nothing.
    pub fn parse(text: &str) -> Result<DeviceProfile, ProfileError> {
        let v: Value = serde_json::from_str(text).map_err(|e| ProfileError::Json(e.to_string()))?;
        let caps =
            v.get("capabilities").and_then(Value::as_object).ok_or(ProfileError::NoCapabilities)?;
        let mut enabled = BTreeSet::new();
        for (cap, c) in caps {
            let at = format!("capabilities.{cap}");
            let c = c.as_object().ok_or_else(|| ProfileError::NotObject(at.clone()))?;
            let Some(features) = c.get("features") else { continue };
            let at = format!("{at}.features");
            let features =
                features.as_object().ok_or_else(|| ProfileError::NotObject(at.clone()))?;
            for (s, members) in features {
                let at = format!("{at}.{s}");
                let members =
                    members.as_object().ok_or_else(|| ProfileError::NotObject(at.clone()))?;
                for (m, on) in members {
                    match on {
                        Value::Bool(true) => {
                            enabled.insert(Feature::new(s, m));
                        }
                        Value::Bool(false) => {}
                        _ => return Err(ProfileError::NotBool(format!("{at}.{m}"))),
                    }
                }
            }
        }
        Ok(DeviceProfile { enabled })
    }

    /// Whether the profile enables `member` of `structure` (either spelled as rtprobe reads it).
    pub fn has(&self, structure: &str, member: &str) -> bool {
        self.enabled.contains(&Feature::new(structure, member))
    }

    /// The descriptor binding flags an engine with these features would use.
    pub fn binding_flags(&self) -> BindingFlags {
        let v12 = |m: &str| self.has(V12, m);
        BindingFlags {
            partially_bound: v12("descriptorBindingPartiallyBound"),
            variable_count: v12("descriptorBindingVariableDescriptorCount"),
            update_after_bind: UpdateAfterBind {
                storage_buffer: v12("descriptorBindingStorageBufferUpdateAfterBind"),
                uniform_buffer: v12("descriptorBindingUniformBufferUpdateAfterBind"),
                sampled_image: v12("descriptorBindingSampledImageUpdateAfterBind"),
                storage_image: v12("descriptorBindingStorageImageUpdateAfterBind"),
                acceleration_structure: self.has(
                    "VkPhysicalDeviceAccelerationStructureFeaturesKHR",
                    "descriptorBindingAccelerationStructureUpdateAfterBind",
                ),
            },
        }
    }
}

/// Which descriptor kinds are bound UPDATE_AFTER_BIND (samplers and combined image samplers
/// with the sampled images).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct UpdateAfterBind {
    pub storage_buffer: bool,
    pub uniform_buffer: bool,
    pub sampled_image: bool,
    pub storage_image: bool,
    pub acceleration_structure: bool,
}

/// The binding flags of the harness's descriptor set layouts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct BindingFlags {
    /// PARTIALLY_BOUND on every binding.
    pub partially_bound: bool,
    /// VARIABLE_DESCRIPTOR_COUNT on a set's last binding when it is a runtime array.
    pub variable_count: bool,
    pub update_after_bind: UpdateAfterBind,
}

impl BindingFlags {
    /// The flags in words, for the report (`partially_bound`, `update_after_bind(storage_buffer)`).
    pub fn words(&self) -> Vec<String> {
        let u = &self.update_after_bind;
        let kinds: Vec<&str> = [
            (u.storage_buffer, "storage_buffer"),
            (u.uniform_buffer, "uniform_buffer"),
            (u.sampled_image, "sampled_image"),
            (u.storage_image, "storage_image"),
            (u.acceleration_structure, "acceleration_structure"),
        ]
        .iter()
        .filter(|(on, _)| *on)
        .map(|(_, k)| *k)
        .collect();
        let mut out = Vec::new();
        if self.partially_bound {
            out.push("partially_bound".to_string());
        }
        if !kinds.is_empty() {
            out.push(format!("update_after_bind({})", kinds.join(", ")));
        }
        if self.variable_count {
            out.push("variable_descriptor_count".to_string());
        }
        out
    }
}

/// What a shader run records of `--profile`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ProfileRecord {
    pub file: String,
    /// FNV-1a 128, hex, of the file's bytes.
    pub hash: String,
    /// The profile's features the harness device was created with (`VkStruct.member`).
    #[serde(default)]
    pub enabled: Vec<String>,
    /// Features the device has that the harness does not turn on (rtprobe's gap, not the
    /// engine's: their effect is not reproduced).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub not_enabled: Vec<String>,
    /// Features of structs rtprobe does not query: neither checked nor turned on.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub unknown: Vec<String>,
    /// Features enabled because a named one requires them, with the rule.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub implied: Vec<String>,
    /// The descriptor set layouts' binding flags (`BindingFlags::words`).
    #[serde(default)]
    pub binding_flags: Vec<String>,
    /// Each variable-sized binding's layout bound and allocated count
    /// (`set 1 binding 3: layout 999998, allocated 64`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub variable_counts: Vec<String>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_true_members_of_every_capability_under_one_name() {
        let p = DeviceProfile::parse(
            r#"{"capabilities": {
                "a": {"features": {"VkPhysicalDeviceRobustness2FeaturesKHR": {"robustBufferAccess2": true, "nullDescriptor": false}}},
                "b": {"extensions": {}, "features": {"VkPhysicalDeviceDescriptorIndexingFeatures": {"descriptorBindingPartiallyBound": true}}}
            }}"#,
        )
        .unwrap();
        assert!(p.has(ROBUSTNESS2, "robustBufferAccess2"));
        assert!(!p.has(ROBUSTNESS2, "nullDescriptor"));
        assert!(p.has(V12, "descriptorBindingPartiallyBound"));
        assert_eq!(p.enabled.len(), 2);
        let f = p.binding_flags();
        assert!(f.partially_bound && !f.variable_count);
        assert_eq!(f.words(), ["partially_bound"]);
    }

    #[test]
    fn bad_files_are_one_line_each() {
        assert!(matches!(DeviceProfile::parse("{"), Err(ProfileError::Json(_))));
        assert_eq!(DeviceProfile::parse("{}"), Err(ProfileError::NoCapabilities));
        let e = DeviceProfile::parse(r#"{"capabilities": {"a": {"features": {"S": {"m": 1}}}}}"#);
        assert_eq!(e, Err(ProfileError::NotBool("capabilities.a.features.S.m".into())));
        let e = DeviceProfile::parse(r#"{"capabilities": {"a": {"features": []}}}"#);
        assert_eq!(e, Err(ProfileError::NotObject("capabilities.a.features".into())));
        for e in [e.unwrap_err(), ProfileError::Json("x".into())] {
            assert!(!e.to_string().contains('\n'));
        }
    }

    #[test]
    fn update_after_bind_follows_each_kinds_feature() {
        let p = DeviceProfile::parse(
            r#"{"capabilities": {"a": {"features": {"VkPhysicalDeviceVulkan12Features": {
                "descriptorBindingStorageBufferUpdateAfterBind": true,
                "descriptorBindingVariableDescriptorCount": true}}}}}"#,
        )
        .unwrap();
        let f = p.binding_flags();
        assert!(f.update_after_bind.storage_buffer && !f.update_after_bind.sampled_image);
        assert_eq!(f.words(), ["update_after_bind(storage_buffer)", "variable_descriptor_count"]);
    }
}
