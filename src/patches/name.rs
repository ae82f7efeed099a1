//! The patches by name: [`PatchName`], their option keys and the list `--list` and `--help` show.
use super::PatchError;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PatchName {
    AsToAddress,
    Nonuniform,
    PinIndex,
    SsboToAddress,
}

/// Name, options and one-line description of each patch.
pub const LIST: &[(&str, &str, &str)] = &[
    ("as-to-address", "offset=BYTES mode=direct|table set=N binding=N", "acceleration structures read through descriptors become OpConvertUToAccelerationStructureKHR of a 64-bit address from push constants, one per descriptor (table mode: the address of the descriptor's own table of addresses, indexed like the array)"),
    ("nonuniform", "strip=true|false", "decorate every dynamically indexed descriptor access NonUniform (what nonuniformEXT would give), or strip every NonUniform decoration"),
    ("pin-index", "set=N binding=N value=K spec-id=ID", "replace the runtime index of dynamically indexed descriptor arrays by an OpSpecConstant (default value K), one SpecId per descriptor"),
    ("ssbo-to-address", "offset=BYTES set=N binding=N", "reads of a storage-buffer descriptor array become PhysicalStorageBuffer loads from the array's own table of buffer addresses in push constants (reads only)"),
];

impl PatchName {
    pub fn parse(s: &str) -> Result<Self, PatchError> {
        match s.trim() {
            "as-to-address" => Ok(PatchName::AsToAddress),
            "nonuniform" => Ok(PatchName::Nonuniform),
            "pin-index" => Ok(PatchName::PinIndex),
            "ssbo-to-address" => Ok(PatchName::SsboToAddress),
            other => Err(PatchError::Unknown(other.into())),
        }
    }

    pub fn as_str(self) -> &'static str {
        match self {
            PatchName::AsToAddress => "as-to-address",
            PatchName::Nonuniform => "nonuniform",
            PatchName::PinIndex => "pin-index",
            PatchName::SsboToAddress => "ssbo-to-address",
        }
    }

    pub(crate) fn keys(self) -> &'static [&'static str] {
        match self {
            PatchName::AsToAddress => &["offset", "mode", "set", "binding"],
            PatchName::Nonuniform => &["strip"],
            PatchName::PinIndex => &["set", "binding", "value", "spec-id"],
            PatchName::SsboToAddress => &["offset", "set", "binding"],
        }
    }
}

/// `--apply`'s help: every patch, from [`LIST`].
pub fn apply_help() -> String {
    let names: Vec<&str> = LIST.iter().map(|p| p.0).collect();
    format!(
        "Patches to apply, in order (comma-separated): {} (`rtprobe patch --list` describes each)",
        names.join(", ")
    )
}
