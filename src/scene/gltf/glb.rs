//! The GLB container (glTF 2.0, "GLB File Format Specification"): a 12-byte header (magic
//! `glTF`, container version 2, the total length), then chunks of `u32` length, `u32` type and
//! data — the JSON chunk first, an optional BIN chunk second, any later chunk of another type
//! ignored ("Chunks": client implementations MUST ignore chunks with unknown types). The JSON
//! chunk ends on a 4-byte boundary ("Chunks": MUST); a BIN chunk that does not (as rtprobe's own
//! `scene make --glb` wrote them before) is still read: its bytes are read one by one. Every length is checked against the
//! bytes there before it is used, so no file makes this panic or allocate.

/// `glTF`, little endian.
const MAGIC: &[u8; 4] = b"glTF";
const JSON: u32 = 0x4E4F_534A;
const BIN: u32 = 0x004E_4942;

/// A GLB split into its JSON and its BIN chunk (borrowed from the file's bytes).
#[derive(Debug, PartialEq)]
pub(super) struct Glb<'a> {
    pub json: &'a [u8],
    pub bin: Option<&'a [u8]>,
}

/// Whether `bytes` are a GLB (rather than glTF JSON): they start with the magic.
pub(super) fn is_glb(bytes: &[u8]) -> bool {
    bytes.starts_with(MAGIC)
}

fn u32_at(bytes: &[u8], at: usize) -> Option<u32> {
    let b = bytes.get(at..at.checked_add(4)?)?;
    Some(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
}

/// `bytes` (starting with the magic) split into chunks, or what is wrong (one line, naming the
/// header field or chunk).
pub(super) fn split(bytes: &[u8]) -> Result<Glb<'_>, String> {
    let version = u32_at(bytes, 4).ok_or("GLB header: shorter than 12 bytes")?;
    if version != 2 {
        return Err(format!("GLB header: container version {version}, not 2"));
    }
    let length = u32_at(bytes, 8).ok_or("GLB header: shorter than 12 bytes")? as usize;
    if length != bytes.len() {
        return Err(format!(
            "GLB header: length {length} where the file has {} bytes (truncated, or not one GLB)",
            bytes.len()
        ));
    }
    let (json_type, json) = chunk(bytes, 12, 0)?;
    if json_type != JSON {
        return Err(format!("GLB chunk 0: type {json_type:#010x}, not JSON (it must be first)"));
    }
    let next = 12 + 8 + json.len();
    let bin = match next < bytes.len() {
        true => match chunk(bytes, next, 1)? {
            (BIN, data) => Some(data),
            _ => None,
        },
        false => None,
    };
    Ok(Glb { json, bin })
}

/// Chunk `n` at byte `at`: its type and data, inside the file and 4-byte aligned.
fn chunk(bytes: &[u8], at: usize, n: usize) -> Result<(u32, &[u8]), String> {
    let short = || format!("GLB chunk {n}: its 8-byte header runs past the end of the file");
    let length = u32_at(bytes, at).ok_or_else(short)? as usize;
    let kind = u32_at(bytes, at + 4).ok_or_else(short)?;
    // The BIN chunk's end is not held to it: rtprobe's `scene make --glb` wrote it unpadded
    // before, and nothing after it is read at an offset it would misalign.
    if length % 4 != 0 && n == 0 {
        return Err(format!(
            "GLB chunk {n}: length {length}, not a multiple of 4 (chunks MUST be 4-byte aligned)"
        ));
    }
    let data = (at + 8)
        .checked_add(length)
        .and_then(|end| bytes.get(at + 8..end))
        .ok_or_else(|| format!("GLB chunk {n}: length {length} runs past the end of the file"))?;
    Ok((kind, data))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::gltf::make::glb;

    #[test]
    fn json_and_bin_chunks_are_split_and_an_unknown_third_ignored() {
        let file = glb(b"{}".to_vec(), &[1, 2, 3, 4, 5]);
        let g = split(&file).unwrap();
        assert_eq!(g.json, b"{}  ", "padded with spaces");
        assert_eq!(g.bin, Some(&[1, 2, 3, 4, 5, 0, 0, 0][..]), "padded with zeros");
        let mut more = file.clone();
        more.extend(4u32.to_le_bytes());
        more.extend(b"XTRA\0\0\0\0");
        let n = more.len() as u32;
        more[8..12].copy_from_slice(&n.to_le_bytes());
        assert_eq!(split(&more).unwrap(), g);
    }

    #[test]
    fn a_glb_without_bin_has_none() {
        let mut file = b"glTF".to_vec();
        file.extend(2u32.to_le_bytes());
        file.extend(24u32.to_le_bytes());
        file.extend(4u32.to_le_bytes());
        file.extend(b"JSON{}  ");
        assert_eq!(split(&file).unwrap(), Glb { json: b"{}  ", bin: None });
        // An unknown second chunk is no BIN.
        file.extend(0u32.to_le_bytes());
        file.extend(b"XTRA");
        file[8..12].copy_from_slice(&32u32.to_le_bytes());
        assert_eq!(split(&file).unwrap().bin, None);
    }

    /// The twin of each check: a header, length or chunk that is wrong is one line naming it.
    #[test]
    fn bad_headers_and_lengths_are_one_line_errors() {
        let good = glb(b"{}".to_vec(), &[0; 8]);
        let with = |at: usize, v: u32| {
            let mut f = good.clone();
            f[at..at + 4].copy_from_slice(&v.to_le_bytes());
            split(&f).unwrap_err()
        };
        assert!(split(b"glTF\x02\0").unwrap_err().contains("shorter than 12"));
        assert!(with(4, 1).contains("container version 1"));
        assert!(with(8, 9999).contains("length 9999 where the file has"));
        assert!(split(&good[..good.len() - 4]).unwrap_err().contains("truncated"));
        assert!(with(12, 3).contains("not a multiple of 4"));
        let mut unpadded = good[..good.len() - 3].to_vec();
        let n = unpadded.len() as u32;
        unpadded[8..12].copy_from_slice(&n.to_le_bytes());
        unpadded[24..28].copy_from_slice(&5u32.to_le_bytes());
        assert_eq!(split(&unpadded).unwrap().bin, Some(&[0u8; 5][..]), "an unpadded BIN chunk");
        assert!(with(12, u32::MAX - 3).contains("chunk 0: length"), "oversized, no overflow");
        assert!(with(16, BIN).contains("not JSON"));
        assert!(with(24, 4096).contains("chunk 1: length 4096 runs past"));
        let mut short = good[..28].to_vec();
        short[8..12].copy_from_slice(&28u32.to_le_bytes());
        assert!(split(&short).unwrap_err().contains("8-byte header runs past"));
    }
}
