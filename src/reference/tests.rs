//! Unit tests of the reference: expected records per cell, value rules, comparison and its
//! tolerances, and the twins that make each check fail.
use super::*;
use crate::model::SceneParams;
use crate::model::{AsAccess, DescriptorModel, IndexSource, Resource, SamplerIndex, Workaround};
use crate::model::{Comparison, NO_NONUNIFORM_VUID};
use std::sync::OnceLock;

fn cell(stage: Stage, index: IndexSource) -> Cell {
    Cell::new(stage, Resource::StorageBuffer, index, DescriptorModel::DescriptorIndexing)
}

fn world() -> &'static (Scene, SceneReference) {
    static W: OnceLock<(Scene, SceneReference)> = OnceLock::new();
    W.get_or_init(|| {
        let scene = Scene::build(&SceneParams::default());
        let r = SceneReference::compute(&scene);
        (scene, r)
    })
}

fn records(e: &[Expected]) -> Vec<Record> {
    e.iter().map(|x| x.record).collect()
}

/// The expected records with the lane evidence a device of 8-lane subgroups writes when each
/// subgroup holds 8 consecutive pixels and the probe pixels among them are its active lanes.
fn with_lanes(e: &[Expected]) -> Vec<Record> {
    let mut out = records(e);
    for (g, chunk) in out.chunks_mut(8).enumerate() {
        let active: Vec<usize> =
            (0..chunk.len()).filter(|&k| chunk[k].flags & FLAG_PROBE != 0).collect();
        let mask = active.iter().fold(0u32, |m, &k| m | 1 << k);
        for &k in &active {
            let r = &mut chunk[k];
            r.lane = k as u32;
            r.leader = (g * 8 + active[0]) as u32;
            r.active_mask = mask;
            r.active_count = active.len() as u32;
        }
    }
    out
}

/// The expected records with every probe pixel's value replaced by `read(record)` (what a
/// faulty driver would read there).
fn reading(e: &[Expected], read: impl Fn(&Record) -> [f32; 4]) -> Vec<Record> {
    e.iter()
        .map(|x| {
            let mut a = x.record;
            if a.flags & FLAG_PROBE != 0 {
                a.value = read(&a);
            }
            a
        })
        .collect()
}

#[test]
fn default_scene_has_hits_misses_spheres_and_few_ambiguous_pixels() {
    let (_, r) = world();
    let hits = r.full.iter().filter(|t| t.hit.is_some()).count();
    let spheres = r.full.iter().filter(|t| t.hit.is_some_and(|h| h.sphere)).count();
    let n = r.full.len();
    assert!(hits > n / 5 && hits < n, "hits {hits} of {n}");
    assert!(spheres > 50, "spheres {spheres}");
    assert!(r.ambiguous_pixels() < n / 20, "ambiguous {}", r.ambiguous_pixels());
    // several geometries per BLAS are hit
    let geoms: std::collections::BTreeSet<u32> =
        r.full.iter().filter_map(|t| t.hit.map(|h| h.geometry)).collect();
    assert!(geoms.len() >= 3, "{geoms:?}");
    // the probe rays hit in every variant almost everywhere (the floor), with different instance sets
    let probe = r.as_probe(&world().0);
    for v in &probe.rays {
        assert!(v.iter().filter(|t| t.hit.is_some()).count() > n * 9 / 10);
    }
    assert!(
        (0..n)
            .filter(|p| probe.rays[0][*p].hit.map(|h| h.instance_id)
                != probe.rays[1][*p].hit.map(|h| h.instance_id))
            .count()
            > n / 10
    );
}

#[test]
fn expected_records_compare_equal_to_themselves_and_corruption_is_caught() {
    let (scene, r) = world();
    let c = cell(Stage::ClosestHit, IndexSource::Dynamic);
    let e = expected(&c, scene, r);
    let mut actual = records(&e);
    let cmp = compare(&e, &actual, 64);
    assert!(cmp.passed() && cmp.compared > 0);
    // Every probed value off by one (as `--inject-fault …@value` makes a driver do).
    for a in actual.iter_mut().filter(|a| a.flags & FLAG_PROBE != 0) {
        a.value[0] += 1.0;
    }
    let cmp = compare(&e, &actual, 64);
    assert!(!cmp.passed());
    assert_eq!(cmp.by_field.keys().collect::<Vec<_>>(), vec!["value"]);
    assert!(cmp.worst_value >= 1.0);
    // Every checked probe pixel is caught, and only those: the n a `value:F` injection can
    // be caught on (closest-hit: the hit pixels only).
    assert_eq!(cmp.mismatched_pixels, cmp.probe_checked);
    assert!(
        cmp.probe_checked > 0 && cmp.probe_checked < cmp.compared,
        "{} of {}",
        cmp.probe_checked,
        cmp.compared
    );
    let raygen = expected(&cell(Stage::Raygen, IndexSource::Literal), scene, r);
    let cmp = compare(&raygen, &records(&raygen), 64);
    assert_eq!(cmp.probe_checked, cmp.compared);
}

/// `base=shader_record|buffer`: the bases differ per hit group and per instance (and from push
/// data's), so a driver that reads the push-data base, another group's record, entry 0 of the
/// bases buffer or one lane's entry for every lane records another slot (and reads another
/// element) on many hit pixels; the right base passes.
#[test]
fn a_wrong_base_source_is_caught() {
    use crate::model::BaseSource;
    let (scene, r) = world();
    let slots = probe::slot_count(Resource::StorageBuffer, scene.params.instances);
    type Wrong = fn(u32, bool) -> u32;
    let cases: [(BaseSource, &str, Wrong); 8] = [
        (BaseSource::ShaderRecord, "push data's", |_, _| probe::DYNAMIC_BASE),
        (BaseSource::ShaderRecord, "the raygen record's", |_, _| probe::RECORD_BASE_OTHER),
        (BaseSource::ShaderRecord, "the other hit group's", |_, sphere| {
            if sphere {
                probe::RECORD_BASE_TRIANGLES
            } else {
                probe::RECORD_BASE_PROCEDURAL
            }
        }),
        (BaseSource::Buffer, "push data's", |_, _| probe::DYNAMIC_BASE),
        (BaseSource::Buffer, "entry 0", |_, _| probe::instance_base(0)),
        (BaseSource::Buffer, "no (a dropped)", |_, _| 0),
        (BaseSource::ShaderRecord, "no (a dropped)", |_, _| 0),
        (BaseSource::Buffer, "the next instance's", |i, _| probe::instance_base(i + 1)),
    ];
    for (base, what, wrong) in cases {
        let c = Cell {
            nonuniform: true,
            base: Some(base),
            ..cell(Stage::ClosestHit, IndexSource::Dynamic)
        };
        let e = expected(&c, scene, r);
        assert!(compare(&e, &records(&e), 64).passed());
        let actual: Vec<Record> = e
            .iter()
            .zip(&r.full)
            .map(|(x, t)| {
                let mut a = x.record;
                if let (true, Some(h)) = (a.flags & FLAG_PROBE != 0, t.hit) {
                    a.slot = wrong(h.instance_id, h.sphere)
                        + (a.custom & (slots - probe::DYNAMIC_BASE - 1));
                    a.value = probe::resource_value(Resource::StorageBuffer, a.slot, a.element);
                }
                a
            })
            .collect();
        let cmp = compare(&e, &actual, 64);
        assert!(
            cmp.mismatched_pixels * 2 > cmp.probe_checked,
            "{base:?}: reading {what} base caught on {} of {}",
            cmp.mismatched_pixels,
            cmp.probe_checked
        );
    }
}

/// Direct heap sampled images with a separate sampler index: the value is the texel the
/// cell's sampler picks, so a driver that samples with sampler 0 (ignoring the index), or with
/// the constant sampler where the index is dynamic, is caught on most probe pixels; the right
/// sampler passes.
#[test]
fn a_wrong_sampler_reads_another_texel_and_is_caught() {
    let (scene, r) = world();
    let direct = |stage, index, nonuniform, sampler| Cell {
        resource: Resource::SampledImage,
        nonuniform,
        descriptor_model: DescriptorModel::DescriptorHeap,
        heap_access: Some(crate::model::HeapAccess::Direct),
        sampler: Some(sampler),
        ..cell(stage, index)
    };
    for stage in [Stage::ClosestHit, Stage::Raygen, Stage::Fragment] {
        for (index, nonuniform) in [
            (IndexSource::Literal, false),
            (IndexSource::Dynamic, true),
            (IndexSource::DynamicElement, false),
        ] {
            for sampler in [SamplerIndex::Constant, SamplerIndex::Dynamic] {
                let c = direct(stage, index, nonuniform, sampler);
                let e = expected(&c, scene, r);
                assert!(compare(&e, &records(&e), 64).passed(), "{}", c.id());
                sampler_zero_is_caught(&c, &e);
                if sampler == SamplerIndex::Dynamic {
                    constant_sampler_is_caught(&c, &e);
                }
            }
        }
    }
}

/// The slot a direct sampled-image probe of `c` reads at record `a`.
fn slot_read(c: &Cell, a: &Record) -> u32 {
    if c.index == IndexSource::DynamicElement || c.index == IndexSource::Dynamic {
        a.slot
    } else {
        probe::LITERAL_SLOT
    }
}

/// The probe pixels of `e` read through sampler `sampler` instead of the cell's.
fn through_sampler(c: &Cell, e: &[Expected], sampler: u32) -> Vec<Record> {
    reading(e, |a| {
        probe::resource_value(
            Resource::SampledImage,
            slot_read(c, a),
            probe::sampled_element(sampler, a.element),
        )
    })
}

/// The same read with sampler 0 (clamp to edge) is caught on most probe pixels.
fn sampler_zero_is_caught(c: &Cell, e: &[Expected]) {
    let wrong = through_sampler(c, e, 0);
    let cmp = compare(e, &wrong, 64);
    // Constant: sampler 2 against 0 differs on 3 elements of 4. Dynamic: a third of the pixels
    // use sampler 0 itself, the others differ on 3 elements of 4.
    let share = if c.sampler == Some(SamplerIndex::Constant) { 0.7 } else { 0.4 };
    assert!(
        cmp.mismatched_pixels as f64 > share * cmp.probe_checked as f64,
        "{}: sampler 0 caught on {} of {}",
        c.id(),
        cmp.mismatched_pixels,
        cmp.probe_checked
    );
}

/// The constant sampler instead of the dynamic one is caught on a third of the probe pixels.
fn constant_sampler_is_caught(c: &Cell, e: &[Expected]) {
    let wrong = through_sampler(c, e, probe::SAMPLER_LITERAL);
    let cmp = compare(e, &wrong, 64);
    assert!(
        cmp.mismatched_pixels * 3 > cmp.probe_checked,
        "{}: constant sampler caught on {} of {}",
        c.id(),
        cmp.mismatched_pixels,
        cmp.probe_checked
    );
}

/// `index=dynamic_element` (the recommended pattern): the reference knows the value of every
/// element of the packed buffer / every layer of the array texture, and a driver that reads
/// the wrong element, the wrong layer (the neighbouring slot's block) or the spec-constant
/// slot's own resource instead of the packed one is caught on every probed pixel.
#[test]
fn dynamic_element_reads_must_be_the_exact_packed_element_and_layer() {
    let (scene, r) = world();
    for resource in [Resource::StorageBuffer, Resource::SampledImage] {
        for stage in [Stage::ClosestHit, Stage::Raygen, Stage::Compute] {
            let c = Cell { resource, ..cell(stage, IndexSource::DynamicElement) };
            let e = expected(&c, scene, r);
            // Same records as the dynamic cell (with nonuniformEXT: exact, no any-element rule).
            let d =
                expected(&Cell { index: IndexSource::Dynamic, nonuniform: true, ..c }, scene, r);
            assert!(e.iter().zip(&d).all(|(a, b)| a.record == b.record
                && a.rule == ValueRule::Exact
                && a.discriminating == b.discriminating));
            assert!(compare(&e, &records(&e), 64).passed());
            let slots = probe::slot_count(resource, scene.params.instances);
            // (slot, element) a faulty driver reads instead: the wrong element, the wrong layer
            // (the neighbouring slot's block), the spec-constant slot's own resource.
            type WrongRead = (&'static str, fn(u32, u32, u32) -> (u32, u32));
            let wrong: [WrongRead; 3] = [
                ("element", |s, e, _| (s, (e + 1) % probe::ELEMENTS)),
                ("layer", |s, e, n| ((s + 1) % n, e)),
                ("own slot", |_, e, _| (probe::PACKED_SLOT, e)),
            ];
            for (what, at) in &wrong {
                let actual = reading(&e, |a: &Record| {
                    let (s, el) = at(a.slot, a.element, slots);
                    probe::resource_value(resource, s, el)
                });
                let cmp = compare(&e, &actual, 64);
                let moved = e
                    .iter()
                    .zip(&actual)
                    .filter(|(x, a)| !x.ambiguous && x.record.value != a.value)
                    .count();
                assert!(
                    !cmp.passed() && cmp.mismatched_pixels >= moved && moved > 0,
                    "{} wrong {what}: {cmp:?}",
                    c.id()
                );
            }
            assert!(
                compare(&e, &records(&e), 64).discrimination.is_some_and(|x| x >= 0.99),
                "{}",
                c.id()
            );
        }
    }
}

/// Bit patterns no correct probe writes where the reference has an ordinary value.
const GARBAGE: [u32; 7] =
    [0x7fc0_0000, 0xffc0_0001, 0x7f80_0000, 0xff80_0000, 0xffff_ffff, 0x0000_0001, 0x807f_ffff];

/// The record with the 32-bit word at byte `offset` replaced by `bits`.
fn with_word(r: &Record, offset: usize, bits: u32) -> Record {
    let mut b = r.to_bytes();
    b[offset..offset + 4].copy_from_slice(&bits.to_le_bytes());
    Record::from_bytes(&b)
}

/// Where the probe measured lane evidence every probe record must carry consistent lane words
/// (and the flag); a record without the flag, or with a lane outside its own mask, a zero or
/// oversized count, a mask with more lanes than counted, or a leader off the image, mismatches.
/// Without lane evidence the words must stay zero.
#[test]
fn lane_words_are_held_to_consistency() {
    let (scene, r) = world();
    let c = cell(Stage::ClosestHit, IndexSource::Literal);
    let mut e = expected(&c, scene, r);
    expect_lanes(&mut e, LaneEvidence::Supported);
    let good = with_lanes(&e);
    assert!(compare(&e, &good, 64).passed());
    let p = e.iter().position(|x| !x.ambiguous && x.record.flags & FLAG_PROBE != 0).unwrap();
    let bad: [fn(&mut Record); 6] = [
        |r| r.flags &= !FLAG_LANES,
        |r| r.active_mask &= !(1 << r.lane),
        |r| r.active_count = 0,
        |r| r.active_count = 129,
        |r| r.active_mask = 0xffff_ffff,
        |r| r.leader = 4096,
    ];
    for (k, spoil) in bad.iter().enumerate() {
        let mut actual = good.clone();
        spoil(&mut actual[p]);
        let cmp = compare(&e, &actual, 64);
        assert_eq!(cmp.mismatched_pixels, 1, "spoiler {k}");
    }
    // without lane evidence, lane words a probe did write mismatch
    let plain = expected(&c, scene, r);
    assert!(compare(&plain, &records(&plain), 64).passed());
    let unflagged: Vec<Record> =
        good.iter().map(|r| Record { flags: r.flags & !FLAG_LANES, ..*r }).collect();
    let cmp = compare(&plain, &unflagged, 64);
    assert!(!cmp.passed() && cmp.by_field.keys().eq(["lanes"]), "{:?}", cmp.by_field);
    // the device's subgroups read back: every probe pixel's subgroup is known
    let lanes = lanes::Lanes::from_records(&good);
    let probe_pixels = e.iter().filter(|x| x.record.flags & FLAG_PROBE != 0).count();
    assert_eq!(lanes.known(), probe_pixels);
    let group = lanes.subgroup(p).unwrap();
    assert!(group.contains(&p) && group.iter().all(|q| q / 8 == p / 8));
}

#[test]
fn garbage_in_any_record_field_never_passes() {
    let (scene, r) = world();
    let c = cell(Stage::ClosestHit, IndexSource::Literal);
    let e = expected(&c, scene, r);
    let good = records(&e);
    assert!(compare(&e, &good, 64).passed());
    // A triangle hit with both barycentrics well inside, a miss (hit and probe fields unset).
    let tri = e
        .iter()
        .position(|x| {
            !x.ambiguous
                && x.record.flags == FLAG_HIT | FLAG_PROBE
                && x.record.bary.iter().all(|b| *b > 0.05)
                && x.record.t > 1.0
        })
        .unwrap();
    let miss = e.iter().position(|x| !x.ambiguous && x.record.flags == 0).unwrap();
    let word_fields: Vec<(&str, usize)> = crate::probe::RECORD_FIELDS
        .iter()
        .filter(|f| !f.glsl_name.starts_with("pad"))
        .flat_map(|f| {
            let words = match f.glsl_type {
                "vec2" => 2,
                "vec4" => 4,
                _ => 1,
            };
            (0..words).map(move |k| (f.glsl_name, f.offset + 4 * k))
        })
        .collect();
    assert_eq!(word_fields.len(), 18);
    for &p in &[tri, miss] {
        for &(name, offset) in &word_fields {
            for bits in GARBAGE {
                let mut actual = good.clone();
                let before = with_word(&actual[p], offset, bits);
                if before == actual[p] {
                    continue;
                }
                actual[p] = before;
                let cmp = compare(&e, &actual, 64);
                assert!(!cmp.passed(), "pixel {p}: {name} = {bits:#x} passed");
                assert_eq!(cmp.mismatched_pixels, 1);
            }
        }
    }
    // the worst figures keep NaN and infinity, and JSON says so
    let mut actual = good.clone();
    actual[tri].bary[1] = f32::NAN;
    let cmp = compare(&e, &actual, 64);
    assert!(cmp.worst_bary.is_nan(), "{cmp:?}");
    // the worker sends comparisons to the supervisor as JSON: NaN survives the trip
    let text = serde_json::to_string(&cmp).unwrap();
    assert!(text.contains(r#""worst_bary":"NaN""#), "{text}");
    assert!(serde_json::from_str::<Comparison>(&text).unwrap().worst_bary.is_nan());
    actual[tri].bary[1] = good[tri].bary[1];
    actual[tri].value[2] = f32::INFINITY;
    let cmp = compare(&e, &actual, 64);
    assert_eq!(cmp.worst_value, f64::INFINITY);
    let json = serde_json::to_value(&cmp).unwrap();
    assert_eq!(json["worst_value"], "inf");
    let back: Comparison = serde_json::from_value(json).unwrap();
    assert_eq!(back.worst_value, f64::INFINITY);
}

#[test]
fn a_driver_returning_instance_id_as_custom_index_is_caught() {
    let (scene, r) = world();
    for resource in [Resource::StorageBuffer, Resource::AccelerationStructure] {
        let as_access =
            (resource == Resource::AccelerationStructure).then_some(AsAccess::Descriptor);
        let c = Cell {
            resource,
            as_access,
            nonuniform: true,
            ..cell(Stage::ClosestHit, IndexSource::Dynamic)
        };
        let e = expected(&c, scene, r);
        let slots = crate::probe::slot_count(resource, scene.params.instances);
        // What the GPU would write if gl_InstanceCustomIndexEXT returned gl_InstanceID.
        let actual: Vec<Record> = e
            .iter()
            .enumerate()
            .map(|(p, x)| {
                let mut a = x.record;
                if a.flags & FLAG_HIT != 0 {
                    a.custom = a.instance_id;
                    a.slot = crate::probe::dynamic_slot(
                        Stage::ClosestHit,
                        (0, 0, 64),
                        a.instance_id,
                        probe::DYNAMIC_BASE,
                        (slots, probe::dyn_mask(resource, scene.params.instances)),
                    );
                    a.value = if resource == Resource::AccelerationStructure {
                        r.as_probe(scene).value(a.slot, p).0
                    } else {
                        crate::probe::resource_value(resource, a.slot, a.element)
                    };
                }
                a
            })
            .collect();
        let cmp = compare(&e, &actual, 64);
        let hits = e.iter().filter(|x| !x.ambiguous && x.record.flags & FLAG_HIT != 0).count();
        assert!(hits > 500);
        assert_eq!(cmp.by_field.get("custom"), Some(&hits), "{cmp:?}");
        let wrong_values = cmp.by_field.get("value").copied().unwrap_or(0);
        assert!(
            wrong_values * 100 >= hits * 95,
            "{resource:?}: {wrong_values} of {hits} hit pixels read another value"
        );
    }
}

/// `heap_access=direct` reads are judged exactly, with and without `nonuniformEXT`: the heap needs
/// no NonUniform (the DescriptorHeapEXT exemption of VUID-RuntimeSpirv-None-10148 / -10149,
/// Vulkan 1.4.360). A driver reading heap index 0, or the literal slot, instead of each lane's
/// index mismatches on nearly every probe pixel (issue 21: such a bundle passed); its own read
/// passes. The set/binding twin without `nonuniformEXT` stays lenient.
#[test]
fn direct_heap_reads_are_judged_exactly() {
    let (scene, r) = world();
    for stage in [Stage::ClosestHit, Stage::Raygen, Stage::Compute] {
        for resource in [Resource::StorageBuffer, Resource::SampledImage] {
            for nonuniform in [false, true] {
                let c = Cell {
                    resource,
                    nonuniform,
                    descriptor_model: DescriptorModel::DescriptorHeap,
                    heap_access: Some(crate::model::HeapAccess::Direct),
                    ..cell(stage, IndexSource::Dynamic)
                };
                let e = expected(&c, scene, r);
                assert!(compare(&e, &records(&e), 64).passed(), "{}", c.id());
                for wrong_slot in [0, probe::LITERAL_SLOT] {
                    let wrong = reading(&e, |a| {
                        let texel = if resource == Resource::SampledImage {
                            probe::sampled_element(probe::SAMPLER_LITERAL, a.element)
                        } else {
                            a.element
                        };
                        probe::resource_value(resource, wrong_slot, texel)
                    });
                    let cmp = compare(&e, &wrong, 64);
                    assert!(cmp.element_reads.is_none(), "{}", c.id());
                    assert!(
                        cmp.mismatched_pixels * 10 >= cmp.probe_checked * 9,
                        "{}: heap index {wrong_slot} caught on {} of {}",
                        c.id(),
                        cmp.mismatched_pixels,
                        cmp.probe_checked
                    );
                }
            }
        }
    }
}

/// A closest-hit lane computes `DYNAMIC_BASE + (custom & mask)`, so no lane computes slots
/// 0..DYNAMIC_BASE: a driver that drops the base reads such a slot wherever the masked custom
/// index is small, and the other-lane heuristic calls that a mismatch; where it lands on a slot
/// another lane computed, it is counted as another lane's read.
#[test]
fn a_driver_ignoring_base_shows_in_the_element_reads() {
    let (scene, r) = world();
    let c =
        Cell { resource: Resource::UniformBuffer, ..cell(Stage::ClosestHit, IndexSource::Dynamic) };
    let e = expected(&c, scene, r);
    let base_dropped = reading(&e, |a| {
        crate::probe::resource_value(
            Resource::UniformBuffer,
            a.slot - crate::probe::DYNAMIC_BASE,
            a.element,
        )
    });
    let cmp = compare(&e, &base_dropped, 64);
    let reads = cmp.element_reads.clone().expect("no-nonuniform cells count their reads");
    assert_eq!(reads.outside_spec, NO_NONUNIFORM_VUID);
    assert_eq!(reads.own, 0, "{reads:?}");
    assert_eq!(reads.other + reads.neither, cmp.any_element_values);
    let below_base = e
        .iter()
        .filter(|x| {
            !x.ambiguous
                && x.record.flags & FLAG_PROBE != 0
                && x.record.slot < 2 * crate::probe::DYNAMIC_BASE
        })
        .count();
    assert_eq!(reads.neither, below_base, "{reads:?}");
    assert!(reads.other > 100 && reads.neither > 100, "{reads:?}");
    assert_eq!(cmp.by_field.get("value"), Some(&reads.neither));
    assert_eq!(cmp.discrimination, None);
    // the same reads with nonuniformEXT are mismatches everywhere
    let nu = Cell { nonuniform: true, ..c };
    let cmp = compare(&expected(&nu, scene, r), &base_dropped, 64);
    assert_eq!(cmp.by_field.get("value"), Some(&(reads.other + reads.neither)));
    // and the own reads are counted as own
    let cmp = compare(&e, &records(&e), 64);
    assert_eq!(cmp.element_reads.map(|x| (x.own, x.other)), Some((reads.other + reads.neither, 0)));
}

/// Issue 21, item 2: without `nonuniformEXT` a hit-stage read of slot 0 — an index dropped to 0,
/// which no lane computes there (every lane's is `DYNAMIC_BASE` or more) — is a mismatch on every
/// probe pixel, for buffers, images and acceleration structures alike (before, "any element of
/// the array" passed it).
#[test]
fn an_index_no_lane_computed_is_a_mismatch_without_nonuniform() {
    let (scene, r) = world();
    for stage in [Stage::ClosestHit, Stage::AnyHit, Stage::Intersection] {
        for resource in
            [Resource::StorageBuffer, Resource::SampledImage, Resource::AccelerationStructure]
        {
            let as_access =
                (resource == Resource::AccelerationStructure).then_some(AsAccess::Descriptor);
            let c = Cell { resource, as_access, ..cell(stage, IndexSource::Dynamic) };
            let e = expected(&c, scene, r);
            assert!(compare(&e, &records(&e), 64).passed(), "{}", c.id());
            let slot0: Vec<Record> = e
                .iter()
                .enumerate()
                .map(|(p, x)| {
                    let mut a = x.record;
                    if a.flags & FLAG_PROBE != 0 {
                        a.value = if resource == Resource::AccelerationStructure {
                            r.as_probe(scene).value(0, p).0
                        } else {
                            probe::resource_value(resource, 0, a.element)
                        };
                    }
                    a
                })
                .collect();
            let cmp = compare(&e, &slot0, 64);
            let reads = cmp.element_reads.clone().unwrap();
            // (an AS read through slot 0 may give the same hit as the lane's own slot)
            assert!(
                reads.neither * 10 >= cmp.probe_checked * 9,
                "{}: slot 0 read caught on {} of {} ({reads:?})",
                c.id(),
                reads.neither,
                cmp.probe_checked
            );
            assert_eq!(reads.other, 0, "{}", c.id());
        }
    }
}

/// With the device's lane evidence an undefined read may only read what a lane of its own
/// subgroup computed: the leader's index broadcast to every lane passes (counted per subgroup),
/// an index only a lane of another subgroup computed is a mismatch there, though it passes
/// against the whole dispatch (no lane evidence).
#[test]
fn with_lane_evidence_an_undefined_read_is_judged_per_subgroup() {
    let (scene, r) = world();
    let c = cell(Stage::Raygen, IndexSource::Dynamic);
    let mut e = expected(&c, scene, r);
    expect_lanes(&mut e, LaneEvidence::Supported);
    let good = with_lanes(&e);
    let lanes = lanes::Lanes::from_records(&good);
    assert!(compare_with(&e, &good, 64, Some(&lanes)).passed());
    let slots = probe::slot_count(Resource::StorageBuffer, scene.params.instances);
    let read = |slot_of: &dyn Fn(usize, &Record) -> u32| -> Vec<Record> {
        good.iter()
            .enumerate()
            .map(|(p, a)| Record {
                value: probe::resource_value(Resource::StorageBuffer, slot_of(p, a), a.element),
                ..*a
            })
            .collect()
    };
    let broadcast = read(&|p, _| good[lanes.leader(p).unwrap()].slot);
    let cmp = compare_with(&e, &broadcast, 64, Some(&lanes));
    let reads = cmp.element_reads.clone().unwrap();
    assert!(cmp.passed() && reads.other > 1000, "{reads:?}");
    assert_eq!(reads.by_subgroup, cmp.any_element_values);
    // Eight pixels on: a slot only the next subgroup's lanes computed.
    let next = read(&|_, a| (a.slot + 8) % slots);
    let cmp = compare_with(&e, &next, 64, Some(&lanes));
    assert_eq!(cmp.mismatched_pixels, cmp.probe_checked, "{:?}", cmp.element_reads);
    assert!(compare(&e, &next, 64).passed(), "the whole dispatch computed those slots");
    // A subgroup the records do not show whole falls back to the dispatch.
    let mut partial = next.clone();
    partial[1].active_count += 1;
    let lanes = lanes::Lanes::from_records(&partial);
    let cmp = compare_with(&e, &partial, 64, Some(&lanes));
    assert!(cmp.element_reads.unwrap().by_subgroup < cmp.probe_checked);
}

#[test]
fn elements_are_read_at_per_primitive_offsets() {
    let (scene, r) = world();
    let c = cell(Stage::ClosestHit, IndexSource::Literal);
    let e = expected(&c, scene, r);
    let elements: std::collections::BTreeSet<u32> =
        e.iter().filter(|x| x.record.flags & FLAG_PROBE != 0).map(|x| x.record.element).collect();
    assert_eq!(elements.len() as u32, crate::probe::ELEMENTS);
    // a driver that always reads v[0] is caught wherever the element is not 0
    let v0 = reading(&e, |a| crate::probe::resource_value(Resource::StorageBuffer, a.slot, 0));
    let cmp = compare(&e, &v0, 64);
    let nonzero = e
        .iter()
        .filter(|x| !x.ambiguous && x.record.flags & FLAG_PROBE != 0 && x.record.element != 0)
        .count();
    assert_eq!(cmp.by_field.get("value"), Some(&nonzero));
}

#[test]
fn an_undefined_read_accepts_another_lanes_index_at_its_own_element_only() {
    let (scene, r) = world();
    let c = Cell { resource: Resource::UniformBuffer, ..cell(Stage::Raygen, IndexSource::Dynamic) };
    let e = expected(&c, scene, r);
    let mut actual = records(&e);
    // Slot 0 (another lane's index: raygen lanes compute every slot) at the lane's own element,
    // as a driver reading one lane's descriptor would return: accepted by the heuristic.
    let own = e[10].record.element;
    actual[10].value = crate::probe::resource_value(Resource::UniformBuffer, 0, own);
    let cmp = compare(&e, &actual, 64);
    assert!(cmp.passed(), "{cmp:?}");
    assert_eq!(cmp.any_element_values, cmp.compared);
    let reads = cmp.element_reads.as_ref().unwrap();
    assert_eq!((reads.other, reads.by_subgroup), (1, 0));
    assert_eq!(reads.heuristic, crate::model::OTHER_LANE_HEURISTIC);
    // Another element of that slot is no lane's read.
    let mut other_element = actual.clone();
    other_element[10].value =
        crate::probe::resource_value(Resource::UniformBuffer, 0, (own + 1) % probe::ELEMENTS);
    assert!(!compare(&e, &other_element, 64).passed());
    // Garbage is not.
    actual[11].value = [7.5, 0.0, 0.0, 0.0];
    let cmp = compare(&e, &actual, 64);
    assert!(!cmp.passed());
    assert_eq!(cmp.element_reads.map(|x| x.neither), Some(1));
    // With nonuniformEXT the element must be exact.
    let nu = Cell { nonuniform: true, ..c };
    let e = expected(&nu, scene, r);
    assert!(!compare(&e, &actual, 64).passed());
}

#[test]
fn dynamic_indices_into_memory_are_checked_exactly() {
    // Without a descriptor array (an address table, written so or patched) a non-uniform
    // index is well defined: another slot's value is a mismatch, not "some element".
    let (scene, r) = world();
    let base = Cell {
        resource: Resource::AccelerationStructure,
        as_access: Some(AsAccess::Descriptor),
        ..cell(Stage::Raygen, IndexSource::Dynamic)
    };
    let cells = [
        Cell { as_access: Some(AsAccess::Address), ..base },
        Cell { as_access: Some(AsAccess::AddressPatched), ..base },
        Cell { patch: Some(Workaround::AsToAddress), ..base },
        Cell {
            resource: Resource::StorageBuffer,
            as_access: None,
            patch: Some(Workaround::SsboToAddress),
            ..base
        },
    ];
    for c in cells {
        let e = expected(&c, scene, r);
        let other_slot = reading(&e, |a| {
            let s = (a.slot + 1) % crate::probe::slot_count(c.resource, scene.params.instances);
            if c.resource == Resource::AccelerationStructure {
                crate::probe::as_value(Some(crate::probe::as_custom(s, 0)))
            } else {
                crate::probe::resource_value(c.resource, s, a.element)
            }
        });
        let cmp = compare(&e, &other_slot, 64);
        assert!(
            !cmp.passed() && cmp.element_reads.is_none() && cmp.discrimination.is_some(),
            "{}: {cmp:?}",
            c.id()
        );
    }
    // the descriptor variant itself is outside the spec's guarantees
    assert!(compare(&expected(&base, scene, r), &records(&expected(&base, scene, r)), 64)
        .element_reads
        .is_some());
}

#[test]
fn miss_probes_only_run_on_misses() {
    let (scene, r) = world();
    let e = expected(&cell(Stage::Miss, IndexSource::Literal), scene, r);
    for (x, t) in e.iter().zip(&r.full) {
        assert_eq!(x.record.flags & FLAG_PROBE != 0, t.hit.is_none());
    }
}

/// AS arrays keep one TLAS variant per slot in larger scenes (their dynamic mask is capped
/// instead), so a wrong slot is still caught everywhere.
#[test]
fn as_cells_discriminate_in_a_large_scene() {
    let scene = Scene::build(&SceneParams {
        instances: 256,
        width: 32,
        height: 32,
        ..SceneParams::default()
    });
    let r = SceneReference::compute(&scene);
    assert_eq!(
        r.as_probe(&scene).rays.len() as u32,
        crate::probe::slot_count(Resource::AccelerationStructure, 256)
    );
    for stage in [Stage::Raygen, Stage::ClosestHit, Stage::Miss, Stage::Compute] {
        let c = Cell {
            resource: Resource::AccelerationStructure,
            as_access: Some(AsAccess::Descriptor),
            nonuniform: true,
            ..cell(stage, IndexSource::Dynamic)
        };
        let e = expected(&c, &scene, &r);
        let cmp = compare(&e, &records(&e), 32);
        assert!(
            cmp.discrimination.is_some_and(|d| d >= 0.5),
            "{}: {:?}",
            c.id(),
            cmp.discrimination
        );
    }
}

/// Every cell of the default plan (all cells, every workaround variant): correct records pass,
/// and where the value is checked exactly, reading any other slot or element would be caught
/// on at least half of the compared probe pixels.
#[test]
fn every_cell_of_the_default_plan_discriminates() {
    let (scene, r) = world();
    let (cells, _) = crate::matrix::plan::all_cells();
    let mut weak = Vec::new();
    let mut checked = 0;
    for base in cells {
        for c in std::iter::once(base)
            .chain(base.applicable_patches().into_iter().map(|p| Cell { patch: Some(p), ..base }))
        {
            let e = expected(&c, scene, r);
            let cmp = compare(&e, &records(&e), 64);
            assert!(cmp.passed(), "{}: {cmp:?}", c.id());
            let probed =
                e.iter().filter(|x| !x.ambiguous && x.record.flags & FLAG_PROBE != 0).count();
            assert!(probed > 50, "{}: only {probed} probe pixels", c.id());
            match (cmp.discrimination, &cmp.element_reads) {
                (Some(d), None) => {
                    checked += 1;
                    if d < 0.5 {
                        weak.push(format!("{} {d:.2}", c.id()));
                    }
                }
                (None, Some(reads)) => assert_eq!(
                    (reads.own, reads.other, reads.neither),
                    (probed, 0, 0),
                    "{}",
                    c.id()
                ),
                other => panic!("{}: {other:?}", c.id()),
            }
        }
    }
    assert!(weak.is_empty(), "cells below 50% discrimination: {weak:?}");
    assert!(checked > 500, "{checked}");
}

/// Records of one subgroup that contradict each other are garbage lane data: where the evidence
/// is judged by (supported) each of its pixels is a mismatch on field `lanes`, and the subgroup
/// is never evidence (no per-subgroup judging, no lane split), judged by or not. Twins: a planted
/// wrong leader, a duplicate lane id, a lane outside the subgroup's mask; each record stays
/// consistent on its own, so only the cross-record check catches them.
#[test]
fn contradicting_lane_records_are_a_finding_never_evidence() {
    let (scene, r) = world();
    let c = cell(Stage::Raygen, IndexSource::Literal);
    let mut e = expected(&c, scene, r);
    expect_lanes(&mut e, LaneEvidence::Supported);
    let good = with_lanes(&e);
    let judge = |records: &[Record], judged: bool| {
        let lanes = lanes::Lanes::for_stage(records, Stage::Raygen).judged_by(judged);
        compare_with(&e, records, 64, Some(&lanes))
    };
    assert!(judge(&good, true).passed());
    let probe = |p: usize| good[p].flags & FLAG_PROBE != 0 && !e[p].ambiguous;
    let g = (0..good.len() / 8).find(|g| (0..8).all(|k| probe(g * 8 + k))).unwrap();
    let members: Vec<usize> = (g * 8..g * 8 + 8).collect();
    let mut wrong_leader = good.clone();
    for &p in &members {
        wrong_leader[p].leader = members[1] as u32;
    }
    let mut duplicate = good.clone();
    duplicate[members[2]].lane = good[members[1]].lane;
    let mut outside = good.clone();
    let q = &mut outside[members[2]];
    (q.lane, q.active_mask, q.active_count) = (9, q.active_mask | 1 << 9, q.active_count + 1);
    for (name, bad) in
        [("wrong leader", wrong_leader), ("duplicate", duplicate), ("outside", outside)]
    {
        assert!(bad.iter().all(|a| lanes::inconsistency(a, bad.len()).is_none()), "{name}");
        let cmp = judge(&bad, true);
        assert_eq!(cmp.mismatched_pixels, members.len(), "{name}: {:?}", cmp.examples);
        assert!(cmp.by_field.keys().eq(["lanes"]), "{name}: {:?}", cmp.by_field);
        assert_eq!(cmp.lane_contradictions, members.len(), "{name}");
        // forced evidence is never judged by: no mismatch, but the subgroup is no evidence either
        let mut spoiled = bad.clone();
        for a in spoiled.iter_mut().filter(|a| a.flags & FLAG_PROBE != 0) {
            a.value[0] += 1.0;
        }
        let cmp = judge(&spoiled, false);
        let split = cmp.lanes.expect("a mismatch with lane words is split");
        let split_pixels = split.leaders.pixels + split.followers.pixels;
        assert_eq!(split_pixels + members.len(), cmp.probe_checked, "{name}");
        assert_eq!(split.contradicted.pixels, members.len(), "{name}: counted apart");
        assert!(split.sentence("closest_hit").contains("contradict each other"), "{name}");
        assert_eq!(cmp.by_field.get("lanes"), None, "{name}");
    }
}

/// Records grouped into device subgroups of up to eight pixels that computed the same slot
/// (`same`), or of eight neighbours (`!same`): lane k of a group of n, mask of n bits.
fn grouped(e: &[Expected], same: bool) -> Vec<Record> {
    let mut out = records(e);
    let mut by: std::collections::BTreeMap<u32, Vec<usize>> = Default::default();
    for (p, x) in e.iter().enumerate().filter(|(_, x)| x.record.flags & FLAG_PROBE != 0) {
        by.entry(if same { x.record.slot } else { p as u32 / 8 }).or_default().push(p);
    }
    for pixels in by.values() {
        for chunk in pixels.chunks(8) {
            for (k, &p) in chunk.iter().enumerate() {
                let r = &mut out[p];
                (r.lane, r.leader) = (k as u32, chunk[0] as u32);
                (r.active_mask, r.active_count) = ((1u32 << chunk.len()) - 1, chunk.len() as u32);
            }
        }
    }
    out
}

/// Where the lane evidence shows every active lane of a subgroup (two or more) computed the same
/// index, the read is uniform within the subgroup and needs no NonUniform
/// (VUID-RuntimeSpirv-subgroupSize-10149, Vulkan 1.4.360): judged exactly, not by the heuristic.
/// Twin: a uniform subgroup's lane reading another element (one another subgroup computed, so
/// the dispatch-wide heuristic would accept it) is a mismatch counted as a defined one.
#[test]
fn a_uniform_subgroup_is_judged_exactly() {
    let (scene, r) = world();
    let c = cell(Stage::Raygen, IndexSource::Dynamic);
    let mut e = expected(&c, scene, r);
    expect_lanes(&mut e, LaneEvidence::Supported);
    assert!(e.iter().any(|x| x.rule != ValueRule::Exact), "an undefined read");
    let judge = |records: &[Record]| {
        compare_with(&e, records, 64, Some(&lanes::Lanes::from_records(records)))
    };
    let uniform = grouped(&e, true);
    let cmp = judge(&uniform);
    let reads = cmp.element_reads.clone().unwrap();
    assert!(cmp.passed() && reads.uniform > 1000 && reads.uniform_mismatched == 0, "{reads:?}");
    assert_eq!(reads.uniform + cmp.any_element_values, reads.own, "{reads:?}");
    // one lane of a uniform subgroup reads the slot of a neighbour outside it
    let lanes = lanes::Lanes::from_records(&uniform);
    let p = (0..e.len())
        .find(|&p| !e[p].ambiguous && lanes.subgroup(p).is_some_and(|g| g.len() >= 2))
        .unwrap();
    let probed = e.iter().filter(|x| x.record.flags & FLAG_PROBE != 0 && !x.ambiguous);
    let other = probed.map(|x| x.record.slot).find(|s| *s != e[p].record.slot).unwrap();
    let mut wrong = uniform.clone();
    wrong[p].value = probe::resource_value(Resource::StorageBuffer, other, wrong[p].element);
    assert!(compare(&e, &wrong, 64).passed(), "without lane evidence the heuristic allows it");
    let cmp = judge(&wrong);
    let reads = cmp.element_reads.clone().unwrap();
    assert_eq!((cmp.mismatched_pixels, reads.uniform_mismatched), (1, 1), "{reads:?}");
    assert!(cmp.by_field.keys().eq(["value"]));
    // subgroups of neighbours computed different slots: the heuristic, never `uniform`
    let mixed = judge(&grouped(&e, false)).element_reads.unwrap();
    assert!(mixed.by_subgroup > 0, "{mixed:?}");
}

/// This thread's CPU time in seconds (a shared machine's load inflates wall time, not this).
fn thread_cpu() -> f64 {
    let mut t = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: a valid clock id and a timespec to write.
    unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut t) };
    t.tv_sec as f64 + t.tv_nsec as f64 * 1e-9
}

/// Not a check: where a cell's CPU check spends its time (`cargo test --release --lib
/// reference::tests::check_cost -- --ignored --nocapture`), over every cell of the default plan
/// in plan order with the lane evidence of 8-lane subgroups, in this thread's CPU time: the
/// records decoded from their bytes record by record (as before) and in one copy (as the
/// worker's readback now does), the expected records computed for every cell (as before) and
/// through the memo (as the executor now does), the lane evidence, the comparison. Three
/// rounds; each figure is the least of them.
#[test]
#[ignore]
fn check_cost() {
    let (scene, r) = world();
    let (cells, _) = crate::matrix::plan::all_cells();
    let mut best = [f64::INFINITY; 6];
    let (mut e, mut decoded, mut memo) = (Vec::new(), Vec::new(), ExpectedMemo::default());
    for _ in 0..3 {
        let mut round = [0.0; 6];
        let mut time = |k: usize, t: f64| round[k] += thread_cpu() - t;
        for c in &cells {
            let undefined = Undefined { descriptor: ProbeSpec::of(c).read == ReadIndex::Undefined };
            let t = thread_cpu();
            expected_into(&mut e, c, (scene, r), undefined);
            expect_lanes(&mut e, LaneEvidence::Supported);
            time(2, t);
            let t = thread_cpu();
            let kept = memo.get(c, (scene, r), undefined, LaneEvidence::Supported).len();
            time(3, t);
            assert_eq!(kept, e.len());
            let good = with_lanes(&e);
            let bytes: Vec<u8> = good.iter().flat_map(|g| g.to_bytes()).collect();
            let t = thread_cpu();
            decoded.clear();
            decoded.extend(bytes.chunks_exact(probe::RECORD_SIZE).map(Record::from_bytes));
            time(0, t);
            let t = thread_cpu();
            Record::decode_all(&bytes, &mut decoded);
            time(1, t);
            let t = thread_cpu();
            let lanes = lanes::Lanes::for_stage(&decoded, c.stage);
            time(4, t);
            let t = thread_cpu();
            let cmp = compare_with(&e, &decoded, 64, Some(&lanes));
            time(5, t);
            assert!(cmp.passed(), "{}", c.id());
        }
        for (b, x) in best.iter_mut().zip(round) {
            *b = b.min(x);
        }
    }
    let ms = best.map(|b| b / cells.len() as f64 * 1e3);
    eprintln!(
        "{} cells, CPU ms per cell: decode {:.3} (one copy {:.3}), expected {:.3} (memo {:.3}), lanes {:.3}, compare {:.3}",
        cells.len(),
        ms[0],
        ms[1],
        ms[2],
        ms[3],
        ms[4],
        ms[5]
    );
}

/// The supervisor's count of ambiguous primary rays is the worker's reference's, on the default
/// scene and on another seed (a count that ignored some rows or threads would differ).
#[test]
fn ambiguous_primaries_match_the_full_reference() {
    let (scene, r) = world();
    assert!(r.ambiguous_pixels() > 0, "the default scene has ambiguous pixels to count");
    assert_eq!(ambiguous_primaries(scene), r.ambiguous_pixels());
    let other = Scene::build(&SceneParams { seed: 7, ..SceneParams::default() });
    assert_eq!(ambiguous_primaries(&other), SceneReference::compute(&other).ambiguous_pixels());
}

/// The reference is computed on every core: each pixel's primary trace still sits at its own
/// index (a row shuffled by the split would put another pixel's hit there).
#[test]
fn the_reference_on_every_core_keeps_each_pixel_in_place() {
    let (scene, r) = world();
    let w = scene.params.width;
    let cull = intersect::Culling::of(scene);
    for p in (0..r.full.len()).step_by(97).chain([r.full.len() - 1]) {
        let (o, d) = scene.primary_ray(p as u32 % w, p as u32 / w);
        assert_eq!(r.full[p], intersect::trace((scene, &cull), o, d, |_| true), "pixel {p}");
    }
    assert_eq!(r.full.len(), scene.params.pixels());
    assert!(r.as_probe(scene).rays.iter().all(|v| v.len() == r.full.len()));
}

/// The AS probe rays are traced at the first cell that reads them, never for the others (the
/// CLI's scene summary, a re-run worker of buffer cells), and what a later AS cell is judged by
/// is what they hold: a probe pixel's value is its ray's instance through the cell's variant.
#[test]
fn the_as_probe_rays_are_traced_only_for_a_cell_that_reads_them() {
    let scene = Scene::build(&SceneParams::default());
    let r = SceneReference::compute(&scene);
    for index in [IndexSource::Literal, IndexSource::Dynamic] {
        let e = expected(&cell(Stage::ClosestHit, index), &scene, &r);
        assert!(e.iter().any(|x| x.record.flags & FLAG_PROBE != 0));
    }
    assert!(!r.as_probe_traced(), "a storage-buffer cell traced the AS probe rays");
    let c = Cell {
        resource: Resource::AccelerationStructure,
        as_access: Some(AsAccess::Descriptor),
        ..cell(Stage::Raygen, IndexSource::Literal)
    };
    let e = expected(&c, &scene, &r);
    assert!(r.as_probe_traced(), "an AS cell judged without its probe rays");
    let probe = r.as_probe(&scene);
    let mut judged = 0;
    for (p, x) in e.iter().enumerate().filter(|(_, x)| x.record.flags & FLAG_PROBE != 0) {
        let v = crate::probe::as_slot_tlas(x.record.slot);
        let custom = probe.rays[v][p].hit.map(|h| crate::probe::as_custom(v as u32, h.instance_id));
        assert_eq!(x.record.value, crate::probe::as_value(custom), "pixel {p}");
        judged += 1;
    }
    assert!(judged > e.len() / 2, "{judged} probe pixels of {}", e.len());
}
