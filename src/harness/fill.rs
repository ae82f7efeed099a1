//! `run --shader --fill TARGET=SOURCE`: the user's bytes in place of the harness's data. A
//! TARGET is a buffer binding (`SET.BINDING`, every element, or `SET.BINDING[ELEM]`), the push
//! constants from a byte offset (`push.OFFSET`) or the shader record from one
//! (`record.OFFSET`); a SOURCE is `zero`, `random:SEED` (SplitMix64's output, little-endian, from
//! SEED) or a file's bytes. [`parse`] reads the text, [`resolve`] holds it to the reflected
//! modules (a target they do not have, a texture, a file larger than the target: one line) and
//! makes the bytes, before any device work; [`Fills`] places them: a buffer element gets the
//! bytes and zeros after them, the push constants and the shader record get them from OFFSET on,
//! the harness's data around them. A filled range is exactly the user's bytes (no sink address
//! or small integer is put into it).
use super::module::UserModule;
use super::reflect::BindingKind;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// What `--fill` cannot take, in one line naming the target.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum FillError {
    /// The text is not `TARGET=SOURCE`.
    #[error("--fill {0}: {1}")]
    Syntax(String, String),
    /// The modules do not have the target, or it is not a buffer.
    #[error("--fill {0}: {1}")]
    Target(String, String),
    /// The source file cannot be read, or does not fit.
    #[error("--fill {0}: {1}")]
    Source(String, String),
}

/// Where a fill goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Target {
    /// A buffer binding: one element, or every element (`None`).
    Binding { set: u32, binding: u32, element: Option<u32> },
    /// The push constants, from this byte on.
    Push(u32),
    /// The shader record data, from this byte on.
    Record(u32),
}

/// Where the bytes come from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Source {
    Zero,
    /// SplitMix64 seeded with this value.
    Random(u64),
    File(PathBuf),
    /// `scene.NAME`: the `--scene` file's data (laid out by the `scene_data` module).
    Scene(super::scene_item::Item),
}

/// One `--fill` as given.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Request {
    pub text: String,
    pub target: Target,
    pub source: Source,
}

/// One fill as the harness places it.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Fill {
    pub target: Target,
    pub bytes: Vec<u8>,
}

/// What the `--fill` forms are, for errors.
const FORMS: &str = "give TARGET=SOURCE: TARGET is SET.BINDING, SET.BINDING[ELEM], push.OFFSET or record.OFFSET; SOURCE is zero, random:SEED, a file or scene.NAME";

fn number<T: std::str::FromStr>(s: &str) -> Option<T> {
    s.trim().parse().ok()
}

fn target(t: &str) -> Option<Target> {
    if let Some(o) = t.strip_prefix("push.") {
        return number(o).map(Target::Push);
    }
    if let Some(o) = t.strip_prefix("record.") {
        return number(o).map(Target::Record);
    }
    let (set, rest) = t.split_once('.')?;
    let (binding, element) = match rest.split_once('[') {
        Some((b, e)) => (b, Some(number(e.strip_suffix(']')?)?)),
        None => (rest, None),
    };
    Some(Target::Binding { set: number(set)?, binding: number(binding)?, element })
}

/// `TARGET=SOURCE`.
pub fn parse(text: &str) -> Result<Request, FillError> {
    let syntax = |why: String| FillError::Syntax(text.to_string(), why);
    let (t, s) = text.split_once('=').ok_or_else(|| syntax(FORMS.into()))?;
    let target = target(t).ok_or_else(|| syntax(format!("target `{t}`: {FORMS}")))?;
    let source = match s {
        "zero" => Source::Zero,
        _ if s.starts_with("scene.") => {
            let item = super::scene_item::Item::parse(&s["scene.".len()..]).ok_or_else(|| {
                let names: Vec<&str> = super::scene_item::ALL.iter().map(|i| i.name()).collect();
                syntax(format!("`{s}`: give scene.NAME, NAME one of {}", names.join(", ")))
            })?;
            Source::Scene(item)
        }
        _ => match s.strip_prefix("random:") {
            Some(seed) => Source::Random(number(seed).ok_or_else(|| {
                syntax(format!("`{s}`: the seed is an unsigned 64-bit integer (random:42)"))
            })?),
            None if s.is_empty() => return Err(syntax(FORMS.into())),
            None => Source::File(PathBuf::from(s)),
        },
    };
    Ok(Request { text: text.to_string(), target, source })
}

/// `n` bytes of SplitMix64 seeded with `seed`, each output little-endian.
pub fn random_bytes(seed: u64, n: usize) -> Vec<u8> {
    let mut state = seed;
    let mut out = Vec::with_capacity(n + 8);
    while out.len() < n {
        state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        out.extend_from_slice(&(z ^ (z >> 31)).to_le_bytes());
    }
    out.truncate(n);
    out
}

/// The bytes target `r.target` holds in `modules`: a buffer element's size, or the bytes from
/// OFFSET to the block's end; a target they do not have is refused naming what they have.
pub(super) fn room(r: &Request, modules: &[UserModule]) -> Result<u32, FillError> {
    let refuse = |why: String| FillError::Target(r.text.clone(), why);
    match r.target {
        Target::Binding { set, binding, element } => {
            let all: Vec<_> =
                modules.iter().flat_map(|m| m.iface.bindings.iter().cloned()).collect();
            let merged = super::bindings::merged(&all).unwrap_or_default();
            let Some(b) = merged.get(&(set, binding)) else {
                let have: Vec<String> = merged.keys().map(|(s, b)| format!("{s}.{b}")).collect();
                return Err(refuse(format!(
                    "no module binds set {set} binding {binding} (bound: {}); give one of those",
                    if have.is_empty() { "none".to_string() } else { have.join(", ") }
                )));
            };
            let size = match b.kind {
                BindingKind::StorageBuffer(n) | BindingKind::UniformBuffer(n) => n,
                BindingKind::AccelerationStructure
                | BindingKind::StorageImage(_)
                | BindingKind::SampledImage
                | BindingKind::Sampler
                | BindingKind::CombinedImageSampler => return Err(refuse(format!("set {set} binding {binding} is {}, not a buffer; --fill fills buffers, push constants and shader records", kind_words(b.kind)))),
            };
            match element {
                Some(e) if e >= b.count => Err(refuse(format!(
                    "set {set} binding {binding} has {} element(s), 0 to {}; give an element in range",
                    b.count,
                    b.count - 1
                ))),
                _ => Ok(size),
            }
        }
        Target::Push(offset) => {
            let end = modules.iter().map(|m| m.iface.push_end).max().unwrap_or(0);
            block_room(offset, end, "push constants", "push").map_err(refuse)
        }
        Target::Record(offset) => {
            let end = modules.iter().map(|m| m.iface.record_end).max().unwrap_or(0);
            block_room(offset, end, "shader record block", "record").map_err(refuse)
        }
    }
}

/// The bytes from `offset` to a block's `end`.
fn block_room(offset: u32, end: u32, what: &str, prefix: &str) -> Result<u32, String> {
    match end {
        0 => Err(format!("no module has a {what}; drop this --fill")),
        _ if offset >= end => Err(format!(
            "byte {offset} is past the end of the {what} ({end} bytes); give {prefix}.0 to {prefix}.{}",
            end - 1
        )),
        _ => Ok(end - offset),
    }
}

fn kind_words(k: BindingKind) -> &'static str {
    match k {
        BindingKind::AccelerationStructure => "an acceleration structure",
        BindingKind::StorageImage(_) => "a storage image",
        BindingKind::StorageBuffer(_) | BindingKind::UniformBuffer(_) => "a buffer",
        BindingKind::SampledImage => "a texture",
        BindingKind::Sampler => "a sampler",
        BindingKind::CombinedImageSampler => "a texture (combined image sampler)",
    }
}

/// `r` held to `modules` (the given ones, sized as they run): the bytes it places. A buffer
/// element's bytes are the whole element (a file's bytes then zeros); a push or record fill
/// runs from OFFSET to the block's end (a file: its length).
pub fn resolve(r: &Request, modules: &[UserModule]) -> Result<Fill, FillError> {
    let room = room(r, modules)? as usize;
    let buffer = matches!(r.target, Target::Binding { .. });
    let bytes = match &r.source {
        Source::Scene(_) => Vec::new(),
        Source::Zero => vec![0; room],
        Source::Random(seed) => random_bytes(*seed, room),
        Source::File(p) => {
            let mut b = read_bounded(p, room).map_err(|e| {
                FillError::Source(
                    r.text.clone(),
                    format!("{}: {e}; give a readable regular file", p.display()),
                )
            })?;
            if b.len() > room {
                return Err(FillError::Source(
                    r.text.clone(),
                    format!("{} holds {} bytes, more than the {room} the target has; give a file of at most {room} bytes", p.display(), b.len()),
                ));
            }
            if buffer {
                b.resize(room, 0);
            }
            b
        }
    };
    Ok(Fill { target: r.target, bytes })
}

/// Where a fill's bytes go: a buffer binding (its element, or every element: `None`), or a byte
/// range of the push constants (`false`) or the shader record (`true`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Span {
    Binding(u32, u32, Option<u32>),
    Block(bool, u32, u32),
}

impl Span {
    fn of(target: Target, len: u32) -> Span {
        match target {
            Target::Binding { set, binding, element } => Span::Binding(set, binding, element),
            Target::Push(o) => Span::Block(false, o, o + len),
            Target::Record(o) => Span::Block(true, o, o + len),
        }
    }

    fn meets(self, other: Span) -> bool {
        match (self, other) {
            (Span::Binding(s, b, e), Span::Binding(s2, b2, e2)) => {
                (s, b) == (s2, b2) && (e.is_none() || e2.is_none() || e == e2)
            }
            (Span::Block(r, a, b), Span::Block(r2, a2, b2)) => r == r2 && a < b2 && a2 < b,
            (Span::Binding(..), Span::Block(..)) | (Span::Block(..), Span::Binding(..)) => false,
        }
    }
}

/// Two of `fills` (each its text, target and the bytes it places: a scene address's 8) that
/// meet — the same buffer element, or overlapping push or record bytes — refused naming both:
/// which one the shader would read is no choice rtprobe should make silently.
pub fn check_disjoint(fills: &[(String, Target, u32)]) -> Result<(), FillError> {
    for (k, (text, target, len)) in fills.iter().enumerate() {
        let here = Span::of(*target, *len);
        if let Some((first, ..)) = fills[..k].iter().find(|(_, t, l)| Span::of(*t, *l).meets(here))
        {
            return Err(FillError::Target(
                text.clone(),
                format!("overlaps --fill {first} (the same buffer element, or push or record bytes both write); give fills that do not overlap (a zero or random fill runs to the block's end: fill the bytes before the other instead, or give a file)"),
            ));
        }
    }
    Ok(())
}

/// The fills of a run, in the order given (none overlaps another: [`check_disjoint`]).
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Fills(pub Vec<Fill>);

impl Fills {
    /// The bytes of element `k` of the buffer binding at `key`, when a fill names it.
    pub fn buffer(&self, key: (u32, u32), k: u32) -> Option<&[u8]> {
        self.0.iter().rev().find_map(|f| match f.target {
            Target::Binding { set, binding, element }
                if (set, binding) == key && element.is_none_or(|e| e == k) =>
            {
                Some(f.bytes.as_slice())
            }
            Target::Binding { .. } | Target::Push(_) | Target::Record(_) => None,
        })
    }

    /// `bytes` (push constants when `record` is false, else the shader record) with every fill
    /// of that block copied in at its offset (clipped to `bytes`).
    pub fn overlay(&self, record: bool, bytes: &mut [u8]) {
        for f in &self.0 {
            let offset = match (f.target, record) {
                (Target::Push(o), false) | (Target::Record(o), true) => o as usize,
                (Target::Push(_) | Target::Record(_) | Target::Binding { .. }, _) => continue,
            };
            let end = (offset + f.bytes.len()).min(bytes.len());
            if offset < end {
                bytes[offset..end].copy_from_slice(&f.bytes[..end - offset]);
            }
        }
    }
}

/// A regular file's bytes, at most `room` + 1 of them (enough to tell that it is too large):
/// `/dev/zero` or a FIFO must neither fill the memory nor block.
fn read_bounded(p: &std::path::Path, room: usize) -> std::io::Result<Vec<u8>> {
    use std::io::Read;
    let f = std::fs::File::open(p)?;
    if !f.metadata()?.is_file() {
        return Err(std::io::Error::other("not a regular file"));
    }
    let mut b = Vec::new();
    f.take(room as u64 + 1).read_to_end(&mut b)?;
    Ok(b)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn targets_and_sources_are_parsed() {
        let p = |s: &str| parse(s).map(|r| (r.target, r.source));
        assert_eq!(
            p("1.2=zero"),
            Ok((Target::Binding { set: 1, binding: 2, element: None }, Source::Zero))
        );
        assert_eq!(
            p("0.3[7]=random:42"),
            Ok((Target::Binding { set: 0, binding: 3, element: Some(7) }, Source::Random(42)))
        );
        assert_eq!(p("push.16=a.bin"), Ok((Target::Push(16), Source::File("a.bin".into()))));
        assert_eq!(p("record.0=zero"), Ok((Target::Record(0), Source::Zero)));
        // Twins: each malformed form is one line saying what to give.
        for bad in ["0.1", "push=zero", "x.1=zero", "0.1[=zero", "0.1=random:x", "0.1="] {
            let e = parse(bad).unwrap_err().to_string();
            assert!(e.starts_with(&format!("--fill {bad}: ")) && !e.contains('\n'), "{e}");
        }
        let p = parse("push.8=scene.scene_desc").unwrap();
        assert_eq!(p.source, Source::Scene(super::super::scene_item::Item::SceneDesc));
        let e = parse("0.1=scene.vertices").unwrap_err().to_string();
        assert!(e.contains("scene.NAME, NAME one of positions,"), "{e}");
    }

    /// Fills that meet are refused naming both: a scene address under a zero fill, two push
    /// ranges overlapping by one byte, an element under a whole-binding fill. The twins:
    /// adjacent push ranges, push and record at one offset, two elements of one binding.
    #[test]
    fn overlapping_fills_are_refused() {
        let f = |t: &str, len| (t.to_string(), parse(t).unwrap().target, len);
        let e = check_disjoint(&[f("push.16=scene.scene_desc", 8), f("push.16=zero", 16)]);
        let e = e.unwrap_err().to_string();
        assert!(
            e.starts_with("--fill push.16=zero: overlaps --fill push.16=scene.scene_desc"),
            "{e}"
        );
        assert!(!e.contains('\n'));
        assert!(check_disjoint(&[f("push.0=zero", 9), f("push.8=zero", 8)]).is_err());
        assert!(check_disjoint(&[f("1.0=zero", 64), f("1.0[2]=zero", 64)]).is_err());
        assert!(check_disjoint(&[f("push.0=zero", 8), f("push.8=zero", 8)]).is_ok());
        assert!(check_disjoint(&[f("push.0=zero", 8), f("record.0=zero", 8)]).is_ok());
        assert!(check_disjoint(&[f("1.0[1]=zero", 64), f("1.0[2]=zero", 64)]).is_ok());
    }

    /// SplitMix64 from seed 0 gives its published first output; another seed other bytes.
    #[test]
    fn random_bytes_are_splitmix64() {
        let b = random_bytes(0, 12);
        assert_eq!(&b[..8], &0xe220_a839_7b1d_cdaf_u64.to_le_bytes());
        assert_eq!(b.len(), 12);
        assert_eq!(random_bytes(0, 12), b);
        assert_ne!(random_bytes(1, 12), b);
    }

    #[test]
    fn overlays_and_buffer_fills_place_the_bytes() {
        let fills = Fills(vec![
            Fill { target: Target::Push(4), bytes: vec![1, 2, 3, 4, 5, 6] },
            Fill { target: Target::Record(2), bytes: vec![9] },
            Fill {
                target: Target::Binding { set: 0, binding: 1, element: Some(2) },
                bytes: vec![7],
            },
        ]);
        let mut push = [0xAA; 8];
        fills.overlay(false, &mut push);
        assert_eq!(push, [0xAA, 0xAA, 0xAA, 0xAA, 1, 2, 3, 4]);
        let mut rec = [0; 4];
        fills.overlay(true, &mut rec);
        assert_eq!(rec, [0, 0, 9, 0]);
        assert_eq!(fills.buffer((0, 1), 2), Some(&[7u8][..]));
        assert_eq!((fills.buffer((0, 1), 1), fills.buffer((1, 1), 2)), (None, None));
    }
}
