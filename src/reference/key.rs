//! What a cell's expected records depend on besides the scene ([`ExpectedKey`]): the fields of
//! its probe spec the reference reads, what is undefined, and whether the records carry lane
//! words. Cells with equal keys have identical expected records, so a caller judging cell after
//! cell keeps the last cell's (`ExpectedMemo`; the plan's descriptor-model siblings are
//! neighbours and share them) instead of computing them again.
use super::rules::Undefined;
use crate::model::{Cell, LaneEvidence, Resource, SceneLayout, Stage};
use crate::probe::spec::{Base, ElementMap, ProbeSpec, ReadIndex, Sampler, SlotSource};

/// The inputs of [`super::expected_into`] and [`super::expect_lanes`] apart from the scene.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ExpectedKey {
    stage: Stage,
    resource: Resource,
    slot: SlotSource,
    read: ReadIndex,
    element: ElementMap,
    base: Base,
    sampler: Sampler,
    layout: Option<SceneLayout>,
    undefined: Undefined,
    lanes: bool,
}

impl ExpectedKey {
    /// The key of `cell` judged as `undefined` says, with lane evidence `lanes`. Every field of
    /// the spec is named: one the reference starts to read must join the key.
    pub fn of(cell: &Cell, undefined: Undefined, lanes: LaneEvidence) -> ExpectedKey {
        let ProbeSpec {
            stage,
            resource,
            slot,
            read,
            element,
            base,
            sampler,
            // a scene-layout cell records the hit triangle's own data
            layout,
            // how the descriptor reaches the shader, never what it reads or where
            model: _,
            heap: _,
            access: _,
            array: _,
            addresses: _,
            reorder: _,
            // a canary's records are never compared; a workaround changes the modules, not
            // what the probe must record
            canary: _,
            workarounds: _,
            // a mutant is judged against the unmutated probe's records (`mutation`)
            mutant: _,
        } = ProbeSpec::of(cell);
        let lanes = lanes.recorded();
        ExpectedKey {
            stage,
            resource,
            slot,
            read,
            element,
            base,
            sampler,
            layout,
            undefined,
            lanes,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::{Expected, ExpectedMemo, SceneReference};
    use super::*;
    use crate::model::SceneParams;
    use crate::probe::spec::ProbeSpec;
    use crate::scene::Scene;

    fn same(a: &[Expected], b: &[Expected]) -> bool {
        a.len() == b.len()
            && a.iter().zip(b).all(|(x, y)| {
                (x.record, x.ambiguous, x.rule, x.discriminating)
                    == (y.record, y.ambiguous, y.rule, y.discriminating)
            })
    }

    /// Over every planned cell, as the driver saw it and with its read undefined, with and
    /// without lane words: cells with equal keys have identical expected records, so the memo
    /// never hands a cell another's. Twins: cells differing only in what is undefined, or in a
    /// read the key names, have different records and different keys.
    #[test]
    fn equal_keys_mean_equal_expected_records() {
        let scene = Scene::build(&SceneParams::default());
        let sref = SceneReference::compute(&scene);
        let (cells, _) = crate::matrix::plan::all_cells();
        let expected = |c: &Cell, undefined, lanes| {
            let mut e = Vec::new();
            super::super::expected_into(&mut e, c, (&scene, &sref), undefined);
            super::super::expect_lanes(&mut e, lanes);
            e
        };
        // each key's first cell (its records computed again at each match: holding every key's
        // records would take a gigabyte)
        let mut kept: Vec<(ExpectedKey, &Cell)> = Vec::new();
        let mut shared = 0;
        for c in &cells {
            let spec_undefined = ProbeSpec::of(c).read == ReadIndex::Undefined;
            for (descriptor, lanes) in
                [(spec_undefined, LaneEvidence::Absent), (true, LaneEvidence::Supported)]
            {
                let undefined = Undefined { descriptor };
                let key = ExpectedKey::of(c, undefined, lanes);
                match kept.iter().find(|(k, _)| *k == key) {
                    Some((_, first)) => {
                        let (a, b) =
                            (expected(first, undefined, lanes), expected(c, undefined, lanes));
                        assert!(
                            same(&a, &b),
                            "{} and {}: same key, other records",
                            first.id(),
                            c.id()
                        );
                        shared += 1;
                    }
                    None => kept.push((key, c)),
                }
            }
        }
        assert!(shared > cells.len() / 2, "descriptor-model siblings share keys: {shared}");
        // different keys: records differ where the key's fields do
        let c = cells.iter().find(|c| ProbeSpec::of(c).read == ReadIndex::Defined).unwrap();
        let (defined, undefined) =
            (Undefined { descriptor: false }, Undefined { descriptor: true });
        let a = ExpectedKey::of(c, defined, LaneEvidence::Absent);
        let b = ExpectedKey::of(c, undefined, LaneEvidence::Absent);
        assert_ne!(a, b);
        let (e, x) = (
            expected(c, defined, LaneEvidence::Absent),
            expected(c, undefined, LaneEvidence::Absent),
        );
        assert!(!same(&e, &x), "{}: undefined changes the rule", c.id());
    }

    /// The memo computes again when the key changes and keeps the records when it does not.
    #[test]
    fn the_memo_follows_the_key() {
        let scene = Scene::build(&SceneParams::default());
        let sref = SceneReference::compute(&scene);
        let (cells, _) = crate::matrix::plan::all_cells();
        let none = Undefined::default();
        let fresh = |c: &Cell| {
            let mut e = Vec::new();
            super::super::expected_into(&mut e, c, (&scene, &sref), none);
            e
        };
        let key = |c: &Cell| ExpectedKey::of(c, none, LaneEvidence::Absent);
        let a = &cells[0];
        let b = cells.iter().find(|c| !same(&fresh(c), &fresh(a))).unwrap();
        let twin = cells.iter().find(|c| c.id() != a.id() && key(c) == key(a)).unwrap();
        let mut memo = ExpectedMemo::default();
        for (c, want) in [(a, a), (twin, a), (b, b), (a, a)] {
            let got = memo.get(c, (&scene, &sref), none, LaneEvidence::Absent).to_vec();
            assert!(same(&got, &fresh(want)), "{} after the previous cell", c.id());
        }
        // lane words change the key (the records carry FLAG_LANES)
        let lanes = memo.get(a, (&scene, &sref), none, LaneEvidence::Supported).to_vec();
        assert!(!same(&lanes, &fresh(a)));
    }
}
