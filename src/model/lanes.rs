//! Lane evidence: whether a cell's probe recorded which subgroup lane did its read and with whom
//! (`probe::Record`'s `lane`, `leader`, `active_mask`, `active_count`), the run option that
//! decides it, and (for a mismatch) how the failing pixels split by those words.
use serde::{Deserialize, Serialize};

/// The rule lane evidence relies on: subgroup operations only in the stages the device lists in
/// `subgroupSupportedStages` (Vulkan 1.4.360, "Validation Rules within a Module").
pub const SUBGROUP_STAGE_VUID: &str = "VUID-RuntimeSpirv-None-06343";

/// The key of a report's `device` listing the probe stages where subgroup ballot works.
pub const DEVICE_BALLOT_STAGES: &str = "subgroup_ballot_stages";

/// Whether the report's `device` (`caps::device_json`) lists subgroup ballot in `stage` (false
/// in reports from before the list).
pub fn device_ballot(device: &serde_json::Value, stage: super::Stage) -> bool {
    device[DEVICE_BALLOT_STAGES]
        .as_array()
        .is_some_and(|a| a.iter().any(|s| s.as_str() == Some(stage.as_str())))
}

/// `run --lane-evidence`: when the probe measures its lane evidence.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LaneMode {
    /// Where the device says subgroup ballot works in the probed stage (`subgroupSupportedStages`
    /// has it and `subgroupSupportedOperations` has BALLOT).
    #[default]
    Auto,
    /// Also where it does not: the shader then breaks [`SUBGROUP_STAGE_VUID`], so the evidence is
    /// a diagnosis only (the reference never judges by it) and the verdicts of such a run are not
    /// those of a valid shader.
    Force,
    /// Never (the probe without the subgroup code).
    Off,
}

impl LaneMode {
    pub const ALL: &'static [LaneMode] = &[LaneMode::Auto, LaneMode::Force, LaneMode::Off];

    pub fn as_str(self) -> &'static str {
        match self {
            LaneMode::Auto => "auto",
            LaneMode::Force => "force",
            LaneMode::Off => "off",
        }
    }

    /// What a cell's probe records under this mode, `supported` being whether the device's
    /// subgroup ballot works in its probed stage.
    pub fn evidence(self, supported: bool) -> LaneEvidence {
        match (self, supported) {
            (LaneMode::Off, _) | (LaneMode::Auto, false) => LaneEvidence::Absent,
            (LaneMode::Auto | LaneMode::Force, true) => LaneEvidence::Supported,
            (LaneMode::Force, false) => LaneEvidence::Forced,
        }
    }
}

/// Whether a cell's records carry lane evidence, and whether it may be judged by.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LaneEvidence {
    /// No lane evidence (the device lacks ballot in the stage, `--lane-evidence off`, or a report
    /// from before lane evidence): the reference does not use it.
    #[default]
    Absent,
    /// Recorded with ballot the device supports in the stage: the reference may use it.
    Supported,
    /// Recorded although the device does not list the stage ([`SUBGROUP_STAGE_VUID`]): shown as a
    /// diagnosis, never judged by.
    Forced,
}

impl LaneEvidence {
    /// The probe was generated with the subgroup code (its records carry `FLAG_LANES`).
    pub fn recorded(self) -> bool {
        match self {
            LaneEvidence::Absent => false,
            LaneEvidence::Supported | LaneEvidence::Forced => true,
        }
    }

    /// The reference may judge by it.
    pub fn usable(self) -> bool {
        match self {
            LaneEvidence::Absent | LaneEvidence::Forced => false,
            LaneEvidence::Supported => true,
        }
    }

    pub fn as_str(self) -> &'static str {
        match self {
            LaneEvidence::Absent => "absent",
            LaneEvidence::Supported => "supported",
            LaneEvidence::Forced => "forced",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_mode_and_the_device_decide_the_evidence() {
        assert_eq!(LaneMode::Auto.evidence(true), LaneEvidence::Supported);
        assert_eq!(LaneMode::Auto.evidence(false), LaneEvidence::Absent);
        assert_eq!(LaneMode::Force.evidence(false), LaneEvidence::Forced);
        assert_eq!(LaneMode::Force.evidence(true), LaneEvidence::Supported);
        assert_eq!(LaneMode::Off.evidence(true), LaneEvidence::Absent);
        assert!(LaneEvidence::Forced.recorded() && !LaneEvidence::Forced.usable());
        assert!(!LaneEvidence::Absent.recorded() && LaneEvidence::Supported.usable());
        // a report without the field reads as no evidence
        assert_eq!(
            serde_json::from_str::<LaneEvidence>("\"forced\"").unwrap(),
            LaneEvidence::Forced
        );
        assert_eq!(LaneEvidence::default(), LaneEvidence::Absent);
    }
}
