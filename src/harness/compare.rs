//! What `--verify` compares and how it judges: every storage image texel for texel and every
//! writable storage buffer byte for byte (counted in 4-byte words), unpatched against patched.
use serde::{Deserialize, Serialize};

/// What a read-back output is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PartKind {
    /// A storage image's texels.
    Image,
    /// A writable storage buffer's bytes (read-only ones are the harness's own data).
    Buffer,
}

/// One read-back output.
#[derive(Clone, Debug, PartialEq)]
pub struct Part {
    pub label: String,
    pub kind: PartKind,
    pub bytes: Vec<u8>,
    /// Bytes per texel (images) or per word (buffers: 4).
    pub texel: u32,
}

/// One output compared: units (texels or words), how many differ, how many distinct values the
/// unpatched one has.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Compared {
    pub label: String,
    pub kind: PartKind,
    pub texels: usize,
    pub differing: usize,
    pub distinct: usize,
}

impl Compared {
    fn unit(&self) -> &'static str {
        match self.kind {
            PartKind::Image => "texels",
            PartKind::Buffer => "4-byte words",
        }
    }
}

/// Unit-by-unit comparison of two runs' outputs (a length difference counts as differing units).
pub fn compare(before: &[Part], after: &[Part]) -> Vec<Compared> {
    before
        .iter()
        .zip(after)
        .map(|(b, a)| {
            let t = b.texel.max(1) as usize;
            let texels: Vec<&[u8]> = b.bytes.chunks(t).collect();
            let differing = texels.iter().zip(a.bytes.chunks(t)).filter(|(x, y)| **x != *y).count()
                + texels.len().abs_diff(a.bytes.len().div_ceil(t));
            let distinct = texels.iter().collect::<std::collections::BTreeSet<_>>().len();
            Compared {
                label: b.label.clone(),
                kind: b.kind,
                texels: texels.len(),
                differing,
                distinct,
            }
        })
        .collect()
}

/// What a comparison comes to.
#[derive(Clone, Debug, PartialEq)]
pub enum Verdict {
    /// Every output identical: one line per output.
    Identical(Vec<String>),
    /// An output differs: the line saying which and by how much.
    Differs(String),
    /// The outputs cannot tell a wrong read from a right one: why.
    Unfit(String),
}

/// Judge the comparison of a pipeline's outputs on `device`.
pub fn judge(device: &str, compared: &[Compared]) -> Verdict {
    let images: Vec<&Compared> = compared.iter().filter(|c| c.kind == PartKind::Image).collect();
    if compared.is_empty() {
        return Verdict::Unfit(
            "the pipeline writes no storage image or storage buffer to compare".into(),
        );
    }
    // Images of one value everywhere prove nothing about the patched reads (a raygen that
    // writes a constant, or results that do not depend on the patched descriptors).
    if !images.is_empty() && images.iter().all(|c| c.distinct <= 1) {
        return Verdict::Unfit("every storage image the pipeline writes holds one value, so the comparison cannot tell a wrong read from a right one; write something that depends on the patched descriptors".into());
    }
    if let Some(c) = compared.iter().find(|c| c.differing > 0) {
        return Verdict::Differs(format!(
            "the patched pipeline's {} differs from the unpatched one's in {} of {} {} on {device}",
            c.label,
            c.differing,
            c.texels,
            c.unit()
        ));
    }
    Verdict::Identical(
        compared
            .iter()
            .map(|c| {
                format!(
                    "verified on {device}: {}: {} {} identical, unpatched and patched ({} distinct values)",
                    c.label,
                    c.texels,
                    c.unit(),
                    c.distinct
                )
            })
            .collect(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn part(kind: PartKind, words: &[u8]) -> Part {
        Part {
            label: "x".into(),
            kind,
            bytes: words.iter().flat_map(|w| [*w, 0, 0, 0]).collect(),
            texel: 4,
        }
    }

    #[test]
    fn comparison_counts_differing_and_distinct_texels() {
        let a = part(PartKind::Image, &[1, 2, 2]);
        let b = part(PartKind::Image, &[1, 2, 3]);
        let c = &compare(std::slice::from_ref(&a), &[b])[0];
        assert_eq!((c.texels, c.differing, c.distinct), (3, 1, 2));
        let same = std::slice::from_ref(&a);
        assert_eq!(compare(same, same)[0].differing, 0);
        // A shorter output differs in what it lacks.
        let short = part(PartKind::Image, &[1, 2]);
        assert_eq!(compare(same, &[short])[0].differing, 1);
    }

    #[test]
    fn a_buffer_that_differs_fails_even_when_every_image_matches() {
        let img = part(PartKind::Image, &[1, 2, 3]);
        let buf = part(PartKind::Buffer, &[7, 8]);
        let same = compare(&[img.clone(), buf.clone()], &[img.clone(), buf.clone()]);
        assert!(matches!(judge("dev", &same), Verdict::Identical(l) if l.len() == 2));
        let other = part(PartKind::Buffer, &[7, 9]);
        match judge("dev", &compare(&[img.clone(), buf], &[img, other])) {
            Verdict::Differs(l) => {
                assert!(l.contains("differs") && l.contains("1 of 2 4-byte words"), "{l}")
            }
            v => panic!("{v:?}"),
        }
    }

    #[test]
    fn one_valued_images_or_nothing_cannot_verify() {
        let flat = part(PartKind::Image, &[5, 5, 5]);
        let c = compare(std::slice::from_ref(&flat), std::slice::from_ref(&flat));
        assert!(matches!(judge("dev", &c), Verdict::Unfit(w) if w.contains("one value")));
        assert!(matches!(judge("dev", &[]), Verdict::Unfit(w) if w.contains("no storage image")));
    }
}
