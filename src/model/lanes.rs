//! Lane evidence: whether a cell's probe recorded which subgroup lane did its read and with whom
//! (`probe::Record`'s `lane`, `leader`, `active_mask`, `active_count`), the run option that
//! decides it, and (for a mismatch) how the failing pixels split by those words.
use serde::{Deserialize, Serialize};

/// The rule lane evidence relies on: subgroup operations only in the stages the device lists in
/// `subgroupSupportedStages` (Vulkan 1.4.360, "Validation Rules within a Module").
pub const SUBGROUP_STAGE_VUID: &str = "VUID-RuntimeSpirv-None-06343";

/// [`SUBGROUP_STAGE_VUID`]'s text, quoted from the Vulkan 1.4.360 specification (appendix "Vulkan
/// Environment for SPIR-V", "Runtime SPIR-V Validation").
pub const SUBGROUP_STAGE_RULE: &str = "Group operations with subgroup scope must not be used if the shader stage is not in subgroupSupportedStages";

/// The rule, quoted with its VUID and the spec version.
pub fn rule_quote() -> String {
    format!("{SUBGROUP_STAGE_VUID} (Vulkan 1.4.360): \"{SUBGROUP_STAGE_RULE}\"")
}

/// The rule quoted, and what it means for lane evidence recorded in `stage` anyway: a "must" the
/// shader breaks, so nothing the driver returns there is owed.
pub fn forced_words(stage: &str) -> String {
    format!(
        "{}; this device's subgroupSupportedStages does not include {stage}, so the probe's ballot there breaks that rule and the driver owes it no meaningful answer: the lane words show how this driver happened to group the lanes, a hint where to look, never a verdict",
        rule_quote()
    )
}

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

/// Of which kind a subgroup's contradicting records are (`reference::lanes::contradictions`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Contradicted {
    /// Garbage lane data: the records of one call disagree among themselves (a duplicate lane, a
    /// lane outside the mask, more records than lanes, a leader that is an active lane but not
    /// the lowest).
    Garbage,
    /// The call's records agree among themselves, but their leader word names a pixel that was
    /// not active in the call: `subgroupBroadcastFirst` returned an inactive lane's value.
    LeaderOutsideCall,
    /// The leader's own call (led by its lowest lane), sharing its leader pixel with a call of
    /// the kind above: left out with it.
    LeaderOwnCall,
}

/// Probe pixels of one kind, and how many of them mismatched.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Split {
    pub pixels: usize,
    pub failed: usize,
}

impl Split {
    pub fn add(&mut self, failed: bool) {
        self.pixels += 1;
        self.failed += usize::from(failed);
    }
}

/// How a mismatching cell's probe pixels split by their lane evidence: whether lane 0 of their
/// subgroup was active in the probed stage's call (bit 0 of the ballot), whether they were their
/// subgroup's first active lane (the leader), and by lane id. Counted over the compared probe
/// pixels whose records carry consistent lane evidence.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct LaneSplit {
    /// Supported or forced (a diagnosis outside the spec).
    pub evidence: LaneEvidence,
    pub lane0_active: Split,
    pub lane0_inactive: Split,
    pub leaders: Split,
    pub followers: Split,
    /// Index: the lane id.
    pub by_lane: Vec<Split>,
    /// Pixels of subgroups whose records contradict each other (`reference::lanes`): garbage lane
    /// data, left out of every split above and counted here.
    #[serde(default)]
    pub contradicted: Split,
    /// Of `contradicted`: pixels of calls whose records agree but whose leader word names a pixel
    /// outside the call ([`Contradicted::LeaderOutsideCall`]).
    #[serde(default)]
    pub leader_outside: Split,
    /// Of `leader_outside`: those whose call lacked lane 0 (bit 0 of the ballot clear).
    #[serde(default)]
    pub leader_outside_lane0_inactive: Split,
    /// Of `leader_outside`: those whose leader word names a pixel whose own record says lane 0
    /// (absent in older reports: not known, so never called lane 0).
    #[serde(default)]
    pub leader_outside_named_lane0: Split,
    /// Of `leader_outside`: the pixel their leader words name, while every one names the same
    /// (a constant leader word looks like this too); `None` once two differ, or with none.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub leader_outside_one_pixel: Option<usize>,
    /// Of `leader_outside`: their leader words name more than one pixel (absent in older
    /// reports: not known).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub leader_outside_several_pixels: bool,
    /// Of `contradicted`: the calls those leaders ran in ([`Contradicted::LeaderOwnCall`]).
    #[serde(default)]
    pub leader_own_call: Split,
}

impl LaneSplit {
    /// Count one probe pixel of lane `lane` in a subgroup whose ballot's low bits are `mask`,
    /// led by pixel `leader`, the pixel itself being `pixel`.
    pub fn add(&mut self, (lane, mask, leader, pixel): (u32, u32, usize, usize), failed: bool) {
        if mask & 1 != 0 {
            self.lane0_active.add(failed);
        } else {
            self.lane0_inactive.add(failed);
        }
        if leader == pixel {
            self.leaders.add(failed);
        } else {
            self.followers.add(failed);
        }
        let lane = lane as usize;
        if self.by_lane.len() <= lane {
            self.by_lane.resize(lane + 1, Split::default());
        }
        self.by_lane[lane].add(failed);
    }

    /// Count one probe pixel of a subgroup whose records contradict each other, of `kind`, its
    /// call having lane 0 active or not, the pixel its leader word names (`named`) recorded as
    /// lane 0 or not.
    pub fn add_contradicted(
        &mut self,
        kind: Contradicted,
        (lane0_active, named_lane0, named): (bool, bool, usize),
        failed: bool,
    ) {
        self.contradicted.add(failed);
        match kind {
            Contradicted::Garbage => {}
            Contradicted::LeaderOutsideCall => {
                self.leader_outside.add(failed);
                if !lane0_active {
                    self.leader_outside_lane0_inactive.add(failed);
                }
                if named_lane0 {
                    self.leader_outside_named_lane0.add(failed);
                }
                match (self.leader_outside_one_pixel, self.leader_outside_several_pixels) {
                    (_, true) => {}
                    (None, false) => self.leader_outside_one_pixel = Some(named),
                    (Some(p), false) if p == named => {}
                    (Some(_), false) => {
                        self.leader_outside_one_pixel = None;
                        self.leader_outside_several_pixels = true;
                    }
                }
            }
            Contradicted::LeaderOwnCall => self.leader_own_call.add(failed),
        }
    }

    /// The calls whose lane words agree but whose leader word names a pixel outside the call, in
    /// words (empty where there are none): only what was observed — whether the calls lack lane
    /// 0, whether the named pixel's own record says lane 0 (else "a pixel outside the call"), how
    /// many of their pixels mismatched — and, where every one lacked lane 0, what that is
    /// consistent with. The leader rule they break is a failed check only where the evidence is
    /// judged by; forced evidence is a diagnosis ([`forced_words`]).
    fn leader_outside_sentence(&self) -> String {
        let (out, own, lane0, named) = (
            self.leader_outside,
            self.leader_own_call,
            self.leader_outside_lane0_inactive,
            self.leader_outside_named_lane0,
        );
        if out.pixels == 0 {
            return String::new();
        }
        let every = lane0.pixels == out.pixels;
        let calls = match every {
            true => "in calls without lane 0".to_string(),
            false => format!("in calls ({} of their pixels without lane 0)", lane0.pixels),
        };
        // "Lane 0" only by the named pixel's own record: lane 0 of some call, not known to be
        // of theirs. One pixel named by all is also what a constant leader word gives.
        let distinct = match (self.leader_outside_one_pixel, self.leader_outside_several_pixels) {
            (Some(p), _) => {
                Some(format!("pixel {p} for all of them, as a constant leader word would give"))
            }
            (None, true) => Some("more than one pixel in all".to_string()),
            (None, false) => None,
        };
        let lane0 = match named.pixels {
            0 => None,
            n if n == out.pixels => {
                Some("the named pixel's own record says lane 0 for all of them".to_string())
            }
            n => Some(format!("the named pixel's own record says lane 0 for {n} of them")),
        };
        let pixel = match [distinct, lane0].into_iter().flatten().collect::<Vec<_>>() {
            v if v.is_empty() => "a pixel outside the call".to_string(),
            v => format!("a pixel outside the call ({})", v.join("; ")),
        };
        let rule = "the leader must be the lowest active lane, subgroupBroadcastFirst = OpGroupNonUniformBroadcastFirst";
        let rule = match self.evidence {
            LaneEvidence::Supported => format!("the cross-record check they fail: {rule}"),
            LaneEvidence::Absent | LaneEvidence::Forced => format!("in a valid shader {rule}"),
        };
        let mut t = format!(
            "{calls} whose leader word names {pixel} ({rule}), {} of {} pixels mismatched",
            out.failed, out.pixels
        );
        if every && self.leader_outside_several_pixels {
            t += " — consistent with a value taken from lane 0 while it is not in the call";
        }
        if own.pixels > 0 {
            t += &format!(
                "; in the calls their leaders ran in (left out with them) {} of {}",
                own.failed, own.pixels
            );
        }
        t + "; where the lane words hold, "
    }

    /// The rest of the contradicting subgroups: garbage lane data (empty where there is none).
    fn garbage_sentence(&self) -> String {
        let (out, own) = (self.leader_outside, self.leader_own_call);
        let garbage = Split {
            pixels: self.contradicted.pixels - out.pixels - own.pixels,
            failed: self.contradicted.failed - out.failed - own.failed,
        };
        match garbage {
            Split { pixels: 0, .. } => String::new(),
            Split { pixels, failed } => format!(
                "; in subgroups whose records contradict each other (garbage lane data, left out above) {failed} of {pixels} pixels"
            ),
        }
    }

    /// `mismatches by lane 0 of the subgroup: inactive in the call 926 of 933 pixels, active 0 of
    /// 1821; leaders 3 of 600, others 923 of 2154; by lane: 0: 0/300, 1: 120/260, …`; forced
    /// evidence of `stage` quotes the rule it breaks ([`forced_words`]).
    pub fn sentence(&self, stage: &str) -> String {
        let lanes: Vec<String> = self
            .by_lane
            .iter()
            .enumerate()
            .filter(|(_, s)| s.pixels > 0)
            .map(|(k, s)| format!("{k}: {}/{}", s.failed, s.pixels))
            .collect();
        let forced = match self.evidence {
            LaneEvidence::Forced => {
                format!(" (forced lane evidence, a diagnosis only: {})", forced_words(stage))
            }
            LaneEvidence::Absent | LaneEvidence::Supported => String::new(),
        };
        let (outside, contradicted) = (self.leader_outside_sentence(), self.garbage_sentence());
        format!(
            "mismatches by lane 0 of the subgroup: {outside}where it was inactive in the call {} of {} pixels, where active {} of {}; subgroup leaders {} of {}, other lanes {} of {}; by lane (mismatched/pixels): {}{contradicted}{forced}",
            self.lane0_inactive.failed,
            self.lane0_inactive.pixels,
            self.lane0_active.failed,
            self.lane0_active.pixels,
            self.leaders.failed,
            self.leaders.pixels,
            self.followers.failed,
            self.followers.pixels,
            lanes.join(", ")
        )
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

    #[test]
    fn the_split_counts_pixels_by_lane_zero_leader_and_lane() {
        let mut s = LaneSplit { evidence: LaneEvidence::Forced, ..Default::default() };
        // a subgroup without lane 0 (lanes 1, 2 active, led by pixel 10): both fail
        s.add((1, 0b110, 10, 10), true);
        s.add((2, 0b110, 10, 11), true);
        // a subgroup with lane 0: it passes
        s.add((0, 0b11, 20, 20), false);
        s.add((1, 0b11, 20, 21), false);
        assert_eq!(s.lane0_inactive, Split { pixels: 2, failed: 2 });
        assert_eq!(s.lane0_active, Split { pixels: 2, failed: 0 });
        assert_eq!(
            (s.leaders, s.followers),
            (Split { pixels: 2, failed: 1 }, Split { pixels: 2, failed: 1 })
        );
        assert_eq!(
            s.by_lane,
            vec![
                Split { pixels: 1, failed: 0 },
                Split { pixels: 2, failed: 1 },
                Split { pixels: 1, failed: 1 }
            ]
        );
        let t = s.sentence("closest_hit");
        assert!(t.starts_with("mismatches by lane 0 of the subgroup: where it was inactive in the call 2 of 2 pixels, where active 0 of 2"), "{t}");
        assert!(
            t.contains("by lane (mismatched/pixels): 0: 0/1, 1: 1/2, 2: 1/1")
                && t.contains("forced lane evidence"),
            "{t}"
        );
        // Forced evidence quotes the rule it breaks, with its version, and says what that means.
        assert!(t.contains("VUID-RuntimeSpirv-None-06343 (Vulkan 1.4.360): \"Group operations with subgroup scope must not be used if the shader stage is not in subgroupSupportedStages\""), "{t}");
        assert!(
            t.contains("subgroupSupportedStages does not include closest_hit")
                && t.contains("never a verdict"),
            "{t}"
        );
        // The twin: evidence the device supports quotes no rule.
        let supported = LaneSplit { evidence: LaneEvidence::Supported, ..s }.sentence("raygen");
        assert!(!supported.contains("06343") && !supported.contains("forced"), "{supported}");
    }

    /// Twins: contradicting subgroups of calls whose leader is a pixel outside the call, every
    /// one without lane 0, are presented as what was observed (the calls lack lane 0, the leader
    /// word names a pixel outside them, mismatched of pixels there, what that is consistent
    /// with); forced evidence never says the records fail a check, supported evidence does; lane
    /// 0 is named only where the named pixel's record says lane 0; a duplicate lane is garbage
    /// and still left out as garbage; a report from before the kinds reads as garbage.
    #[test]
    fn a_leader_outside_the_call_is_evidence_and_garbage_stays_garbage() {
        let mut s = LaneSplit { evidence: LaneEvidence::Forced, ..Default::default() };
        s.add((0, 0b11, 20, 20), false);
        for p in [8, 8, 16] {
            s.add_contradicted(Contradicted::LeaderOutsideCall, (false, false, p), true);
        }
        s.add_contradicted(Contradicted::LeaderOutsideCall, (false, false, 16), false);
        s.add_contradicted(Contradicted::LeaderOwnCall, (true, false, 8), false);
        assert_eq!(s.contradicted, Split { pixels: 5, failed: 3 });
        let t = s.sentence("closest_hit");
        assert!(
            t.starts_with("mismatches by lane 0 of the subgroup: in calls without lane 0 whose leader word names a pixel outside the call (more than one pixel in all) (in a valid shader the leader must be the lowest active lane, subgroupBroadcastFirst = OpGroupNonUniformBroadcastFirst), 3 of 4 pixels mismatched — consistent with a value taken from lane 0 while it is not in the call; in the calls their leaders ran in (left out with them) 0 of 1; where the lane words hold, where it was inactive in the call 0 of 0 pixels, where active 0 of 1")
                && !t.contains("garbage"),
            "{t}"
        );
        // forced evidence: a diagnosis, never a failed check or a value the driver handed over
        assert!(
            !t.contains(" fail") && !t.contains("handed") && !t.contains("lane 0's pixel"),
            "{t}"
        );
        assert!(t.contains("a diagnosis only"), "{t}");
        let judged = LaneSplit { evidence: LaneEvidence::Supported, ..s.clone() };
        let j = judged.sentence("raygen");
        assert!(j.contains("(the cross-record check they fail: the leader must be"), "{j}");
        // the named pixels' own records say lane 0: said so, of those pixels, not of the calls
        let mut named = LaneSplit { evidence: LaneEvidence::Forced, ..Default::default() };
        named.add_contradicted(Contradicted::LeaderOutsideCall, (false, true, 8), true);
        named.add_contradicted(Contradicted::LeaderOutsideCall, (false, true, 40), true);
        let n = named.sentence("closest_hit");
        assert!(n.contains("whose leader word names a pixel outside the call (more than one pixel in all; the named pixel's own record says lane 0 for all of them) ("), "{n}");
        assert!(n.contains("consistent with a value taken from lane 0"), "{n}");
        // twin: every call names one pixel — a constant leader word gives that too, so no
        // lane 0 story is told
        let mut one = LaneSplit { evidence: LaneEvidence::Forced, ..Default::default() };
        one.add_contradicted(Contradicted::LeaderOutsideCall, (false, true, 0), true);
        one.add_contradicted(Contradicted::LeaderOutsideCall, (false, true, 0), true);
        let o = one.sentence("closest_hit");
        assert!(
            o.contains("(pixel 0 for all of them, as a constant leader word would give; the named"),
            "{o}"
        );
        assert!(!o.contains("consistent with a value taken from lane 0"), "{o}");
        s.add_contradicted(Contradicted::Garbage, (true, false, 3), true);
        let t = s.sentence("closest_hit");
        assert!(
            t.contains("(garbage lane data, left out above) 1 of 1 pixels") && t.contains("3 of 4"),
            "{t}"
        );
        // one call with lane 0 among them: counted, not called lane 0's signature
        s.add_contradicted(Contradicted::LeaderOutsideCall, (true, false, 24), true);
        let t = s.sentence("closest_hit");
        assert!(
            t.contains("in calls (4 of their pixels without lane 0) whose leader word")
                && t.contains("4 of 5 pixels")
                && !t.contains("consistent with"),
            "{t}"
        );
        let old: LaneSplit = serde_json::from_str(
            r#"{"evidence":"forced","lane0_active":{"pixels":1,"failed":0},"lane0_inactive":{"pixels":0,"failed":0},"leaders":{"pixels":1,"failed":0},"followers":{"pixels":0,"failed":0},"by_lane":[],"contradicted":{"pixels":945,"failed":924}}"#,
        )
        .unwrap();
        assert!(old
            .sentence("closest_hit")
            .contains("(garbage lane data, left out above) 924 of 945 pixels"));
    }
}
