//! `run --shader --profile FILE`: the engine's Vulkan Profiles JSON read (one line when it is
//! not one), held to the device before any run (a feature the device lacks is one line naming
//! it: the engine could not run there either), and what the harness then enables and binds
//! recorded (`model::profile::ProfileRecord`).
use super::exit::{self, coded};
use crate::caps::profile_check;
use crate::harness::profile::ProfileSetup;
use crate::harness::UserModule;
use crate::model::profile::{DeviceProfile, ProfileRecord};
use crate::model::DescriptorModel;
use crate::vk::{DeviceInfo, Requirements};
use anyhow::Result;
use std::path::Path;

/// A profile as read: the features, the file's name and hash.
pub struct Loaded {
    pub profile: DeviceProfile,
    pub file: String,
    pub hash: String,
}

/// `--profile FILE` read and parsed.
pub fn read(path: Option<&Path>) -> Result<Option<Loaded>> {
    let Some(path) = path else { return Ok(None) };
    let shown = path.display();
    let bytes = std::fs::read(path)
        .map_err(|e| coded(exit::BAD_INPUT, format!("--profile {shown}: {e}")))?;
    let text = String::from_utf8(bytes.clone()).map_err(|_| {
        coded(
            exit::BAD_INPUT,
            format!("--profile {shown}: not UTF-8 text; give a Vulkan Profiles JSON"),
        )
    })?;
    let profile = DeviceProfile::parse(&text)
        .map_err(|e| coded(exit::BAD_INPUT, format!("--profile {shown}: {e}")))?;
    let hash = super::patch_inputs::hash_hex(&bytes);
    Ok(Some(Loaded { profile, file: shown.to_string(), hash }))
}

/// The harness setup `loaded` asks for (none: the defaults).
pub fn setup(loaded: Option<&Loaded>) -> ProfileSetup {
    loaded.map(|l| ProfileSetup::of(&l.profile)).unwrap_or_default()
}

/// `loaded` held to `info`: a feature the device lacks is one line naming every one (exit 5);
/// else what the device `req` makes is given of the profile, and the binding flags under
/// `model` with the variable-sized bindings of `modules` (the full pipeline).
pub fn check(
    loaded: &Loaded,
    info: &DeviceInfo,
    req: &Requirements,
    (model, modules): (DescriptorModel, &[UserModule]),
) -> Result<ProfileRecord> {
    let sorted = profile_check::check(&loaded.profile, info);
    if !sorted.lacks.is_empty() {
        return Err(coded(
            exit::UNSUPPORTED_DEVICE,
            format!(
                "--profile {}: {} lacks {} (the engine could not run there either); run on a device that has it, or remove it from the profile",
                loaded.file,
                info.name(),
                sorted.lacks.join(", ")
            ),
        ));
    }
    let given = crate::vk::device::enabled_feature_names(req, info);
    let (enabled, not_enabled): (Vec<_>, Vec<_>) =
        sorted.has.iter().partition(|f| given.contains(&f.member));
    let flags = setup(Some(loaded)).flags;
    let (flags, variable_counts) = match model {
        DescriptorModel::DescriptorIndexing => {
            (flags.words(), crate::harness::run::variable_counts(modules, &flags, info))
        }
        DescriptorModel::DescriptorBuffer | DescriptorModel::DescriptorHeap => {
            (Vec::new(), Vec::new())
        }
    };
    Ok(ProfileRecord {
        file: loaded.file.clone(),
        hash: loaded.hash.clone(),
        enabled: enabled.iter().map(|f| f.name()).collect(),
        not_enabled: not_enabled.iter().map(|f| f.name()).collect(),
        unknown: sorted.unknown,
        implied: crate::harness::profile::implied(&loaded.profile),
        binding_flags: flags,
        variable_counts,
    })
}
