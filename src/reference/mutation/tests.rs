//! The reference's predictions for the scene-layout cells' mutants: a `per_mesh` cell's wrong
//! slot reads another mesh buffer's data (`scene::layout::read_mesh_words`), caught exactly; a
//! texture cell's broadcast reads the texture of the lowest textured lane of the pixel's
//! subgroup (the texture is read inside the textured branch); the twin: a scene whose every
//! entry samples one texture makes the broadcast undiscriminating (equivalent, never killed).
use crate::model::{
    Cell, DescriptorModel, IndexSource, LaneEvidence, Resource, SceneLayout, SceneParams, Stage,
};
use crate::mutants::{IndexFn, Mutation as Site};
use crate::probe::{Record, FLAG_PROBE};
use crate::reference::{
    expect_lanes, expected, lanes::Lanes, mutant_after_run, mutant_before_run, Expected,
    SceneReference, Undefined,
};
use crate::scene::Scene;

fn layout_cell(resource: Resource, layout: SceneLayout) -> Cell {
    let c = Cell::new(
        Stage::ClosestHit,
        resource,
        IndexSource::Dynamic,
        DescriptorModel::DescriptorIndexing,
    );
    Cell { nonuniform: true, scene_layout: Some(layout), ..c }
}

fn descriptor(to: IndexFn) -> Site {
    Site::DescriptorIndex { heap: false, to }
}

/// Device records with lane evidence: 8 consecutive pixels per subgroup, the probe pixels among
/// them its active lanes.
fn with_lanes(e: &[Expected]) -> Vec<Record> {
    let mut out: Vec<Record> = e.iter().map(|x| x.record).collect();
    for (g, chunk) in out.chunks_mut(8).enumerate() {
        let active: Vec<usize> =
            (0..chunk.len()).filter(|&k| chunk[k].flags & FLAG_PROBE != 0).collect();
        let mask = active.iter().fold(0u32, |m, &k| m | 1 << k);
        for &k in &active {
            let r = &mut chunk[k];
            (r.lane, r.leader) = (k as u32, (g * 8 + active[0]) as u32);
            (r.active_mask, r.active_count) = (mask, active.len() as u32);
        }
    }
    out
}

#[test]
fn a_per_mesh_cells_wrong_slot_is_predicted_and_caught_exactly() {
    let scene = Scene::build(&SceneParams::default());
    let sref = SceneReference::compute(&scene);
    let c = layout_cell(Resource::StorageBuffer, SceneLayout::PerMesh);
    let undefined = Undefined { descriptor: false };
    let slots = crate::probe::slot_count(Resource::StorageBuffer, scene.params.instances);
    for to in [IndexFn::Zero, IndexFn::Next(slots), IndexFn::Doubled(slots)] {
        let p = mutant_before_run(&c, (&scene, &sref), undefined, descriptor(to));
        assert!(p.differing > 100 && p.caught == p.differing, "{to:?}: {p:?}");
        assert_eq!(p.caught_by_heuristic, 0, "{to:?}: judged exactly");
    }
    // the prediction is the wrong slot's buffer as the shader reads it
    let m = super::Mutation::new(descriptor(IndexFn::Next(slots)));
    let mutated = crate::reference::expected_mutated(&c, &scene, &sref, undefined, &m);
    let own = expected(&c, &scene, &sref);
    let d = crate::scene::layout::LayoutData::new(&scene).unwrap();
    let (e, o) = mutated.iter().zip(&own).find(|(e, o)| e.record != o.record).unwrap();
    let words = d.mesh_words(&scene, ((o.record.slot + 1) % slots) as usize);
    let f = crate::scene::layout::read_mesh_words(&words, o.record.geometry, o.record.primitive);
    assert_eq!(Some(e.record.value), f.map(|f| f.value()));
    assert_eq!(e.record.slot, o.record.slot, "the record keeps the computed slot");
}

#[test]
fn a_texture_cells_broadcast_reads_the_first_textured_lanes_texture() {
    let mut scene = Scene::build(&SceneParams::default());
    // mesh 0's entries untextured: some subgroups' lowest lane takes the untextured branch
    scene.textures.geometry_image[0].iter_mut().for_each(|g| *g = None);
    let sref = SceneReference::compute(&scene);
    let c = layout_cell(Resource::SampledImage, SceneLayout::SharedBuffers);
    let mut e = expected(&c, &scene, &sref);
    expect_lanes(&mut e, LaneEvidence::Supported);
    let records = with_lanes(&e);
    let lanes = Lanes::for_stage(&records, Stage::ClosestHit);
    let leaders = super::leader_slots(&e, (&records, &lanes), true);
    let element = |q: usize| super::selecting_index(&e[q], true);
    let mut past_an_untextured_leader = 0;
    for (p, got) in leaders.iter().enumerate() {
        let Some(group) = lanes.subgroup(p) else { continue };
        let first = group
            .iter()
            .copied()
            .filter(|&q| element(q).is_some())
            .min_by_key(|&q| records[q].lane);
        let want = element(p).and(first).and_then(element);
        assert_eq!(*got, want, "pixel {p}");
        let leader = group.iter().copied().min_by_key(|&q| records[q].lane).unwrap();
        past_an_untextured_leader += (got.is_some() && element(leader).is_none()) as usize;
    }
    assert!(past_an_untextured_leader > 0, "no subgroup led by an untextured lane");
    let p = mutant_after_run(
        &c,
        (&scene, &sref),
        (Undefined { descriptor: false }, LaneEvidence::Supported),
        descriptor(IndexFn::Broadcast),
        (&e, &records),
    );
    assert!(p.differing > 0 && p.caught == p.differing && p.from_lanes, "{p:?}");
}

#[test]
fn one_texture_for_every_entry_makes_the_broadcast_undiscriminating() {
    let mut scene = Scene::build(&SceneParams::default());
    scene.textures.geometry_image.iter_mut().flatten().for_each(|g| *g = Some(0));
    let sref = SceneReference::compute(&scene);
    let c = layout_cell(Resource::SampledImage, SceneLayout::SharedBuffers);
    let undefined = Undefined { descriptor: false };
    let one = mutant_before_run(&c, (&scene, &sref), undefined, descriptor(IndexFn::Broadcast));
    assert!(!one.applicable(), "{one:?}");
    // the twin: the procedural scene's four textures discriminate it
    let scene = Scene::build(&SceneParams::default());
    let sref = SceneReference::compute(&scene);
    let four = mutant_before_run(&c, (&scene, &sref), undefined, descriptor(IndexFn::Broadcast));
    assert!(four.applicable() && four.differing > 100, "{four:?}");
}
