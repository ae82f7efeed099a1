//! The axis registry: every axis of a cell declared once — its name, help line, values and
//! stand-ins, whether bisection prefers it, how it appears in a cell id and in a sentence, and how
//! a cell reads and sets it. Cell ids and their parse, `--filter` and its help, the `caps`
//! matrix's axes, bisection's axis order and isolation sentences all derive from [`AXES`].
//! What an axis value *means* for the probe is elsewhere, in one exhaustive match each
//! (`probe::spec` for the shaders and the reference, `caps::support` for the device).
//!
//! Adding an axis: a variant of [`AxisId`], an entry here, a field of [`Cell`]; the compiler then
//! lists the exhaustive matches that must say what it means, and `tests` below check that every
//! consumer covers every value.
use super::axes::{
    AsAccess, BaseSource, DescriptorModel, HeapAccess, IndexSource, Reorder, Resource,
    SamplerIndex, SceneLayout, Stage,
};
use super::cell::{Canary, Cell, Workaround};
use super::mutant::Mutant;

/// The axes, closed: a consumer that must say something about each one matches this exhaustively.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum AxisId {
    Stage,
    Resource,
    Index,
    Nonuniform,
    AsAccess,
    DescriptorModel,
    HeapAccess,
    Canary,
    Reorder,
    Base,
    Sampler,
    Patch,
    Mutant,
    SceneLayout,
}

/// Whether bisection describes a fault by this axis before the others: secondary axes (where a
/// value comes from) only stand in a minimal conjunction when no primary term separates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Rank {
    Primary,
    Secondary,
}

/// How an axis's value appears in a cell id (`stage.resource.index[.nonuniform]…`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Segment {
    /// `.value`; stand-ins are left out.
    Value,
    /// `.word` when the (boolean) value is `true`.
    Flag(&'static str),
    /// `.prefix` + value; stand-ins are left out.
    Prefixed(&'static str),
    /// `.prefix` + value after every other segment (the workaround applied to the cell); stand-ins
    /// are left out.
    Last(&'static str),
    /// The whole id is `canary.<value>` (the other axes are the canary's carrier).
    Whole,
}

/// One axis, declared once.
pub struct Axis {
    pub id: AxisId,
    pub name: &'static str,
    /// One line for `--filter` help.
    pub help: &'static str,
    /// Its own values, in plan order.
    pub values: &'static [&'static str],
    /// What a cell reads where it holds no value of its own (`none` where the axis does not
    /// apply; `push_data`, the default base of cells that have one).
    pub stand_ins: &'static [&'static str],
    pub rank: Rank,
    pub segment: Segment,
    /// The cell's value, or the stand-in that applies to it.
    pub get: fn(&Cell) -> &'static str,
    /// Set a value (never a stand-in) on a cell; false when it is not one of `values`.
    pub set: fn(&mut Cell, &str) -> bool,
    /// The cell's words in an isolation sentence (`describe`); empty where there is nothing to say.
    pub phrase: fn(&Cell) -> String,
}

impl Axis {
    /// Every value a filter accepts: the values, then the stand-ins.
    pub fn filter_values(&self) -> impl Iterator<Item = &'static str> {
        self.values.iter().chain(self.stand_ins).copied()
    }
}

fn set_opt<T>(slot: &mut Option<T>, parse: fn(&str) -> Option<T>, v: &str) -> bool {
    parse(v).map(|x| *slot = Some(x)).is_some()
}

fn set_req<T>(slot: &mut T, parse: fn(&str) -> Option<T>, v: &str) -> bool {
    parse(v).map(|x| *slot = x).is_some()
}

/// Every axis, in the order filters, bisection and exact filters list them (the order of the
/// first releases' reports); cell ids follow it too, with [`Segment::Last`] segments at the end.
pub const AXES: &[Axis] = &[
    Axis {
        id: AxisId::Stage,
        name: "stage",
        help: "the stage that does the probed read",
        values: Stage::NAMES,
        stand_ins: &[],
        rank: Rank::Primary,
        segment: Segment::Value,
        get: |c| c.stage.as_str(),
        set: |c, v| set_req(&mut c.stage, Stage::parse, v),
        phrase: |c| c.stage.to_string(),
    },
    Axis {
        id: AxisId::Resource,
        name: "resource",
        help: "the kind of descriptor it reads",
        values: Resource::NAMES,
        stand_ins: &[],
        rank: Rank::Primary,
        segment: Segment::Value,
        get: |c| c.resource.as_str(),
        set: |c, v| set_req(&mut c.resource, Resource::parse, v),
        phrase: |c| format!(" reading {}", c.resource),
    },
    Axis {
        id: AxisId::Index,
        name: "index",
        help: "how the descriptor (or element) is chosen",
        values: IndexSource::NAMES,
        stand_ins: &[],
        rank: Rank::Primary,
        segment: Segment::Value,
        get: |c| c.index.as_str(),
        set: |c, v| set_req(&mut c.index, IndexSource::parse, v),
        phrase: |c| format!(" with {} index", c.index),
    },
    Axis {
        id: AxisId::Nonuniform,
        name: "nonuniform",
        help: "nonuniformEXT on a dynamic index",
        values: &["true"],
        stand_ins: &["false"],
        rank: Rank::Primary,
        segment: Segment::Flag("nonuniform"),
        get: |c| if c.nonuniform { "true" } else { "false" },
        set: |c, v| (v == "true").then(|| c.nonuniform = true).is_some(),
        phrase: |c| {
            if c.nonuniform {
                " (nonuniformEXT)".into()
            } else {
                String::new()
            }
        },
    },
    Axis {
        id: AxisId::AsAccess,
        name: "as_access",
        help: "how an acceleration structure is reached (AS cells only)",
        values: AsAccess::NAMES,
        stand_ins: &["none"],
        rank: Rank::Primary,
        segment: Segment::Value,
        get: |c| c.as_access.map(AsAccess::as_str).unwrap_or("none"),
        set: |c, v| set_opt(&mut c.as_access, AsAccess::parse, v),
        phrase: |c| match c.as_access {
            None => String::new(),
            Some(AsAccess::Descriptor) => " through a descriptor".into(),
            Some(AsAccess::Address) => " through a device address".into(),
            Some(AsAccess::AddressPatched) => {
                " through a device address (as-to-address applied to the descriptor variant)".into()
            }
        },
    },
    Axis {
        id: AxisId::DescriptorModel,
        name: "descriptor_model",
        help: "how descriptors are bound",
        values: DescriptorModel::NAMES,
        stand_ins: &[],
        rank: Rank::Primary,
        segment: Segment::Value,
        get: |c| c.descriptor_model.as_str(),
        set: |c, v| set_req(&mut c.descriptor_model, DescriptorModel::parse, v),
        phrase: |c| format!(", {}", c.descriptor_model),
    },
    Axis {
        id: AxisId::HeapAccess,
        name: "heap_access",
        help: "how a descriptor_heap cell's shaders reach the heap",
        values: HeapAccess::NAMES,
        stand_ins: &["none"],
        rank: Rank::Primary,
        segment: Segment::Value,
        get: |c| c.heap_access.map(HeapAccess::as_str).unwrap_or("none"),
        set: |c, v| set_opt(&mut c.heap_access, HeapAccess::parse, v),
        phrase: |c| {
            match c.heap_access {
                None => "",
                Some(HeapAccess::MappedConstantOffset) => " (set/binding mapped to the heap at a constant offset)",
                Some(HeapAccess::MappedPushIndex) => " (set/binding mapped to the heap, index in push data: HEAP_WITH_PUSH_INDEX)",
                Some(HeapAccess::MappedIndirectIndex) => " (set/binding mapped to the heap, index loaded from a buffer: HEAP_WITH_INDIRECT_INDEX)",
                Some(HeapAccess::MappedShaderRecordIndex) => " (set/binding mapped to the heap, index in the shader record: HEAP_WITH_SHADER_RECORD_INDEX)",
                Some(HeapAccess::Direct) => " (layout(descriptor_heap) GLSL)",
            }
            .into()
        },
    },
    Axis {
        id: AxisId::Canary,
        name: "canary",
        help: "a deliberately faulting cell (--canaries)",
        values: Canary::NAMES,
        stand_ins: &["none"],
        rank: Rank::Primary,
        segment: Segment::Whole,
        get: |c| c.canary.map(Canary::as_str).unwrap_or("none"),
        set: |c, v| set_opt(&mut c.canary, Canary::parse, v),
        phrase: |c| c.canary.map(|k| format!("canary {}", k.as_str())).unwrap_or_default(),
    },
    Axis {
        id: AxisId::Patch,
        name: "patch",
        help: "the SPIR-V workaround applied to the cell's shaders",
        values: Workaround::NAMES,
        stand_ins: &["none"],
        rank: Rank::Primary,
        segment: Segment::Last("patch-"),
        get: |c| c.patch.map(Workaround::as_str).unwrap_or("none"),
        set: |c, v| set_opt(&mut c.patch, Workaround::parse, v),
        phrase: |c| c.patch.map(|p| format!(", patched with {}", p.as_str())).unwrap_or_default(),
    },
    Axis {
        id: AxisId::Reorder,
        name: "reorder",
        help: "shader execution reordering in raygen before a closest-hit read",
        values: Reorder::NAMES,
        stand_ins: &["none"],
        rank: Rank::Primary,
        segment: Segment::Value,
        get: |c| c.reorder.map(Reorder::as_str).unwrap_or("none"),
        set: |c, v| set_opt(&mut c.reorder, Reorder::parse, v),
        phrase: |c| c.reorder.map(|r| format!(", raygen reordering with {r}")).unwrap_or_default(),
    },
    Axis {
        id: AxisId::Base,
        name: "base",
        help: "where a closest-hit dynamic index's base comes from",
        values: BaseSource::NAMES,
        stand_ins: &["push_data", "none"],
        rank: Rank::Secondary,
        segment: Segment::Prefixed("base_"),
        get: |c| match c.base {
            Some(b) => b.as_str(),
            None if c.base_applies() => "push_data",
            None => "none",
        },
        set: |c, v| set_opt(&mut c.base, BaseSource::parse, v),
        phrase: |c| {
            match c.base {
                None => "",
                Some(BaseSource::ShaderRecord) => ", base from the SBT shader record",
                Some(BaseSource::Buffer) => {
                    ", base loaded from a per-instance buffer (device address)"
                }
            }
            .into()
        },
    },
    Axis {
        id: AxisId::Sampler,
        name: "sampler",
        help: "the sampler index of a direct-heap sampled image",
        values: SamplerIndex::NAMES,
        stand_ins: &["none"],
        rank: Rank::Secondary,
        segment: Segment::Prefixed("sampler_"),
        get: |c| c.sampler.map(SamplerIndex::as_str).unwrap_or("none"),
        set: |c, v| set_opt(&mut c.sampler, SamplerIndex::parse, v),
        phrase: |c| {
            match c.sampler {
                None => "",
                Some(SamplerIndex::Constant) => ", separate sampler heap, constant sampler index",
                Some(SamplerIndex::Dynamic) => ", separate sampler heap, dynamic sampler index",
            }
            .into()
        },
    },
    Axis {
        id: AxisId::Mutant,
        name: "mutant",
        help: "an emulated driver bug mutated into the probe's SPIR-V, only by run --mutants",
        values: Mutant::NAMES,
        stand_ins: &["none"],
        rank: Rank::Secondary,
        segment: Segment::Last("mutant-"),
        get: |c| c.mutant.map(Mutant::as_str).unwrap_or("none"),
        set: |c, v| set_opt(&mut c.mutant, Mutant::parse, v),
        phrase: |c| c.mutant.map(|m| format!(", mutated with {}", m.as_str())).unwrap_or_default(),
    },
    Axis {
        id: AxisId::SceneLayout,
        name: "scene_layout",
        help: "how a closest-hit fetches its hit triangle's data, in scene-layout cells only",
        values: SceneLayout::NAMES,
        stand_ins: &["none"],
        rank: Rank::Primary,
        segment: Segment::Value,
        get: |c| c.scene_layout.map(SceneLayout::as_str).unwrap_or("none"),
        set: |c, v| set_opt(&mut c.scene_layout, SceneLayout::parse, v),
        phrase: |c| {
            match c.scene_layout {
                None => "",
                Some(SceneLayout::SharedBuffers) => ", the hit triangle fetched from shared scene buffers through a SceneDesc of addresses",
                Some(SceneLayout::PerMesh) => ", the hit triangle fetched from its mesh's storage buffer selected by the custom index",
            }
            .into()
        },
    },
];

/// The axis called `name`.
pub fn axis(name: &str) -> Option<&'static Axis> {
    AXES.iter().find(|a| a.name == name)
}

/// The axis names, in id order.
pub fn names() -> impl Iterator<Item = &'static str> {
    AXES.iter().map(|a| a.name)
}

/// The `--filter` short help (`-h`): the syntax and every axis name.
pub fn filter_help_short() -> String {
    format!("Select cells: `axis=value[|value],…`, every term must match; repeatable (all must match). Axes: {}", names().collect::<Vec<_>>().join(", "))
}

/// The `--filter` help (`--help`): one line per axis with its values.
pub fn filter_help() -> String {
    let mut s = String::from("Select cells: `axis=value[|value],…`; every term must match (values within a term are alternatives); repeat --filter for more filters, all must match. Axes:");
    for a in AXES {
        s += &format!(
            "\n  {}: {} ({})",
            a.name,
            a.help,
            a.filter_values().collect::<Vec<_>>().join(", ")
        );
    }
    s
}

/// Every axis of `c` as an exact `--filter` (stand-ins included).
pub fn exact_filter(c: &Cell) -> String {
    AXES.iter().map(|a| format!("{}={}", a.name, (a.get)(c))).collect::<Vec<_>>().join(",")
}

/// The axes in the order a cell's id and its sentence list them: registry order, the
/// [`Segment::Last`] ones at the end.
fn in_id_order() -> impl Iterator<Item = &'static Axis> {
    let last = |a: &&Axis| matches!(a.segment, Segment::Last(_));
    AXES.iter().filter(move |a| !last(a)).chain(AXES.iter().filter(last))
}

/// The id suffix of a `--cells-scale` copy (`.copy-k`), after every axis.
const COPY: &str = ".copy-";

/// A cell's id: its axis values in registry order (see [`Segment`]), then `.copy-k` for copy k.
pub fn id(c: &Cell) -> String {
    let base = axes_id(c);
    if c.copy > 0 {
        format!("{base}{COPY}{}", c.copy)
    } else {
        base
    }
}

/// The axes' part of a cell's id.
fn axes_id(c: &Cell) -> String {
    if let Some(k) = c.canary {
        return format!("canary.{}", k.as_str());
    }
    let mut parts: Vec<String> = Vec::new();
    for a in in_id_order() {
        let v = (a.get)(c);
        if a.stand_ins.contains(&v) {
            continue;
        }
        match a.segment {
            Segment::Value => parts.push(v.into()),
            Segment::Flag(word) => parts.push(word.into()),
            Segment::Prefixed(p) | Segment::Last(p) => parts.push(format!("{p}{v}")),
            Segment::Whole => {}
        }
    }
    parts.join(".")
}

/// A string that is no cell id, with why (`id`: the string).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum IdError {
    /// `canaries`: every canary's name, for the message.
    #[error("{id:?} is not a cell id (canaries: {canaries})")]
    NoSuchCanary { id: String, canaries: String },
    /// An axis without stand-in has no value at its place (`values`: the axis's values).
    #[error("{id:?} is not a cell id ({axis} must be one of {values})")]
    MissingValue { id: String, axis: &'static str, values: String },
    #[error("{id:?} is not a cell id ({rest:?} is no axis value at its place)")]
    Misplaced { id: String, rest: String },
    /// It parses, but [`id`] writes the cell another way.
    #[error("{id:?} is not a cell id (it reads back as {reads})")]
    NotCanonical { id: String, reads: String },
}

/// The cell a well-formed id names: the segments read in registry order, each axis absent from
/// the id taking its stand-in. Refuses what [`id`] would not write back the same.
pub fn parse_id(s: &str) -> Result<Cell, IdError> {
    let copy = s.rsplit_once(COPY).and_then(|(base, k)| Some(base).zip(k.parse::<u32>().ok()));
    let Some((base, k)) = copy.filter(|&(_, k)| k > 0) else {
        return parse_axes(s);
    };
    let c = Cell { copy: k, ..parse_axes(base)? };
    if id(&c) != s {
        return Err(IdError::NotCanonical { id: s.into(), reads: id(&c) });
    }
    Ok(c)
}

/// The cell whose axes' part of the id is `s` (no copy suffix).
fn parse_axes(s: &str) -> Result<Cell, IdError> {
    if let Some(name) = s.strip_prefix("canary.") {
        return Canary::parse(name).map(Cell::canary).ok_or_else(|| IdError::NoSuchCanary {
            id: s.into(),
            canaries: Canary::NAMES.join(", "),
        });
    }
    let mut c = Cell::new(
        Stage::Raygen,
        Resource::StorageBuffer,
        IndexSource::Literal,
        DescriptorModel::DescriptorIndexing,
    );
    let mut parts = s.split('.').peekable();
    for a in in_id_order() {
        let Some(&next) = parts.peek() else { break };
        let taken = match a.segment {
            Segment::Value => (a.set)(&mut c, next),
            Segment::Flag(word) => next == word && (a.set)(&mut c, "true"),
            Segment::Prefixed(p) | Segment::Last(p) => {
                next.strip_prefix(p).is_some_and(|v| (a.set)(&mut c, v))
            }
            Segment::Whole => false,
        };
        if taken {
            parts.next();
        } else if a.stand_ins.is_empty() {
            return Err(IdError::MissingValue {
                id: s.into(),
                axis: a.name,
                values: a.values.join(", "),
            });
        }
    }
    if let Some(rest) = parts.next() {
        return Err(IdError::Misplaced { id: s.into(), rest: rest.into() });
    }
    if id(&c) != s {
        return Err(IdError::NotCanonical { id: s.into(), reads: id(&c) });
    }
    Ok(c)
}

/// One cell as a sentence a driver engineer can read without knowing rtprobe's ids.
pub fn describe(c: &Cell) -> String {
    if c.canary.is_some() {
        let canary = AXES.iter().find(|a| a.segment == Segment::Whole).expect("the canary axis");
        return (canary.phrase)(c);
    }
    in_id_order().map(|a| (a.phrase)(c)).collect()
}

/// A cell's id, its parse and its axis values come from the registry.
impl Cell {
    /// The stable id ([`id`]).
    pub fn id(&self) -> String {
        id(self)
    }

    /// The cell an id names ([`parse_id`]).
    pub fn parse_id(id: &str) -> Result<Cell, IdError> {
        parse_id(id)
    }

    /// The value of an axis by its name (a stand-in where the cell has none), for filters.
    pub fn axis_value(&self, axis: &str) -> Option<String> {
        self::axis(axis).map(|a| (a.get)(self).to_string())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_axis_is_declared_once_with_distinct_values() {
        let mut ids: Vec<AxisId> = AXES.iter().map(|a| a.id).collect();
        ids.sort();
        ids.dedup();
        assert_eq!(ids.len(), AXES.len());
        let mut n: Vec<&str> = names().collect();
        n.sort();
        n.dedup();
        assert_eq!(n.len(), AXES.len());
        for a in AXES {
            let mut v: Vec<&str> = a.filter_values().collect();
            let len = v.len();
            v.sort();
            v.dedup();
            assert_eq!(v.len(), len, "{}: a value twice", a.name);
        }
    }

    #[test]
    fn filters_and_bisection_list_the_axes_as_the_first_reports_did() {
        // `--filter`s written into reports (repro bundles' exact filters, merge and --resume
        // compare them) and bisection's term order are the order of the first releases.
        assert_eq!(
            names().collect::<Vec<_>>(),
            [
                "stage",
                "resource",
                "index",
                "nonuniform",
                "as_access",
                "descriptor_model",
                "heap_access",
                "canary",
                "patch",
                "reorder",
                "base",
                "sampler",
                "mutant",
                "scene_layout"
            ]
        );
        let c = Cell {
            nonuniform: true,
            patch: Some(Workaround::PinIndex),
            ..Cell::new(
                Stage::ClosestHit,
                Resource::StorageBuffer,
                IndexSource::Dynamic,
                DescriptorModel::DescriptorIndexing,
            )
        };
        assert_eq!(
            exact_filter(&c),
            "stage=closest_hit,resource=storage_buffer,index=dynamic,nonuniform=true,as_access=none,descriptor_model=descriptor_indexing,heap_access=none,canary=none,patch=pin-index,reorder=none,base=push_data,sampler=none,mutant=none,scene_layout=none"
        );
        assert_eq!(describe(&c), "closest_hit reading storage_buffer with dynamic index (nonuniformEXT), descriptor_indexing, patched with pin-index");
    }

    #[test]
    fn ids_round_trip_and_bad_ids_are_refused() {
        let c = Cell {
            nonuniform: true,
            base: Some(BaseSource::Buffer),
            patch: Some(Workaround::PinIndex),
            ..Cell::new(
                Stage::ClosestHit,
                Resource::StorageBuffer,
                IndexSource::Dynamic,
                DescriptorModel::DescriptorBuffer,
            )
        };
        assert_eq!(id(&c), "closest_hit.storage_buffer.dynamic.nonuniform.descriptor_buffer.base_buffer.patch-pin-index");
        assert_eq!(parse_id(&id(&c)), Ok(c));
        // A mutant comes last, after the workaround.
        let m = Cell { mutant: Some(Mutant::IndexNext), ..c };
        assert_eq!(id(&m), "closest_hit.storage_buffer.dynamic.nonuniform.descriptor_buffer.base_buffer.patch-pin-index.mutant-index-next");
        assert_eq!(parse_id(&id(&m)), Ok(m));
        assert_eq!(m.unmutated(), c);
        assert_eq!(parse_id("canary.infinite_loop"), Ok(Cell::canary(Canary::InfiniteLoop)));
        for bad in [
            "",
            "closest_hit",
            "closest_hit.storage_buffer.dynamic",
            "closest_hit.storage_buffer.dynamic.descriptor_buffer.extra",
            "canary.nope",
            "closest_hit.storage_buffer.dynamic.descriptor_buffer.base_push_data",
        ] {
            assert!(parse_id(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn a_copy_keeps_its_number_in_its_id_and_bad_copies_are_refused() {
        let base = Cell::new(
            Stage::Raygen,
            Resource::StorageBuffer,
            IndexSource::Literal,
            DescriptorModel::DescriptorIndexing,
        );
        let c = Cell { copy: 12, ..base };
        assert_eq!(id(&c), "raygen.storage_buffer.literal.descriptor_indexing.copy-12");
        assert_eq!(parse_id(&id(&c)), Ok(c));
        assert_ne!(parse_id(&id(&c)), Ok(base), "the copy is not its base cell");
        for bad in [
            "raygen.storage_buffer.literal.descriptor_indexing.copy-0",
            "raygen.storage_buffer.literal.descriptor_indexing.copy-012",
            "raygen.storage_buffer.literal.descriptor_indexing.copy-x",
            "raygen.storage_buffer.literal.copy-3",
        ] {
            assert!(parse_id(bad).is_err(), "{bad}");
        }
    }
}
