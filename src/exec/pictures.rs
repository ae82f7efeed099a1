//! Mismatch pictures, the way CTS logs image comparisons: for a cell whose records differ from
//! the reference, `expected.png` and `actual.png` show the record fields side by side as false
//! colour, and `diff.png` marks every pixel the comparison counted as a mismatch (red), skipped
//! as ambiguous (grey) or matched (dark green). Written under `--dump DIR/<cell id>/`.
//!
//! Panels of `expected.png` / `actual.png`, left to right, each `width` pixels wide:
//! - `hit`: the flags — green where the ray hit, blue where the probed stage ran, black neither;
//! - `instance`, `primitive`: a colour per id on hit pixels, black elsewhere;
//! - `value`: a colour per probed value (its bits) where the probe ran, black elsewhere.
//!
//! Each pixel's class comes from [`reference::compare`] run on that pixel alone, so the diff
//! counts are exactly the report's counts.
use crate::probe::{Record, FLAG_HIT, FLAG_PROBE};
use crate::reference::{self, Expected};
use std::path::{Path, PathBuf};

/// The panels of the expected / actual pictures, in order.
pub const PANELS: [&str; 4] = ["hit", "instance", "primitive", "value"];

pub const MISMATCH: [u8; 3] = [255, 0, 0];
pub const AMBIGUOUS: [u8; 3] = [128, 128, 128];
pub const MATCH: [u8; 3] = [0, 72, 0];
const BLACK: [u8; 3] = [0, 0, 0];

#[derive(Debug, thiserror::Error)]
pub enum PictureError {
    #[error("{path}: {source}")]
    Io { path: PathBuf, source: std::io::Error },
    #[error(transparent)]
    Write(#[from] crate::atomic::WriteError),
    #[error("{path}: {source}")]
    Encode { path: PathBuf, source: png::EncodingError },
    #[error("{expected} expected records for {actual} actual ones")]
    Length { expected: usize, actual: usize },
}

/// A colour for an id or bit pattern: a hash, each channel in 48..=255 so it is never black.
fn false_colour(key: u64) -> [u8; 3] {
    let mut h = key.wrapping_add(0x9e37_79b9_7f4a_7c15);
    h = (h ^ (h >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    h = (h ^ (h >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    h ^= h >> 31;
    let c = |s: u32| 48 + ((h >> s) % 208) as u8;
    [c(0), c(16), c(32)]
}

/// The colour of one record's field (`panel` indexes [`PANELS`]).
pub fn field_colour(r: &Record, panel: usize) -> [u8; 3] {
    let hit = r.flags & FLAG_HIT != 0;
    let probed = r.flags & FLAG_PROBE != 0;
    match panel {
        0 => [0, if hit { 255 } else { 0 }, if probed { 255 } else { 0 }],
        1 if hit => false_colour(r.custom as u64),
        2 if hit => false_colour((1 << 40) | r.primitive as u64),
        3 if probed => {
            let bits = r.value.iter().fold(0u64, |a, v| a.rotate_left(16) ^ v.to_bits() as u64);
            false_colour((2 << 40) ^ bits)
        }
        _ => BLACK,
    }
}

/// Per pixel: the diff colour ([`MISMATCH`], [`AMBIGUOUS`] or [`MATCH`]).
pub fn classify(expected: &[Expected], actual: &[Record], width: u32) -> Vec<[u8; 3]> {
    expected
        .iter()
        .zip(actual)
        .map(|(e, a)| {
            let c = reference::compare(std::slice::from_ref(e), std::slice::from_ref(a), width);
            if c.ambiguous > 0 {
                AMBIGUOUS
            } else if c.mismatched_pixels > 0 {
                MISMATCH
            } else {
                MATCH
            }
        })
        .collect()
}

fn strip(records: &[Record], width: u32, height: u32) -> Vec<u8> {
    let (w, h) = (width as usize, height as usize);
    let mut rgb = vec![0u8; w * PANELS.len() * h * 3];
    for y in 0..h {
        for x in 0..w {
            let r = &records[y * w + x];
            for p in 0..PANELS.len() {
                let i = (y * w * PANELS.len() + p * w + x) * 3;
                rgb[i..i + 3].copy_from_slice(&field_colour(r, p));
            }
        }
    }
    rgb
}

fn write_png(path: &Path, width: u32, height: u32, rgb: &[u8]) -> Result<(), PictureError> {
    let mut bytes = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut bytes, width, height);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let encode = |e| PictureError::Encode { path: path.to_path_buf(), source: e };
        let mut w = enc.write_header().map_err(encode)?;
        w.write_image_data(rgb).map_err(encode)?;
        w.finish().map_err(encode)?;
    }
    Ok(crate::atomic::write_atomic_with(path, &bytes, false)?)
}

/// Write `expected.png`, `actual.png` and `diff.png` into `dir`; returns their paths in that order.
pub fn write(
    dir: &Path,
    expected: &[Expected],
    actual: &[Record],
    width: u32,
    height: u32,
) -> Result<Vec<String>, PictureError> {
    let n = (width * height) as usize;
    if expected.len() != n || actual.len() != n {
        return Err(PictureError::Length { expected: expected.len(), actual: actual.len() });
    }
    std::fs::create_dir_all(dir)
        .map_err(|e| PictureError::Io { path: dir.to_path_buf(), source: e })?;
    let exp: Vec<Record> = expected.iter().map(|e| e.record).collect();
    let diff: Vec<u8> = classify(expected, actual, width).concat();
    let files = [
        ("expected.png", PANELS.len() as u32 * width, strip(&exp, width, height)),
        ("actual.png", PANELS.len() as u32 * width, strip(actual, width, height)),
        ("diff.png", width, diff),
    ];
    let mut paths = Vec::new();
    for (name, w, rgb) in files {
        let p = dir.join(name);
        write_png(&p, w, height, &rgb)?;
        paths.push(p.to_string_lossy().into_owned());
    }
    Ok(paths)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reference::ValueRule;

    fn rec(flags: u32, instance: u32, value: f32) -> Record {
        Record {
            flags,
            custom: instance,
            primitive: 2,
            value: [value, 1.0, 2.0, 0.25],
            ..Default::default()
        }
    }

    fn decode(p: &str) -> (u32, u32, Vec<u8>) {
        let d = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(p).unwrap()));
        let mut r = d.read_info().unwrap();
        let mut buf = vec![0; r.output_buffer_size().unwrap()];
        let info = r.next_frame(&mut buf).unwrap();
        buf.truncate(info.buffer_size());
        (info.width, info.height, buf)
    }

    #[test]
    fn diff_marks_mismatches_red_and_ambiguous_grey_and_panels_show_fields() {
        // 2x2: a match, a value mismatch, an ambiguous pixel (differs, but skipped), a miss.
        let e = |r: Record, ambiguous| Expected {
            record: r,
            ambiguous,
            rule: ValueRule::Exact,
            discriminating: false,
        };
        let expected = vec![
            e(rec(3, 4, 5.0), false),
            e(rec(3, 4, 5.0), false),
            e(rec(3, 4, 5.0), true),
            e(rec(0, 0, 0.0), false),
        ];
        let actual = vec![rec(3, 4, 5.0), rec(3, 4, 6.0), rec(3, 9, 5.0), rec(0, 0, 0.0)];
        let d = crate::tempdir::tempdir().unwrap();
        let paths = write(d.path(), &expected, &actual, 2, 2).unwrap();
        assert_eq!(paths.len(), 3);
        let (w, h, diff) = decode(&paths[2]);
        assert_eq!((w, h), (2, 2));
        let px: Vec<&[u8]> = diff.chunks(3).collect();
        assert_eq!(px, vec![&MATCH[..], &MISMATCH[..], &AMBIGUOUS[..], &MATCH[..]]);
        let (w, _, exp) = decode(&paths[0]);
        let (_, _, act) = decode(&paths[1]);
        assert_eq!(w, 8, "four panels of width 2");
        let at = |img: &[u8], panel: usize, x: usize, y: usize| {
            img[(y * 8 + panel * 2 + x) * 3..][..3].to_vec()
        };
        // value panel differs exactly at the mismatching pixel; the hit panel is green+blue on hits.
        assert_ne!(at(&exp, 3, 1, 0), at(&act, 3, 1, 0));
        assert_eq!(at(&exp, 3, 0, 0), at(&act, 3, 0, 0));
        assert_eq!(at(&exp, 0, 0, 0), vec![0, 255, 255]);
        assert_eq!(at(&exp, 0, 1, 1), vec![0, 0, 0]);
        // the instance panel shows the ambiguous pixel's different instance
        assert_ne!(at(&exp, 1, 0, 1), at(&act, 1, 0, 1));
    }

    #[test]
    fn wrong_lengths_are_an_error_not_a_panic() {
        let d = crate::tempdir::tempdir().unwrap();
        assert!(matches!(
            write(d.path(), &[], &[Record::default()], 1, 1),
            Err(PictureError::Length { .. })
        ));
    }
}
