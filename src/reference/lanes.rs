//! The device's lane evidence, read back from its records (`probe::Record`'s `lane`, `leader`,
//! `active_mask`, `active_count` with `probe::FLAG_LANES`): which pixels ran in the same subgroup
//! instance of the probed stage's call as a pixel, and which pixel was its first active lane
//! (whose index a uniform broadcast would hand every lane). Also the per-record consistency the
//! comparison holds every such record to.
//!
//! A subgroup is known only when the records show all of it: as many pixels share its leader as
//! its active count, they agree on the count and the mask, and the leader is among them. Where a
//! stage runs more than once per pixel (any-hit, intersection) a later call overwrites an earlier
//! one's evidence, and a fragment subgroup may hold helper invocations that write no record: such
//! subgroups stay unknown, and whoever asks falls back to what holds without them.
use crate::probe::{Record, FLAG_LANES, FLAG_PROBE};
use std::collections::HashMap;

/// The largest subgroup size Vulkan allows (`subgroupSize` is a power of two, at most 128).
pub const MAX_SUBGROUP: u32 = 128;

/// What is wrong with a record's lane words, if anything: a lane or count beyond any subgroup,
/// no active lane, the lane's own bit clear in the low 32 bits of the ballot, more bits set than
/// lanes counted, or a leader that is no pixel of the image.
pub fn inconsistency(r: &Record, pixels: usize) -> Option<&'static str> {
    if r.active_count == 0 || r.active_count > MAX_SUBGROUP {
        return Some("active count outside 1..=128");
    }
    if r.lane >= MAX_SUBGROUP {
        return Some("lane id at or above 128");
    }
    if r.lane < 32 && r.active_mask & (1 << r.lane) == 0 {
        return Some("the lane's own bit is clear in the active mask");
    }
    if r.active_mask.count_ones() > r.active_count {
        return Some("more lanes in the mask than the active count");
    }
    if r.leader as usize >= pixels {
        return Some("leader is not a pixel of the image");
    }
    None
}

/// Subgroup membership from a cell's records.
#[derive(Clone, Debug, Default)]
pub struct Lanes {
    /// Per pixel: its leader pixel, where its record carries consistent lane evidence.
    leader: Vec<Option<usize>>,
    /// Per leader pixel: the members of its subgroup, where the records show all of it.
    groups: HashMap<usize, Vec<usize>>,
}

impl Lanes {
    /// Read the lane evidence of every probe record (`FLAG_PROBE` and `FLAG_LANES` set, lane
    /// words consistent).
    pub fn from_records(records: &[Record]) -> Lanes {
        let n = records.len();
        let with_lanes = |r: &Record| {
            r.flags & (FLAG_PROBE | FLAG_LANES) == FLAG_PROBE | FLAG_LANES
                && inconsistency(r, n).is_none()
        };
        let leader: Vec<Option<usize>> =
            records.iter().map(|r| with_lanes(r).then_some(r.leader as usize)).collect();
        let mut members: HashMap<usize, Vec<usize>> = HashMap::new();
        for (p, l) in leader.iter().enumerate() {
            if let Some(l) = l {
                members.entry(*l).or_default().push(p);
            }
        }
        let groups = members
            .into_iter()
            .filter(|(l, m)| {
                let first = &records[m[0]];
                m.len() == first.active_count as usize
                    && m.contains(l)
                    && m.iter().all(|&q| {
                        records[q].active_count == first.active_count
                            && records[q].active_mask == first.active_mask
                    })
            })
            .collect();
        Lanes { leader, groups }
    }

    /// The pixels that ran in the same subgroup instance of the probed stage's call as pixel `p`
    /// (`p` included, in pixel order), when the records show the whole subgroup.
    pub fn subgroup(&self, p: usize) -> Option<&[usize]> {
        let l = (*self.leader.get(p)?)?;
        self.groups.get(&l).map(Vec::as_slice)
    }

    /// The pixel of the first active lane of `p`'s subgroup (its leader): the lane whose index
    /// `subgroupBroadcastFirst` hands every lane. `None` where `p` carries no lane evidence.
    pub fn leader(&self, p: usize) -> Option<usize> {
        *self.leader.get(p)?
    }

    /// Pixels whose subgroup the records show whole.
    pub fn known(&self) -> usize {
        self.groups.values().map(Vec::len).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A probe record of lane `lane` in a subgroup led by pixel `leader`, `mask` active.
    fn rec(lane: u32, leader: u32, mask: u32) -> Record {
        Record {
            flags: FLAG_PROBE | FLAG_LANES,
            lane,
            leader,
            active_mask: mask,
            active_count: mask.count_ones(),
            ..Default::default()
        }
    }

    #[test]
    fn whole_subgroups_are_known_and_partial_ones_are_not() {
        // Pixels 0..4: one subgroup of lanes 1, 2, 5, 6 led by pixel 0 (lane 0 inactive).
        // Pixels 4..6: a subgroup of three active lanes of which only two wrote a record.
        let mask = 0b0110_0110;
        let mut records = vec![rec(1, 0, mask), rec(2, 0, mask), rec(5, 0, mask), rec(6, 0, mask)];
        records.push(rec(0, 4, 0b111));
        records.push(rec(1, 4, 0b111));
        records.push(Record { flags: FLAG_PROBE, ..Default::default() });
        let lanes = Lanes::from_records(&records);
        assert_eq!(lanes.subgroup(2), Some(&[0, 1, 2, 3][..]));
        assert_eq!(lanes.leader(3), Some(0));
        assert_eq!(lanes.subgroup(5), None);
        assert_eq!(lanes.leader(5), Some(4));
        assert_eq!((lanes.subgroup(6), lanes.leader(6)), (None, None));
        assert_eq!(lanes.known(), 4);
        // Members disagreeing on the mask: not one subgroup.
        records[1].active_mask = 0b0110_0011;
        assert_eq!(Lanes::from_records(&records).subgroup(0), None);
    }

    #[test]
    fn inconsistent_lane_words_are_named() {
        let good = rec(3, 0, 0b1000);
        assert_eq!(inconsistency(&good, 4), None);
        assert!(inconsistency(&Record { active_count: 0, ..good }, 4).is_some());
        assert!(inconsistency(&Record { active_count: 129, ..good }, 4).is_some());
        assert!(inconsistency(&Record { lane: 128, ..good }, 4).is_some());
        assert!(inconsistency(&Record { active_mask: 0b0100, ..good }, 4).is_some());
        assert!(inconsistency(&Record { active_mask: 0b1111, ..good }, 4).is_some());
        assert!(inconsistency(&Record { leader: 4, ..good }, 4).is_some());
        // lanes past 32 are not in the recorded mask (wave64): only the count bounds them
        assert_eq!(inconsistency(&Record { lane: 40, active_count: 64, ..good }, 4), None);
        // inconsistent records join no subgroup
        let bad = Record { active_count: 0, ..rec(0, 0, 1) };
        assert_eq!(Lanes::from_records(&[bad]).leader(0), None);
    }
}
