//! The reference run with a mutant's mutation (`run --mutants`): which slot, sampler, packed
//! element or value the mutated probe reads ([`Mutation`], built from the site `mutants::site`
//! resolved, with the same index arithmetic as the SPIR-V rewrite: `mutants::index`), and what
//! that predicts against the cell's own expectation ([`predict`]): on how many checked pixels the
//! records differ (none: the mutant is *equivalent*, not applicable to the cell) and on how many
//! of them the cell's comparison must flag it (the rest its lenient rule allows).
//!
//! `index-broadcast` reads, on each pixel, the slot the first active lane of its subgroup
//! computed: which lane that was is known only from the device's own lane evidence (the
//! records' `leader`), so its prediction is made after the run ([`leader_slots`]; the reference's
//! `mutant_after_run`); before the run (`mutant_before_run`) it is equivalent only where every
//! checked pixel computes the same slot ([`one_slot`]).
use super::compare::compare_with;
use super::lanes::Lanes;
use super::rules::Expected;
use crate::model::MutantPrediction;
use crate::mutants::{index, value, IndexFn, Mutation as Site};
use crate::probe::{Record, FLAG_PROBE};

/// A mutant's mutation as the reference applies it: the rewritten site, and for a broadcast the
/// slot each pixel's subgroup leader computed (`None`: unknown, the pixel's own).
#[derive(Clone, Debug)]
pub struct Mutation {
    pub site: Site,
    pub leader_slots: Vec<Option<u32>>,
}

impl Mutation {
    pub fn new(site: Site) -> Mutation {
        Mutation { site, leader_slots: vec![] }
    }

    /// The descriptor (or AS table entry) the mutated probe reads at pixel `p`, for an unmutated
    /// `read`; `masked`: the stage's dynamic value without its base (`custom & mask`).
    pub(super) fn read_slot(&self, read: u32, masked: u32, p: usize) -> u32 {
        let to = match self.site {
            Site::DescriptorIndex { to, .. } | Site::AddressIndex { to } => to,
            Site::PackedElement { .. }
            | Site::Layer
            | Site::SamplerIndex { .. }
            | Site::ValueBits => return read,
        };
        match to {
            IndexFn::Broadcast => self.leader_slots.get(p).copied().flatten().unwrap_or(read),
            IndexFn::DropBase => masked,
            IndexFn::Zero | IndexFn::Next(_) | IndexFn::Doubled(_) => {
                index::apply_fn(to, read).unwrap_or(read)
            }
        }
    }

    /// The sampler heap index the mutated probe samples with, for an unmutated `sampler`.
    pub(super) fn sampler(&self, sampler: u32) -> u32 {
        match self.site {
            Site::SamplerIndex { to } => index::apply_fn(to, sampler).unwrap_or(sampler),
            Site::DescriptorIndex { .. }
            | Site::AddressIndex { .. }
            | Site::PackedElement { .. }
            | Site::Layer
            | Site::ValueBits => sampler,
        }
    }

    /// The (slot, element) whose value a packed read returns, for an unmutated (`slot`,
    /// `element`): element 0 of the packed buffer holds slot 0's element 0; layer 0 of the array
    /// texture holds slot 0's texels.
    pub(super) fn packed(&self, slot: u32, element: u32) -> (u32, u32) {
        match self.site {
            Site::PackedElement { .. } => (0, 0),
            Site::Layer => (0, element),
            Site::DescriptorIndex { .. }
            | Site::AddressIndex { .. }
            | Site::SamplerIndex { .. }
            | Site::ValueBits => (slot, element),
        }
    }

    /// The value the mutated probe stores, for an unmutated `v`.
    pub(super) fn value(&self, v: [f32; 4]) -> [f32; 4] {
        match self.site {
            Site::ValueBits => [v[0], v[1], v[2], value::flip(v[3])],
            Site::DescriptorIndex { .. }
            | Site::AddressIndex { .. }
            | Site::SamplerIndex { .. }
            | Site::PackedElement { .. }
            | Site::Layer => v,
        }
    }
}

/// The descriptor index pixel `p`'s probe selects with, as a broadcast hands it on: a texture
/// cell's texture element where its hit's material has a texture (`None` without: that lane
/// takes the untextured branch and reads no texture), else the slot (`None`: no probe).
pub fn selecting_index(e: &Expected, textures: bool) -> Option<u32> {
    if e.record.flags & FLAG_PROBE == 0 {
        return None;
    }
    if !textures {
        return Some(e.record.slot);
    }
    let element = e.record.value[2];
    (element >= 0.0).then_some(element as u32)
}

/// Per pixel, the index its subgroup's first active lane computed (what `subgroupBroadcastFirst`
/// of the index hands every lane), read from the device's lane evidence (`lanes`, from the
/// device's `records`). Where the index is read on every probe lane (`textures` false) that is
/// the slot of the pixel's leader (where its record carries consistent evidence and its leader
/// is a probe pixel). A texture cell reads its texture inside the branch its textured lanes
/// take (`scene::textures::BODY`), so there the first active lane is the textured member of the
/// pixel's subgroup with the lowest lane, known only where the records show the whole subgroup.
pub fn leader_slots(
    expected: &[Expected],
    (records, lanes): (&[Record], &Lanes),
    textures: bool,
) -> Vec<Option<u32>> {
    (0..expected.len())
        .map(|p| {
            if !textures {
                let leader = expected.get(lanes.leader(p)?)?;
                return (leader.record.flags & FLAG_PROBE != 0).then_some(leader.record.slot);
            }
            selecting_index(expected.get(p)?, true)?;
            let first = lanes
                .subgroup(p)?
                .iter()
                .filter(|&&q| selecting_index(&expected[q], true).is_some())
                .min_by_key(|&&q| records.get(q).map_or(u32::MAX, |r| r.lane))?;
            selecting_index(&expected[*first], true)
        })
        .collect()
}

/// `mutated` against `expected`: the checked pixels whose records differ, and those the
/// comparison flags, judged as the cell is (`lanes`: the device's subgroups where its evidence
/// may be judged by). The mutated records take the device's lane words (`device`), so that only
/// the mutation can make a difference.
pub fn predict(
    expected: &[Expected],
    mutated: &[Expected],
    (device, lanes): (Option<&[Record]>, Option<&Lanes>),
    width: u32,
) -> MutantPrediction {
    let records: Vec<Record> = mutated
        .iter()
        .enumerate()
        .map(|(p, m)| match device.and_then(|d| d.get(p)) {
            Some(d) => Record {
                lane: d.lane,
                leader: d.leader,
                active_mask: d.active_mask,
                active_count: d.active_count,
                ..m.record
            },
            None => m.record,
        })
        .collect();
    let differing = expected
        .iter()
        .zip(mutated)
        .filter(|(e, m)| !e.ambiguous && !m.ambiguous && e.record != m.record)
        .count();
    let cmp = compare_with(expected, &records, width, lanes);
    // value mismatches of pixels the heuristic judged (a mutant changes only the value)
    let caught_by_heuristic =
        cmp.element_reads.as_ref().map_or(0, |r| r.neither.saturating_sub(r.uniform_mismatched));
    MutantPrediction {
        differing,
        caught: cmp.mismatched_pixels,
        caught_by_heuristic,
        from_lanes: false,
    }
}

/// Whether `site` is a broadcast (its prediction needs the device's lane evidence).
pub fn broadcast(site: Site) -> bool {
    matches!(
        site,
        Site::DescriptorIndex { to: IndexFn::Broadcast, .. }
            | Site::AddressIndex { to: IndexFn::Broadcast }
    )
}

/// A broadcast's prediction before the run: every checked probe pixel whose selecting index
/// ([`selecting_index`]) is not the first one's may read another descriptor (0: all compute the
/// same index, the broadcast is equivalent: the scene's data cannot discriminate it).
pub fn one_slot(expected: &[Expected], textures: bool) -> MutantPrediction {
    let mut slots =
        expected.iter().filter(|e| !e.ambiguous).filter_map(|e| selecting_index(e, textures));
    let first = slots.next();
    let differing = slots.filter(|s| Some(*s) != first).count();
    MutantPrediction { differing, caught: differing, caught_by_heuristic: 0, from_lanes: true }
}

#[cfg(test)]
mod tests;
