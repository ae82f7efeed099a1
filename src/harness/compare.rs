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

/// One read-back output (the `run --shader` child hands it over as JSON).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Part {
    pub label: String,
    pub kind: PartKind,
    pub bytes: Vec<u8>,
    /// Bytes per texel (images) or per word (buffers: 4).
    pub texel: u32,
    /// What a buffer held before the trace (the harness's fill); `None` for images.
    pub initial: Option<Vec<u8>>,
    /// A buffer some module writes through atomics (an append queue): the order its records
    /// are filled in is the driver's scheduling, so they may be compared as a multiset.
    pub scheduled: bool,
    /// A buffer block's trailing array: its byte offset and stride (`ArrayStride`), the records
    /// an append queue fills. Without it no multiset comparison is made.
    pub records: Option<(u32, u32)>,
}

/// One output compared: units (texels or words), how many differ, how many distinct values the
/// written units hold (both runs), how many the trace wrote, how many were unstable.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Compared {
    pub label: String,
    pub kind: PartKind,
    pub texels: usize,
    pub differing: usize,
    pub distinct: usize,
    /// Units the trace wrote: all of an image; a buffer's that differ from its initial fill in
    /// either run. Only written units are compared.
    #[serde(default)]
    pub written: usize,
    /// Units that differ between two runs of the unpatched pipeline (an append queue's order):
    /// left out of the comparison.
    #[serde(default)]
    pub unstable: usize,
    /// The words differ in place but not as a multiset, and the order is the driver's (unstable
    /// words, or an atomically written buffer): counted as identical, and said.
    #[serde(default)]
    pub reordered: bool,
}

impl Compared {
    fn unit(&self) -> &'static str {
        match self.kind {
            PartKind::Image => "texels",
            PartKind::Buffer => "4-byte words",
        }
    }

    /// Whether the output can tell a wrong read from a right one: written, more than one value,
    /// and compared in place (a reordered atomically written buffer is not).
    fn informative(&self) -> bool {
        self.written > 0 && self.distinct > 1 && !self.reordered
    }
}

/// Unit-by-unit comparison of the unpatched pipeline's outputs (`before`, and `again` from a
/// second unpatched trace) with the patched one's (`after`). A unit that differs between the
/// two unpatched runs is unstable and left out; a buffer unit equal to its initial fill in every
/// run was not written and is left out; a length difference counts as differing units.
///
/// A buffer written through atomics ([`Part::scheduled`]) whose block ends in an array
/// ([`Part::records`]) and whose words differ in place but not as records (the words before the
/// array identical in place, unstable ones aside; the array's `ArrayStride`-byte elements the
/// same multiset) is `reordered`: the order an append queue fills in is the driver's scheduling
/// (two unpatched runs may fill it in the same order by chance and the patched one in another;
/// CI saw 8402 of 16388 words move). Such a buffer counts as no difference and as no evidence
/// either: its in-place comparison failed, and a multiset cannot tell a record moved by the
/// driver from one a wrong read put at another index (review: a pixel-indexed array beside an
/// atomic counter; fields of a `uint data[]` queue swapped). The verdict then rests on the other
/// outputs, else the run is unfit. Unstable units alone never allow a multiset; images never.
pub fn compare(before: &[Part], again: &[Part], after: &[Part]) -> Vec<Compared> {
    compare_within(before, again, after, None)
}

/// How far a 32-bit float word of `after` may be from `before`'s and still count as equal
/// (`run --shader --compare --tolerance`): an absolute difference, and which words are floats.
pub struct Tolerance<'a> {
    /// The largest absolute difference that passes (0: only equal values, `0.0 == -0.0`).
    pub abs: f32,
    /// Whether the 4-byte word at byte `offset` of output `part` (its index) is a 32-bit float;
    /// every other word must be bit-identical.
    pub float: &'a dyn Fn(usize, usize) -> bool,
}

impl Tolerance<'_> {
    /// Whether unit `k` of output `part` (`t` bytes: a texel or a word) is equal within the
    /// tolerance: bit-identical words are; else a float word whose values are both finite and
    /// at most `abs` apart (a NaN or an infinity never passes); any other word never.
    fn same(&self, part: usize, k: usize, x: &[u8], y: &[u8]) -> bool {
        if x.len() != y.len() {
            return false;
        }
        let word = |c: &[u8]| c.try_into().map(f32::from_le_bytes).ok();
        x.chunks(4).zip(y.chunks(4)).enumerate().all(|(j, (wx, wy))| {
            wx == wy
                || ((self.float)(part, k * x.len() + 4 * j)
                    && matches!((word(wx), word(wy)), (Some(a), Some(b))
                        if a.is_finite() && b.is_finite() && (a - b).abs() <= self.abs))
        })
    }
}

/// [`compare`], units equal within `tol` where one is given (bit-identical without): the one
/// comparer of `--verify`, `run --shader`'s variants and `--compare`.
pub fn compare_within(
    before: &[Part],
    again: &[Part],
    after: &[Part],
    tol: Option<&Tolerance>,
) -> Vec<Compared> {
    before
        .iter()
        .zip(again)
        .zip(after)
        .enumerate()
        .map(|(n, ((b, g), a))| {
            compare_one(b, g, a, |k, x, y| match tol {
                Some(t) => t.same(n, k, x, y),
                None => x == y,
            })
        })
        .collect()
}

fn compare_one<'a>(
    b: &'a Part,
    g: &'a Part,
    a: &'a Part,
    same: impl Fn(usize, &[u8], &[u8]) -> bool,
) -> Compared {
    let t = b.texel.max(1) as usize;
    let units = |p: &'a Part| -> Vec<&'a [u8]> { p.bytes.chunks(t).collect() };
    let (bs, gs, as_) = (units(b), units(g), units(a));
    let init: Option<Vec<&[u8]>> = b.initial.as_ref().map(|i| i.chunks(t).collect());
    let (mut unstable, mut differing) = (0, 0);
    let (mut kept_b, mut kept_a) = (Vec::new(), Vec::new());
    for (k, x) in bs.iter().enumerate() {
        if gs.get(k) != Some(x) {
            unstable += 1;
            continue;
        }
        let y = as_.get(k);
        let unwritten =
            init.as_ref().and_then(|i| i.get(k)).is_some_and(|i| x == i && y == Some(i));
        if unwritten {
            continue;
        }
        kept_b.push(*x);
        if let Some(y) = y {
            kept_a.push(*y);
        }
        differing += usize::from(!y.is_some_and(|y| same(k, x, y)));
    }
    // Units only the patched output has (the loop counted those only the unpatched one has).
    differing += as_.len().saturating_sub(bs.len());
    let reordered =
        b.scheduled && differing > 0 && b.kind == PartKind::Buffer && same_records(b, g, a);
    if reordered {
        differing = 0;
    }
    let distinct = kept_b.iter().chain(&kept_a).collect::<std::collections::BTreeSet<_>>().len();
    Compared {
        label: b.label.clone(),
        kind: b.kind,
        texels: bs.len(),
        differing,
        distinct,
        written: kept_b.len(),
        unstable,
        reordered,
    }
}

/// Whether `b` (and `g`, its second run) and `a` are the same buffer up to the order of the
/// records of its trailing array (see [`compare`]).
fn same_records(b: &Part, g: &Part, a: &Part) -> bool {
    let Some((offset, stride)) = b.records else {
        return false;
    };
    let (offset, stride) = (offset as usize, stride as usize);
    if a.bytes.len() != b.bytes.len() || offset > b.bytes.len() || stride == 0 {
        return false;
    }
    let head_same = (0..offset / 4).all(|k| {
        let w = |p: &Part| p.bytes.get(k * 4..k * 4 + 4).map(<[u8]>::to_vec);
        w(b) != w(g) || w(b) == w(a)
    });
    let n = (b.bytes.len() - offset) / stride;
    let end = offset + n * stride;
    let sorted = |bytes: &[u8]| {
        let mut r: Vec<Vec<u8>> = bytes.chunks(stride).map(<[u8]>::to_vec).collect();
        r.sort_unstable();
        r
    };
    head_same
        && sorted(&b.bytes[offset..end]) == sorted(&a.bytes[offset..end])
        && b.bytes[end..] == a.bytes[end..]
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

/// Judge the comparison of a pipeline's outputs on `device`: a difference first (in any
/// output, informative or not); only when nothing differs, unfit when no compared output was
/// written with more than one value (a raygen that writes a constant, a buffer the trace never
/// writes, results that do not depend on the patched descriptors).
pub fn judge(device: &str, compared: &[Compared]) -> Verdict {
    if compared.is_empty() {
        return Verdict::Unfit(
            "the pipeline writes no storage image or storage buffer to compare".into(),
        );
    }
    if let Some(c) = compared.iter().find(|c| c.differing > 0) {
        return Verdict::Differs(format!(
            "the patched pipeline's {} differs from the unpatched one's in {} of {} {} on {device}{}",
            c.label,
            c.differing,
            c.texels,
            c.unit(),
            unstable_note(c)
        ));
    }
    if !compared.iter().any(Compared::informative) {
        return Verdict::Unfit("nothing the pipeline wrote can tell a wrong read from a right one: its storage images hold one value and its writable buffers were not written by the trace (or hold one value); write something that depends on the patched descriptors".into());
    }
    Verdict::Identical(compared.iter().map(|c| identical_line(device, c)).collect())
}

/// ", N … left out: they differ between two unpatched runs" when any were.
fn unstable_note(c: &Compared) -> String {
    if c.unstable == 0 {
        return String::new();
    }
    format!(
        " ({} {} left out: they differ between two runs of the unpatched pipeline)",
        c.unstable,
        c.unit()
    )
}

fn identical_line(device: &str, c: &Compared) -> String {
    if c.reordered {
        return format!("on {device}: {}: the same records in another order (written through atomics: the order is the driver's scheduling); not compared in place, not counted{}", c.label, unstable_note(c));
    }
    if c.kind == PartKind::Buffer && c.written == 0 {
        return format!("on {device}: {}: not written by the trace (its initial data in every run; not counted){}", c.label, unstable_note(c));
    }
    let written = if c.kind == PartKind::Buffer && c.written < c.texels {
        format!(" ({} written)", c.written)
    } else {
        String::new()
    };
    format!(
        "verified on {device}: {}: {} {} identical{written}, unpatched and patched ({} distinct values){}",
        c.label,
        c.texels,
        c.unit(),
        c.distinct,
        unstable_note(c)
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn part(kind: PartKind, words: &[u8]) -> Part {
        let initial = (kind == PartKind::Buffer).then(|| vec![0xEE; words.len() * 4]);
        Part {
            label: "x".into(),
            kind,
            bytes: words.iter().flat_map(|w| [*w, 0, 0, 0]).collect(),
            texel: 4,
            initial,
            scheduled: false,
            records: (kind == PartKind::Buffer).then_some((4, 4)),
        }
    }

    /// Compare with the second unpatched run equal to the first.
    fn cmp(before: &[Part], after: &[Part]) -> Vec<Compared> {
        compare(before, before, after)
    }

    #[test]
    fn comparison_counts_differing_and_distinct_texels() {
        let a = part(PartKind::Image, &[1, 2, 2]);
        let b = part(PartKind::Image, &[1, 2, 3]);
        let c = &cmp(std::slice::from_ref(&a), &[b])[0];
        assert_eq!((c.texels, c.differing, c.distinct, c.written), (3, 1, 3, 3));
        let same = std::slice::from_ref(&a);
        assert_eq!(cmp(same, same)[0].differing, 0);
        // A shorter or a longer output differs in what one lacks.
        let short = part(PartKind::Image, &[1, 2]);
        assert_eq!(cmp(same, &[short])[0].differing, 1);
        let long = part(PartKind::Image, &[1, 2, 2, 4, 5]);
        assert_eq!(cmp(same, &[long])[0].differing, 2);
    }

    #[test]
    fn a_buffer_that_differs_fails_even_when_every_image_matches() {
        let img = part(PartKind::Image, &[1, 2, 3]);
        let buf = part(PartKind::Buffer, &[7, 8]);
        let same = cmp(&[img.clone(), buf.clone()], &[img.clone(), buf.clone()]);
        assert!(matches!(judge("dev", &same), Verdict::Identical(l) if l.len() == 2));
        let other = part(PartKind::Buffer, &[7, 9]);
        match judge("dev", &cmp(&[img.clone(), buf], &[img, other])) {
            Verdict::Differs(l) => {
                assert!(l.contains("differs") && l.contains("1 of 2 4-byte words"), "{l}")
            }
            v => panic!("{v:?}"),
        }
    }

    /// `--compare --tolerance`: a float word within the tolerance is equal, one beyond it or a
    /// non-finite one differs, an integer word must be identical; words the harness left
    /// unwritten or unstable stay out as without a tolerance.
    #[test]
    fn a_tolerance_passes_near_floats_only() {
        let floats = |v: &[f32]| Part {
            bytes: v.iter().flat_map(|x| x.to_le_bytes()).collect(),
            ..part(PartKind::Image, &[0; 4])
        };
        let (a, near, far) = (
            floats(&[1.0, 2.0, 3.0, 4.0]),
            floats(&[1.0, 2.0005, 3.0, 4.0]),
            floats(&[1.0, 2.1, 3.0, 4.0]),
        );
        let all = |_: usize, _: usize| true;
        let t = Tolerance { abs: 1e-3, float: &all };
        let within = |x: &Part, y: &Part, t: Option<&Tolerance>| {
            compare_within(
                std::slice::from_ref(x),
                std::slice::from_ref(x),
                std::slice::from_ref(y),
                t,
            )[0]
            .differing
        };
        assert_eq!((within(&a, &near, Some(&t)), within(&a, &far, Some(&t))), (0, 1));
        // Twin: without a tolerance, or at 0, the near one differs too.
        assert_eq!(within(&a, &near, None), 1);
        assert_eq!(within(&a, &near, Some(&Tolerance { abs: 0.0, float: &all })), 1);
        // Non-finite values never pass; identical bits do.
        let nan = floats(&[1.0, f32::NAN, 3.0, 4.0]);
        let inf = floats(&[1.0, f32::INFINITY, 3.0, 4.0]);
        let huge = Tolerance { abs: f32::MAX, float: &all };
        assert_eq!((within(&a, &nan, Some(&huge)), within(&a, &inf, Some(&huge))), (1, 1));
        assert_eq!(within(&nan, &nan, Some(&huge)), 0);
        // Integer words (here the second) must be identical, whatever the tolerance.
        let ints = |_: usize, offset: usize| offset % 16 != 4;
        assert_eq!(within(&a, &near, Some(&Tolerance { abs: 1.0, float: &ints })), 1);
        // An unstable unit stays out.
        let c = compare_within(
            std::slice::from_ref(&a),
            std::slice::from_ref(&far),
            std::slice::from_ref(&far),
            Some(&t),
        );
        assert_eq!((c[0].unstable, c[0].differing), (1, 0));
    }

    /// Review item 4: a one-valued image used to make the run unfit before any difference was
    /// looked for, so a differing buffer beside it went unreported.
    #[test]
    fn a_difference_beside_a_one_valued_image_is_reported() {
        let flat = part(PartKind::Image, &[5, 5, 5]);
        let (buf, other) = (part(PartKind::Buffer, &[7, 8]), part(PartKind::Buffer, &[7, 9]));
        let c = cmp(&[flat.clone(), buf], &[flat, other]);
        assert!(matches!(judge("dev", &c), Verdict::Differs(l) if l.contains("1 of 2")), "{c:?}");
    }

    #[test]
    fn one_valued_images_or_nothing_cannot_verify() {
        let flat = part(PartKind::Image, &[5, 5, 5]);
        let c = cmp(std::slice::from_ref(&flat), std::slice::from_ref(&flat));
        assert!(matches!(judge("dev", &c), Verdict::Unfit(w) if w.contains("one value")));
        assert!(matches!(judge("dev", &[]), Verdict::Unfit(w) if w.contains("no storage image")));
        // A one-valued image beside a written, many-valued buffer: the buffer verifies.
        let buf = part(PartKind::Buffer, &[7, 8]);
        let c = cmp(&[flat.clone(), buf.clone()], &[flat, buf]);
        assert!(matches!(judge("dev", &c), Verdict::Identical(_)), "{c:?}");
    }

    /// Review item 5: a buffer the trace never writes compared "identical" (its initial fill).
    #[test]
    fn a_buffer_left_as_filled_is_not_written_and_proves_nothing() {
        let mut buf = part(PartKind::Buffer, &[7, 8, 9]);
        buf.initial = Some(buf.bytes.clone());
        let c = cmp(std::slice::from_ref(&buf), std::slice::from_ref(&buf));
        assert_eq!((c[0].written, c[0].differing), (0, 0));
        assert!(matches!(judge("dev", &c), Verdict::Unfit(w) if w.contains("not written")));
        // Beside an informative image it is said, not counted.
        let img = part(PartKind::Image, &[1, 2, 3]);
        let c = cmp(&[img.clone(), buf.clone()], &[img, buf.clone()]);
        match judge("dev", &c) {
            Verdict::Identical(l) => assert!(l[1].contains("not written by the trace"), "{l:?}"),
            v => panic!("{v:?}"),
        }
        // One word written: compared, and its change is a difference.
        let mut wrote = buf.clone();
        wrote.bytes[4] = 1;
        let mut wrong = buf.clone();
        wrong.bytes[4] = 2;
        let c = cmp(std::slice::from_ref(&wrote), std::slice::from_ref(&wrong));
        assert_eq!((c[0].written, c[0].differing), (1, 1));
    }

    /// Review item 6: units that differ between two unpatched runs are left out, said, and a
    /// permutation of an append queue's records is no difference; a stable change still is.
    #[test]
    fn unstable_units_are_left_out_and_a_reordered_queue_is_no_difference() {
        let run1 = part(PartKind::Buffer, &[3, 10, 20, 30, 40]);
        let run2 = part(PartKind::Buffer, &[3, 20, 10, 30, 40]);
        let patched = part(PartKind::Buffer, &[3, 30, 20, 10, 40]);
        // Not written through atomics: unstable units left out, the rest compared in place.
        let c = compare(
            std::slice::from_ref(&run1),
            std::slice::from_ref(&run2),
            std::slice::from_ref(&patched),
        );
        assert_eq!((c[0].unstable, c[0].differing, c[0].reordered), (2, 1, false), "{c:?}");
        let q = |p: &Part| Part { scheduled: true, ..p.clone() };
        let img = part(PartKind::Image, &[1, 2, 3]);
        let c = compare(
            &[img.clone(), q(&run1)],
            &[img.clone(), q(&run2)],
            &[img.clone(), q(&patched)],
        );
        assert_eq!((c[1].unstable, c[1].differing, c[1].reordered), (2, 0, true), "{c:?}");
        match judge("dev", &c) {
            Verdict::Identical(l) => assert!(
                l[1].contains("2 4-byte words left out") && l[1].contains("not counted"),
                "{l:?}"
            ),
            v => panic!("{v:?}"),
        }
        // Twin: a value the unpatched runs never hold is a difference.
        let wrong = part(PartKind::Buffer, &[3, 10, 20, 99, 40]);
        let c = compare(std::slice::from_ref(&run1), &[run2], &[wrong]);
        assert_eq!(c[0].differing, 1, "{c:?}");
        assert!(matches!(judge("dev", &c), Verdict::Differs(l) if l.contains("left out")));
    }

    /// CI: two unpatched runs filled an append queue in the same order and the patched one in
    /// another (8402 of 16388 words moved). A buffer written through atomics is compared as a
    /// multiset; a buffer that is not, or a changed record, still differs.
    #[test]
    fn an_atomic_queue_in_another_order_is_no_difference_even_when_both_runs_agree() {
        let mut run = part(PartKind::Buffer, &[3, 10, 20, 30, 40]);
        let mut patched = part(PartKind::Buffer, &[3, 30, 20, 10, 40]);
        // Not written through atomics: the move is a difference.
        let c = cmp(std::slice::from_ref(&run), std::slice::from_ref(&patched));
        assert_eq!((c[0].unstable, c[0].differing, c[0].reordered), (0, 2, false), "{c:?}");
        (run.scheduled, patched.scheduled) = (true, true);
        let c = cmp(std::slice::from_ref(&run), std::slice::from_ref(&patched));
        assert_eq!((c[0].unstable, c[0].differing, c[0].reordered), (0, 0, true), "{c:?}");
        // No difference, but no evidence either: alone it cannot verify.
        assert!(matches!(judge("dev", &c), Verdict::Unfit(_)), "{c:?}");
        let img = part(PartKind::Image, &[1, 2, 3]);
        let c = cmp(&[img.clone(), run.clone()], &[img, patched.clone()]);
        match judge("dev", &c) {
            Verdict::Identical(l) => assert!(l[1].contains("in another order"), "{l:?}"),
            v => panic!("{v:?}"),
        }
        // Twin: one record changed is a difference, whatever the order.
        let mut wrong = part(PartKind::Buffer, &[3, 30, 20, 11, 40]);
        wrong.scheduled = true;
        let c = cmp(std::slice::from_ref(&run), std::slice::from_ref(&wrong));
        assert_eq!((c[0].differing, c[0].reordered), (2, false), "{c:?}");
    }

    /// Review: a patch that swapped two tables' addresses moved albedo and emissive between the
    /// fields of every appended record and passed, the words compared loose. Records are whole
    /// (`ArrayStride` bytes): whole records in another order are no difference, fields swapped
    /// inside them are; a buffer with no record array and an image are never compared as a
    /// multiset; the words before the array (the counter) must match in place.
    #[test]
    fn records_are_compared_whole_and_only_in_buffers_that_have_them() {
        let queue = |words: &[u8], records| {
            let mut p = part(PartKind::Buffer, words);
            (p.scheduled, p.records) = (true, records);
            p
        };
        let run = queue(&[2, 10, 11, 20, 21], Some((4, 8)));
        let moved = queue(&[2, 20, 21, 10, 11], Some((4, 8)));
        let fields = queue(&[2, 11, 10, 21, 20], Some((4, 8)));
        let c = cmp(std::slice::from_ref(&run), std::slice::from_ref(&moved));
        assert_eq!((c[0].differing, c[0].reordered), (0, true), "{c:?}");
        let c = cmp(std::slice::from_ref(&run), std::slice::from_ref(&fields));
        assert_eq!((c[0].differing, c[0].reordered), (4, false), "{c:?}");
        // Loose words would have passed both.
        let loose = queue(&[2, 10, 11, 20, 21], Some((4, 4)));
        let c = cmp(std::slice::from_ref(&loose), &[queue(&[2, 11, 10, 21, 20], Some((4, 4)))]);
        assert!(c[0].reordered, "{c:?}");
        // The counter before the records must match in place.
        let c = cmp(std::slice::from_ref(&run), &[queue(&[3, 20, 21, 10, 11], Some((4, 8)))]);
        assert!(c[0].differing > 0 && !c[0].reordered, "{c:?}");
        // No record array: in place only.
        let flat = queue(&[2, 10, 11, 20, 21], None);
        let c = cmp(std::slice::from_ref(&flat), &[queue(&[2, 20, 21, 10, 11], None)]);
        assert_eq!((c[0].differing, c[0].reordered), (4, false), "{c:?}");
        // An image with unstable texels: the rest compared in place, never as a multiset.
        let (i1, i2) = (part(PartKind::Image, &[1, 2, 3, 4]), part(PartKind::Image, &[9, 2, 3, 4]));
        let moved = part(PartKind::Image, &[9, 3, 2, 4]);
        let c = compare(std::slice::from_ref(&i1), &[i2], &[moved]);
        assert_eq!((c[0].unstable, c[0].differing, c[0].reordered), (1, 2, false), "{c:?}");
    }
}
