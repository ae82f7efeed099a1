//! What `run --shader --profile` changes in the harness: the robustness features its device is
//! created with, and the binding flags of its descriptor set layouts (`model::profile`'s
//! [`BindingFlags`]: PARTIALLY_BOUND, UPDATE_AFTER_BIND with the pool's flag,
//! VARIABLE_DESCRIPTOR_COUNT on a set's last binding when it is a runtime array).
use super::reflect::{Binding, BindingKind};
use crate::model::profile::{BindingFlags, DeviceProfile, CORE, ROBUSTNESS2};
use crate::vk::Robustness;
use ash::vk;
use serde::{Deserialize, Serialize};

/// Why the harness enables robustBufferAccess with robustBufferAccess2 where a profile omits it:
/// the validation layer (1.3.239 here) holds a device to this VUID.
pub const IMPLIED_RBA: &str = "VkPhysicalDeviceFeatures.robustBufferAccess, enabled with robustBufferAccess2 (VUID-VkPhysicalDeviceRobustness2FeaturesKHR-robustBufferAccess2-04000, Vulkan 1.4.360: \"If robustBufferAccess2 is enabled then robustBufferAccess must also be enabled\")";

/// Features the harness enables that `p` implies without naming them.
pub fn implied(p: &DeviceProfile) -> Vec<String> {
    let missing = p.has(ROBUSTNESS2, "robustBufferAccess2") && !p.has(CORE, "robustBufferAccess");
    missing.then(|| IMPLIED_RBA.to_string()).into_iter().collect()
}

/// The profile as the harness's child gets it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct ProfileSetup {
    pub robust_buffer_access: bool,
    pub robust_image_access: bool,
    pub robust_buffer_access2: bool,
    pub robust_image_access2: bool,
    pub null_descriptor: bool,
    pub flags: BindingFlags,
}

impl ProfileSetup {
    pub fn of(p: &DeviceProfile) -> ProfileSetup {
        ProfileSetup {
            // robustBufferAccess2 needs robustBufferAccess ([`IMPLIED_RBA`]); its bounds
            // checks are a subset of robustBufferAccess2's, so the engine's behaviour stays.
            robust_buffer_access: p.has(CORE, "robustBufferAccess")
                || p.has(ROBUSTNESS2, "robustBufferAccess2"),
            robust_image_access: p.has("VkPhysicalDeviceVulkan13Features", "robustImageAccess"),
            robust_buffer_access2: p.has(ROBUSTNESS2, "robustBufferAccess2"),
            robust_image_access2: p.has(ROBUSTNESS2, "robustImageAccess2"),
            null_descriptor: p.has(ROBUSTNESS2, "nullDescriptor"),
            flags: p.binding_flags(),
        }
    }

    /// What this setup changes in the harness, in words and one order: each robustness feature
    /// it enables (`robustBufferAccess2`), then, with descriptor sets (`sets`), the binding
    /// flags (`BindingFlags::words`). The cell id's `profile` (`model::shader_options`).
    pub fn effective(&self, sets: bool) -> Vec<String> {
        let robust = [
            (self.robust_buffer_access, "robustBufferAccess"),
            (self.robust_image_access, "robustImageAccess"),
            (self.robust_buffer_access2, "robustBufferAccess2"),
            (self.robust_image_access2, "robustImageAccess2"),
            (self.null_descriptor, "nullDescriptor"),
        ];
        let mut out: Vec<String> =
            robust.iter().filter(|(on, _)| *on).map(|(_, n)| n.to_string()).collect();
        if sets {
            out.extend(self.flags.words());
        }
        out
    }

    pub fn robustness(&self) -> Robustness {
        Robustness {
            robust_buffer_access: self.robust_buffer_access,
            robust_image_access: self.robust_image_access,
            robust_buffer_access2: self.robust_buffer_access2,
            robust_image_access2: self.robust_image_access2,
            null_descriptor: self.null_descriptor,
        }
    }
}

/// Whether `kind` is bound UPDATE_AFTER_BIND under `f`.
fn update_after_bind(f: &BindingFlags, kind: BindingKind) -> bool {
    let u = &f.update_after_bind;
    match kind {
        BindingKind::StorageBuffer(_) => u.storage_buffer,
        BindingKind::UniformBuffer(_) => u.uniform_buffer,
        BindingKind::SampledImage | BindingKind::Sampler | BindingKind::CombinedImageSampler => {
            u.sampled_image
        }
        BindingKind::StorageImage(_) => u.storage_image,
        BindingKind::AccelerationStructure => u.acceleration_structure,
    }
}

/// The flags of one set's bindings (in binding order) and whether any is UPDATE_AFTER_BIND (the
/// layout and the pool then need their UPDATE_AFTER_BIND_POOL flags).
pub fn set_flags(f: &BindingFlags, set: &[&Binding]) -> (Vec<vk::DescriptorBindingFlags>, bool) {
    let last = set.iter().map(|b| b.binding).max();
    let flags: Vec<vk::DescriptorBindingFlags> = set
        .iter()
        .map(|b| {
            let mut x = vk::DescriptorBindingFlags::empty();
            if f.partially_bound {
                x |= vk::DescriptorBindingFlags::PARTIALLY_BOUND;
            }
            if update_after_bind(f, b.kind) {
                x |= vk::DescriptorBindingFlags::UPDATE_AFTER_BIND;
            }
            if f.variable_count && b.runtime && Some(b.binding) == last {
                x |= vk::DescriptorBindingFlags::VARIABLE_DESCRIPTOR_COUNT;
            }
            x
        })
        .collect();
    let uab = flags.iter().any(|x| x.contains(vk::DescriptorBindingFlags::UPDATE_AFTER_BIND));
    (flags, uab)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn binding(b: u32, kind: BindingKind, runtime: bool) -> Binding {
        Binding {
            set: 0,
            binding: b,
            kind,
            count: if runtime { 64 } else { 1 },
            runtime,
            writable: false,
            ints: Default::default(),
            atomic: false,
            records: None,
        }
    }

    #[test]
    fn variable_count_only_on_a_last_runtime_array() {
        let f = BindingFlags { variable_count: true, partially_bound: true, ..Default::default() };
        let tex = binding(3, BindingKind::SampledImage, true);
        let tlas = binding(0, BindingKind::AccelerationStructure, false);
        let (flags, uab) = set_flags(&f, &[&tlas, &tex]);
        assert!(!uab);
        assert!(!flags[0].contains(vk::DescriptorBindingFlags::VARIABLE_DESCRIPTOR_COUNT));
        assert!(flags[1].contains(vk::DescriptorBindingFlags::VARIABLE_DESCRIPTOR_COUNT));
        assert!(flags.iter().all(|x| x.contains(vk::DescriptorBindingFlags::PARTIALLY_BOUND)));
        // Twin: a last binding that is no runtime array gets none.
        let fixed = binding(5, BindingKind::SampledImage, false);
        let (flags, _) = set_flags(&f, &[&tex, &fixed]);
        let variable = vk::DescriptorBindingFlags::VARIABLE_DESCRIPTOR_COUNT;
        assert!(flags.iter().all(|x| !x.contains(variable)));
    }

    #[test]
    fn robust_buffer_access_comes_with_robust_buffer_access2() {
        let p = |json: &str| DeviceProfile::parse(json).unwrap();
        let r2 = p(
            r#"{"capabilities": {"a": {"features": {"VkPhysicalDeviceRobustness2FeaturesEXT": {"robustBufferAccess2": true}}}}}"#,
        );
        let s = ProfileSetup::of(&r2);
        assert!(s.robust_buffer_access && s.robust_buffer_access2);
        assert_eq!(implied(&r2).len(), 1);
        // Twin: named by the profile, nothing implied; no robustness asked, none enabled.
        let both = p(
            r#"{"capabilities": {"a": {"features": {"VkPhysicalDeviceRobustness2FeaturesEXT": {"robustBufferAccess2": true}, "VkPhysicalDeviceFeatures": {"robustBufferAccess": true}}}}}"#,
        );
        assert!(implied(&both).is_empty());
        let none = ProfileSetup::of(&DeviceProfile::default());
        assert!(!none.robust_buffer_access && !none.robust_buffer_access2);
    }

    /// Issue 24: the cell id's profile words are the setup's effect: one feature more is
    /// another word; a feature the harness does not turn on, or the binding flags under a model
    /// without sets, none.
    #[test]
    fn effective_words_follow_what_the_harness_turns_on() {
        let p = |json: &str| ProfileSetup::of(&DeviceProfile::parse(json).unwrap());
        let base = p(
            r#"{"capabilities": {"a": {"features": {"VkPhysicalDeviceRobustness2FeaturesEXT": {"robustBufferAccess2": true}, "VkPhysicalDeviceVulkan12Features": {"descriptorBindingPartiallyBound": true}}}}}"#,
        );
        let words = base.effective(true);
        assert_eq!(words, ["robustBufferAccess", "robustBufferAccess2", "partially_bound"]);
        assert_eq!(base.effective(false), ["robustBufferAccess", "robustBufferAccess2"]);
        let more = p(
            r#"{"capabilities": {"a": {"features": {"VkPhysicalDeviceRobustness2FeaturesEXT": {"robustBufferAccess2": true, "nullDescriptor": true}, "VkPhysicalDeviceVulkan12Features": {"descriptorBindingPartiallyBound": true}}}}}"#,
        );
        assert_ne!(more.effective(true), words);
        let inert = p(
            r#"{"capabilities": {"a": {"features": {"VkPhysicalDeviceFeatures": {"shaderInt64": true}}}}}"#,
        );
        assert!(inert.effective(true).is_empty());
    }

    #[test]
    fn update_after_bind_per_kind() {
        let mut f = BindingFlags::default();
        f.update_after_bind.sampled_image = true;
        let tex = binding(1, BindingKind::CombinedImageSampler, false);
        let tlas = binding(0, BindingKind::AccelerationStructure, false);
        let (flags, uab) = set_flags(&f, &[&tlas, &tex]);
        assert!(uab);
        let none = vk::DescriptorBindingFlags::empty();
        assert_eq!(flags, [none, vk::DescriptorBindingFlags::UPDATE_AFTER_BIND]);
        assert!(!set_flags(&BindingFlags::default(), &[&tex]).1);
    }
}
