//! A cell's records against the reference's: per pixel the hit fields within their tolerances
//! (`T_REL_TOL`, `BARY_TOL`) and the probed value by its rule, with counts, worst errors, the
//! own/other/neither reads of an undefined index (judged by the other-lane heuristic against the
//! slots [`OtherLanes`] names), and the first mismatches as examples.
use super::lanes::Lanes;
use super::rules::{Expected, ValueRule, BARY_TOL, T_REL_TOL};
use crate::model::{
    Comparison, ElementReads, LaneSplit, Mismatch, NO_NONUNIFORM_VUID, OTHER_LANE_HEURISTIC,
};
use crate::probe::{Record, FLAG_HIT, FLAG_LANES, FLAG_LAYOUT, FLAG_PROBE};

/// The larger error, NaN when either is NaN (`f64::max` would drop it).
fn worst(acc: f64, e: f64) -> f64 {
    if acc.is_nan() || e.is_nan() {
        f64::NAN
    } else {
        acc.max(e)
    }
}

type Bad = Vec<(&'static str, String, String)>;

/// Integer and float fields a flag says were not written: their exact bits.
fn unset_fields_differ(bad: &mut Bad, fields: &[(&'static str, u32, u32)]) {
    for &(name, e, a) in fields {
        if e != a {
            bad.push((name, format!("{e:#x}"), format!("{a:#x}")));
        }
    }
}

fn compare_hit(c: &mut Comparison, bad: &mut Bad, r: &Record, a: &Record) {
    for (name, e, g) in [
        ("custom", r.custom, a.custom),
        ("instance_id", r.instance_id, a.instance_id),
        ("geometry", r.geometry, a.geometry),
        ("primitive", r.primitive, a.primitive),
    ] {
        if e != g {
            bad.push((name, e.to_string(), g.to_string()));
        }
    }
    let te = ((a.t as f64 - r.t as f64) / (r.t as f64).abs().max(1.0)).abs();
    c.worst_t_rel = worst(c.worst_t_rel, te);
    if te.is_nan() || te > T_REL_TOL {
        bad.push(("t", r.t.to_string(), a.t.to_string()));
    }
    let be = (0..2).map(|k| (a.bary[k] as f64 - r.bary[k] as f64).abs()).fold(0.0, worst);
    c.worst_bary = worst(c.worst_bary, be);
    if be.is_nan() || be > BARY_TOL {
        bad.push(("bary", format!("{:?}", r.bary), format!("{:?}", a.bary)));
    }
}

/// The lane words: consistent where the probe measured them (`FLAG_LANES`), else all zero.
/// `words`: [`LaneWords::of`] the actual record.
fn compare_lanes(bad: &mut Bad, r: &Record, a: &Record, words: LaneWords) {
    if r.flags & FLAG_LANES != 0 {
        if let LaneWords::Inconsistent(why) = words {
            let words = format!(
                "lane {} leader {} mask {:#x} count {}",
                a.lane, a.leader, a.active_mask, a.active_count
            );
            bad.push(("lanes", format!("consistent lane words ({why})"), words));
        }
    } else {
        unset_fields_differ(
            bad,
            &[
                ("lanes", 0, a.lane),
                ("lanes", 0, a.leader),
                ("lanes", 0, a.active_mask),
                ("lanes", 0, a.active_count),
            ],
        );
    }
}

/// What an expected record's lane words ask of the actual one, checked once per pixel (the
/// comparison and the lane split both need it).
#[derive(Clone, Copy)]
enum LaneWords {
    /// The expected record carries no lane words (`FLAG_LANES` clear).
    Absent,
    Consistent,
    /// [`super::lanes::inconsistency`]'s reason.
    Inconsistent(&'static str),
}

impl LaneWords {
    fn of(r: &Record, a: &Record, pixels: usize) -> LaneWords {
        if r.flags & FLAG_LANES == 0 {
            return LaneWords::Absent;
        }
        match super::lanes::inconsistency(a, pixels) {
            Some(why) => LaneWords::Inconsistent(why),
            None => LaneWords::Consistent,
        }
    }
}

/// The descriptor indices other lanes computed, for the other-lane heuristic of undefined reads:
/// each probe pixel's expected slot (and, where its hit is ambiguous, the slot it recorded: it may
/// have hit the other surface), per subgroup where the device's lane evidence shows the whole
/// subgroup, else over the whole dispatch. Each subgroup's slots are gathered once, when the cell
/// has an undefined read at all, into one vector (no allocation per pixel or per subgroup).
struct OtherLanes<'a> {
    lanes: Option<&'a Lanes>,
    dispatch: Vec<u32>,
    /// Per leader pixel of a subgroup the records show whole: how its reads are judged.
    by_leader: Vec<Option<Group>>,
    /// The slots of every such subgroup, each subgroup's sorted and deduplicated, end to end.
    slots: Vec<u32>,
}

/// One whole subgroup's judgement: whether it is proven uniform, and where its slots lie in
/// `OtherLanes::slots`.
#[derive(Clone, Copy)]
struct Group {
    uniform: bool,
    slots: (usize, usize),
}

impl<'a> OtherLanes<'a> {
    fn new(expected: &'a [Expected], actual: &'a [Record], lanes: Option<&'a Lanes>) -> Self {
        let lenient = expected.iter().any(|e| e.rule != ValueRule::Exact);
        let mut dispatch: Vec<u32> = if lenient {
            (0..expected.len()).flat_map(|q| Self::computed(expected, actual, q)).collect()
        } else {
            vec![]
        };
        dispatch.sort_unstable();
        dispatch.dedup();
        let mut others = OtherLanes { lanes, dispatch, by_leader: vec![], slots: vec![] };
        if let Some(l) = lanes.filter(|_| lenient) {
            others.gather(expected, actual, l);
        }
        others
    }

    /// Every whole subgroup's slots: those its lanes computed ([`OtherLanes::computed`]) and
    /// those its probe records hold; uniform where it has two lanes or more and one slot.
    fn gather(&mut self, expected: &[Expected], actual: &[Record], lanes: &Lanes) {
        let mut scratch: Vec<u32> = Vec::new();
        for (leader, group) in lanes.subgroups() {
            scratch.clear();
            scratch.extend(group.iter().flat_map(|&q| Self::computed(expected, actual, q)));
            let recorded = group.iter().map(|&q| &actual[q]);
            scratch.extend(recorded.filter(|a| a.flags & FLAG_PROBE != 0).map(|a| a.slot));
            scratch.sort_unstable();
            scratch.dedup();
            let start = self.slots.len();
            self.slots.extend_from_slice(&scratch);
            let uniform = group.len() >= 2 && scratch.len() == 1;
            if self.by_leader.len() <= leader {
                self.by_leader.resize(leader + 1, None);
            }
            self.by_leader[leader] = Some(Group { uniform, slots: (start, self.slots.len()) });
        }
    }

    /// The slots lane `q` computed: its expected slot where the probe runs there, and its
    /// recorded one too where its hit is ambiguous.
    fn computed(expected: &[Expected], actual: &[Record], q: usize) -> impl Iterator<Item = u32> {
        let e = &expected[q];
        let probe = e.record.flags & FLAG_PROBE != 0;
        let recorded = (e.ambiguous && actual[q].flags & FLAG_PROBE != 0).then(|| actual[q].slot);
        probe.then_some(e.record.slot).into_iter().chain(recorded)
    }

    /// How pixel `p`'s undefined read is judged: exactly where its subgroup is proven uniform,
    /// else against the slots its subgroup's lanes (or the dispatch's) computed.
    fn of(&self, p: usize) -> Judged<'_> {
        // (a pixel's leader has a group here exactly where `Lanes::subgroup` shows it whole)
        let leader = self.lanes.and_then(|l| l.leader(p));
        let group = leader.and_then(|l| self.by_leader.get(l).copied().flatten());
        match group {
            None => Judged::Dispatch(&self.dispatch),
            Some(Group { uniform: true, .. }) => Judged::Uniform,
            Some(Group { slots: (a, b), .. }) => Judged::Subgroup(&self.slots[a..b]),
        }
    }
}

/// How an undefined read (a dynamic set/binding index without `NonUniform`, `ValueRule::
/// AnyElement`) is judged at one pixel.
enum Judged<'s> {
    /// Every active lane of its subgroup computed (and recorded) the same slot, and the subgroup
    /// has at least two active lanes, so its effective subgroup size is above 1: the resource is
    /// uniform within the subgroup, and `VUID-RuntimeSpirv-subgroupSize-10149` (Vulkan 1.4.360)
    /// asks for `NonUniform` only on a resource "not uniform within the invocation group, and not
    /// uniform within the subgroup". The read is defined: judged exactly. (A one-lane subgroup
    /// proves no subgroup size above 1, where `VUID-RuntimeSpirv-None-10148` asks for uniformity
    /// within the whole invocation group, which lane evidence cannot show.)
    Uniform,
    /// The slots the lanes of its subgroup computed (the heuristic, per subgroup).
    Subgroup(&'s [u32]),
    /// The slots any lane of the dispatch computed (the heuristic without lane evidence).
    Dispatch(&'s [u32]),
}

fn compare_probe(
    c: &mut Comparison,
    bad: &mut Bad,
    (e, a, p): (&Expected, &Record, usize),
    others: &OtherLanes,
) {
    let r = &e.record;
    for (name, x, g) in [("slot", r.slot, a.slot), ("element", r.element, a.element)] {
        if x != g {
            bad.push((name, x.to_string(), g.to_string()));
        }
    }
    // A scene-layout record's other two vertex indices.
    if r.flags & FLAG_LAYOUT != 0 {
        for (name, x, g) in [("pad", r.pad, a.pad), ("pad2", r.pad2, a.pad2)] {
            if x != g {
                bad.push((name, x.to_string(), g.to_string()));
            }
        }
    }
    let own = r.value == a.value;
    let judged = match e.rule {
        ValueRule::Exact => None,
        ValueRule::AnyElement { .. } => Some(others.of(p)),
    };
    let (slots, by_subgroup, uniform): (&[u32], bool, bool) = match judged {
        None => (&[], false, false),
        Some(Judged::Uniform) => (&[], true, true),
        Some(Judged::Subgroup(s)) => (s, true, false),
        Some(Judged::Dispatch(s)) => (s, false, false),
    };
    let allowed = !own && !uniform && e.rule.allows(a.value, slots.iter().copied());
    if !allowed {
        let ve =
            r.value.iter().zip(a.value).map(|(x, y)| (*x as f64 - y as f64).abs()).fold(0.0, worst);
        c.worst_value = worst(c.worst_value, ve);
    }
    match e.rule {
        ValueRule::Exact => {
            if e.discriminating {
                *c.discrimination.get_or_insert(0.0) += 1.0;
            } else {
                c.discrimination.get_or_insert(0.0);
            }
        }
        ValueRule::AnyElement { .. } => {
            let reads = c.element_reads.get_or_insert_with(|| ElementReads {
                outside_spec: NO_NONUNIFORM_VUID.into(),
                heuristic: OTHER_LANE_HEURISTIC.into(),
                ..Default::default()
            });
            if uniform {
                reads.uniform += 1;
                reads.uniform_mismatched += usize::from(!own);
            } else {
                c.any_element_values += 1;
                reads.by_subgroup += usize::from(by_subgroup);
            }
            match (own, allowed) {
                (true, _) => reads.own += 1,
                (false, true) => reads.other += 1,
                (false, false) => reads.neither += 1,
            }
        }
    }
    if !own && !allowed {
        bad.push(("value", format!("{:?}", r.value), format!("{:?}", a.value)));
    }
}

/// [`compare_with`] without lane evidence (undefined reads judged against the whole dispatch).
pub fn compare(expected: &[Expected], actual: &[Record], width: u32) -> Comparison {
    compare_with(expected, actual, width, None)
}

/// Compare the records; `lanes`: the device's subgroups read from the records. Where it may be
/// judged by (`Lanes::judged`) an undefined read may only read what a lane of its own subgroup
/// computed, a subgroup proven uniform is judged exactly, and a subgroup whose records contradict
/// each other is a mismatch on field `lanes` (garbage lane data). Where the records carry lane
/// evidence and some mismatch, `lanes` of the result splits the probe pixels by it, without the
/// contradicted subgroups (its `evidence` is for the caller to say).
pub fn compare_with(
    expected: &[Expected],
    actual: &[Record],
    width: u32,
    lanes: Option<&Lanes>,
) -> Comparison {
    let others = OtherLanes::new(expected, actual, lanes.filter(|l| l.judged));
    let mut c = Comparison { pixels: expected.len(), ..Default::default() };
    let mut exact_probe_pixels = 0usize;
    let mut split = LaneSplit::default();
    for (i, (e, a)) in expected.iter().zip(actual).enumerate() {
        if e.ambiguous {
            c.ambiguous += 1;
            continue;
        }
        c.compared += 1;
        let r = &e.record;
        if r.flags & FLAG_PROBE != 0 {
            c.probe_checked += 1;
            // (the denominator of the discrimination: exact pixels whose probe fields were read)
            exact_probe_pixels += usize::from(e.rule == ValueRule::Exact && r.flags == a.flags);
        }
        let words = LaneWords::of(r, a, expected.len());
        let mut bad = compare_pixel(&mut c, (e, a, i), &others, words);
        let contradiction = lanes.and_then(|l| Some((l.contradiction(i)?, l.judged)));
        c.lane_contradictions += usize::from(contradiction.is_some());
        if let Some((c, true)) = contradiction {
            bad.push((
                "lanes",
                "lane words consistent with their subgroup's records".into(),
                c.why.into(),
            ));
        }
        let lane_words = matches!(words, LaneWords::Consistent);
        match (lane_words, contradiction) {
            (true, None) => {
                split.add((a.lane, a.active_mask, a.leader as usize, i), !bad.is_empty())
            }
            (true, Some((c, _))) => split.add_contradicted(
                c.kind,
                (c.lane0_active, c.named_lane0, c.named),
                !bad.is_empty(),
            ),
            (false, _) => {}
        }
        if !bad.is_empty() {
            c.mismatched_pixels += 1;
            bad.dedup_by(|x, y| x.0 == y.0);
            for (field, exp, act) in bad {
                *c.by_field.entry(field.to_string()).or_default() += 1;
                if c.examples.len() < 8 {
                    let pixel = [i as u32 % width, i as u32 / width];
                    c.examples.push(Mismatch {
                        pixel,
                        field: field.into(),
                        expected: exp,
                        actual: act,
                    });
                }
            }
        }
    }
    if let Some(d) = c.discrimination.as_mut() {
        *d /= exact_probe_pixels as f64;
    }
    let split_any = !split.by_lane.is_empty() || split.contradicted.pixels > 0;
    c.lanes = (c.mismatched_pixels > 0 && split_any).then_some(split);
    c
}

/// One compared pixel's differing fields: flags, the hit's fields (or their zero bits), the lane
/// words, the probe's fields (or their zero bits).
fn compare_pixel(
    c: &mut Comparison,
    (e, a, i): (&Expected, &Record, usize),
    others: &OtherLanes,
    words: LaneWords,
) -> Bad {
    let r = &e.record;
    let mut bad: Bad = Vec::new();
    if r.flags != a.flags {
        bad.push(("flags", r.flags.to_string(), a.flags.to_string()));
        return bad;
    }
    if r.flags & FLAG_HIT != 0 {
        compare_hit(c, &mut bad, r, a);
    } else {
        unset_fields_differ(
            &mut bad,
            &[
                ("custom", r.custom, a.custom),
                ("instance_id", r.instance_id, a.instance_id),
                ("geometry", r.geometry, a.geometry),
                ("primitive", r.primitive, a.primitive),
                ("t", r.t.to_bits(), a.t.to_bits()),
                ("bary", r.bary[0].to_bits(), a.bary[0].to_bits()),
                ("bary", r.bary[1].to_bits(), a.bary[1].to_bits()),
            ],
        );
    }
    compare_lanes(&mut bad, r, a, words);
    if r.flags & FLAG_PROBE != 0 {
        compare_probe(c, &mut bad, (e, a, i), others);
    } else {
        let v = |k: usize| ("value", r.value[k].to_bits(), a.value[k].to_bits());
        let fields = [("slot", r.slot, a.slot), ("element", r.element, a.element)];
        unset_fields_differ(&mut bad, &fields);
        unset_fields_differ(&mut bad, &[v(0), v(1), v(2), v(3)]);
    }
    bad
}
