//! The CPU reference: the scene traced in f64 ([`intersect`]), the record every cell should
//! produce per pixel ([`expected`], from the cell's probe spec, `probe::spec::ProbeSpec`, as the
//! generated GLSL is), and the comparison with documented tolerances ([`compare`]).
//!
//! Tolerances: every integer field (flags, custom index, instance id, geometry, primitive, slot,
//! element) must match exactly; probe values exactly (small integers and quarters, exact in f32);
//! `t` within 1e-3 relative (f32 traversal vs f64, inverse transforms computed on both sides);
//! barycentrics within 1e-3. A non-finite value where the reference is finite is always a
//! mismatch, and the worst-error figures keep NaN / ∞ (written as strings in JSON). Fields a flag
//! says were not written must hold the zero bits the shader initialised. Pixels whose hit lies
//! within 1e-4 (barycentric) of an edge or silhouette, or within 1e-4 relative distance of another
//! surface, are counted as `ambiguous` and skipped: there the GPU may pick either surface.
//!
//! `index=dynamic` without `nonuniform` indexes with a value that differs between invocations but
//! carries no `NonUniform` decoration. That is invalid usage ([`NO_NONUNIFORM_VUID`]) and in ray
//! tracing stages the invocation group is implementation-defined, so the Vulkan spec guarantees
//! nothing there; engines do it anyway, so the cells stay. Their value must be the value of *some*
//! element of the array ([`ValueRule::AnyElement`]), which still catches garbage reads, device
//! losses and crashes; [`ElementReads`] counts pixels that read their own element, another one,
//! or neither. The slot the shader computed is still exact. Where no descriptor array is indexed
//! any more (`as_access=address|address_patched`, the `as-to-address` / `ssbo-to-address`
//! patches) a non-uniform index reads memory, which is well defined: those cells are exact.
//!
//! Separate-sampler probes (`sampler` axis, direct heap sampled images) sample a shifted coordinate,
//! so their value is the texel their sampler's address mode picks ([`probe::sampled_element`]):
//! reading with another sampler reads another texel on most pixels, and that is a mismatch. A
//! dynamic sampler index without `nonuniformEXT` (only in cells whose dynamic descriptor index
//! goes without it) falls under the any-element rule with the rest of the read.
//!
//! Discrimination: on each exactly checked probe pixel, whether every other slot of the array and
//! every other element of the slot holds a different value, i.e. whether reading any wrong
//! element would have been caught there.
pub mod intersect;
pub mod watertight;

use crate::model::{Cell, Resource, Stage};
use crate::probe::spec::{ElementMap, ProbeSpec, ReadIndex, Sampler};
use crate::probe::{self, HitIds, Record, FLAG_HIT, FLAG_PROBE, MAX_AS_VARIANTS};
use crate::scene::Scene;
use intersect::TraceRef;
use crate::model::{Comparison, ElementReads, Mismatch, NO_NONUNIFORM_VUID};

pub const T_REL_TOL: f64 = 1e-3;
pub const BARY_TOL: f64 = 1e-3;

/// Primary rays of every pixel through the scene TLAS, and AS probe rays through every probe TLAS
/// variant.
pub struct SceneReference {
    /// Primary rays through the scene TLAS.
    pub full: Vec<TraceRef>,
    /// `probe[v][pixel]`: the AS probe ray through probe TLAS variant `v`.
    pub probe: Vec<Vec<TraceRef>>,
}

impl SceneReference {
    pub fn compute(scene: &Scene) -> Self {
        let (w, h) = (scene.params.width, scene.params.height);
        let n = scene.instances.len() as u32;
        let variants = probe::as_variants(scene.params.instances);
        let mut full = Vec::with_capacity(scene.params.pixels());
        let mut probe_rays: Vec<Vec<TraceRef>> = (0..variants).map(|_| Vec::with_capacity(scene.params.pixels())).collect();
        let with_floor: Vec<(u32, &crate::scene::Instance)> =
            scene.instances.iter().enumerate().map(|(k, i)| (k as u32, i)).chain(std::iter::once((n, &scene.floor))).collect();
        for y in 0..h {
            for x in 0..w {
                let (o, d) = scene.primary_ray(x, y);
                full.push(intersect::trace(scene, o, d, |_| true));
                let cands = intersect::candidates(scene, o, probe::PROBE_DIR, with_floor.iter().copied());
                for (v, rays) in probe_rays.iter_mut().enumerate() {
                    rays.push(intersect::resolve(&cands, |h| h.instance_id == n || probe::as_variant_has(v as u32, h.instance_id)));
                }
            }
        }
        Self { full, probe: probe_rays }
    }

    pub fn ambiguous_pixels(&self) -> usize {
        self.full.iter().filter(|t| t.ambiguous).count()
    }

    /// The AS probe's value through AS slot `slot` at pixel `p`, and whether it is ambiguous.
    pub fn as_value(&self, slot: u32, p: usize) -> ([f32; 4], bool) {
        let v = probe::as_slot_tlas(slot);
        let t = self.probe[v][p];
        (probe::as_value(t.hit.map(|h| probe::as_custom(v as u32, h.instance_id))), t.ambiguous)
    }
}

/// How the probed value is checked.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ValueRule {
    Exact,
    /// Any element of the probed array is allowed (non-uniform index without NonUniform); for AS
    /// arrays, the first component of any probe TLAS variant's value (`as_values[..variants]`).
    AnyElement { resource: Resource, slots: u32, as_values: [f32; MAX_AS_VARIANTS as usize], variants: u32 },
    /// Only the sampler index is undefined (a dynamic sampler index whose `NonUniform` the
    /// compiler dropped; the texture index is defined): the read slot's element through any of the
    /// sampler heap's samplers (`values[s]` through sampler `s`). Slot and element stay exact.
    AnySampler { values: [[f32; 4]; probe::SAMPLER_MODES.len()] },
}

/// What the driver saw undefined in a cell's probed read: the descriptor index (a non-uniform
/// index without `NonUniform`: any element of the array), or only the sampler index.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Undefined {
    pub descriptor: bool,
    pub sampler: bool,
}

#[derive(Clone, Copy, Debug)]
pub struct Expected {
    pub record: Record,
    pub ambiguous: bool,
    pub rule: ValueRule,
    /// Every other slot / element would have given another value here (exact rule only).
    pub discriminating: bool,
}

impl ValueRule {
    /// Whether `v` is the value of some element of the array.
    fn allows(&self, v: [f32; 4]) -> bool {
        match *self {
            ValueRule::Exact => false,
            ValueRule::AnyElement { resource: Resource::AccelerationStructure, as_values, variants, .. } => {
                v[1..] == [0.0, 0.0, 1.0] && as_values[..variants as usize].contains(&v[0])
            }
            ValueRule::AnySampler { values } => values.contains(&v),
            ValueRule::AnyElement { resource, slots, .. } => {
                let (s, e) = (v[0] - 1.0, v[3] - 0.25);
                let whole = |x: f32, n: u32| x >= 0.0 && x.fract() == 0.0 && (x as u32) < n;
                whole(s, slots) && whole(e, probe::ELEMENTS) && probe::resource_value(resource, s as u32, e as u32) == v
            }
        }
    }
}

/// Whether every other (slot, element) of a buffer/image array holds a value unlike `value`.
fn buffer_value_discriminates(resource: Resource, slots: u32, slot: u32, element: u32) -> bool {
    let value = probe::resource_value(resource, slot, element);
    (0..slots).all(|s| (0..probe::ELEMENTS).all(|e| (s, e) == (slot, element) || probe::resource_value(resource, s, e) != value))
}

/// What `cell` must write for every pixel. (A test that needs a wrong result injects one:
/// `run --inject-fault`, `matrix::inject`.)
pub fn expected(cell: &Cell, scene: &Scene, sref: &SceneReference) -> Vec<Expected> {
    expected_with(cell, scene, sref, Undefined { descriptor: ProbeSpec::of(cell).read == ReadIndex::Undefined, sampler: false })
}

/// What every probed pixel of one cell shares: its spec, the array's size, what is undefined, and
/// the buffer/image discrimination, which depends only on (slot, element): computed once each.
struct Probed<'a> {
    spec: ProbeSpec,
    sref: &'a SceneReference,
    width: u32,
    slots: u32,
    variants: u32,
    undefined: Undefined,
    buffer_disc: Vec<Option<bool>>,
}

impl Probed<'_> {
    /// Fill in what the probe writes at pixel (x, y) (index `p`), whose primary ray got `hit`.
    fn probe(&mut self, e: &mut Expected, (x, y, p): (u32, u32, usize), hit: Option<intersect::Hit>) {
        let spec = self.spec;
        let (rec, slots) = (&mut e.record, self.slots);
        // The stage's runtime value (the dynamic slot, the dynamic sampler's source).
        let base = hit.map(|h| probe::hit_base(spec.base, h.instance_id, h.sphere)).unwrap_or(probe::DYNAMIC_BASE);
        let dynamic = probe::dynamic_slot(spec.stage, x, y, self.width, hit.map(|h| h.instance).unwrap_or(0), base, slots);
        // dynamic_element records the dynamic value as its slot and reads that slot's element
        // from the packed resource (probe::packed_element): the same record.
        let slot = spec.slot.fixed().unwrap_or(dynamic);
        rec.flags |= FLAG_PROBE;
        rec.slot = slot;
        // pin-index: the shader still records its computed slot, but reads the pinned one.
        let read = match spec.read {
            ReadIndex::Pinned => probe::SPEC_SLOT,
            ReadIndex::Defined | ReadIndex::Undefined => slot,
        };
        match spec.element {
            ElementMap::None => {
                let (value, amb) = self.sref.as_value(read, p);
                e.ambiguous |= amb;
                rec.value = value;
                e.discriminating = (0..slots).all(|s| s == read || self.sref.as_value(s, p).0 != value);
            }
            ElementMap::Own | ElementMap::Packed | ElementMap::Layer => {
                let ids = hit.map(|h| HitIds { instance_id: h.instance_id, geometry: h.geometry, primitive: h.primitive }).unwrap_or_default();
                rec.element = probe::element(spec.stage, x, y, ids);
                // A separate-sampler probe reads the texel its sampler's address mode picks.
                let texel = match spec.sampler {
                    Sampler::None => rec.element,
                    Sampler::Constant => probe::sampled_element(probe::SAMPLER_LITERAL, rec.element),
                    Sampler::Dynamic { .. } => probe::sampled_element(probe::sampler_slot(dynamic), rec.element),
                };
                rec.value = probe::resource_value(spec.resource, read, texel);
                let k = (read * probe::ELEMENTS + texel) as usize;
                e.discriminating = *self.buffer_disc[k].get_or_insert_with(|| buffer_value_discriminates(spec.resource, slots, read, texel));
                if self.undefined.sampler && spec.sampler != Sampler::None {
                    let values = std::array::from_fn(|s| probe::resource_value(spec.resource, read, probe::sampled_element(s as u32, rec.element)));
                    e.rule = ValueRule::AnySampler { values };
                    e.discriminating = false;
                }
            }
        }
        if self.undefined.descriptor {
            let mut as_values = [0.0; MAX_AS_VARIANTS as usize];
            if spec.element == ElementMap::None {
                for v in 0..self.variants {
                    let (value, amb) = self.sref.as_value(v, p);
                    as_values[v as usize] = value[0];
                    e.ambiguous |= amb;
                }
            }
            e.rule = ValueRule::AnyElement { resource: spec.resource, slots, as_values, variants: self.variants };
            e.discriminating = false;
        }
    }
}

/// [`expected`] with what is undefined decided by the caller: the driver saw a non-uniform
/// descriptor or sampler index without `NonUniform` — the cell's shape (its spec's
/// [`ReadIndex::Undefined`]) or a compiler that dropped the qualifier
/// (`exec::heap::dropped_nonuniform`).
pub fn expected_with(cell: &Cell, scene: &Scene, sref: &SceneReference, undefined: Undefined) -> Vec<Expected> {
    let spec = ProbeSpec::of(cell);
    let (w, h) = (scene.params.width, scene.params.height);
    let slots = probe::slot_count(spec.resource, scene.params.instances);
    let variants = probe::as_variants(scene.params.instances);
    let buffer_disc = vec![None; (slots * probe::ELEMENTS) as usize];
    let mut probed = Probed { spec, sref, width: w, slots, variants, undefined, buffer_disc };
    let mut out = Vec::with_capacity(scene.params.pixels());
    for y in 0..h {
        for x in 0..w {
            let p = (y * w + x) as usize;
            let mut e = Expected { record: Record::default(), ambiguous: false, rule: ValueRule::Exact, discriminating: false };
            let primary = sref.full[p];
            if spec.stage.is_ray_tracing() {
                e.ambiguous = primary.ambiguous;
                if let Some(hit) = primary.hit {
                    let rec = &mut e.record;
                    rec.flags |= FLAG_HIT;
                    rec.custom = hit.instance;
                    rec.instance_id = hit.instance_id;
                    rec.geometry = hit.geometry;
                    rec.primitive = hit.primitive;
                    rec.t = hit.t as f32;
                    rec.bary = [hit.bary[0] as f32, hit.bary[1] as f32];
                }
            }
            let hit = primary.hit;
            let probe_runs = match spec.stage {
                Stage::Raygen | Stage::Callable | Stage::Fragment | Stage::Compute => true,
                Stage::ClosestHit | Stage::AnyHit => hit.is_some(),
                Stage::Intersection => hit.is_some_and(|h| h.sphere),
                Stage::Miss => hit.is_none(),
            };
            if probe_runs {
                probed.probe(&mut e, (x, y, p), hit);
            }
            out.push(e);
        }
    }
    out
}

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
    for (name, e, g) in [("custom", r.custom, a.custom), ("instance_id", r.instance_id, a.instance_id), ("geometry", r.geometry, a.geometry), ("primitive", r.primitive, a.primitive)] {
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

fn compare_probe(c: &mut Comparison, bad: &mut Bad, e: &Expected, a: &Record) {
    let r = &e.record;
    for (name, x, g) in [("slot", r.slot, a.slot), ("element", r.element, a.element)] {
        if x != g {
            bad.push((name, x.to_string(), g.to_string()));
        }
    }
    let own = r.value == a.value;
    let allowed = !own && e.rule.allows(a.value);
    if !allowed {
        let ve = r.value.iter().zip(a.value).map(|(x, y)| (*x as f64 - y as f64).abs()).fold(0.0, worst);
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
        ValueRule::AnyElement { .. } | ValueRule::AnySampler { .. } => {
            c.any_element_values += 1;
            let reads = c.element_reads.get_or_insert_with(|| ElementReads { outside_spec: NO_NONUNIFORM_VUID.into(), ..Default::default() });
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

pub fn compare(expected: &[Expected], actual: &[Record], width: u32) -> Comparison {
    let mut c = Comparison { pixels: expected.len(), ..Default::default() };
    let mut exact_probe_pixels = 0usize;
    for (i, (e, a)) in expected.iter().zip(actual).enumerate() {
        if e.ambiguous {
            c.ambiguous += 1;
            continue;
        }
        c.compared += 1;
        let r = &e.record;
        if r.flags & FLAG_PROBE != 0 {
            c.probe_checked += 1;
        }
        let mut bad: Bad = Vec::new();
        if r.flags != a.flags {
            bad.push(("flags", r.flags.to_string(), a.flags.to_string()));
        } else {
            if r.flags & FLAG_HIT != 0 {
                compare_hit(&mut c, &mut bad, r, a);
            } else {
                unset_fields_differ(&mut bad, &[
                    ("custom", r.custom, a.custom),
                    ("instance_id", r.instance_id, a.instance_id),
                    ("geometry", r.geometry, a.geometry),
                    ("primitive", r.primitive, a.primitive),
                    ("t", r.t.to_bits(), a.t.to_bits()),
                    ("bary", r.bary[0].to_bits(), a.bary[0].to_bits()),
                    ("bary", r.bary[1].to_bits(), a.bary[1].to_bits()),
                ]);
            }
            if r.flags & FLAG_PROBE != 0 {
                if e.rule == ValueRule::Exact {
                    exact_probe_pixels += 1;
                }
                compare_probe(&mut c, &mut bad, e, a);
            } else {
                let mut fields = vec![("slot", r.slot, a.slot), ("element", r.element, a.element)];
                fields.extend((0..4).map(|k| ("value", r.value[k].to_bits(), a.value[k].to_bits())));
                unset_fields_differ(&mut bad, &fields);
            }
        }
        if !bad.is_empty() {
            c.mismatched_pixels += 1;
            bad.dedup_by(|x, y| x.0 == y.0);
            for (field, exp, act) in bad {
                *c.by_field.entry(field.to_string()).or_default() += 1;
                if c.examples.len() < 8 {
                    let pixel = [i as u32 % width, i as u32 / width];
                    c.examples.push(Mismatch { pixel, field: field.into(), expected: exp, actual: act });
                }
            }
        }
    }
    if let Some(d) = c.discrimination.as_mut() {
        *d /= exact_probe_pixels as f64;
    }
    c
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::SceneParams;
    use crate::model::{AsAccess, DescriptorModel, IndexSource, Resource, SamplerIndex, Workaround};
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
        let geoms: std::collections::BTreeSet<u32> = r.full.iter().filter_map(|t| t.hit.map(|h| h.geometry)).collect();
        assert!(geoms.len() >= 3, "{geoms:?}");
        // the probe rays hit in every variant almost everywhere (the floor), with different instance sets
        for v in &r.probe {
            assert!(v.iter().filter(|t| t.hit.is_some()).count() > n * 9 / 10);
        }
        assert!((0..n).filter(|p| r.probe[0][*p].hit.map(|h| h.instance_id) != r.probe[1][*p].hit.map(|h| h.instance_id)).count() > n / 10);
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
        assert!(cmp.probe_checked > 0 && cmp.probe_checked < cmp.compared, "{} of {}", cmp.probe_checked, cmp.compared);
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
            (BaseSource::ShaderRecord, "the other hit group's", |_, sphere| if sphere { probe::RECORD_BASE_TRIANGLES } else { probe::RECORD_BASE_PROCEDURAL }),
            (BaseSource::Buffer, "push data's", |_, _| probe::DYNAMIC_BASE),
            (BaseSource::Buffer, "entry 0", |_, _| probe::instance_base(0)),
            (BaseSource::Buffer, "no (a dropped)", |_, _| 0),
            (BaseSource::ShaderRecord, "no (a dropped)", |_, _| 0),
            (BaseSource::Buffer, "the next instance's", |i, _| probe::instance_base(i + 1)),
        ];
        for (base, what, wrong) in cases {
            let c = Cell { nonuniform: true, base: Some(base), ..cell(Stage::ClosestHit, IndexSource::Dynamic) };
            let e = expected(&c, scene, r);
            assert!(compare(&e, &records(&e), 64).passed());
            let actual: Vec<Record> = e
                .iter()
                .zip(&r.full)
                .map(|(x, t)| {
                    let mut a = x.record;
                    if let (true, Some(h)) = (a.flags & FLAG_PROBE != 0, t.hit) {
                        a.slot = wrong(h.instance_id, h.sphere) + (a.custom & (slots - probe::DYNAMIC_BASE - 1));
                        a.value = probe::resource_value(Resource::StorageBuffer, a.slot, a.element);
                    }
                    a
                })
                .collect();
            let cmp = compare(&e, &actual, 64);
            assert!(cmp.mismatched_pixels * 2 > cmp.probe_checked, "{base:?}: reading {what} base caught on {} of {}", cmp.mismatched_pixels, cmp.probe_checked);
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
            for (index, nonuniform) in [(IndexSource::Literal, false), (IndexSource::Dynamic, true), (IndexSource::DynamicElement, false)] {
                for sampler in [SamplerIndex::Constant, SamplerIndex::Dynamic] {
                    let c = direct(stage, index, nonuniform, sampler);
                    let e = expected(&c, scene, r);
                    assert!(compare(&e, &records(&e), 64).passed(), "{}", c.id());
                    // The same read with sampler 0 (clamp to edge): element 1 of the slot read.
                    let slot_read = |a: &Record| if index == IndexSource::DynamicElement || index == IndexSource::Dynamic { a.slot } else { probe::LITERAL_SLOT };
                    let wrong = reading(&e, |a| probe::resource_value(Resource::SampledImage, slot_read(a), probe::sampled_element(0, a.element)));
                    let cmp = compare(&e, &wrong, 64);
                    // Constant: sampler 2 against 0 differs on 3 elements of 4. Dynamic: a third
                    // of the pixels use sampler 0 itself, the others differ on 3 elements of 4.
                    let share = if sampler == SamplerIndex::Constant { 0.7 } else { 0.4 };
                    assert!(cmp.mismatched_pixels as f64 > share * cmp.probe_checked as f64, "{}: sampler 0 caught on {} of {}", c.id(), cmp.mismatched_pixels, cmp.probe_checked);
                    // The compiler dropped the sampler index's NonUniform (and only that): any
                    // sampler's texel of the right slot passes, counted as another element; a
                    // wrong slot still mismatches everywhere.
                    if c.sampler_nonuniform() {
                        let e = expected_with(&c, scene, r, Undefined { descriptor: false, sampler: true });
                        let cmp = compare(&e, &wrong, 64);
                        assert!(cmp.passed() && cmp.element_reads.as_ref().is_some_and(|x| x.other > 0), "{}: {:?}", c.id(), cmp.element_reads);
                        let slots = probe::slot_count(Resource::SampledImage, scene.params.instances);
                        let off = reading(&e, |a| probe::resource_value(Resource::SampledImage, (slot_read(a) + 1) % slots, probe::sampled_element(0, a.element)));
                        let cmp = compare(&e, &off, 64);
                        assert_eq!(cmp.mismatched_pixels, cmp.probe_checked, "{}: another slot through any sampler", c.id());
                    }
                    if sampler == SamplerIndex::Dynamic {
                        // The constant sampler instead of the dynamic one.
                        let wrong = reading(&e, |a| probe::resource_value(Resource::SampledImage, slot_read(a), probe::sampled_element(probe::SAMPLER_LITERAL, a.element)));
                        let cmp = compare(&e, &wrong, 64);
                        assert!(cmp.mismatched_pixels * 3 > cmp.probe_checked, "{}: constant sampler caught on {} of {}", c.id(), cmp.mismatched_pixels, cmp.probe_checked);
                    }
                }
            }
        }
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
                let d = expected(&Cell { index: IndexSource::Dynamic, nonuniform: true, ..c }, scene, r);
                assert!(e.iter().zip(&d).all(|(a, b)| a.record == b.record && a.rule == ValueRule::Exact && a.discriminating == b.discriminating));
                assert!(compare(&e, &records(&e), 64).passed());
                let slots = probe::slot_count(resource, scene.params.instances);
                // (slot, element) a faulty driver reads instead: the wrong element, the wrong layer
                // (the neighbouring slot's block), the spec-constant slot's own resource.
                let wrong: [(&str, fn(u32, u32, u32) -> (u32, u32)); 3] = [
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
                    let moved = e.iter().zip(&actual).filter(|(x, a)| !x.ambiguous && x.record.value != a.value).count();
                    assert!(!cmp.passed() && cmp.mismatched_pixels >= moved && moved > 0, "{} wrong {what}: {cmp:?}", c.id());
                }
                assert!(compare(&e, &records(&e), 64).discrimination.is_some_and(|x| x >= 0.99), "{}", c.id());
            }
        }
    }

    /// Bit patterns no correct probe writes where the reference has an ordinary value.
    const GARBAGE: [u32; 7] = [0x7fc0_0000, 0xffc0_0001, 0x7f80_0000, 0xff80_0000, 0xffff_ffff, 0x0000_0001, 0x807f_ffff];

    /// The record with the 32-bit word at byte `offset` replaced by `bits`.
    fn with_word(r: &Record, offset: usize, bits: u32) -> Record {
        let mut b = r.to_bytes();
        b[offset..offset + 4].copy_from_slice(&bits.to_le_bytes());
        Record::from_bytes(&b)
    }

    #[test]
    fn garbage_in_any_record_field_never_passes() {
        let (scene, r) = world();
        let c = cell(Stage::ClosestHit, IndexSource::Literal);
        let e = expected(&c, scene, r);
        let good = records(&e);
        assert!(compare(&e, &good, 64).passed());
        // A triangle hit with both barycentrics well inside, a miss (hit and probe fields unset).
        let tri = e.iter().position(|x| !x.ambiguous && x.record.flags == FLAG_HIT | FLAG_PROBE && x.record.bary.iter().all(|b| *b > 0.05) && x.record.t > 1.0).unwrap();
        let miss = e.iter().position(|x| !x.ambiguous && x.record.flags == 0).unwrap();
        let word_fields: Vec<(&str, usize)> = crate::probe::RECORD_FIELDS
            .iter()
            .filter(|f| !f.glsl_name.starts_with("pad"))
            .flat_map(|f| {
                let words = match f.glsl_type { "vec2" => 2, "vec4" => 4, _ => 1 };
                (0..words).map(move |k| (f.glsl_name, f.offset + 4 * k))
            })
            .collect();
        assert_eq!(word_fields.len(), 14);
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
            let as_access = (resource == Resource::AccelerationStructure).then_some(AsAccess::Descriptor);
            let c = Cell { resource, as_access, nonuniform: true, ..cell(Stage::ClosestHit, IndexSource::Dynamic) };
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
                        a.slot = crate::probe::dynamic_slot(Stage::ClosestHit, 0, 0, 64, a.instance_id, probe::DYNAMIC_BASE, slots);
                        a.value = if resource == Resource::AccelerationStructure { r.as_value(a.slot, p).0 } else { crate::probe::resource_value(resource, a.slot, a.element) };
                    }
                    a
                })
                .collect();
            let cmp = compare(&e, &actual, 64);
            let hits = e.iter().filter(|x| !x.ambiguous && x.record.flags & FLAG_HIT != 0).count();
            assert!(hits > 500);
            assert_eq!(cmp.by_field.get("custom"), Some(&hits), "{cmp:?}");
            let wrong_values = cmp.by_field.get("value").copied().unwrap_or(0);
            assert!(wrong_values * 100 >= hits * 95, "{resource:?}: {wrong_values} of {hits} hit pixels read another value");
        }
    }

    #[test]
    fn a_driver_ignoring_base_shows_in_the_element_reads() {
        let (scene, r) = world();
        let c = Cell { resource: Resource::UniformBuffer, ..cell(Stage::ClosestHit, IndexSource::Dynamic) };
        let e = expected(&c, scene, r);
        let base_dropped = reading(&e, |a| crate::probe::resource_value(Resource::UniformBuffer, a.slot - crate::probe::DYNAMIC_BASE, a.element));
        let cmp = compare(&e, &base_dropped, 64);
        let reads = cmp.element_reads.clone().expect("no-nonuniform cells count their reads");
        assert_eq!(reads.outside_spec, NO_NONUNIFORM_VUID);
        assert_eq!((reads.own, reads.neither), (0, 0), "{reads:?}");
        assert_eq!(reads.other, cmp.any_element_values);
        assert!(reads.other > 100);
        assert!(cmp.passed(), "which element is read is undefined without nonuniformEXT");
        assert_eq!(cmp.discrimination, None);
        // the same reads with nonuniformEXT are mismatches
        let nu = Cell { nonuniform: true, ..c };
        let cmp = compare(&expected(&nu, scene, r), &base_dropped, 64);
        assert_eq!(cmp.by_field.get("value"), Some(&reads.other));
        // and the own reads are counted as own
        let cmp = compare(&e, &records(&e), 64);
        assert_eq!(cmp.element_reads.map(|x| (x.own, x.other)), Some((reads.other, 0)));
    }

    #[test]
    fn elements_are_read_at_per_primitive_offsets() {
        let (scene, r) = world();
        let c = cell(Stage::ClosestHit, IndexSource::Literal);
        let e = expected(&c, scene, r);
        let elements: std::collections::BTreeSet<u32> = e.iter().filter(|x| x.record.flags & FLAG_PROBE != 0).map(|x| x.record.element).collect();
        assert_eq!(elements.len() as u32, crate::probe::ELEMENTS);
        // a driver that always reads v[0] is caught wherever the element is not 0
        let v0 = reading(&e, |a| crate::probe::resource_value(Resource::StorageBuffer, a.slot, 0));
        let cmp = compare(&e, &v0, 64);
        let nonzero = e.iter().filter(|x| !x.ambiguous && x.record.flags & FLAG_PROBE != 0 && x.record.element != 0).count();
        assert_eq!(cmp.by_field.get("value"), Some(&nonzero));
    }

    #[test]
    fn nonuniform_index_without_qualifier_accepts_any_element_but_not_garbage() {
        let (scene, r) = world();
        let c = Cell { resource: Resource::UniformBuffer, ..cell(Stage::Raygen, IndexSource::Dynamic) };
        let e = expected(&c, scene, r);
        let mut actual = records(&e);
        // Another element's value (as a driver reading one lane's descriptor would return): fine.
        actual[10].value = crate::probe::resource_value(Resource::UniformBuffer, 0, 2);
        let cmp = compare(&e, &actual, 64);
        assert!(cmp.passed(), "{cmp:?}");
        assert_eq!(cmp.any_element_values, cmp.compared);
        assert_eq!(cmp.element_reads.as_ref().map(|x| x.other), Some(1));
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
        let base = Cell { resource: Resource::AccelerationStructure, as_access: Some(AsAccess::Descriptor), ..cell(Stage::Raygen, IndexSource::Dynamic) };
        let cells = [
            Cell { as_access: Some(AsAccess::Address), ..base },
            Cell { as_access: Some(AsAccess::AddressPatched), ..base },
            Cell { patch: Some(Workaround::AsToAddress), ..base },
            Cell { resource: Resource::StorageBuffer, as_access: None, patch: Some(Workaround::SsboToAddress), ..base },
        ];
        for c in cells {
            let e = expected(&c, scene, r);
            let other_slot = reading(&e, |a| {
                let s = (a.slot + 1) % crate::probe::slot_count(c.resource, scene.params.instances);
                if c.resource == Resource::AccelerationStructure { crate::probe::as_value(Some(crate::probe::as_custom(s, 0))) } else { crate::probe::resource_value(c.resource, s, a.element) }
            });
            let cmp = compare(&e, &other_slot, 64);
            assert!(!cmp.passed() && cmp.element_reads.is_none() && cmp.discrimination.is_some(), "{}: {cmp:?}", c.id());
        }
        // the descriptor variant itself is outside the spec's guarantees
        assert!(compare(&expected(&base, scene, r), &records(&expected(&base, scene, r)), 64).element_reads.is_some());
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
        let scene = Scene::build(&SceneParams { instances: 256, width: 32, height: 32, ..SceneParams::default() });
        let r = SceneReference::compute(&scene);
        assert_eq!(r.probe.len() as u32, crate::probe::slot_count(Resource::AccelerationStructure, 256));
        for stage in [Stage::Raygen, Stage::ClosestHit, Stage::Miss, Stage::Compute] {
            let c = Cell { resource: Resource::AccelerationStructure, as_access: Some(AsAccess::Descriptor), nonuniform: true, ..cell(stage, IndexSource::Dynamic) };
            let e = expected(&c, &scene, &r);
            let cmp = compare(&e, &records(&e), 32);
            assert!(cmp.discrimination.is_some_and(|d| d >= 0.5), "{}: {:?}", c.id(), cmp.discrimination);
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
            for c in std::iter::once(base).chain(base.applicable_patches().into_iter().map(|p| Cell { patch: Some(p), ..base })) {
                let e = expected(&c, scene, r);
                let cmp = compare(&e, &records(&e), 64);
                assert!(cmp.passed(), "{}: {cmp:?}", c.id());
                let probed = e.iter().filter(|x| !x.ambiguous && x.record.flags & FLAG_PROBE != 0).count();
                assert!(probed > 50, "{}: only {probed} probe pixels", c.id());
                match (cmp.discrimination, &cmp.element_reads) {
                    (Some(d), None) => {
                        checked += 1;
                        if d < 0.5 {
                            weak.push(format!("{} {d:.2}", c.id()));
                        }
                    }
                    (None, Some(reads)) => assert_eq!((reads.own, reads.other, reads.neither), (probed, 0, 0), "{}", c.id()),
                    other => panic!("{}: {other:?}", c.id()),
                }
            }
        }
        assert!(weak.is_empty(), "cells below 50% discrimination: {weak:?}");
        assert!(checked > 500, "{checked}");
    }
}
