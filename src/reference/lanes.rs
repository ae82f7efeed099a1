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
//!
//! Records that share a subgroup key (their `leader`) must also agree with each other
//! ([`contradictions`]): the leader is the lowest set lane of the active mask, lane ids are
//! distinct and inside the mask, and the mask and count are the same in every record. A subgroup
//! whose records contradict each other is wrong lane data from the driver, of two kinds
//! (`model::lanes::Contradicted`): a leader word naming a pixel outside a call whose records
//! otherwise agree (`subgroupBroadcastFirst` returning an inactive lane's value: lavapipe 26's
//! calls without lane 0), or garbage. Either way its pixels join no subgroup and no split (the
//! split counts them apart, by kind), and where the evidence is judged by (`supported`) each of
//! them is a mismatch on field `lanes` (`compare`). In stages that may run more than once per pixel
//! (any-hit, intersection: a later call overwrites an earlier one's words) records sharing a
//! leader may come from different calls, so only the per-record checks hold there.
use crate::model::lanes::Contradicted;
use crate::model::Stage;
use crate::probe::{Record, FLAG_LANES, FLAG_PROBE};

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

/// Whether each pixel's record comes from one call of the probed stage, so that records sharing
/// a leader are one subgroup instance: not in any-hit and intersection, which may run several
/// times per pixel.
pub fn one_call_per_pixel(stage: Stage) -> bool {
    match stage {
        Stage::Raygen
        | Stage::ClosestHit
        | Stage::Miss
        | Stage::Callable
        | Stage::Fragment
        | Stage::Compute => true,
        Stage::AnyHit | Stage::Intersection => false,
    }
}

/// Per pixel: the probe records with consistent lane words (`FLAG_PROBE` and `FLAG_LANES` set,
/// [`inconsistency`] none) and their leader pixel.
fn leaders(records: &[Record]) -> Vec<Option<usize>> {
    let n = records.len();
    let with_lanes = |r: &Record| {
        r.flags & (FLAG_PROBE | FLAG_LANES) == FLAG_PROBE | FLAG_LANES
            && inconsistency(r, n).is_none()
    };
    records.iter().map(|r| with_lanes(r).then_some(r.leader as usize)).collect()
}

/// The pixels sharing each leader, found in one counting pass (no map, no per-group vector):
/// `order` holds the pixels with a leader sorted by leader, in pixel order within one leader, and
/// leader `l`'s members are `order[start[l]..start[l + 1]]`.
struct Members {
    order: Vec<usize>,
    start: Vec<usize>,
}

impl Members {
    fn of(leader: &[Option<usize>]) -> Members {
        let mut start = vec![0usize; leader.len() + 1];
        for l in leader.iter().flatten() {
            start[l + 1] += 1;
        }
        for k in 1..start.len() {
            start[k] += start[k - 1];
        }
        let mut next = start.clone();
        let mut order = vec![0; start[leader.len()]];
        for (p, l) in leader.iter().enumerate() {
            if let Some(l) = *l {
                order[next[l]] = p;
                next[l] += 1;
            }
        }
        Members { order, start }
    }

    /// The members of leader `l`'s subgroup (empty where no record names `l`).
    fn group(&self, l: usize) -> &[usize] {
        &self.order[self.start[l]..self.start[l + 1]]
    }

    /// Every leader some record names, with its members (in pixel order).
    fn groups(&self) -> impl Iterator<Item = (usize, &[usize])> {
        (0..self.start.len() - 1).map(|l| (l, self.group(l))).filter(|(_, g)| !g.is_empty())
    }
}

/// Whether two of `group`'s records claim the same lane (a bit set per lane below
/// [`MAX_SUBGROUP`], no allocation; a lane at or above it, which [`inconsistency`] refuses
/// before, is compared with every other).
fn duplicate_lane(records: &[Record], group: &[usize]) -> bool {
    let mut seen = [0u64; (MAX_SUBGROUP / 64) as usize];
    group.iter().enumerate().any(|(k, &q)| {
        let lane = records[q].lane;
        if lane >= MAX_SUBGROUP {
            return group[..k].iter().any(|&o| records[o].lane == lane);
        }
        let (word, bit) = ((lane / 64) as usize, 1u64 << (lane % 64));
        let dup = seen[word] & bit != 0;
        seen[word] |= bit;
        dup
    })
}

/// What is wrong between the records of one subgroup (`group`: the pixels whose records name
/// `leader`), if anything: members disagreeing on the mask or count, two members
/// claiming one lane, a lane outside the subgroup's mask, or a leader that is not the lowest set
/// lane of the mask (`subgroupBroadcastFirst` is SPIR-V's `OpGroupNonUniformBroadcastFirst`: "the
/// Value of the invocation from the active invocation with the lowest id in the group", the id in
/// a subgroup being `SubgroupLocalInvocationId`, the record's `lane`).
pub fn subgroup_contradiction(
    records: &[Record],
    leader: usize,
    group: &[usize],
) -> Option<&'static str> {
    let leader_member = group.contains(&leader);
    // The subgroup's mask: its leader's record's where the leader is a member.
    let first = &records[if leader_member { leader } else { group[0] }];
    let mask = first.active_mask;
    if group.iter().any(|&q| records[q].lane < 32 && mask & (1 << records[q].lane) == 0) {
        return Some("a lane outside its subgroup's active mask");
    }
    if group.iter().any(|&q| {
        records[q].active_mask != first.active_mask || records[q].active_count != first.active_count
    }) {
        return Some("records of one subgroup disagree on the active mask or count");
    }
    if duplicate_lane(records, group) {
        return Some("two records of one subgroup claim the same lane");
    }
    if group.len() > first.active_count as usize {
        return Some("more records in one subgroup than its active count");
    }
    let leads = leader_member
        && if mask == 0 {
            records[leader].lane >= 32
        } else {
            records[leader].lane == mask.trailing_zeros()
        };
    if !leads {
        return Some("the leader is not the lowest set lane of the subgroup's active mask");
    }
    None
}

/// Why a pixel's subgroup's records contradict each other, and which kind of contradiction it is
/// (`model::lanes::Contradicted`: garbage, or a leader word naming a pixel outside the call).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Contradiction {
    pub kind: Contradicted,
    /// The check that failed, in words ([`subgroup_contradiction`]'s, or the leader rule's).
    pub why: &'static str,
    /// Lane 0 was active in this pixel's call (bit 0 of its ballot).
    pub lane0_active: bool,
    /// The pixel its leader word names carries lane words of its own, and they say lane 0 (on
    /// lavapipe 26's closest-hit it is a miss pixel, without them: not known to be lane 0).
    pub named_lane0: bool,
    /// The pixel its leader word names.
    pub named: usize,
}

/// The leader rule, as a pixel whose call's leader word names a pixel outside the call fails it.
pub const LEADER_RULE: &str = "the leader is not the lowest set lane of the subgroup's active mask";

/// Where the records sharing `leader` (`group`) fail [`subgroup_contradiction`] only because the
/// leader word of some call names a pixel outside it: per member (in `group`'s order), its kind.
/// The members split into calls by their mask and count; each call's records must agree among
/// themselves (distinct lanes, each inside the call's mask, no more records than its count); the
/// call holding the leader's pixel (if any) must be led by its lowest set lane; every other call
/// must not count the leader's lane (`leader_lane`, where its record carries lane words) among
/// its active lanes; and at least two records outside the leader's call must name it (a lone
/// one is what a random leader word gives). Then `subgroupBroadcastFirst` handed those calls the value of a lane that
/// was not active in them (lavapipe 26's closest-hit: lane 0's pixel where lane 0 was not in the
/// call), and the leader's own call merely shares the key. Anything else is garbage: `None`.
fn leader_outside(
    records: &[Record],
    leader: usize,
    leader_lane: Option<u32>,
    group: &[usize],
) -> Option<Vec<Contradicted>> {
    let mut calls: Vec<(u32, u32, Vec<usize>)> = Vec::new();
    for &q in group {
        let key = (records[q].active_mask, records[q].active_count);
        match calls.iter_mut().find(|c| (c.0, c.1) == key) {
            Some(c) => c.2.push(q),
            None => calls.push((key.0, key.1, vec![q])),
        }
    }
    let mut outside = false;
    for (mask, count, members) in &calls {
        let mut seen = std::collections::HashSet::new();
        let agree = *mask != 0
            && members.len() <= *count as usize
            && members.iter().all(|&q| {
                let lane = records[q].lane;
                seen.insert(lane) && (lane >= 32 || mask & (1 << lane) != 0)
            });
        let led = if members.contains(&leader) {
            records[leader].lane == mask.trailing_zeros()
        } else {
            outside = true;
            leader_lane.is_none_or(|k| k >= 32 || mask & (1 << k) == 0)
        };
        if !agree || !led {
            return None;
        }
    }
    let own = |q: usize| calls.iter().any(|c| c.2.contains(&leader) && c.2.contains(&q));
    // A lone record naming a pixel outside its call is what a random leader word gives: at least
    // two records outside the leader's call must name it.
    if group.iter().filter(|&&q| !own(q)).count() < 2 {
        return None;
    }
    outside.then(|| {
        group
            .iter()
            .map(
                |&q| {
                    if own(q) {
                        Contradicted::LeaderOwnCall
                    } else {
                        Contradicted::LeaderOutsideCall
                    }
                },
            )
            .collect()
    })
}

/// Whether the cross-record checks of [`subgroup_contradiction`] hold in `stage`: where each
/// pixel's record comes from one call of it ([`one_call_per_pixel`]) and the pixel a leader names
/// is that leader's own. Not in fragment shaders, where a helper invocation (no record of its
/// own) or a fragment of another primitive whose record then holds that pixel may lead a
/// subgroup; the NVIDIA H200 (580.159.04) led 28 of the 128 subgroups of a fragment probe so, and
/// records keyed by the leader pixel are not one subgroup instance there. Elsewhere a leader that
/// ran no probe (e.g. lavapipe 26's closest-hit under forced evidence: lane 0's pixel, a miss,
/// named by every lane of a call lane 0 was not in) is a contradiction.
fn cross_checked(stage: Stage) -> bool {
    one_call_per_pixel(stage) && stage != Stage::Fragment
}

/// Per pixel: why its subgroup's records contradict each other ([`subgroup_contradiction`]) and
/// of which kind ([`leader_outside`], else garbage), checked where [`cross_checked`] says the
/// checks hold.
pub fn contradictions(records: &[Record], stage: Stage) -> Vec<Option<Contradiction>> {
    let leader = leaders(records);
    contradicted(records, stage, &leader, &Members::of(&leader))
}

/// [`contradictions`] over subgroups already grouped (`leader` as [`leaders`] gave it).
fn contradicted(
    records: &[Record],
    stage: Stage,
    leader: &[Option<usize>],
    members: &Members,
) -> Vec<Option<Contradiction>> {
    let mut out = vec![None; records.len()];
    if !cross_checked(stage) {
        return out;
    }
    for (l, group) in members.groups() {
        let Some(why) = subgroup_contradiction(records, l, group) else { continue };
        let leader_lane = leader.get(l).copied().flatten().map(|_| records[l].lane);
        let kinds = leader_outside(records, l, leader_lane, group)
            .unwrap_or_else(|| vec![Contradicted::Garbage; group.len()]);
        for (&q, kind) in group.iter().zip(kinds) {
            let why = match kind {
                Contradicted::Garbage => why,
                Contradicted::LeaderOutsideCall | Contradicted::LeaderOwnCall => LEADER_RULE,
            };
            out[q] = Some(Contradiction {
                kind,
                why,
                lane0_active: records[q].active_mask & 1 != 0,
                named_lane0: leader_lane == Some(0),
                named: l,
            });
        }
    }
    out
}

/// Subgroup membership from a cell's records.
#[derive(Clone, Debug, Default)]
pub struct Lanes {
    /// Per pixel: its leader pixel, where its record carries consistent lane evidence and its
    /// subgroup's records do not contradict each other.
    leader: Vec<Option<usize>>,
    /// The pixels with a leader, by leader (see `Members`); a contradicted subgroup's pixels
    /// stay in it, but no pixel names its leader any more.
    order: Vec<usize>,
    /// Per leader pixel: where its members lie in `order` when the records show all of its
    /// subgroup (`None` otherwise).
    whole: Vec<Option<(usize, usize)>>,
    /// Per pixel: why its subgroup's records contradict each other ([`contradictions`]).
    contradicted: Vec<Option<Contradiction>>,
    /// The evidence may be judged by (`LaneEvidence::Supported`): undefined reads per subgroup,
    /// uniform subgroups exactly, contradictions as mismatches. Otherwise (forced evidence) it
    /// only splits a mismatch for the diagnosis.
    pub judged: bool,
}

impl Lanes {
    /// [`Lanes::for_stage`] of a stage that runs once per pixel (raygen).
    pub fn from_records(records: &[Record]) -> Lanes {
        Lanes::for_stage(records, Stage::Raygen)
    }

    /// Read the lane evidence of every probe record of a cell probing `stage` (`FLAG_PROBE` and
    /// `FLAG_LANES` set, lane words consistent, the subgroup's records not contradicting each
    /// other): the records grouped by leader once, each subgroup checked and, when its records
    /// show all of it, kept whole.
    pub fn for_stage(records: &[Record], stage: Stage) -> Lanes {
        let mut leader = leaders(records);
        let members = Members::of(&leader);
        let contradicted = contradicted(records, stage, &leader, &members);
        let mut whole = vec![None; records.len()];
        for (l, m) in members.groups() {
            if contradicted[m[0]].is_some() {
                continue;
            }
            let first = &records[m[0]];
            let all = m.len() == first.active_count as usize
                && m.contains(&l)
                && m.iter().all(|&q| {
                    records[q].active_count == first.active_count
                        && records[q].active_mask == first.active_mask
                });
            if all {
                whole[l] = Some((members.start[l], members.start[l + 1]));
            }
        }
        for (l, c) in leader.iter_mut().zip(&contradicted) {
            if c.is_some() {
                *l = None;
            }
        }
        Lanes { leader, order: members.order, whole, contradicted, judged: true }
    }

    /// This evidence, judged by only where `judged` (see [`Lanes::judged`]).
    pub fn judged_by(self, judged: bool) -> Lanes {
        Lanes { judged, ..self }
    }

    /// Why pixel `p`'s subgroup's records contradict each other, if they do.
    pub fn contradiction(&self, p: usize) -> Option<Contradiction> {
        self.contradicted.get(p).copied().flatten()
    }

    /// The pixels that ran in the same subgroup instance of the probed stage's call as pixel `p`
    /// (`p` included, in pixel order), when the records show the whole subgroup.
    pub fn subgroup(&self, p: usize) -> Option<&[usize]> {
        let l = (*self.leader.get(p)?)?;
        let (a, b) = self.whole[l]?;
        Some(&self.order[a..b])
    }

    /// Every subgroup the records show whole: its leader pixel and its members (in pixel order).
    pub fn subgroups(&self) -> impl Iterator<Item = (usize, &[usize])> {
        self.whole.iter().enumerate().filter_map(|(l, w)| w.map(|(a, b)| (l, &self.order[a..b])))
    }

    /// The pixel of the first active lane of `p`'s subgroup (its leader): the lane whose index
    /// `subgroupBroadcastFirst` hands every lane. `None` where `p` carries no lane evidence.
    pub fn leader(&self, p: usize) -> Option<usize> {
        *self.leader.get(p)?
    }

    /// Pixels whose subgroup the records show whole.
    pub fn known(&self) -> usize {
        self.subgroups().map(|(_, m)| m.len()).sum()
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

    /// Eight pixels in one subgroup of lanes 1, 2, 5, 6 (lane 0 inactive), led by pixel 0.
    fn group() -> Vec<Record> {
        let mask = 0b0110_0110;
        vec![rec(1, 0, mask), rec(2, 0, mask), rec(5, 0, mask), rec(6, 0, mask)]
    }

    /// Twins of the cross-record checks: each planted fault makes the whole subgroup a
    /// contradiction, unknown as a subgroup and without a leader.
    #[test]
    fn records_of_one_subgroup_must_agree_with_each_other() {
        let good = group();
        assert_eq!(contradictions(&good, Stage::ClosestHit), vec![None; 4]);
        let lanes = Lanes::for_stage(&good, Stage::ClosestHit);
        assert_eq!(
            (lanes.subgroup(1).map(<[usize]>::len), lanes.contradiction(1)),
            (Some(4), None)
        );
        let wrong_leader: Vec<Record> = good.iter().map(|r| Record { leader: 1, ..*r }).collect();
        let mut duplicate = good.clone();
        duplicate[2].lane = 2;
        let mut outside = good.clone();
        outside[3] = Record { lane: 3, active_mask: 0b0110_1110, active_count: 5, ..outside[3] };
        let mut mask_differs = good.clone();
        mask_differs[3].active_mask = 0b0110_0110 | 1 << 9;
        mask_differs[3].active_count = 5;
        let planted = [
            (wrong_leader, "the leader is not the lowest set lane"),
            (duplicate, "claim the same lane"),
            (outside, "a lane outside"),
            (mask_differs, "disagree on the active mask"),
        ];
        for (records, why) in planted {
            // each record is consistent on its own: only the cross-record check sees the fault
            assert!(records.iter().all(|r| inconsistency(r, 4).is_none()), "{why}");
            let c = contradictions(&records, Stage::ClosestHit);
            let garbage = |w: &Option<Contradiction>| {
                w.is_some_and(|w| w.why.contains(why) && w.kind == Contradicted::Garbage)
            };
            assert!(c.iter().all(garbage), "{why}: {c:?}");
            let lanes = Lanes::for_stage(&records, Stage::ClosestHit);
            assert_eq!(
                (lanes.subgroup(0), lanes.leader(0), lanes.known()),
                (None, None, 0),
                "{why}"
            );
            // in any-hit a pixel's record may come from another call, in fragment shaders the
            // leader's pixel from another primitive: not checked there
            assert_eq!(contradictions(&records, Stage::AnyHit), vec![None; 4], "{why}");
            assert_eq!(contradictions(&records, Stage::Fragment), vec![None; 4], "{why}");
        }
        // lavapipe 26's closest-hit (forced evidence): lanes 1, 2, 5, 6 active, and every one
        // names pixel 8, lane 0's, which ran no probe (no record): a contradiction there, but
        // not in a fragment shader, where a helper invocation may lead and write no record.
        let mut lane0 = good.clone();
        lane0.extend(std::iter::repeat_n(Record::default(), 5));
        for r in &mut lane0[..4] {
            r.leader = 8;
        }
        let c = contradictions(&lane0, Stage::ClosestHit);
        let outside = |w: &Option<Contradiction>| {
            w.is_some_and(|w| w.why == LEADER_RULE && w.kind == Contradicted::LeaderOutsideCall)
        };
        assert!(c[..4].iter().all(outside), "{c:?}");
        // pixel 8 carries no lane words: not known to be lane 0
        assert!(c[..4].iter().all(|w| w.is_some_and(|w| !w.named_lane0)), "{c:?}");
        assert_eq!(contradictions(&lane0, Stage::Fragment), vec![None; 9]);
    }

    /// A random leader word: each record of the call names a different pixel outside it, so no
    /// two records name one leader. That is garbage, not a leader outside the call; the twin,
    /// two records of the call naming the same outside pixel, is of that kind.
    #[test]
    fn a_random_leader_word_is_garbage() {
        let mut records = group();
        records.extend(std::iter::repeat_n(Record::default(), 5));
        for (k, r) in records[..4].iter_mut().enumerate() {
            r.leader = [8, 5, 7, 6][k];
        }
        let c = contradictions(&records, Stage::ClosestHit);
        assert!(c[..4].iter().all(|w| w.is_some_and(|w| w.kind == Contradicted::Garbage)), "{c:?}");
        records[1].leader = 8;
        let c = contradictions(&records, Stage::ClosestHit);
        let kind = |p: usize| c[p].map(|w| w.kind);
        assert_eq!(
            (kind(0), kind(1), kind(2), kind(3)),
            (
                Some(Contradicted::LeaderOutsideCall),
                Some(Contradicted::LeaderOutsideCall),
                Some(Contradicted::Garbage),
                Some(Contradicted::Garbage)
            ),
            "{c:?}"
        );
    }

    /// A call without lane 0 whose lanes all name lane 0's pixel, which ran the probe in another
    /// call (lanes 0, 3 active): the cross-record check fails, of the leader-outside-the-call kind
    /// (what lavapipe 26's closest-hit records show), and lane 0's own call only shares the key.
    /// Twins: a duplicate lane in the call, or a leader that is an active lane of the call, make
    /// it garbage again.
    #[test]
    fn a_leader_outside_the_call_is_told_from_garbage() {
        let mut records = group();
        for r in &mut records {
            r.leader = 4;
        }
        records.push(rec(0, 4, 0b1001));
        records.push(rec(3, 4, 0b1001));
        let c = contradictions(&records, Stage::ClosestHit);
        let kinds: Vec<_> = c.iter().map(|w| w.map(|w| (w.kind, w.lane0_active))).collect();
        let (out, own) = (Contradicted::LeaderOutsideCall, Contradicted::LeaderOwnCall);
        assert_eq!(
            kinds,
            [[Some((out, false)); 4].as_slice(), &[Some((own, true)); 2]].concat(),
            "{c:?}"
        );
        assert!(c.iter().all(|w| w.is_some_and(|w| w.why == LEADER_RULE)));
        // pixel 4's own record says lane 0: the leader word names lane 0's pixel
        assert!(c.iter().all(|w| w.is_some_and(|w| w.named_lane0)), "{c:?}");
        let lanes = Lanes::for_stage(&records, Stage::ClosestHit);
        assert_eq!((lanes.leader(0), lanes.leader(4), lanes.known()), (None, None, 0));
        let mut duplicate = records.clone();
        duplicate[2].lane = 1;
        let mut active = records.clone();
        // the leader's call is lanes 1, 3, led by lane 1: an active lane of the other call too
        (active[4], active[5]) = (rec(1, 4, 0b1010), rec(3, 4, 0b1010));
        for (name, bad) in [("duplicate", duplicate), ("leader active in the call", active)] {
            let c = contradictions(&bad, Stage::ClosestHit);
            assert!(
                c.iter().all(|w| w.is_some_and(|w| w.kind == Contradicted::Garbage)),
                "{name}: {c:?}"
            );
        }
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
