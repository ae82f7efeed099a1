//! A Vulkan Profiles JSON's features (`model::profile`) held to a device: each one the device
//! has, lacks, or that rtprobe cannot tell (a struct or member the caps report does not read:
//! [`super::fields`] is the one reading of `DeviceInfo`'s features by Vulkan name).
use super::fields;
use crate::model::profile::{DeviceProfile, Feature};
use crate::vk::DeviceInfo;

/// The feature structs [`fields::features`] writes when the device has them: one of these
/// absent on a device is a struct (an extension) the device lacks.
pub const KNOWN_STRUCTS: &[&str] = &[
    "VkPhysicalDeviceFeatures",
    "VkPhysicalDeviceVulkan11Features",
    "VkPhysicalDeviceVulkan12Features",
    "VkPhysicalDeviceVulkan13Features",
    "VkPhysicalDeviceAccelerationStructureFeaturesKHR",
    "VkPhysicalDeviceRayTracingPipelineFeaturesKHR",
    "VkPhysicalDeviceRayQueryFeaturesKHR",
    "VkPhysicalDeviceRayTracingMaintenance1FeaturesKHR",
    "VkPhysicalDeviceRayTracingPositionFetchFeaturesKHR",
    "VkPhysicalDeviceDescriptorBufferFeaturesEXT",
    "VkPhysicalDeviceDescriptorHeapFeaturesEXT",
    "VkPhysicalDeviceShaderUntypedPointersFeaturesKHR",
    "VkPhysicalDeviceRobustness2FeaturesEXT",
    "VkPhysicalDeviceFaultFeaturesEXT",
    "VkPhysicalDeviceMaintenance5FeaturesKHR",
    "VkPhysicalDeviceMaintenance6FeaturesKHR",
    "VkPhysicalDevicePipelineLibraryGroupHandlesFeaturesEXT",
    "VkPhysicalDevicePipelineBinaryFeaturesKHR",
    "VkPhysicalDeviceRayTracingValidationFeaturesNV",
    "VkPhysicalDeviceRayTracingInvocationReorderFeaturesNV",
    "VkPhysicalDeviceRayTracingInvocationReorderFeaturesEXT",
    "VkPhysicalDeviceClusterAccelerationStructureFeaturesNV",
    "VkPhysicalDevicePartitionedAccelerationStructureFeaturesNV",
    "VkPhysicalDeviceDenseGeometryFormatFeaturesAMDX",
    "VkPhysicalDeviceRayTracingMotionBlurFeaturesNV",
    "VkPhysicalDeviceRayTracingLinearSweptSpheresFeaturesNV",
    "VkPhysicalDeviceOpacityMicromapFeaturesEXT",
    "VkPhysicalDeviceOpacityMicromapFeaturesKHR",
    "VkPhysicalDevicePipelineOpacityMicromapFeaturesARM",
    "VkPhysicalDeviceDisplacementMicromapFeaturesNV",
];

/// A profile's features sorted by what the device says of them.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ProfileCheck {
    pub has: Vec<Feature>,
    /// `VkStruct.member` the device does not have (its struct absent: the extension missing).
    pub lacks: Vec<String>,
    /// `VkStruct.member` rtprobe does not read: not checked.
    pub unknown: Vec<String>,
}

/// Sorts `profile`'s features by the device's caps (`fields::features(info)`).
pub fn check(profile: &DeviceProfile, info: &DeviceInfo) -> ProfileCheck {
    sort(profile, &serde_json::Value::Object(fields::features(info)))
}

/// [`check`] over a caps `features` object.
pub fn sort(profile: &DeviceProfile, features: &serde_json::Value) -> ProfileCheck {
    let mut out = ProfileCheck::default();
    for f in &profile.enabled {
        let known = KNOWN_STRUCTS.contains(&f.structure.as_str());
        match (known, features.get(&f.structure).map(|s| s.get(&f.member))) {
            (false, _) | (true, Some(None)) => out.unknown.push(f.name()),
            (true, None) => out.lacks.push(f.name()),
            (true, Some(Some(v))) if v.as_bool() == Some(true) => out.has.push(f.clone()),
            (true, Some(Some(_))) => out.lacks.push(f.name()),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn features_are_had_lacked_or_unknown() {
        let p = DeviceProfile::parse(
            r#"{"capabilities": {"a": {"features": {
                "VkPhysicalDeviceRobustness2FeaturesKHR": {"robustBufferAccess2": true, "nullDescriptor": true},
                "VkPhysicalDeviceFeatures": {"samplerAnisotropy": true},
                "VkPhysicalDeviceRayTracingMotionBlurFeaturesNV": {"rayTracingMotionBlur": true},
                "VkPhysicalDeviceFooFeaturesX": {"foo": true}}}}}"#,
        )
        .unwrap();
        let caps = json!({
            "VkPhysicalDeviceFeatures": {"robustBufferAccess": true},
            "VkPhysicalDeviceRobustness2FeaturesEXT": {"robustBufferAccess2": true, "nullDescriptor": false},
        });
        let c = sort(&p, &caps);
        let has: Vec<String> = c.has.iter().map(Feature::name).collect();
        assert_eq!(has, ["VkPhysicalDeviceRobustness2FeaturesEXT.robustBufferAccess2"]);
        assert_eq!(
            c.lacks,
            [
                "VkPhysicalDeviceRayTracingMotionBlurFeaturesNV.rayTracingMotionBlur",
                "VkPhysicalDeviceRobustness2FeaturesEXT.nullDescriptor"
            ]
        );
        assert_eq!(
            c.unknown,
            ["VkPhysicalDeviceFeatures.samplerAnisotropy", "VkPhysicalDeviceFooFeaturesX.foo"]
        );
    }
}
