//! Accessor reads: every component type, packed and strided, normalized texture coordinates, and
//! each range an accessor can run past.
use super::*;

/// A document of one buffer view (`view` JSON) over `bytes` and one accessor (`accessor` JSON,
/// its `bufferView` 0).
fn doc(view: serde_json::Value, accessor: serde_json::Value) -> Root {
    serde_json::from_value(serde_json::json!({
        "asset": {"version": "2.0"},
        "buffers": [{"byteLength": 64}],
        "bufferViews": [view],
        "accessors": [accessor],
    }))
    .unwrap()
}

fn bytes() -> Vec<Vec<u8>> {
    vec![(0u8..64).collect()]
}

#[test]
fn indices_of_each_unsigned_type_little_endian() {
    let view = serde_json::json!({"buffer": 0, "byteOffset": 4, "byteLength": 24});
    let read = |ct: u32, count: u32| {
        let a = serde_json::json!({"bufferView": 0, "byteOffset": 4, "componentType": ct, "count": count, "type": "SCALAR"});
        indices(&doc(view.clone(), a), &bytes(), 0).unwrap()
    };
    assert_eq!(read(U8, 3), [8, 9, 10]);
    assert_eq!(read(U16, 2), [0x0908, 0x0b0a]);
    assert_eq!(read(U32, 2), [0x0b0a_0908, 0x0f0e_0d0c]);
}

#[test]
fn floats_packed_and_strided() {
    let mut data = vec![0u8; 64];
    for (i, f) in [1.0f32, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0].iter().enumerate() {
        data[4 * i..4 * i + 4].copy_from_slice(&f.to_le_bytes());
    }
    let a = serde_json::json!({"bufferView": 0, "componentType": F32, "count": 2, "type": "VEC3"});
    let packed = doc(serde_json::json!({"buffer": 0, "byteLength": 32}), a.clone());
    assert_eq!(vec3(&packed, &[data.clone()], 0).unwrap(), [[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]);
    let strided = doc(serde_json::json!({"buffer": 0, "byteLength": 32, "byteStride": 16}), a);
    assert_eq!(vec3(&strided, &[data.clone()], 0).unwrap(), [[1.0, 2.0, 3.0], [5.0, 6.0, 7.0]]);
    let uv = serde_json::json!({"bufferView": 0, "byteOffset": 4, "componentType": F32, "count": 2, "type": "VEC2"});
    let uvs = doc(serde_json::json!({"buffer": 0, "byteLength": 32, "byteStride": 20}), uv);
    assert_eq!(vec2(&uvs, &[data], 0).unwrap(), [[2.0, 3.0], [7.0, 8.0]]);
}

#[test]
fn normalized_texcoords_of_bytes_and_shorts() {
    let view = serde_json::json!({"buffer": 0, "byteLength": 8, "byteStride": 4});
    let a = |ct: u32| serde_json::json!({"bufferView": 0, "componentType": ct, "normalized": true, "count": 2, "type": "VEC2"});
    let b = vec2(&doc(view.clone(), a(U8)), &[vec![0, 255, 7, 7, 51, 0, 7, 7]], 0).unwrap();
    assert_eq!(b, [[0.0, 1.0], [51.0 / 255.0, 0.0]]);
    let s = vec2(&doc(view, a(U16)), &[vec![0, 0, 0xff, 0xff, 0, 0x80, 0, 0]], 0).unwrap();
    assert_eq!(s, [[0.0, 1.0], [32768.0 / 65535.0, 0.0]]);
}

#[test]
fn element_sizes_pad_matrix_columns() {
    assert_eq!(element_size(U8, "MAT2"), Some(8));
    assert_eq!(element_size(U8, "MAT3"), Some(12));
    assert_eq!(element_size(U16, "MAT3"), Some(24));
    assert_eq!(element_size(F32, "MAT4"), Some(64));
    assert_eq!(element_size(I16, "VEC4"), Some(8));
    assert_eq!(element_size(5124, "SCALAR"), None, "signed int is not glTF");
    assert_eq!(element_size(F32, "VEC5"), None);
}

/// The twins: an accessor past its view, its view past the buffer's bytes, a stride below the
/// element, a count that overflows — each an error, never a panic.
#[test]
fn reads_past_a_range_are_errors() {
    let a = |count: u64, off: u32| serde_json::json!({"bufferView": 0, "byteOffset": off, "componentType": F32, "count": count, "type": "VEC3"});
    let view = serde_json::json!({"buffer": 0, "byteLength": 24});
    assert!(vec3(&doc(view.clone(), a(2, 0)), &bytes(), 0).is_ok());
    assert!(vec3(&doc(view.clone(), a(2, 4)), &bytes(), 0)
        .unwrap_err()
        .contains("past its bufferView"));
    assert!(vec3(&doc(view.clone(), a(3, 0)), &bytes(), 0)
        .unwrap_err()
        .contains("past its bufferView"));
    assert!(vec3(&doc(view.clone(), a(u64::MAX, 0)), &bytes(), 0).is_err());
    assert!(vec3(&doc(view.clone(), a(0, 0)), &bytes(), 0).is_err());
    let big = serde_json::json!({"buffer": 0, "byteOffset": 48, "byteLength": 24});
    assert!(vec3(&doc(big, a(2, 0)), &bytes(), 0).unwrap_err().contains("past its buffer"));
    let narrow = serde_json::json!({"buffer": 0, "byteLength": 24, "byteStride": 8});
    assert!(vec3(&doc(narrow, a(2, 0)), &bytes(), 0).is_err(), "stride below 12 bytes");
    assert!(vec3(&doc(view, a(1, 0)), &bytes(), 1).unwrap_err().contains("no accessor 1"));
}

/// Without a `bufferView` every element is zeros, whatever its type, and no buffer is needed.
#[test]
fn an_accessor_without_a_view_reads_zeros() {
    let root = |kind: &str, count: u64| -> Root {
        serde_json::from_value(serde_json::json!({
            "asset": {"version": "2.0"},
            "accessors": [{"componentType": F32, "count": count, "type": kind}],
        }))
        .unwrap()
    };
    assert_eq!(vec3(&root("VEC3", 3), &[], 0).unwrap(), [[0.0; 3]; 3]);
    assert_eq!(vec2(&root("VEC2", 2), &[], 0).unwrap(), [[0.0; 2]; 2]);
    assert_eq!(element_size(F32, "MAT4"), Some(ZEROS.len() as u64), "the largest element fits");
}

/// A sparse accessor is never read, with a view or without one (its base values or zeros are not
/// its elements).
#[test]
fn a_sparse_accessor_is_refused_by_the_read_itself() {
    let view = serde_json::json!({"buffer": 0, "byteLength": 24});
    let a = serde_json::json!({"bufferView": 0, "componentType": F32, "count": 2, "type": "VEC3", "sparse": {"count": 1}});
    let e = vec3(&doc(view, a), &bytes(), 0).unwrap_err();
    assert!(e.contains("sparse"), "{e}");
}
