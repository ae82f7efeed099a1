//! `run --shader --compare REPORT [--tolerance T]`: each variant's outputs against those of
//! another `rtprobe.shader-run/1` report of the same cell (another device or driver). A report
//! carries its variants' first outputs (`model::shader_outputs`, base64 up to a cap, with the
//! units its own attempts disagreed on); they are compared by `harness::compare_within`, the
//! comparer of the variants, with the units unwritten or unstable on either side left out.
//! Without a tolerance a difference is a note (a driver may legitimately round otherwise); with
//! one, an output beyond it is the attempt's `against`, a `mismatch` finding naming it.
use super::exit::{self, coded};
use super::shader_exec::Ran;
use crate::harness::ints::{Fill, IntWords};
use crate::harness::reflect::BindingKind;
use crate::harness::{self, Part, PartKind, Tolerance, UserModule};
use crate::model::base64;
use crate::model::shader_outputs::{CompareInfo, OutputData, OutputKind, EMBED_CAP};
use crate::model::shader_run::{ShaderRunReport, SCHEMA};
use anyhow::Result;
use rspirv::spirv::ImageFormat;
use std::path::Path;

/// The `--compare` report, read and checked: a shader-run report of `cell`, else one line.
/// `cell_options_without_size`: this run has no `--array-size` of its own.
pub fn load(path: &Path, cell: &str, cell_options_without_size: bool) -> Result<ShaderRunReport> {
    let bad = |why: String| coded(exit::BAD_INPUT, format!("--compare {}: {why}", path.display()));
    let text = std::fs::read(path).map_err(|e| bad(e.to_string()))?;
    let v: serde_json::Value = serde_json::from_slice(&text)
        .map_err(|e| bad(format!("not JSON ({e}); give a `run --shader` report")))?;
    if v["schema"] != SCHEMA {
        return Err(bad(format!(
            "schema {}, not {SCHEMA}; give a `run --shader` report",
            v["schema"]
        )));
    }
    let r: ShaderRunReport = serde_json::from_value(v)
        .map_err(|e| bad(format!("not a readable {SCHEMA} report ({e})")))?;
    // A report whose arrays the index check sized up has that size in its id: this run's
    // check may size its own alike, and the id is held to it again then.
    let sized_up = r.index_bounds.as_ref().is_some_and(|b| b.grown.is_some());
    if !(sized_up && cell_options_without_size) {
        same_cell(path, &r, cell)?;
    }
    Ok(r)
}

/// `--compare`'s report `r` is of this run's `cell` (checked again once the index check has
/// sized arrays up: the size is in the cell id).
pub fn same_cell(path: &Path, r: &ShaderRunReport, cell: &str) -> Result<()> {
    if r.cell == cell {
        return Ok(());
    }
    Err(coded(
        exit::BAD_INPUT,
        format!(
            "--compare {}: a report of another cell ({}), not this run's {cell}; compare reports of the same shaders",
            path.display(),
            r.cell
        ),
    ))
}

/// The units (texels, words) of each output in which a later attempt differs from the first.
fn unstable_units(first: &[Part], ran: &[Ran]) -> Vec<Vec<u32>> {
    first
        .iter()
        .enumerate()
        .map(|(n, p)| {
            let t = p.texel.max(1) as usize;
            let mut units = std::collections::BTreeSet::new();
            for later in ran.iter().filter_map(|r| r.parts.as_ref()).skip(1) {
                let Some(q) = later.get(n) else { continue };
                for (k, x) in p.bytes.chunks(t).enumerate() {
                    if q.bytes.chunks(t).nth(k) != Some(x) {
                        units.insert(k as u32);
                    }
                }
            }
            units.into_iter().collect()
        })
        .collect()
}

/// A variant's first outputs as the report embeds them.
fn to_data(ran: &[Ran]) -> Vec<OutputData> {
    let Some(first) = ran.iter().find_map(|r| r.parts.as_ref()) else { return vec![] };
    first
        .iter()
        .zip(unstable_units(first, ran))
        .map(|(p, unstable)| OutputData {
            label: p.label.clone(),
            kind: match p.kind {
                PartKind::Image => OutputKind::Image,
                PartKind::Buffer => OutputKind::Buffer,
            },
            texel: p.texel,
            bytes: base64::encode(&p.bytes),
            initial: p.initial.as_deref().map(base64::encode),
            scheduled: p.scheduled,
            records: p.records,
            unstable,
        })
        .collect()
}

/// Each variant's embedded outputs, in order, while they fit [`EMBED_CAP`]; a note for those
/// left out.
pub fn embed(variants: &[(&str, &[Ran])]) -> (Vec<Vec<OutputData>>, Option<String>) {
    let (mut total, mut left) = (0usize, Vec::new());
    let data = variants
        .iter()
        .map(|(name, ran)| {
            let d = to_data(ran);
            let size: usize =
                d.iter().map(|o| o.bytes.len() + o.initial.as_ref().map_or(0, String::len)).sum();
            if total + size > EMBED_CAP * 4 / 3 {
                left.push(*name);
                return vec![];
            }
            total += size;
            d
        })
        .collect();
    let note = (!left.is_empty()).then(|| {
        format!("outputs of {} not embedded: over the report's {} MiB cap; --compare against this report compares them by hash only", left.join(", "), EMBED_CAP >> 20)
    });
    (data, note)
}

/// An embedded output back as a part.
fn from_data(d: &OutputData) -> Result<Part, String> {
    let bytes = base64::decode(&d.bytes).map_err(|e| format!("{}: {e}", d.label))?;
    let initial = d.initial.as_deref().map(base64::decode).transpose();
    Ok(Part {
        label: d.label.clone(),
        kind: match d.kind {
            OutputKind::Image => PartKind::Image,
            OutputKind::Buffer => PartKind::Buffer,
        },
        bytes,
        texel: d.texel,
        initial: initial.map_err(|e| format!("{}: {e}", d.label))?,
        scheduled: d.scheduled,
        records: d.records,
    })
}

/// Flip the first byte of each of `units` (so the unit differs from the original's).
fn flip(p: &mut Part, units: &[u32]) {
    let t = p.texel.max(1) as usize;
    for u in units {
        if let Some(b) = p.bytes.get_mut(*u as usize * t) {
            *b ^= 0xFF;
        }
    }
}

/// Which words of an output are 32-bit floats: every word of a float32 storage image, the
/// words a buffer's block types leave float (every alias of the binding agreeing), none else.
enum Floats {
    All,
    None,
    Block(Vec<IntWords>),
}

fn floats_of(modules: &[UserModule], label: &str) -> Floats {
    let numbers: Vec<u32> =
        label.split(|c: char| !c.is_ascii_digit()).filter_map(|w| w.parse().ok()).collect();
    let [set, binding, ..] = numbers[..] else { return Floats::None };
    let bindings = modules
        .iter()
        .flat_map(|m| &m.iface.bindings)
        .filter(|b| (b.set, b.binding) == (set, binding));
    let mut blocks = Vec::new();
    for b in bindings {
        match b.kind {
            BindingKind::StorageImage(
                ImageFormat::Rgba32f | ImageFormat::Rg32f | ImageFormat::R32f,
            ) if label.starts_with("set ") => return Floats::All,
            BindingKind::StorageBuffer(_) if label.starts_with("storage buffer") => {
                blocks.push(b.ints.clone())
            }
            BindingKind::StorageImage(_)
            | BindingKind::StorageBuffer(_)
            | BindingKind::UniformBuffer(_)
            | BindingKind::AccelerationStructure
            | BindingKind::SampledImage
            | BindingKind::Sampler
            | BindingKind::CombinedImageSampler => {}
        }
    }
    if blocks.is_empty() {
        Floats::None
    } else {
        Floats::Block(blocks)
    }
}

impl Floats {
    fn at(&self, offset: usize) -> bool {
        match self {
            Floats::All => true,
            Floats::None => false,
            Floats::Block(b) => b.iter().all(|w| w.at(offset as u32) == Fill::Float),
        }
    }
}

/// What the comparison needs of the run.
pub struct Against<'a> {
    pub other: &'a ShaderRunReport,
    pub path: &'a Path,
    pub tolerance: Option<f32>,
    pub modules: &'a [UserModule],
}

fn unit(kind: PartKind) -> &'static str {
    match kind {
        PartKind::Image => "texels",
        PartKind::Buffer => "4-byte words",
    }
}

/// What comparing one variant came to: a line for the notes (a difference without a
/// tolerance, or why nothing was compared), and whether its outputs differed.
struct Came {
    note: Option<String>,
    differed: bool,
    /// Output units compared (written, and stable on both devices).
    compared: usize,
}

/// The other report's outputs of `name` and `again`: a copy with the units unstable on either
/// device flipped, which `harness::compare` leaves out.
fn theirs(a: &Against, name: &str, ran: &[Ran]) -> Result<(Vec<Part>, Vec<Part>), String> {
    let path = a.path.display();
    let Some(v) = a.other.variants.iter().find(|v| v.name == name) else {
        return Err(format!("{path} has no {name} variant: not compared"));
    };
    if v.data.is_empty() {
        return Err(format!(
            "{path} carries no outputs of {name} (none ran, or over its cap): not compared"
        ));
    }
    let before: Vec<Part> = v
        .data
        .iter()
        .map(from_data)
        .collect::<Result<_, _>>()
        .map_err(|e| format!("{path}: its outputs of {name} are unreadable: {e}"))?;
    let ours = ran
        .iter()
        .find_map(|r| r.parts.as_deref())
        .map(|f| unstable_units(f, ran))
        .unwrap_or_default();
    let mut again = before.clone();
    for (n, (p, d)) in again.iter_mut().zip(&v.data).enumerate() {
        let mut units: std::collections::BTreeSet<u32> = d.unstable.iter().copied().collect();
        units.extend(ours.get(n).into_iter().flatten());
        flip(p, &units.into_iter().collect::<Vec<_>>());
    }
    Ok((before, again))
}

/// One variant's attempts against the other report's outputs of the same variant.
fn compare_variant(a: &Against, name: &str, ran: &mut [Ran]) -> Came {
    let (before, again) = match theirs(a, name, ran) {
        Ok(t) => t,
        Err(note) => return Came { note: Some(note), differed: false, compared: 0 },
    };
    let floats: Vec<Floats> = before.iter().map(|p| floats_of(a.modules, &p.label)).collect();
    let float = |n: usize, offset: usize| floats.get(n).is_some_and(|f| f.at(offset));
    let tol = a.tolerance.map(|abs| Tolerance { abs, float: &float });
    let (path, device) = (a.path.display(), &a.other.device);
    let beyond = a.tolerance.map(|t| format!(" beyond --tolerance {t}")).unwrap_or_default();
    let mut first = None;
    let mut compared = 0;
    for r in ran.iter_mut() {
        let Some(parts) = &r.parts else { continue };
        let labels = |p: &[Part]| p.iter().map(|p| p.label.clone()).collect::<Vec<_>>();
        let line = if labels(parts) != labels(&before) {
            Some(format!(
                "{name}: its outputs ({}) are not those of {path} ({}, on {device})",
                labels(parts).join(", "),
                labels(&before).join(", ")
            ))
        } else {
            let c = harness::compare_within(&before, &again, parts, tol.as_ref());
            compared += c.iter().map(|c| c.written.saturating_sub(c.unstable)).sum::<usize>();
            c.iter().find(|c| c.differing > 0).map(|d| {
                format!(
                    "{name}: {} differs from {path}'s (on {device}) in {} of {} {}{beyond}",
                    d.label,
                    d.differing,
                    d.texels,
                    unit(d.kind)
                )
            })
        };
        if a.tolerance.is_some() {
            r.attempt.against.clone_from(&line);
        }
        first = first.or(line);
    }
    let differed = first.is_some();
    let note = first.filter(|_| a.tolerance.is_none()).map(|l| {
        format!(
            "compared: {l} (a note: a driver may round otherwise; --tolerance makes it a finding)"
        )
    });
    Came { note, differed, compared }
}

/// Every variant against the other report: the notes and what the report records.
pub fn compare_all(
    a: &Against,
    unpatched: &mut [Ran],
    patched: &mut [(String, Vec<Ran>)],
) -> (Vec<String>, CompareInfo) {
    let mut all = vec![compare_variant(a, "unpatched", unpatched)];
    for (name, ran) in patched.iter_mut() {
        all.push(compare_variant(a, name, ran));
    }
    let differences = all.iter().filter(|c| c.differed).count();
    let compared: usize = all.iter().map(|c| c.compared).sum();
    let mut notes: Vec<String> = all.into_iter().filter_map(|c| c.note).collect();
    if compared == 0 && differences == 0 {
        notes.push(format!(
            "compared with {} (on {}): nothing was compared — no output unit written and stable in both runs — so this is no evidence that the outputs agree",
            a.path.display(),
            a.other.device
        ));
    } else if differences == 0 {
        notes.push(format!(
            "compared with {} (on {}): no variant's outputs differ",
            a.path.display(),
            a.other.device
        ));
    }
    let info = CompareInfo {
        report: a.path.display().to_string(),
        device: a.other.device.clone(),
        tolerance: a.tolerance,
        differences,
    };
    (notes, info)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::shader_run::ShaderAttempt;
    use crate::model::{Attempt, Outcome};

    fn ran(words: &[u8]) -> Ran {
        let part = Part {
            label: "storage buffer set 0 binding 3[0]".into(),
            kind: PartKind::Buffer,
            bytes: words.iter().flat_map(|w| [*w, 0, 0, 0]).collect(),
            texel: 4,
            initial: Some(vec![0xEE; words.len() * 4]),
            scheduled: false,
            records: Some((0, 4)),
        };
        let attempt = ShaderAttempt::bare(Attempt::new(Outcome::Pass, true));
        Ran { attempt, parts: Some(vec![part]), device: None }
    }

    #[test]
    fn embedded_outputs_round_trip_with_their_unstable_units() {
        let runs = [ran(&[1, 2, 3]), ran(&[1, 9, 3])];
        let data = to_data(&runs);
        assert_eq!(data[0].unstable, [1]);
        let back = from_data(&data[0]).unwrap();
        assert_eq!(&back, &runs[0].parts.as_ref().unwrap()[0]);
        let (all, note) = embed(&[("unpatched", &runs)]);
        assert_eq!((all[0].len(), note), (1, None));
        // Twin: a flipped unit differs from the original, and is left out by the comparer.
        let mut again = back.clone();
        flip(&mut again, &[1]);
        assert_ne!(again.bytes[4], back.bytes[4]);
        let other = runs[1].parts.clone().unwrap();
        let c = harness::compare(std::slice::from_ref(&back), &[again], &other);
        assert_eq!((c[0].unstable, c[0].differing), (1, 0));
        let c = harness::compare(std::slice::from_ref(&back), std::slice::from_ref(&back), &other);
        assert_eq!(c[0].differing, 1);
    }

    #[test]
    fn unreadable_data_is_an_error() {
        let mut d = to_data(&[ran(&[1])]).remove(0);
        d.bytes = "!!".into();
        assert!(from_data(&d).is_err());
    }
}
