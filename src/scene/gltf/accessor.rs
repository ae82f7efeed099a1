//! Accessors read into vertex and index lists (glTF 2.0, "Accessors"): each element at
//! `bufferView.byteOffset + accessor.byteOffset + i × stride` of its buffer, the stride
//! `bufferView.byteStride` or, when undefined, the element's size ("Data Alignment": tightly
//! packed), components little endian ("Buffers and Buffer Views"). Normalized unsigned integers
//! become `c / 255.0` and `c / 65535.0` ("Animations", the normalization table). The sizes here
//! are what [`super::validate`] checks every accessor's range with, before any is read; a read
//! still checks its range, so an unvalidated accessor is an error, not a panic. An accessor
//! without a `bufferView` reads as zeros (the `accessor.bufferView` schema: "When undefined, the
//! accessor MUST be initialized with zeros; `sparse` property or extensions MAY override zeros
//! with actual values"; a sparse one is refused, by validation where a read mesh holds it, and
//! here).
use super::doc::{Accessor, Root};

/// The bytes of any element of an accessor without a `bufferView`: the largest element (MAT4
/// of floats) is 64 bytes.
static ZEROS: [u8; 64] = [0; 64];

pub(super) const I8: u32 = 5120;
pub(super) const U8: u32 = 5121;
pub(super) const I16: u32 = 5122;
pub(super) const U16: u32 = 5123;
pub(super) const U32: u32 = 5125;
pub(super) const F32: u32 = 5126;

/// Bytes of one component of `component_type` ("Accessor Data Types"); `None`: not a glTF type
/// (5124, signed int, is not supported by glTF 2.0).
pub(super) fn component_size(component_type: u32) -> Option<u64> {
    match component_type {
        I8 | U8 => Some(1),
        I16 | U16 => Some(2),
        U32 | F32 => Some(4),
        _ => None,
    }
}

/// Bytes of one element: components × size, matrix columns padded to 4 bytes ("Data
/// Alignment": MAT2 of bytes, MAT3 of bytes or shorts); `None` for an unknown type.
pub(super) fn element_size(component_type: u32, kind: &str) -> Option<u64> {
    let c = component_size(component_type)?;
    let column = |rows: u64| (rows * c).div_ceil(4) * 4;
    match kind {
        "SCALAR" => Some(c),
        "VEC2" => Some(2 * c),
        "VEC3" => Some(3 * c),
        "VEC4" => Some(4 * c),
        "MAT2" => Some(2 * column(2)),
        "MAT3" => Some(3 * column(3)),
        "MAT4" => Some(4 * column(4)),
        _ => None,
    }
}

/// An accessor's elements in its buffer's bytes.
struct Elements<'a> {
    bytes: &'a [u8],
    stride: usize,
    count: usize,
    component_type: u32,
    normalized: bool,
}

impl Elements<'_> {
    /// Component `k` of element `i` as `f32`: floats as they are, normalized integers scaled to
    /// [0, 1], other integers converted.
    fn float(&self, i: usize, k: usize) -> f32 {
        let v = self.int_or_float(i, k);
        match (self.component_type, self.normalized) {
            (U8, true) => v / 255.0,
            (U16, true) => v / 65535.0,
            _ => v,
        }
    }

    fn int_or_float(&self, i: usize, k: usize) -> f32 {
        match self.component_type {
            F32 => f32::from_bits(self.word(i, k)),
            _ => self.uint(i, k) as f32,
        }
    }

    /// Component `k` of element `i` as an unsigned integer (float bits for floats).
    fn uint(&self, i: usize, k: usize) -> u32 {
        match self.component_type {
            U8 | I8 => self.bytes[i * self.stride + k] as u32,
            U16 | I16 => {
                let at = i * self.stride + 2 * k;
                u16::from_le_bytes([self.bytes[at], self.bytes[at + 1]]) as u32
            }
            _ => self.word(i, k),
        }
    }

    fn word(&self, i: usize, k: usize) -> u32 {
        let at = i * self.stride + 4 * k;
        let b = &self.bytes[at..at + 4];
        u32::from_le_bytes([b[0], b[1], b[2], b[3]])
    }
}

/// Accessor `index`'s elements, or why they cannot be read (one line): it is missing, names a
/// buffer view that is not there, or its last element lies past its view or buffer. Without a
/// buffer view every element is [`ZEROS`] (stride 0).
fn elements<'a>(root: &Root, buffers: &'a [Vec<u8>], index: usize) -> Result<Elements<'a>, String> {
    let a: &Accessor = root.accessors.get(index).ok_or(format!("no accessor {index}"))?;
    let size = element_size(a.component_type, &a.kind)
        .ok_or(format!("accessor {index}: unknown componentType or type"))?;
    // Validation refuses it where a read mesh holds it; here too, so that no path reads a
    // sparse accessor's base values (or zeros) as if they were its elements.
    if a.sparse.is_some() {
        return Err(format!("accessor {index}: sparse, which rtprobe does not read"));
    }
    let Some(v) = a.buffer_view else {
        return Ok(Elements {
            bytes: &ZEROS[..size as usize],
            stride: 0,
            count: a.count as usize,
            component_type: a.component_type,
            normalized: a.normalized,
        });
    };
    let view = root.buffer_views.get(v).ok_or(format!("accessor {index}: no bufferView {v}"))?;
    let stride = view.byte_stride.unwrap_or(size);
    let span = a
        .count
        .checked_sub(1)
        .and_then(|last| last.checked_mul(stride))
        .and_then(|s| s.checked_add(size))
        .ok_or(format!("accessor {index}: count {}", a.count))?;
    let start = view.byte_offset.checked_add(a.byte_offset);
    let end = start.and_then(|s| s.checked_add(span));
    let past = || format!("accessor {index} runs past its buffer");
    if a.byte_offset.saturating_add(span) > view.byte_length || stride < size {
        return Err(format!("accessor {index} runs past its bufferView {v}"));
    }
    let (start, end) = (start.ok_or_else(past)?, end.ok_or_else(past)?);
    let buffer = buffers.get(view.buffer).ok_or_else(past)?;
    let bytes = usize::try_from(start)
        .ok()
        .zip(usize::try_from(end).ok())
        .and_then(|(s, e)| buffer.get(s..e))
        .ok_or_else(past)?;
    Ok(Elements {
        bytes,
        stride: stride as usize,
        count: a.count as usize,
        component_type: a.component_type,
        normalized: a.normalized,
    })
}

/// A VEC3 float accessor (POSITION, NORMAL).
pub(super) fn vec3(root: &Root, buffers: &[Vec<u8>], a: usize) -> Result<Vec<[f32; 3]>, String> {
    let e = elements(root, buffers, a)?;
    Ok((0..e.count).map(|i| [e.float(i, 0), e.float(i, 1), e.float(i, 2)]).collect())
}

/// A VEC2 accessor of floats or normalized unsigned bytes or shorts (TEXCOORD_n).
pub(super) fn vec2(root: &Root, buffers: &[Vec<u8>], a: usize) -> Result<Vec<[f32; 2]>, String> {
    let e = elements(root, buffers, a)?;
    Ok((0..e.count).map(|i| [e.float(i, 0), e.float(i, 1)]).collect())
}

/// A SCALAR accessor of unsigned bytes, shorts or ints (indices).
pub(super) fn indices(root: &Root, buffers: &[Vec<u8>], a: usize) -> Result<Vec<u32>, String> {
    let e = elements(root, buffers, a)?;
    Ok((0..e.count).map(|i| e.uint(i, 0)).collect())
}

#[cfg(test)]
#[path = "accessor_tests.rs"]
mod tests;
