//! `run --shader`'s `--fill` planned before any device work (`harness::fill`: parsed, held to
//! the given modules as they run, the bytes made, fills that overlap refused; a problem is one
//! line and exit 2, or 9 for a file that cannot be read or does not fit), and the options that
//! change what runs, for the cell id (`model::shader_options`).
use super::args::RunArgs;
use super::exit::{self, coded};
use super::shader_plan::{hash_hex, ShaderPlan};
use crate::harness::fill::{self, FillError, Fills, Source, Target};
use crate::harness::scene_data::SceneFill;
use crate::harness::Sizes;
use crate::model::shader_options::CellOptions;
use crate::model::DescriptorModel;
use anyhow::Result;

/// Every `--fill`, resolved against the given modules sized by `sizes`, with each one's words
/// for the cell options (`TARGET=zero`, `TARGET=random:SEED`, `TARGET=file:HASH`,
/// `TARGET=scene.NAME`); the `scene.NAME` ones apart, placed by the child (`scene`: `--scene`'s
/// loaded scene).
pub fn fills(
    a: &RunArgs,
    plan: &ShaderPlan,
    sizes: &Sizes,
    scene: Option<&crate::scene::gltf::Loaded>,
) -> Result<(Fills, Vec<SceneFill>, Vec<String>)> {
    let given = sizes.apply(plan.given.clone());
    let (mut out, mut scene_fills, mut words) = (Vec::new(), Vec::new(), Vec::new());
    // Each fill's text, target and bytes placed, for the overlap check.
    let mut spans = Vec::new();
    for (at, text) in a.fill.iter().enumerate() {
        let coded_err = |e: FillError| match e {
            FillError::Syntax(..) | FillError::Target(..) => coded(exit::USAGE, e.to_string()),
            FillError::Source(..) => coded(exit::BAD_INPUT, e.to_string()),
        };
        let r = fill::parse(text).map_err(coded_err)?;
        if let Source::Scene(item) = r.source {
            let Some(loaded) = scene else {
                return Err(coded(
                    exit::USAGE,
                    format!(
                        "--fill {text}: scene.{} needs --scene FILE; give the glTF scene it reads",
                        item.name()
                    ),
                ));
            };
            let images = loaded.images;
            scene_fills.push(
                crate::harness::scene_data::resolve_scene(&r, &given, (at, images))
                    .map_err(coded_err)?,
            );
            spans.push((text.clone(), r.target, 8));
            words.push(format!("{}=scene.{}", target_words(r.target), item.name()));
            continue;
        }
        let f = fill::resolve(&r, &given).map_err(coded_err)?;
        let source = match &r.source {
            Source::Zero => "zero".to_string(),
            Source::Random(seed) => format!("random:{seed}"),
            Source::File(_) => format!("file:{}", hash_hex(&f.bytes)),
            Source::Scene(item) => format!("scene.{}", item.name()),
        };
        words.push(format!("{}={source}", target_words(r.target)));
        spans.push((text.clone(), r.target, f.bytes.len() as u32));
        out.push(f);
    }
    fill::check_disjoint(&spans).map_err(|e| coded(exit::USAGE, e.to_string()))?;
    Ok((Fills(out), scene_fills, words))
}

/// A target as `--fill` writes it.
fn target_words(t: Target) -> String {
    match t {
        Target::Binding { set, binding, element: None } => format!("{set}.{binding}"),
        Target::Binding { set, binding, element: Some(e) } => format!("{set}.{binding}[{e}]"),
        Target::Push(o) => format!("push.{o}"),
        Target::Record(o) => format!("record.{o}"),
    }
}

/// What a run's cell id takes beyond its arguments: `--spec`'s values in their normal form,
/// `--fill`'s words, and `--profile`'s effect on the harness.
pub struct Resolved {
    pub spec: Vec<String>,
    pub fill: Vec<String>,
    pub profile: Vec<String>,
    /// `--scene`'s file hash.
    pub scene: Option<String>,
}

/// The options of this run that change what runs: `--entry`, `--spec`, `--fill`,
/// `--array-size`, `--sink-size`, a `model` other than the modules imply, `--heap-layout`'s
/// content hash, `--profile`'s effect (`resolved`).
pub fn cell_options(
    a: &RunArgs,
    plan: &ShaderPlan,
    model: DescriptorModel,
    resolved: Resolved,
) -> Result<CellOptions> {
    let implied = if crate::harness::heap::uses_heap(&plan.given) {
        DescriptorModel::DescriptorHeap
    } else {
        DescriptorModel::DescriptorIndexing
    };
    let heap_layout =
        match &a.heap_layout {
            Some(f) => Some(hash_hex(&std::fs::read(f).map_err(|e| {
                coded(exit::BAD_INPUT, format!("--heap-layout {}: {e}", f.display()))
            })?)),
            None => None,
        };
    Ok(CellOptions {
        entry: a.entry.clone(),
        spec: resolved.spec,
        fill: resolved.fill,
        array_size: a.array_size,
        sink_size: a.sink_size,
        descriptor_model: (model != implied).then(|| model.as_str().to_string()),
        heap_layout,
        profile: resolved.profile,
        scene: resolved.scene,
        hit_groups: {
            let mut h = a.hit_groups.clone();
            h.sort();
            h
        },
    })
}
