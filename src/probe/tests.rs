//! Unit tests of the probe contract: layouts against their GLSL, slots, elements and values.
use super::*;

/// std430 alignment and size of the GLSL types the contract uses.
fn std430(ty: &str) -> (usize, usize) {
    match ty {
        "uint" | "float" => (4, 4),
        "vec2" | "uvec2" => (8, 8),
        "vec4" => (16, 16),
        other => panic!("unknown type {other}"),
    }
}

/// The offsets GLSL gives the members in declaration order (std430 struct rules).
fn glsl_offsets(fields: &[Field]) -> (Vec<usize>, usize) {
    let mut at = 0usize;
    let mut align_max = 1usize;
    let offs = fields
        .iter()
        .map(|f| {
            let (a, s) = std430(f.glsl_type);
            align_max = align_max.max(a);
            at = at.div_ceil(a) * a;
            let o = at;
            at += s;
            o
        })
        .collect();
    (offs, at.div_ceil(align_max) * align_max)
}

#[test]
fn glsl_record_layout_is_the_rust_layout() {
    let (offs, size) = glsl_offsets(RECORD_FIELDS);
    assert_eq!(offs, RECORD_FIELDS.iter().map(|f| f.offset).collect::<Vec<_>>());
    assert_eq!(size, RECORD_SIZE);
    // every byte of the Rust struct is covered by a member GLSL declares
    let covered: usize = RECORD_FIELDS.iter().map(|f| std430(f.glsl_type).1).sum();
    assert_eq!(covered, RECORD_SIZE);
    let (poffs, psize) = glsl_offsets(PUSH_FIELDS);
    assert_eq!(poffs, PUSH_FIELDS.iter().map(|f| f.offset).collect::<Vec<_>>());
    assert_eq!(psize as u32, PUSH_BLOCK_BYTES);
    let g = glsl_declarations();
    assert!(g.contains("layout(offset = 32) uvec2 asTable;"), "{g}");
    assert!(g.contains("vec4 value; // offset 48"), "{g}");
}

#[test]
fn shader_record_layout_is_the_rust_layout() {
    let (offs, size) = glsl_offsets(SHADER_RECORD_FIELDS);
    assert_eq!(offs, SHADER_RECORD_FIELDS.iter().map(|f| f.offset).collect::<Vec<_>>());
    assert_eq!(size, std::mem::size_of::<ShaderRecordData>());
    let b = ShaderRecordData { heap_index: 9, dyn_base: DYNAMIC_BASE }.to_bytes();
    assert_eq!(b, [9u32.to_le_bytes(), DYNAMIC_BASE.to_le_bytes()].concat());
    assert!(glsl_shader_record().contains("uint dynBase; // offset 4"));
}

#[test]
fn samplers_pick_the_texels_their_address_modes_say() {
    // Shifted one image to the right and one up: clamp-to-edge reads the right column of the
    // first row, repeat the element itself, mirrored repeat the point-mirrored element.
    for e in 0..ELEMENTS {
        assert_eq!(sampled_element(0, e), 1, "clamp, element {e}");
        assert_eq!(sampled_element(1, e), e, "repeat, element {e}");
        assert_eq!(sampled_element(2, e), 3 - e, "mirrored repeat, element {e}");
    }
    // The spec's wrapping on negative and far coordinates.
    assert_eq!(wrap(AddressMode::Repeat, -1, 2), 1);
    assert_eq!(wrap(AddressMode::MirroredRepeat, -1, 2), 0);
    assert_eq!(wrap(AddressMode::MirroredRepeat, 2, 2), 1);
    assert_eq!(wrap(AddressMode::MirroredRepeat, 4, 2), 0);
    assert_eq!(wrap(AddressMode::ClampToEdge, 7, 2), 1);
    // The constant sampler differs from sampler 0 on most elements, and a dynamic index covers
    // every sampler.
    assert!(
        (0..ELEMENTS)
            .filter(|e| sampled_element(SAMPLER_LITERAL, *e) != sampled_element(0, *e))
            .count()
            >= 3
    );
    assert_eq!((0..6).map(sampler_slot).collect::<Vec<_>>(), [0, 1, 2, 0, 1, 2]);
}

/// The one-copy decode reads what `from_bytes` reads, record by record (every field distinct,
/// a NaN's bits kept, a trailing partial record left out); the twin: a byte moved within a
/// record changes what both read.
#[test]
fn decode_all_reads_as_from_bytes_does() {
    let mut bytes: Vec<u8> = (0..3 * RECORD_SIZE + 7).map(|i| (i * 37 % 251) as u8).collect();
    bytes[RECORD_SIZE + offset_of!(Record, t)..][..4]
        .copy_from_slice(&0x7fc0_0001u32.to_le_bytes());
    let mut out = vec![Record::default(); 9];
    Record::decode_all(&bytes, &mut out);
    let one_by_one: Vec<Record> = bytes.chunks_exact(RECORD_SIZE).map(Record::from_bytes).collect();
    assert_eq!(out.len(), 3);
    let as_bytes = |v: &[Record]| v.iter().flat_map(Record::to_bytes).collect::<Vec<u8>>();
    assert_eq!(as_bytes(&out), as_bytes(&one_by_one));
    assert_eq!(as_bytes(&out), bytes[..3 * RECORD_SIZE]);
    assert_eq!(out[1].t.to_bits(), 0x7fc0_0001);
    bytes.swap(offset_of!(Record, slot), offset_of!(Record, element));
    Record::decode_all(&bytes, &mut out);
    assert_ne!((out[0].slot, out[0].element), (one_by_one[0].slot, one_by_one[0].element));
    assert_eq!(out[0].slot, Record::from_bytes(&bytes).slot);
}

#[test]
fn record_round_trips_through_bytes() {
    let r = Record {
        flags: 3,
        custom: 0xfffff3,
        instance_id: 7,
        geometry: 2,
        primitive: 9,
        t: 1.5,
        bary: [0.25, 0.5],
        slot: 4,
        element: 3,
        pad: 0,
        pad2: 11,
        value: [1.0, 2.0, 3.0, 0.25],
        lane: 5,
        leader: 4093,
        active_mask: 0b1110_0000,
        active_count: 3,
    };
    let bytes = r.to_bytes();
    assert_eq!(Record::from_bytes(&bytes), r);
    // the bytes sit where GLSL's std430 layout puts them
    let word = |o: usize| u32::from_le_bytes(bytes[o..o + 4].try_into().unwrap());
    let at = |name: &str| RECORD_FIELDS.iter().find(|f| f.glsl_name == name).unwrap().offset;
    assert_eq!(word(at("custom")), 0xfffff3);
    assert_eq!(word(at("element")), 3);
    assert_eq!(f32::from_bits(word(at("value") + 12)), 0.25);
    assert_eq!(
        [word(at("lane")), word(at("leader")), word(at("activeMask")), word(at("activeCount"))],
        [5, 4093, 0b1110_0000, 3]
    );
    // the lane evidence sits after every word the record had before it (older readers' offsets)
    assert_eq!(at("lane"), 64);
}

#[test]
fn push_constants_bytes_follow_the_offsets() {
    let p = PushConstants {
        as_table: 0x1122_3344_5566_7788,
        bad_address: 9,
        ..push_constants(64, 32, 16, Resource::StorageBuffer)
    };
    let b = p.to_bytes(0xabcd);
    assert_eq!(b.len() as u32, PUSH_CONSTANT_BYTES);
    let u64_at = |o: usize| u64::from_le_bytes(b[o..o + 8].try_into().unwrap());
    assert_eq!(u64_at(offset_of!(PushConstants, as_table)), 0x1122_3344_5566_7788);
    assert_eq!(u64_at(PATCHED_TABLE_OFFSET as usize), 0xabcd);
    assert_eq!(u32::from_le_bytes(b[12..16].try_into().unwrap()), DYNAMIC_BASE);
}

#[test]
fn slots_fit_the_array_and_values_are_distinct() {
    let n = slot_count(Resource::StorageBuffer, 16);
    assert_eq!(n, DYNAMIC_BASE + 16);
    assert_eq!(slot_count(Resource::AccelerationStructure, 16), n);
    assert_eq!(slot_count(Resource::StorageBuffer, 4096), DYNAMIC_BASE + 4096);
    assert_eq!(as_variants(4096), MAX_AS_VARIANTS);
    assert!([LITERAL_SLOT, SPEC_SLOT, PUSH_SLOT].iter().all(|s| *s < n));
    // A `--scene` file's few instances: the constant slots still inside every array (one
    // instance gave 4 slots, and lavapipe crashed reading slot 5 and 7 past them).
    for instances in 1..=16 {
        for r in Resource::ALL {
            let n = slot_count(*r, instances);
            assert!([LITERAL_SLOT, SPEC_SLOT, PUSH_SLOT, PACKED_SLOT].iter().all(|s| *s < n));
            assert!(DYNAMIC_BASE + dyn_mask(*r, instances) < n, "{r:?} {instances}");
        }
    }
    assert_eq!(
        dynamic_slot(Stage::ClosestHit, (0, 0, 64), 0xfffff5, DYNAMIC_BASE, (n, 15)),
        DYNAMIC_BASE + 5
    );
    assert!(dynamic_slot(Stage::Fragment, (63, 63, 64), 0, DYNAMIC_BASE, (n, 15)) < n);
    // One instance: 8 slots for the constant ones, but the hit stages' mask stays the push
    // block's `dynMask` (0), whatever the custom index (a mesh index with bit 2 set read slot
    // base + 4 in the reference while the GPU read the base).
    let (n1, m1) = (slot_count(Resource::StorageBuffer, 1), dyn_mask(Resource::StorageBuffer, 1));
    assert_eq!((n1, m1), (PUSH_SLOT + 1, 0));
    assert_eq!(
        dynamic_slot(Stage::ClosestHit, (0, 0, 64), 4, DYNAMIC_BASE, (n1, m1)),
        DYNAMIC_BASE
    );
    let mut seen = std::collections::HashSet::new();
    for r in Resource::ALL {
        for s in 0..n {
            for e in 0..ELEMENTS {
                assert!(seen.insert(resource_value(*r, s, e).map(f32::to_bits)), "{r:?} {s} {e}");
            }
        }
    }
    assert_eq!(as_variants(16), n);
    // The packed buffer holds every (slot, element) once, at the index the GLSL computes.
    let packed = packed_bytes(Resource::StorageBuffer, n);
    assert_eq!(packed.len(), (n * ELEMENTS * 16) as usize);
    let at = |d: u32, e: u32| -> [f32; 4] {
        let o = packed_element(d, e) as usize * 16;
        [0, 1, 2, 3]
            .map(|k| f32::from_le_bytes(packed[o + 4 * k..o + 4 * k + 4].try_into().unwrap()))
    };
    assert_eq!(
        at(DYNAMIC_BASE + 5, 3),
        resource_value(Resource::StorageBuffer, DYNAMIC_BASE + 5, 3)
    );
    assert_ne!(at(DYNAMIC_BASE + 5, 3), at(DYNAMIC_BASE + 5, 2));
    assert!(glsl_declarations().contains(
        "uint packedElement(uint slot, uint element) { return slot * ELEMENTS + element; }"
    ));
    assert!(PACKED_SLOT < n);
    assert_ne!(as_value(Some(as_custom(1, 3))), as_value(Some(as_custom(2, 3))));
}
