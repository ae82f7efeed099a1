//! `run --shader`'s terminal summary (one line per variant, the notes, then `verdict: PASS|FAIL
//! — …` as `run` says it) and its exit code (`run`'s: 1 for a finding, an `error` included, as
//! for generated cells), and `--dump DIR`: every storage image the trace wrote, of each
//! variant's first attempt that ran and of every attempt that differs, as PNG.
use super::exit;
use crate::harness::reflect::BindingKind;
use crate::harness::{Part, PartKind, UserModule};
use crate::model::shader_run::{Judgement, ShaderRunReport, ShaderVariant, CANNOT_SHOW};
use anyhow::Result;
use rspirv::spirv::ImageFormat;
use std::path::{Path, PathBuf};

/// The validation layer's word on `v`'s attempts: errors and warnings, or that none ran.
fn messages_text(v: &ShaderVariant, validated: bool) -> String {
    if !validated {
        return "not validated (--validate runs the validation layer)".into();
    }
    let errors: u64 = v.attempts.iter().map(|a| a.validation_messages).sum();
    let warnings: u64 = v.attempts.iter().map(|a| a.validation_warnings).sum();
    match warnings {
        0 => format!("{errors} validation errors"),
        w => format!("{errors} validation errors, {w} warnings (counted, no verdict)"),
    }
}

/// One line for a variant: its verdict, its attempts and what decided it (`validated`: the run
/// had the validation layer).
pub fn variant_line(v: &ShaderVariant, validated: bool) -> String {
    let n = v.attempts.len();
    let messages: u64 = v.attempts.iter().map(|a| a.validation_messages).sum();
    let head = format!("  {}: {} ({n} attempt{})", v.name, v.judgement.as_str(), plural_s(n));
    let tail = match v.judgement {
        Judgement::Pass => match (&v.uncompared, n) {
            (Some(why), _) => format!("attempts agree among themselves, {why}"),
            (None, 1) if v.patch.is_none() => "one attempt, nothing to compare".into(),
            (None, _) => format!("outputs identical, {}", messages_text(v, validated)),
        },
        Judgement::Validation => match &v.gpu_av {
            Some(g) => format!("faulted; re-run under GPU-AV ({} attempts)", g.attempts.len()),
            None => format!("{messages} validation messages: not evidence about the driver"),
        },
        Judgement::Fault
        | Judgement::Unstable
        | Judgement::PatchDiffers
        | Judgement::CompareDiffers
        | Judgement::Error => v.incidence.as_ref().map(|i| i.label()).unwrap_or_default(),
    };
    let detail = v.detail.as_deref().map(|d| format!(": {d}")).unwrap_or_default();
    let teardown = v.teardown.as_deref().map(|t| format!("; {t}")).unwrap_or_default();
    let gpu_av = match (&v.gpu_av, v.judgement) {
        // A report is the variant's detail already.
        (Some(g), Judgement::Fault) => format!("; {}", g.line),
        _ => String::new(),
    };
    format!("{head} — {tail}{detail}{teardown}{gpu_av}")
}

fn plural_s(n: usize) -> &'static str {
    if n == 1 {
        ""
    } else {
        "s"
    }
}

/// The verdict line and the exit code.
pub fn verdict(r: &ShaderRunReport) -> (String, u8) {
    let attempts: usize = r.variants.iter().map(|v| v.attempts.len()).sum();
    match r.worst() {
        Some(w) if w.outcome.is_finding() => (
            format!(
                "verdict: FAIL — {}: {} of {} ({})",
                r.cell,
                w.outcome.as_str(),
                w.name,
                w.judgement.as_str()
            ),
            exit::FINDINGS,
        ),
        _ => (
            format!(
                "verdict: PASS — {}: {} variant{}, {attempts} attempts, no fault, {}, {}",
                r.cell,
                r.variants.len(),
                plural_s(r.variants.len()),
                verdict_messages(r),
                differences(r)
            ),
            exit::OK,
        ),
    }
}

/// What a PASS says of validation: no error (and the warnings counted), or that none ran.
fn verdict_messages(r: &ShaderRunReport) -> String {
    if !r.options["validate"].as_bool().unwrap_or(false) {
        return "not validated".into();
    }
    let warnings: u64 =
        r.variants.iter().flat_map(|v| &v.attempts).map(|a| a.validation_warnings).sum();
    match warnings {
        0 => "no validation message".into(),
        w => format!("no validation error ({w} warnings)"),
    }
}

/// What a PASS says of the outputs: never "no difference" where nothing could show one.
fn differences(r: &ShaderRunReport) -> String {
    if let Some(n) = r.notes.iter().find(|n| n.starts_with(CANNOT_SHOW)) {
        return n.clone();
    }
    if r.variants.iter().any(|v| v.uncompared.is_some()) {
        return "no difference among each variant's own attempts (the unpatched pipeline produced no outputs)".into();
    }
    let teardowns = r.variants.iter().filter(|v| v.teardown.is_some()).count();
    match teardowns {
        0 => "no difference".into(),
        n => format!(
            "no difference, but {n} child{} failed in teardown",
            if n == 1 { "" } else { "ren" }
        ),
    }
}

/// The summary lines, verdict last; with a baseline, its lines, and the exit code says only
/// what it did not expect (as `run --baseline`).
pub fn summary(r: &ShaderRunReport, report_path: &Path, allow: bool) -> (Vec<String>, u8) {
    let mut lines = vec![format!("{} on {}", r.cell, r.device)];
    let validated = r.options["validate"].as_bool().unwrap_or(false);
    lines.extend(r.variants.iter().map(|v| variant_line(v, validated)));
    lines.extend(r.notes.iter().map(|n| format!("  note: {n}")));
    lines.push(format!("report: {}", report_path.display()));
    let (mut v, mut code) = verdict(r);
    if let Some(b) = &r.baseline {
        lines.extend(crate::fleet::baseline::render(b, allow).lines().map(String::from));
        code = if b.ok(allow) { exit::OK } else { exit::FINDINGS };
        if code == exit::OK && v.starts_with("verdict: FAIL") {
            v += " (as the baseline expects)";
        }
    }
    lines.push(v);
    (lines, code)
}

/// The format of the storage image `label` (`set S binding B[k]`) names.
fn image_format(modules: &[UserModule], label: &str) -> Option<ImageFormat> {
    let mut words = label.split([' ', '[']);
    let (_, set, _, binding) = (words.next()?, words.next()?, words.next()?, words.next()?);
    let (set, binding) = (set.parse::<u32>().ok()?, binding.parse::<u32>().ok()?);
    modules.iter().flat_map(|m| &m.iface.bindings).find_map(|b| match b.kind {
        BindingKind::StorageImage(f) if (b.set, b.binding) == (set, binding) => Some(f),
        _ => None,
    })
}

/// An IEEE half as f32.
fn half(h: u16) -> f32 {
    let (sign, exp, frac) = ((h >> 15) as u32, ((h >> 10) & 0x1f) as i32, (h & 0x3ff) as f32);
    let v = match exp {
        0 => frac * 2f32.powi(-24),
        31 => f32::INFINITY,
        e => (1.0 + frac / 1024.0) * 2f32.powi(e - 15),
    };
    if sign == 1 {
        -v
    } else {
        v
    }
}

/// A texel's first three channels as 8-bit colour: floats clamped to [0, 1], integers' low byte.
fn rgb(f: ImageFormat, t: &[u8]) -> [u8; 3] {
    let word = |k: usize| t.get(4 * k..4 * k + 4).map(|b| [b[0], b[1], b[2], b[3]]);
    let unit = |x: f32| (x.clamp(0.0, 1.0) * 255.0).round() as u8;
    let mut out = [0u8; 3];
    for (k, c) in out.iter_mut().enumerate() {
        *c = match f {
            ImageFormat::Rgba32f | ImageFormat::Rg32f | ImageFormat::R32f => {
                word(k).map_or(0, |w| unit(f32::from_le_bytes(w)))
            }
            ImageFormat::Rgba16f => {
                t.get(2 * k..2 * k + 2).map_or(0, |b| unit(half(u16::from_le_bytes([b[0], b[1]]))))
            }
            ImageFormat::Rgba8 => t.get(k).copied().unwrap_or(0),
            _ => word(k).map_or(0, |w| w[0]),
        };
    }
    out
}

/// Write `parts`' storage images as `DIR/PREFIX-set-S-binding-B-K.png` (not those left all
/// zero: the harness clears every storage image before the trace); returns the paths.
pub fn dump(
    dir: &Path,
    prefix: &str,
    modules: &[UserModule],
    parts: &[Part],
) -> Result<Vec<PathBuf>> {
    let mut written = Vec::new();
    let shown = |p: &&Part| p.kind == PartKind::Image && p.bytes.iter().any(|b| *b != 0);
    for p in parts.iter().filter(shown) {
        let Some(f) = image_format(modules, &p.label) else { continue };
        let size = crate::harness::SIZE;
        let pixels: Vec<u8> =
            p.bytes.chunks(p.texel.max(1) as usize).flat_map(|t| rgb(f, t)).collect();
        if pixels.len() != (size * size * 3) as usize {
            continue;
        }
        let name: String = p
            .label
            .chars()
            .map(|c| if c.is_ascii_alphanumeric() { c } else { '-' })
            .collect::<String>()
            .split('-')
            .filter(|s| !s.is_empty())
            .collect::<Vec<_>>()
            .join("-");
        let path = dir.join(format!("{prefix}-{name}.png"));
        let mut bytes = Vec::new();
        {
            let mut enc = png::Encoder::new(&mut bytes, size, size);
            enc.set_color(png::ColorType::Rgb);
            enc.set_depth(png::BitDepth::Eight);
            let mut w = enc.write_header()?;
            w.write_image_data(&pixels)?;
            w.finish()?;
        }
        crate::atomic::write_atomic_with(&path, &bytes, false)?;
        written.push(path);
    }
    Ok(written)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::shader_run::ShaderAttempt;
    use crate::model::{Attempt, Outcome};

    fn variant(patch: Option<&str>, uncompared: Option<&str>) -> ShaderVariant {
        let a = ShaderAttempt::bare(Attempt::new(Outcome::Pass, true));
        let name = patch.unwrap_or("unpatched");
        let p = patch.map(String::from);
        ShaderVariant::judged(name, p, vec![], vec![a.clone(), a], uncompared.map(String::from))
    }

    fn report(variants: Vec<ShaderVariant>, notes: Vec<String>) -> ShaderRunReport {
        ShaderRunReport {
            schema: String::new(),
            rtprobe_version: String::new(),
            device: "d".into(),
            cell: "c".into(),
            options: serde_json::Value::Null,
            inputs: vec![],
            variants,
            outcome: Outcome::Pass,
            notes,
            injection: None,
            profile: None,
            cell_options: Default::default(),
            compare: None,
            index_bounds: None,
            baseline: None,
        }
    }

    /// Warnings are counted where errors are; a run without the layer says so, never "0".
    #[test]
    fn validation_is_said_as_it_ran() {
        let mut v = variant(Some("as-to-address"), None);
        assert!(variant_line(&v, false).contains("outputs identical, not validated"));
        assert!(variant_line(&v, true).ends_with("outputs identical, 0 validation errors"));
        v.attempts[0].validation_warnings = 2;
        let line = variant_line(&v, true);
        assert!(line.ends_with("0 validation errors, 2 warnings (counted, no verdict)"), "{line}");
        let mut r = report(vec![v], vec![]);
        assert!(verdict(&r).0.contains("no fault, not validated,"), "{}", verdict(&r).0);
        r.options = serde_json::json!({ "validate": true });
        assert!(verdict(&r).0.contains("no fault, no validation error (2 warnings),"));
        r.variants[0].attempts[0].validation_warnings = 0;
        assert!(verdict(&r).0.contains("no fault, no validation message,"));
    }

    #[test]
    fn identical_is_said_only_of_outputs_compared() {
        let compared = variant(Some("as-to-address"), None);
        assert!(variant_line(&compared, true).contains("outputs identical"));
        let alone = variant(Some("as-to-address"), Some("not compared: none"));
        let line = variant_line(&alone, true);
        assert!(!line.contains("identical") && line.contains("not compared: none"), "{line}");
        let (v, _) = verdict(&report(vec![alone], vec![]));
        assert!(!v.ends_with("no difference"), "{v}");
        let note = format!("{CANNOT_SHOW}: nothing written");
        let (v, _) = verdict(&report(vec![compared.clone()], vec![note]));
        assert!(v.ends_with("cannot show a difference: nothing written"), "{v}");
        let (v, _) = verdict(&report(vec![compared.clone()], vec![]));
        assert!(v.ends_with("no difference"), "{v}");
        let mut torn = compared;
        torn.teardown = Some("after its last attempt, the child process died".into());
        assert!(variant_line(&torn, true).contains("after its last attempt"));
        let (v, _) = verdict(&report(vec![torn], vec![]));
        assert!(v.contains("failed in teardown"), "{v}");
    }

    #[test]
    fn halves_and_texels_become_colours() {
        assert_eq!(half(0x3c00), 1.0);
        assert_eq!(half(0xc000), -2.0);
        assert_eq!(half(0x3800), 0.5);
        let t: Vec<u8> = [1.0f32, 0.5, -3.0, 1.0].iter().flat_map(|x| x.to_le_bytes()).collect();
        assert_eq!(rgb(ImageFormat::Rgba32f, &t), [255, 128, 0]);
        assert_eq!(rgb(ImageFormat::Rgba8, &[9, 8, 7, 6]), [9, 8, 7]);
        assert_eq!(rgb(ImageFormat::R32ui, &[0x41, 1, 0, 0]), [0x41, 0, 0]);
    }
}
