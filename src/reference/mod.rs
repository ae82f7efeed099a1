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
//! patches) a non-uniform index reads memory, which is well defined: those cells are exact. So
//! are `layout(descriptor_heap)` reads (`heap_access=direct`), with or without `nonuniformEXT`:
//! their modules declare `DescriptorHeapEXT`, and the heap "can be accessed non-uniformly, with no
//! further decoration required" (Vulkan 1.4.360, Descriptor Heap Interface; the VUIDs above apply
//! only where that capability is not declared). Which module declares what is `exec`'s to say
//! (`patches::uniformity`); a set/binding index whose `nonuniformEXT` a compiler dropped is
//! undefined as the driver saw it.
//!
//! Separate-sampler probes (`sampler` axis, direct heap sampled images) sample a shifted coordinate,
//! so their value is the texel their sampler's address mode picks ([`probe::sampled_element`]):
//! reading with another sampler reads another texel on most pixels, and that is a mismatch, with
//! or without `nonuniformEXT` on a dynamic sampler index (heap modules: exact).
//!
//! Lane evidence (`probe::FLAG_LANES`, where the probe measured it: [`expect_lanes`]): each such
//! record's lane words must be consistent ([`lanes::inconsistency`]); [`lanes::Lanes`] reads the
//! device's subgroups back from them. Records without it must hold zero lane words.
//!
//! Mutants (`run --mutants`): [`mutation`] is the reference run with a mutant's mutation (which
//! slot, sampler, packed element or value the mutated probe reads), to predict whether it applies
//! and what the comparison must flag; a mutant attempt is judged with [`expected`] of its
//! unmutated cell.
//!
//! Discrimination: on each exactly checked probe pixel, whether every other slot of the array and
//! every other element of the slot holds a different value, i.e. whether reading any wrong
//! element would have been caught there.
mod boxes;
pub mod bvh;
mod compare;
pub mod intersect;
mod key;
pub mod lanes;
pub mod limits;
pub mod mutation;
mod rules;
pub mod watertight;

use crate::model::{Cell, LaneEvidence, Resource, Stage};
use crate::probe::spec::{ElementMap, ProbeSpec, ReadIndex, Sampler};
use crate::probe::{
    self, HitIds, Record, FLAG_HIT, FLAG_LANES, FLAG_LAYOUT, FLAG_PROBE, MAX_AS_VARIANTS,
};
use crate::scene::{Geometry, Scene};
pub use compare::{compare, compare_with};
use intersect::TraceRef;
pub use key::ExpectedKey;
pub use rules::{Expected, Undefined, ValueRule, BARY_TOL, T_REL_TOL};

/// Primary rays of every pixel through the scene TLAS, and AS probe rays through every probe TLAS
/// variant, traced the first time a cell reads them ([`SceneReference::as_probe`]).
pub struct SceneReference {
    /// Primary rays through the scene TLAS.
    pub full: Vec<TraceRef>,
    /// The AS probe rays, traced on every core at the first read of a cell that needs them
    /// (its AS probe, or an undefined read judged against every variant's value): the CLI's
    /// scene summary reads only `full`, and a re-run worker's cells often have no AS probe
    /// (90 ms of such a worker on lavapipe 25).
    as_probe: std::sync::OnceLock<AsProbe>,
    /// What culls the scene's triangles, built once for the primary rays and kept for the AS
    /// probe rays.
    cull: intersect::Culling,
}

/// The AS probe rays of every pixel through every probe TLAS variant, and their values.
pub struct AsProbe {
    /// `rays[v][pixel]`: the AS probe ray through probe TLAS variant `v`.
    pub rays: Vec<Vec<TraceRef>>,
    /// The AS probe's value and ambiguity per pixel and variant (`[pixel * variants + v]`), read
    /// from `rays` once: what [`AsProbe::value`] answers for every cell, the variants of one
    /// pixel side by side.
    table: Vec<([f32; 4], bool)>,
}

/// How many of `scene`'s primary rays are ambiguous (what [`SceneReference::ambiguous_pixels`]
/// counts), traced alone — no AS probe rays — on every core: the supervisor's scene summary needs
/// only this count, and the whole reference is the worker's.
pub fn ambiguous_primaries(scene: &Scene) -> usize {
    let (w, h) = (scene.params.width, scene.params.height);
    let cull = intersect::Culling::of(scene);
    let rows = on_every_core(h, |y| {
        (0..w)
            .filter(|&x| {
                let (o, d) = scene.primary_ray(x, y);
                intersect::trace((scene, &cull), o, d, |_| true).ambiguous
            })
            .count()
    });
    rows.into_iter().sum()
}

/// `row(y)` for every `y` below `rows`, in order, the rows spread over every core (the
/// reference is pure and per pixel: the same results as one thread, sooner).
fn on_every_core<T: Send>(rows: u32, row: impl Fn(u32) -> T + Sync) -> Vec<T> {
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let threads = threads.min(rows as usize).max(1) as u32;
    let chunk = rows.div_ceil(threads);
    let row = &row;
    std::thread::scope(|s| {
        let parts: Vec<_> = (0..threads)
            .map(|t| {
                s.spawn(move || (t * chunk..rows.min((t + 1) * chunk)).map(row).collect::<Vec<T>>())
            })
            .collect();
        parts
            .into_iter()
            .flat_map(|p| p.join().unwrap_or_else(|e| std::panic::resume_unwind(e)))
            .collect::<Vec<T>>()
    })
}

impl SceneReference {
    /// Every pixel's primary ray traced (the AS probe rays wait for a cell that reads them).
    pub fn compute(scene: &Scene) -> Self {
        let (w, h) = (scene.params.width, scene.params.height);
        let cull = intersect::Culling::of(scene);
        let rows = on_every_core(h, |y| {
            (0..w)
                .map(|x| {
                    let (o, d) = scene.primary_ray(x, y);
                    intersect::trace((scene, &cull), o, d, |_| true)
                })
                .collect::<Vec<_>>()
        });
        let full = rows.into_iter().flatten().collect();
        Self { full, as_probe: std::sync::OnceLock::new(), cull }
    }

    pub fn ambiguous_pixels(&self) -> usize {
        self.full.iter().filter(|t| t.ambiguous).count()
    }

    /// The AS probe rays of `scene` (the scene `full` was traced in), traced at the first call.
    pub fn as_probe(&self, scene: &Scene) -> &AsProbe {
        debug_assert_eq!(scene.params.pixels(), self.full.len(), "another scene");
        self.as_probe.get_or_init(|| AsProbe::trace(scene, &self.cull))
    }

    /// Whether the AS probe rays have been traced.
    pub fn as_probe_traced(&self) -> bool {
        self.as_probe.get().is_some()
    }
}

impl AsProbe {
    /// The AS probe ray of every pixel through every variant, on every core (`cull`: the
    /// scene's, built with its reference).
    fn trace(scene: &Scene, cull: &intersect::Culling) -> Self {
        let (w, h) = (scene.params.width, scene.params.height);
        let n = scene.instances.len() as u32;
        let variants = probe::as_variants(scene.params.instances);
        let with_floor: Vec<(u32, &crate::scene::Instance)> = scene
            .instances
            .iter()
            .enumerate()
            .map(|(k, i)| (k as u32, i))
            .chain(std::iter::once((n, &scene.floor)))
            .collect();
        // One pixel: the AS probe ray through every variant.
        let pixel = |x: u32, y: u32| {
            let (o, _) = scene.primary_ray(x, y);
            let cands = intersect::candidates(
                (scene, cull),
                o,
                probe::PROBE_DIR,
                with_floor.iter().copied(),
            );
            (0..variants)
                .map(|v| {
                    intersect::resolve(&cands, |h| {
                        h.instance_id == n || probe::as_variant_has(v, h.instance_id)
                    })
                })
                .collect::<Vec<TraceRef>>()
        };
        let rows = on_every_core(h, |y| (0..w).map(|x| pixel(x, y)).collect::<Vec<_>>());
        let mut rays: Vec<Vec<TraceRef>> =
            (0..variants).map(|_| Vec::with_capacity(scene.params.pixels())).collect();
        for probes in rows.into_iter().flatten() {
            for (r, t) in rays.iter_mut().zip(probes) {
                r.push(t);
            }
        }
        let pixels = scene.params.pixels();
        let table = (0..pixels)
            .flat_map(|p| (0..rays.len()).map(move |v| (p, v)))
            .map(|(p, v)| {
                let t = rays[v][p];
                (Self::probe_value(v, t), t.ambiguous)
            })
            .collect();
        AsProbe { rays, table }
    }

    /// The AS probe's value through AS slot `slot` at pixel `p`, and whether it is ambiguous.
    pub fn value(&self, slot: u32, p: usize) -> ([f32; 4], bool) {
        let v = probe::as_slot_tlas(slot);
        let variants = self.rays.len();
        if v >= variants || p >= self.table.len() / variants.max(1) {
            // no such variant or pixel: indexing `rays` says so, as it always did
            let t = self.rays[v][p];
            return (Self::probe_value(v, t), t.ambiguous);
        }
        self.table[p * variants + v]
    }

    /// The AS probe's value for probe ray `t` through TLAS variant `v`.
    fn probe_value(v: usize, t: TraceRef) -> [f32; 4] {
        probe::as_value(t.hit.map(|h| probe::as_custom(v as u32, h.instance_id)))
    }
}

/// Whether every other (slot, element) of a buffer/image array holds a value unlike `value`.
fn buffer_value_discriminates(resource: Resource, slots: u32, slot: u32, element: u32) -> bool {
    let value = probe::resource_value(resource, slot, element);
    (0..slots).all(|s| {
        (0..probe::ELEMENTS)
            .all(|e| (s, e) == (slot, element) || probe::resource_value(resource, s, e) != value)
    })
}

/// What `cell` must write for every pixel. (A test that needs a wrong result injects one:
/// `run --inject-fault`, `matrix::inject`.)
pub fn expected(cell: &Cell, scene: &Scene, sref: &SceneReference) -> Vec<Expected> {
    expected_with(
        cell,
        scene,
        sref,
        Undefined { descriptor: ProbeSpec::of(cell).read == ReadIndex::Undefined },
    )
}

/// Where the probe measured its lane evidence (`lanes.recorded()`), every probe pixel of
/// `expected` must carry it (`FLAG_LANES`, consistent lane words); elsewhere the lane words stay 0.
pub fn expect_lanes(expected: &mut [Expected], lanes: LaneEvidence) {
    if lanes.recorded() {
        for e in expected.iter_mut().filter(|e| e.record.flags & FLAG_PROBE != 0) {
            e.record.flags |= FLAG_LANES;
        }
    }
}

/// What every probed pixel of one cell shares: its spec, the array's size, what is undefined, and
/// the buffer/image discrimination, which depends only on (slot, element): computed once each.
struct Probed<'a> {
    spec: ProbeSpec,
    scene: &'a Scene,
    sref: &'a SceneReference,
    width: u32,
    /// The array's slots and the hit stages' mask of the custom index (`probe::dynamic_slot`).
    slots: (u32, u32),
    variants: u32,
    undefined: Undefined,
    buffer_disc: Vec<Option<bool>>,
    /// A mutant's mutation (`mutation`): what the mutated probe reads instead.
    mutation: Option<&'a mutation::Mutation>,
    /// A mutated `per_mesh` cell's buffers, per mesh slot (`scene::layout::LayoutData::mesh_words`):
    /// what a hit reads through a mutant's wrong slot; empty otherwise.
    mesh_words: Vec<Vec<u32>>,
}

impl Probed<'_> {
    /// Fill in what the probe writes at pixel (x, y) (index `p`), whose primary ray got `hit`.
    fn probe(
        &mut self,
        e: &mut Expected,
        (x, y, p): (u32, u32, usize),
        hit: Option<intersect::Hit>,
    ) {
        let spec = self.spec;
        let dynamic = self.dynamic_slot(x, y, hit);
        if let (Some(_), Some(h)) = (spec.layout, hit) {
            return self.fetch_layout(e, dynamic, (h, p));
        }
        // dynamic_element records the dynamic value as its slot and reads that slot's element
        // from the packed resource (probe::packed_element): the same record.
        let slot = spec.slot.fixed().unwrap_or(dynamic);
        e.record.flags |= FLAG_PROBE;
        e.record.slot = slot;
        // pin-index: the shader still records its computed slot, but reads the pinned one.
        let read = match spec.read {
            ReadIndex::Pinned => probe::SPEC_SLOT,
            ReadIndex::Defined | ReadIndex::Undefined => slot,
        };
        let read = match self.mutation {
            Some(m) => m.read_slot(read, self.masked_slot(x, y, hit), p),
            None => read,
        };
        match spec.element {
            ElementMap::None => self.read_as(e, read, p),
            ElementMap::Own | ElementMap::Packed | ElementMap::Layer => {
                self.read_resource(e, (x, y), hit, (read, dynamic))
            }
        }
        if self.undefined.descriptor {
            self.any_element(e, p);
        }
        if let Some(m) = self.mutation {
            e.record.value = m.value(e.record.value);
        }
    }

    /// The stage's dynamic value without its base (`custom & mask` in hit stages): what
    /// `base-dropped` reads.
    fn masked_slot(&self, x: u32, y: u32, hit: Option<intersect::Hit>) -> u32 {
        let custom = hit.map(|h| h.instance).unwrap_or(0);
        probe::dynamic_slot(self.spec.stage, (x, y, self.width), custom, 0, self.slots)
    }

    /// The stage's runtime value at pixel (x, y): the dynamic slot, the dynamic sampler's source.
    fn dynamic_slot(&self, x: u32, y: u32, hit: Option<intersect::Hit>) -> u32 {
        let spec = self.spec;
        let base =
            hit.map(|h| spec.base.value(h.instance_id, h.sphere)).unwrap_or(probe::DYNAMIC_BASE);
        let custom = hit.map(|h| h.instance).unwrap_or(0);
        probe::dynamic_slot(spec.stage, (x, y, self.width), custom, base, self.slots)
    }

    /// A scene-layout closest-hit on triangle hit `h`, at mesh slot `slot`: the scene's own
    /// triangle (`scene::layout::fetch`), whichever layout it went through — so both layouts'
    /// records are the same. Every other triangle's data differs somewhere in its words (its
    /// material index is its primitive entry's own), so the read discriminates. A mutant's
    /// rewritten descriptor index (`mutants::site`) reads another slot's mesh buffer
    /// (`per_mesh`) or another texture element (texture cells); the record keeps the slot and
    /// the element the cell computed.
    fn fetch_layout(&self, e: &mut Expected, slot: u32, (h, p): (intersect::Hit, usize)) {
        let Geometry::Mesh(mesh) = self.scene.instances[h.instance_id as usize].geometry else {
            return;
        };
        let read = |index: u32| self.mutation.map_or(index, |m| m.read_slot(index, index, p));
        let own = crate::scene::layout::fetch(self.scene, mesh, h.geometry, h.primitive);
        let f = match self.mesh_words.get(read(slot) as usize) {
            Some(w) if read(slot) != slot => {
                crate::scene::layout::read_mesh_words(w, h.geometry, h.primitive).unwrap_or(own)
            }
            Some(_) | None => own,
        };
        let rec = &mut e.record;
        rec.flags |= FLAG_PROBE | FLAG_LAYOUT;
        rec.slot = slot;
        [rec.element, rec.pad, rec.pad2] = f.indices;
        rec.value = f.value();
        if self.spec.layout_textures() {
            // The texture cell samples the entry's material's texture (`scene::textures`); a
            // scene without textures never runs it (the executor refuses the cell).
            if let Ok(t) = self.scene.textures.decoded() {
                rec.value = t.fetch_read(f.material, h.primitive, read).value();
            }
        }
        e.discriminating = true;
    }

    /// An acceleration structure probe reading AS slot `read` at pixel `p`.
    fn read_as(&self, e: &mut Expected, read: u32, p: usize) {
        let probe = self.sref.as_probe(self.scene);
        let (value, amb) = probe.value(read, p);
        e.ambiguous |= amb;
        e.record.value = value;
        e.discriminating = (0..self.slots.0).all(|s| s == read || probe.value(s, p).0 != value);
    }

    /// A buffer or image probe reading slot `read` at pixel (x, y); `dynamic` is the stage's
    /// runtime value (a dynamic sampler's source).
    fn read_resource(
        &mut self,
        e: &mut Expected,
        (x, y): (u32, u32),
        hit: Option<intersect::Hit>,
        (read, dynamic): (u32, u32),
    ) {
        let spec = self.spec;
        let rec = &mut e.record;
        let ids = hit
            .map(|h| HitIds {
                instance_id: h.instance_id,
                geometry: h.geometry,
                primitive: h.primitive,
            })
            .unwrap_or_default();
        rec.element = probe::element(spec.stage, x, y, ids);
        // A separate-sampler probe reads the texel its sampler's address mode picks.
        let sampler = |s: u32| self.mutation.map_or(s, |m| m.sampler(s));
        let texel = match spec.sampler {
            Sampler::None => rec.element,
            Sampler::Constant => {
                probe::sampled_element(sampler(probe::SAMPLER_LITERAL), rec.element)
            }
            Sampler::Dynamic { .. } => {
                probe::sampled_element(sampler(probe::sampler_slot(dynamic)), rec.element)
            }
        };
        let (read, texel) = self.mutation.map_or((read, texel), |m| m.packed(read, texel));
        rec.value = probe::resource_value(spec.resource, read, texel);
        let k = (read * probe::ELEMENTS + texel) as usize;
        let slots = self.slots.0;
        e.discriminating = *self.buffer_disc[k]
            .get_or_insert_with(|| buffer_value_discriminates(spec.resource, slots, read, texel));
    }

    /// An undefined descriptor read: judged by the other-lane heuristic ([`ValueRule::AnyElement`]).
    fn any_element(&self, e: &mut Expected, p: usize) {
        let mut as_values = [0.0; MAX_AS_VARIANTS as usize];
        if self.spec.element == ElementMap::None {
            let probe = self.sref.as_probe(self.scene);
            for v in 0..self.variants {
                let (value, amb) = probe.value(v, p);
                as_values[v as usize] = value[0];
                e.ambiguous |= amb;
            }
        }
        // Set/binding reads only (heap reads are never undefined): no separate sampler, so the
        // lane's texel is its element.
        e.rule = ValueRule::AnyElement {
            resource: self.spec.resource,
            texel: e.record.element,
            as_values,
            variants: self.variants,
        };
        e.discriminating = false;
    }
}

/// [`expected`] with what is undefined decided by the caller: the driver saw a non-uniform
/// set/binding descriptor index without `NonUniform` — the cell's shape (its spec's
/// [`ReadIndex::Undefined`]) or a compiler that dropped the qualifier — in a module that does not
/// declare `DescriptorHeapEXT` (`patches::uniformity`).
pub fn expected_with(
    cell: &Cell,
    scene: &Scene,
    sref: &SceneReference,
    undefined: Undefined,
) -> Vec<Expected> {
    let mut out = Vec::new();
    expected_probed(&mut out, cell, scene, sref, (undefined, None));
    out
}

/// [`expected_with`] written into `out` (cleared first): a caller judging cell after cell keeps
/// one buffer, and its pages stay mapped and warm.
pub fn expected_into(
    out: &mut Vec<Expected>,
    cell: &Cell,
    (scene, sref): (&Scene, &SceneReference),
    undefined: Undefined,
) {
    expected_probed(out, cell, scene, sref, (undefined, None));
}

/// [`expected_with`] of the probe mutated as `m` says: what a mutant's records are predicted to
/// be (`mutation`).
pub fn expected_mutated(
    cell: &Cell,
    scene: &Scene,
    sref: &SceneReference,
    undefined: Undefined,
    m: &mutation::Mutation,
) -> Vec<Expected> {
    let mut out = Vec::new();
    expected_probed(&mut out, cell, scene, sref, (undefined, Some(m)));
    out
}

/// What mutant `site` is predicted to do to `cell` after its run: the reference run with the
/// mutation (a broadcast's leaders from the device's `records`: [`lanes::Lanes`]), judged as
/// `undefined` and with the lane evidence `lanes` as the cell is, against the cell's own
/// `expected` records (`mutation::predict`).
pub fn mutant_after_run(
    cell: &Cell,
    (scene, sref): (&Scene, &SceneReference),
    (undefined, lanes): (Undefined, LaneEvidence),
    site: crate::mutants::Mutation,
    (expected, records): (&[Expected], &[Record]),
) -> crate::model::MutantPrediction {
    let mut m = mutation::Mutation::new(site);
    let from_lanes = mutation::broadcast(site);
    let subgroups = lanes::Lanes::for_stage(records, cell.stage);
    if from_lanes {
        let textures = ProbeSpec::of(cell).layout_textures();
        m.leader_slots = mutation::leader_slots(expected, (records, &subgroups), textures);
    }
    let mut mutated = expected_mutated(cell, scene, sref, undefined, &m);
    expect_lanes(&mut mutated, lanes);
    let judged = lanes.usable().then_some(&subgroups);
    let p = mutation::predict(expected, &mutated, (Some(records), judged), scene.params.width);
    crate::model::MutantPrediction { from_lanes, ..p }
}

/// Whether mutant `site` can apply to `cell` before anything ran: the prediction without the
/// device's records (a broadcast: `mutation::one_slot`).
pub fn mutant_before_run(
    cell: &Cell,
    (scene, sref): (&Scene, &SceneReference),
    undefined: Undefined,
    site: crate::mutants::Mutation,
) -> crate::model::MutantPrediction {
    let expected = expected_with(cell, scene, sref, undefined);
    if mutation::broadcast(site) {
        return mutation::one_slot(&expected, ProbeSpec::of(cell).layout_textures());
    }
    let mutated = expected_mutated(cell, scene, sref, undefined, &mutation::Mutation::new(site));
    mutation::predict(&expected, &mutated, (None, None), scene.params.width)
}

/// Every pixel's expected record, written into `out` (cleared first).
fn expected_probed(
    out: &mut Vec<Expected>,
    cell: &Cell,
    scene: &Scene,
    sref: &SceneReference,
    (undefined, mutation): (Undefined, Option<&mutation::Mutation>),
) {
    let spec = ProbeSpec::of(cell);
    let (w, h) = (scene.params.width, scene.params.height);
    let slots = probe::slot_count(spec.resource, scene.params.instances);
    let variants = probe::as_variants(scene.params.instances);
    let buffer_disc = vec![None; (slots * probe::ELEMENTS) as usize];
    // A per_mesh geometry cell's mutant reads another slot's buffer (a texture cell's rewrites
    // its texture element: binding 2 holds the textures there).
    let per_mesh = spec.layout == Some(crate::model::SceneLayout::PerMesh);
    let mesh_words = if per_mesh && !spec.layout_textures() && mutation.is_some() {
        crate::scene::layout::LayoutData::new(scene)
            .map_or(vec![], |d| (0..d.slot_mesh.len()).map(|s| d.mesh_words(scene, s)).collect())
    } else {
        vec![]
    };
    let mut probed = Probed {
        spec,
        scene,
        sref,
        width: w,
        slots: (slots, probe::dyn_mask(spec.resource, scene.params.instances)),
        variants,
        undefined,
        buffer_disc,
        mutation,
        mesh_words,
    };
    out.clear();
    out.reserve(scene.params.pixels());
    for y in 0..h {
        for x in 0..w {
            let p = (y * w + x) as usize;
            let mut e = Expected {
                record: Record::default(),
                ambiguous: false,
                rule: ValueRule::Exact,
                discriminating: false,
            };
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
                // A scene-layout closest-hit fetches triangles: the sphere's group has no probe.
                Stage::ClosestHit if spec.layout.is_some() => hit.is_some_and(|h| !h.sphere),
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
}

/// The last cell's expected records and their key, kept from cell to cell (one scene: a caller
/// keeps one memo per scene).
#[derive(Default)]
pub struct ExpectedMemo {
    key: Option<ExpectedKey>,
    records: Vec<Expected>,
}

impl ExpectedMemo {
    /// `cell`'s expected records judged as `undefined` says, with lane evidence `lanes`: the kept
    /// ones where its key is the last cell's, else computed into the kept buffer.
    pub fn get(
        &mut self,
        cell: &Cell,
        world: (&Scene, &SceneReference),
        undefined: Undefined,
        lanes: LaneEvidence,
    ) -> &[Expected] {
        let key = ExpectedKey::of(cell, undefined, lanes);
        if self.key != Some(key) {
            expected_into(&mut self.records, cell, world, undefined);
            expect_lanes(&mut self.records, lanes);
            self.key = Some(key);
        }
        &self.records
    }
}

#[cfg(test)]
mod tests;
