//! The probe contract shared by the GPU side (`shadergen`) and the CPU side (`reference`): the
//! record every probe writes per pixel, the push constants, its flags, which slot and element each
//! index source selects, the value each resource slot holds, and the TLAS variants the
//! acceleration-structure slots refer to. What a cell's axis values mean for its probe is
//! resolved once, in [`spec`] ([`spec::ProbeSpec::of`]).
//!
//! One source of truth: the GLSL `struct Record`, the `Records` buffer and the push-constant block
//! are generated from the Rust structs here ([`glsl_declarations`]); member offsets come from
//! `offset_of!`, and a unit test checks them against the std430 rules GLSL applies.
//! `probes/common.glsl` holds only functions and constants that mirror functions here.
pub mod spec;

use crate::model::{Resource, Stage};
use std::mem::offset_of;

/// One record per pixel (std430, 80 bytes): what the ray hit, what the probed stage read, and
/// the probed stage's lane evidence ([`FLAG_LANES`]): which subgroup lane did the read, with whom.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Record {
    pub flags: u32,
    /// `gl_InstanceCustomIndexEXT` of the committed hit.
    pub custom: u32,
    /// `gl_InstanceID` of the committed hit (its index in the TLAS).
    pub instance_id: u32,
    /// `gl_GeometryIndexEXT` of the committed hit.
    pub geometry: u32,
    /// `gl_PrimitiveID` (within its geometry).
    pub primitive: u32,
    pub t: f32,
    pub bary: [f32; 2],
    /// The descriptor slot the probe computed.
    pub slot: u32,
    /// The element of the slot's resource the probe read (per-primitive or per-pixel offset).
    pub element: u32,
    /// Written by the hang injection's loop and the infinite-loop canary (a store the compiler
    /// cannot drop).
    pub pad: u32,
    pub pad2: u32,
    pub value: [f32; 4],
    /// Lane evidence (with [`FLAG_LANES`]; zero without): `gl_SubgroupInvocationID` of the
    /// probed stage's invocation.
    pub lane: u32,
    /// `subgroupBroadcastFirst` of this pixel's linear index (`x + y * width`): the pixel of the
    /// first active lane of this invocation's subgroup in the probed stage's call. Pixels with
    /// equal `leader` ran in the same subgroup instance of that call.
    pub leader: u32,
    /// The low 32 bits of `subgroupBallot(true)`: which lanes of the subgroup were active.
    pub active_mask: u32,
    /// `subgroupBallotBitCount(subgroupBallot(true))`: active lanes (above 32 on wave64 devices).
    pub active_count: u32,
}

/// GLSL name and type of a member of a Rust struct shared with the shaders, at its Rust offset.
#[derive(Clone, Copy, Debug)]
pub struct Field {
    pub glsl_name: &'static str,
    pub glsl_type: &'static str,
    pub offset: usize,
}

macro_rules! fields {
    ($ty:ty { $($field:ident : $name:literal $glsl:literal),* $(,)? }) => {
        &[$(Field { glsl_name: $name, glsl_type: $glsl, offset: offset_of!($ty, $field) }),*]
    };
}

/// The record's members, in order, as GLSL declares them.
pub const RECORD_FIELDS: &[Field] = fields!(Record {
    flags: "flags" "uint",
    custom: "custom" "uint",
    instance_id: "instanceId" "uint",
    geometry: "geometry" "uint",
    primitive: "primitive" "uint",
    t: "t" "float",
    bary: "bary" "vec2",
    slot: "slot" "uint",
    element: "element" "uint",
    pad: "pad" "uint",
    pad2: "pad2" "uint",
    value: "value" "vec4",
    lane: "lane" "uint",
    leader: "leader" "uint",
    active_mask: "activeMask" "uint",
    active_count: "activeCount" "uint",
});

pub const RECORD_SIZE: usize = std::mem::size_of::<Record>();
const _: () = assert!(RECORD_SIZE == 80);

impl Record {
    /// The bytes the GPU writes for this record (tests build garbage records from them).
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut b = vec![0u8; RECORD_SIZE];
        let mut put = |o: usize, v: u32| b[o..o + 4].copy_from_slice(&v.to_le_bytes());
        put(offset_of!(Record, flags), self.flags);
        put(offset_of!(Record, custom), self.custom);
        put(offset_of!(Record, instance_id), self.instance_id);
        put(offset_of!(Record, geometry), self.geometry);
        put(offset_of!(Record, primitive), self.primitive);
        put(offset_of!(Record, t), self.t.to_bits());
        put(offset_of!(Record, bary), self.bary[0].to_bits());
        put(offset_of!(Record, bary) + 4, self.bary[1].to_bits());
        put(offset_of!(Record, slot), self.slot);
        put(offset_of!(Record, element), self.element);
        put(offset_of!(Record, pad), self.pad);
        put(offset_of!(Record, pad2), self.pad2);
        for k in 0..4 {
            put(offset_of!(Record, value) + 4 * k, self.value[k].to_bits());
        }
        put(offset_of!(Record, lane), self.lane);
        put(offset_of!(Record, leader), self.leader);
        put(offset_of!(Record, active_mask), self.active_mask);
        put(offset_of!(Record, active_count), self.active_count);
        b
    }

    /// Every whole record of `bytes` into `out` (cleared first): what [`Record::from_bytes`]
    /// gives record by record, on a little-endian host in one copy.
    pub fn decode_all(bytes: &[u8], out: &mut Vec<Record>) {
        let n = bytes.len() / RECORD_SIZE;
        out.clear();
        if cfg!(target_endian = "little") {
            out.reserve(n);
            // SAFETY: a `Record` is `repr(C)`, 20 four-byte fields and no padding (80 bytes,
            // asserted), each a `u32` or an `f32`, so every bit pattern is one; the GPU writes it
            // in that order (`from_bytes` reads each field at its `offset_of!`), little-endian as
            // the host. `out` has room for `n` records, all written before the length is set.
            unsafe {
                std::ptr::copy_nonoverlapping(
                    bytes.as_ptr(),
                    out.as_mut_ptr().cast::<u8>(),
                    n * RECORD_SIZE,
                );
                out.set_len(n);
            }
        } else {
            out.extend(bytes.chunks_exact(RECORD_SIZE).map(Record::from_bytes));
        }
    }

    pub fn from_bytes(b: &[u8]) -> Record {
        let u = |o: usize| u32::from_le_bytes(b[o..o + 4].try_into().expect("4 bytes"));
        let f = |o: usize| f32::from_bits(u(o));
        Record {
            flags: u(offset_of!(Record, flags)),
            custom: u(offset_of!(Record, custom)),
            instance_id: u(offset_of!(Record, instance_id)),
            geometry: u(offset_of!(Record, geometry)),
            primitive: u(offset_of!(Record, primitive)),
            t: f(offset_of!(Record, t)),
            bary: [f(offset_of!(Record, bary)), f(offset_of!(Record, bary) + 4)],
            slot: u(offset_of!(Record, slot)),
            element: u(offset_of!(Record, element)),
            pad: u(offset_of!(Record, pad)),
            pad2: u(offset_of!(Record, pad2)),
            value: [0, 1, 2, 3].map(|k| f(offset_of!(Record, value) + 4 * k)),
            lane: u(offset_of!(Record, lane)),
            leader: u(offset_of!(Record, leader)),
            active_mask: u(offset_of!(Record, active_mask)),
            active_count: u(offset_of!(Record, active_count)),
        }
    }
}

/// The probes' push constants. 64-bit addresses are `uvec2` in GLSL (no int64 needed to pass them).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PushConstants {
    pub width: u32,
    pub height: u32,
    /// Slot read with `index=push_constant`.
    pub push_slot: u32,
    /// Runtime base of `index=dynamic` in hit stages.
    pub dyn_base: u32,
    /// Size of the probed descriptor array.
    pub slot_count: u32,
    /// canary.infinite_loop
    pub loop_forever: u32,
    /// Mask applied to `gl_InstanceCustomIndexEXT` by `index=dynamic` in hit stages.
    pub dyn_mask: u32,
    /// Salt of the `value:F:SEED` injection's pixel hash (`matrix::inject::value_salt`; 0 otherwise).
    pub inject_salt: u32,
    /// Device address of the TLAS address table (as_access=address).
    pub as_table: u64,
    /// canary.invalid_address
    pub bad_address: u64,
    /// Device address of the per-instance bases (`base=buffer`; [`base_buffer`]).
    pub base_address: u64,
    /// Device address of the `SceneDesc` of `scene_layout=shared_buffers` (`scene::layout`).
    pub scene_desc: u64,
}

pub const PUSH_FIELDS: &[Field] = fields!(PushConstants {
    width: "width" "uint",
    height: "height" "uint",
    push_slot: "pushSlot" "uint",
    dyn_base: "dynBase" "uint",
    slot_count: "slotCount" "uint",
    loop_forever: "loopForever" "uint",
    dyn_mask: "dynMask" "uint",
    inject_salt: "injectSalt" "uint",
    as_table: "asTable" "uvec2",
    bad_address: "badAddress" "uvec2",
    base_address: "baseAddress" "uvec2",
    scene_desc: "sceneDesc" "uvec2",
});

/// Bytes of the probes' own push-constant block.
pub const PUSH_BLOCK_BYTES: u32 = std::mem::size_of::<PushConstants>() as u32;
/// Push-constant offset of the table address the address patches append (the block's end).
pub const PATCHED_TABLE_OFFSET: u32 = PUSH_BLOCK_BYTES;
/// The whole push-constant range: the probes' block plus the patches' 8-byte table address.
pub const PUSH_CONSTANT_BYTES: u32 = PATCHED_TABLE_OFFSET + 8;
const _: () = assert!(PUSH_BLOCK_BYTES % 8 == 0);

impl PushConstants {
    /// The bytes pushed at offset 0: the block, then the patched-table address.
    pub fn to_bytes(&self, patched_table: u64) -> Vec<u8> {
        let mut b = vec![0u8; PUSH_CONSTANT_BYTES as usize];
        let mut put = |o: usize, bytes: &[u8]| b[o..o + bytes.len()].copy_from_slice(bytes);
        put(offset_of!(PushConstants, width), &self.width.to_le_bytes());
        put(offset_of!(PushConstants, height), &self.height.to_le_bytes());
        put(offset_of!(PushConstants, push_slot), &self.push_slot.to_le_bytes());
        put(offset_of!(PushConstants, dyn_base), &self.dyn_base.to_le_bytes());
        put(offset_of!(PushConstants, slot_count), &self.slot_count.to_le_bytes());
        put(offset_of!(PushConstants, loop_forever), &self.loop_forever.to_le_bytes());
        put(offset_of!(PushConstants, dyn_mask), &self.dyn_mask.to_le_bytes());
        put(offset_of!(PushConstants, inject_salt), &self.inject_salt.to_le_bytes());
        put(offset_of!(PushConstants, as_table), &self.as_table.to_le_bytes());
        put(offset_of!(PushConstants, bad_address), &self.bad_address.to_le_bytes());
        put(offset_of!(PushConstants, base_address), &self.base_address.to_le_bytes());
        put(offset_of!(PushConstants, scene_desc), &self.scene_desc.to_le_bytes());
        put(PATCHED_TABLE_OFFSET as usize, &patched_table.to_le_bytes());
        b
    }
}

/// A scene-layout record (`scene_layout` cells): `element`, `pad` and `pad2` hold the hit
/// triangle's three vertex indices and `value` one coordinate of each vertex and its material
/// (`scene::layout::Fetched`), so the check compares `pad` and `pad2` too.
pub const FLAG_LAYOUT: u32 = 8;
/// The primary ray hit something.
pub const FLAG_HIT: u32 = 1;
/// The probed stage ran for this pixel and wrote `slot`, `element` and `value`.
pub const FLAG_PROBE: u32 = 2;
/// The probed stage wrote its lane evidence (`lane`, `leader`, `active_mask`, `active_count`):
/// set where the probe was generated with it ([`LANE_EXTENSION`]); without it those words are 0.
pub const FLAG_LANES: u32 = 4;
/// The GLSL extension the lane evidence needs (SPIR-V `GroupNonUniformBallot`).
pub const LANE_EXTENSION: &str = "GL_KHR_shader_subgroup_ballot";

/// Slot read with `index=literal` (a literal in the GLSL).
pub const LITERAL_SLOT: u32 = 3;
/// Slot read with `index=spec_constant` (specialization constant 0 is set to this; its default is 0).
pub const SPEC_SLOT: u32 = 5;
/// Slot read with `index=push_constant`.
pub const PUSH_SLOT: u32 = 7;
/// With `index=dynamic_element` (the engines' recommended pattern) the descriptor at this slot
/// (indexed by the spec constant, so `SPEC_SLOT`) is the packed resource: one buffer holding every
/// slot's elements (element `e` of slot `d` at [`packed_element`]`(d, e)`), or one array image
/// whose layer `d` holds slot `d`'s texels. The other slots keep their own resources, so a driver
/// reading another descriptor reads other values.
pub const PACKED_SLOT: u32 = SPEC_SLOT;
/// The runtime base added to the masked `gl_InstanceCustomIndexEXT` with `index=dynamic` in hit
/// stages (not 1, so that a driver dropping or mis-scaling it reads another slot).
pub const DYNAMIC_BASE: u32 = 3;
/// Fragment probes draw one quad per TILE×TILE pixels; its flat varying is the tile number.
pub const TILE: u32 = 8;
/// Elements per slot: every probed buffer holds `vec4 v[ELEMENTS]`, every image 2×2 texels.
pub const ELEMENTS: u32 = 4;
/// The largest `dyn_mask` of an AS probe array: AS arrays stay small (one TLAS variant per slot)
/// whatever the scene's size.
pub const AS_DYN_MASK_MAX: u32 = 31;
/// Probe TLAS variants at most: one per slot of the largest AS array.
pub const MAX_AS_VARIANTS: u32 = DYNAMIC_BASE + AS_DYN_MASK_MAX + 1;
/// Probe TLAS custom indices: `variant * AS_CUSTOM_STRIDE + instance` (the floor is instance
/// `instances`), so that every variant answers differently wherever the probe ray hits.
pub const AS_CUSTOM_STRIDE: u32 = 8192;
/// Direction of the AS probe ray (from the pixel's primary origin), unlike the primary ray's +z.
pub const PROBE_DIR: [f32; 3] = [0.25, -0.125, 1.0];

/// The bits of a custom index that tell instances apart (custom indices keep a permutation of
/// the instance indices there).
pub fn instance_mask(instances: u32) -> u32 {
    instances.next_power_of_two() - 1
}

/// The mask `index=dynamic` applies to the custom index in hit stages for an array of `resource`.
pub fn dyn_mask(resource: Resource, instances: u32) -> u32 {
    match resource {
        Resource::StorageBuffer
        | Resource::UniformBuffer
        | Resource::SampledImage
        | Resource::StorageImage => instance_mask(instances),
        Resource::AccelerationStructure => instance_mask(instances).min(AS_DYN_MASK_MAX),
    }
}

/// Number of descriptors in the probed array of `resource` (and of addresses in the AS address
/// table): the base, then one slot per value of the masked custom index — and never fewer than
/// the constant slots' (`LITERAL_SLOT`, `SPEC_SLOT`, `PUSH_SLOT`) need. A procedural scene has
/// 16 instances or more, so the masked index covers them; a `--scene` file may have one instance
/// (mask 0: four slots), where a spec-constant or push-constant index would read past the array.
pub fn slot_count(resource: Resource, instances: u32) -> u32 {
    (DYNAMIC_BASE + dyn_mask(resource, instances) + 1).max(PUSH_SLOT + 1)
}

/// The push constants of a probe cell reading `resource` (the canary fields and table address
/// set by the caller).
pub fn push_constants(
    width: u32,
    height: u32,
    instances: u32,
    resource: Resource,
) -> PushConstants {
    PushConstants {
        width,
        height,
        push_slot: PUSH_SLOT,
        dyn_base: DYNAMIC_BASE,
        slot_count: slot_count(resource, instances),
        dyn_mask: dyn_mask(resource, instances),
        ..Default::default()
    }
}

/// The shader record data after every SBT handle (std430; GLSL `shaderRecordEXT` block generated
/// by [`glsl_shader_record`]): the probed array's heap index (what HEAP_WITH_SHADER_RECORD_INDEX
/// reads at offset 0 for `heap_access=mapped_shader_record_index`), and the runtime base a
/// closest-hit probe reads with `base=shader_record`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ShaderRecordData {
    pub heap_index: u32,
    pub dyn_base: u32,
}

pub const SHADER_RECORD_FIELDS: &[Field] = fields!(ShaderRecordData {
    heap_index: "heapIndex" "uint",
    dyn_base: "dynBase" "uint",
});

impl ShaderRecordData {
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut b = vec![0u8; std::mem::size_of::<ShaderRecordData>()];
        b[offset_of!(ShaderRecordData, heap_index)..][..4]
            .copy_from_slice(&self.heap_index.to_le_bytes());
        b[offset_of!(ShaderRecordData, dyn_base)..][..4]
            .copy_from_slice(&self.dyn_base.to_le_bytes());
        b
    }
}

/// `base=shader_record`: the `dyn_base` in the triangle hit group's record, the procedural (sphere)
/// hit group's, and every other group's (raygen, miss, callable). They differ from each other and
/// from push data's [`DYNAMIC_BASE`], and the hit groups' are not 0, so a hit shader that reads
/// another group's record, the push constant, or drops the base computes another slot. All are
/// below [`DYNAMIC_BASE`], so the slot stays inside the array ([`slot_count`]).
pub const RECORD_BASE_TRIANGLES: u32 = DYNAMIC_BASE - 1;
pub const RECORD_BASE_PROCEDURAL: u32 = DYNAMIC_BASE - 2;
pub const RECORD_BASE_OTHER: u32 = 0;

/// `base=buffer`: the base stored for instance `instance_id` (1, 2, 1, 2, …: neighbours differ,
/// none is 0 or push data's [`DYNAMIC_BASE`], so reading another instance's entry, one lane's
/// entry for the whole wave, the push constant, or dropping the base computes another slot on
/// many pixels; below [`DYNAMIC_BASE`], so the slot stays inside the array).
pub fn instance_base(instance_id: u32) -> u32 {
    1 + instance_id % 2
}

/// The per-instance bases `base=buffer` reads at `gl_InstanceID` ([`instance_base`]): one entry
/// per scene instance and one for the AS probe's floor instance (`gl_InstanceID == instances` in
/// the probe TLAS), so no hit reads past the end.
pub fn base_buffer(instances: u32) -> Vec<u8> {
    (0..=instances).flat_map(|i| instance_base(i).to_le_bytes()).collect()
}

/// A sampler's address mode (the Vulkan modes the sampler heap's samplers use).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AddressMode {
    ClampToEdge,
    Repeat,
    MirroredRepeat,
}

/// The sampler heap's samplers, by index: all nearest-filtered, differing in address mode (u, v
/// and w alike). Sampler 0 is the one mapped (combined image sampler) cells use.
pub const SAMPLER_MODES: [AddressMode; 3] =
    [AddressMode::ClampToEdge, AddressMode::Repeat, AddressMode::MirroredRepeat];
/// The sampler a `sampler=constant` probe uses: not 0, so that a driver ignoring the sampler
/// index reads another texel.
pub const SAMPLER_LITERAL: u32 = 2;
/// Separate-sampler probes sample at the element's texel centre shifted by this (normalized
/// coordinates, u and v), outside [0, 1], so that the address mode picks the texel.
pub const SAMPLER_SHIFT: [f32; 2] = [1.0, -1.0];

/// The sampler a `sampler=dynamic` probe uses for the stage's runtime value `dynamic` (the value
/// `index=dynamic` would use as its slot).
pub fn sampler_slot(dynamic: u32) -> u32 {
    dynamic % SAMPLER_MODES.len() as u32
}

/// Vulkan's texel wrapping of integer coordinate `i` in a dimension of `size` texels (spec,
/// "Texel Coordinate Systems": wrapping operation), nearest filtering.
fn wrap(mode: AddressMode, i: i64, size: i64) -> i64 {
    let mirror = |a: i64| if a >= 0 { a } else { -(1 + a) };
    match mode {
        AddressMode::ClampToEdge => i.clamp(0, size - 1),
        AddressMode::Repeat => i.rem_euclid(size),
        AddressMode::MirroredRepeat => (size - 1) - mirror(i.rem_euclid(2 * size) - size),
    }
}

/// The element (texel `(e & 1, e >> 1)` of a 2×2 image) a separate-sampler probe reads when it
/// samples element `element`'s texel centre shifted by [`SAMPLER_SHIFT`] with sampler `sampler`.
pub fn sampled_element(sampler: u32, element: u32) -> u32 {
    let mode = SAMPLER_MODES[sampler as usize % SAMPLER_MODES.len()];
    let texel = |t: u32, shift: f32| {
        // Unnormalized coordinate of the shifted centre, then nearest: floor.
        let u = (f64::from(t) + 0.5) / 2.0 + f64::from(shift);
        wrap(mode, (u * 2.0).floor() as i64, 2) as u32
    };
    texel(element & 1, SAMPLER_SHIFT[0]) + 2 * texel(element >> 1, SAMPLER_SHIFT[1])
}

/// The value element `element` of a buffer or image slot holds (exact in f32), distinct per
/// resource kind, slot and element.
pub fn resource_value(resource: Resource, slot: u32, element: u32) -> [f32; 4] {
    let r = Resource::ALL.iter().position(|x| *x == resource).unwrap_or(0) as f32;
    [
        slot as f32 + 1.0,
        r * 16.0 + 1.0,
        1000.0 + (slot * ELEMENTS + element) as f32,
        0.25 + element as f32,
    ]
}

/// Number of probe TLAS variants: one per slot of the AS array, so that every slot answers
/// differently.
pub fn as_variants(instances: u32) -> u32 {
    slot_count(Resource::AccelerationStructure, instances)
}

/// Which probe TLAS variant an acceleration-structure slot refers to (its own).
pub fn as_slot_tlas(slot: u32) -> usize {
    slot as usize
}

/// Whether probe TLAS `variant` holds scene instance `k` (the floor is in every variant).
pub fn as_variant_has(variant: u32, k: u32) -> bool {
    k % 3 != variant % 3
}

/// The custom index instance `k` carries in probe TLAS `variant` (`k = instances`: the floor).
pub fn as_custom(variant: u32, k: u32) -> u32 {
    variant * AS_CUSTOM_STRIDE + k
}

/// The AS probe's value: the probe ray's committed custom index + 1, or 0 on a miss.
pub fn as_value(hit_custom: Option<u32>) -> [f32; 4] {
    [hit_custom.map(|c| c as f32 + 1.0).unwrap_or(0.0), 0.0, 0.0, 1.0]
}

/// The slot `index=dynamic` selects in `stage` for pixel (x, y); in hit stages `base` ([`spec::Base::value`])
/// plus the custom index of the hit masked with `mask` ([`dyn_mask`], the push block's
/// `dynMask`: not derived from `slots`, which a few-instance scene's constant slots widen);
/// elsewhere the pixel's index modulo `slots` ([`slot_count`]).
pub fn dynamic_slot(
    stage: Stage,
    (x, y, width): (u32, u32, u32),
    hit_custom: u32,
    base: u32,
    (slots, mask): (u32, u32),
) -> u32 {
    match stage {
        Stage::ClosestHit | Stage::AnyHit | Stage::Intersection => base + (hit_custom & mask),
        Stage::Raygen | Stage::Miss | Stage::Callable | Stage::Compute => (x + y * width) % slots,
        Stage::Fragment => ((y / TILE) * (width / TILE) + x / TILE) % slots,
    }
}

/// Where element `element` of slot `slot` sits in the packed buffer (`index=dynamic_element`;
/// GLSL: `packedElement`, generated by [`glsl_declarations`]). It holds
/// `resource_value(resource, slot, element)` there, so the record of such a cell is the record
/// of the `dynamic` cell: `slot` is the dynamic value, `element` the element within it.
pub fn packed_element(slot: u32, element: u32) -> u32 {
    slot * ELEMENTS + element
}

/// The packed buffer's bytes for `slots` slots of `resource` (every slot's elements in slot order).
pub fn packed_bytes(resource: Resource, slots: u32) -> Vec<u8> {
    let mut v = vec![[0f32; 4]; (slots * ELEMENTS) as usize];
    for d in 0..slots {
        for e in 0..ELEMENTS {
            v[packed_element(d, e) as usize] = resource_value(resource, d, e);
        }
    }
    v.into_iter().flatten().flat_map(f32::to_le_bytes).collect()
}

/// What a hit stage knows about its hit, for the element offset.
#[derive(Clone, Copy, Debug, Default)]
pub struct HitIds {
    pub instance_id: u32,
    pub geometry: u32,
    pub primitive: u32,
}

/// The element a buffer/image probe reads in `stage` (GLSL: `hitElement` / `pixelElement` in
/// `probes/common.glsl`): per primitive in hit stages, per pixel elsewhere.
pub fn element(stage: Stage, x: u32, y: u32, hit: HitIds) -> u32 {
    match stage {
        Stage::ClosestHit | Stage::AnyHit | Stage::Intersection => {
            hit.primitive.wrapping_add(hit.geometry).wrapping_add(hit.instance_id) & (ELEMENTS - 1)
        }
        Stage::Raygen | Stage::Miss | Stage::Callable | Stage::Compute | Stage::Fragment => {
            ((x >> 1) ^ y) & (ELEMENTS - 1)
        }
    }
}

fn glsl_zero(ty: &str) -> &'static str {
    match ty {
        "uint" => "0u",
        "float" => "0.0",
        "vec2" => "vec2(0.0)",
        "uvec2" => "uvec2(0u)",
        "vec4" => "vec4(0.0)",
        other => panic!("no zero for GLSL type {other}"),
    }
}

/// The GLSL twin of [`Record`] and [`PushConstants`], the records buffer, the contract's
/// constants, and `emptyRecord()` / `probeRecord(slot, element, value)` constructors, generated so
/// that no shader spells the member order.
pub fn glsl_declarations() -> String {
    let mut s = String::from("// Generated from src/probe.rs (Record, PushConstants): do not edit by hand.\nstruct Record {\n");
    for f in RECORD_FIELDS {
        s += &format!("    {} {}; // offset {}\n", f.glsl_type, f.glsl_name, f.offset);
    }
    s += "};\n\nlayout(set = 0, binding = 0, std430) buffer Records { Record records[]; };\n\n";
    s += "layout(push_constant, std430) uniform PushConstants {\n";
    for f in PUSH_FIELDS {
        s += &format!("    layout(offset = {}) {} {};\n", f.offset, f.glsl_type, f.glsl_name);
    }
    s += "} pc;\n\n";
    s += &format!("const uint FLAG_HIT = {FLAG_HIT}u;\nconst uint FLAG_PROBE = {FLAG_PROBE}u;\nconst uint FLAG_LANES = {FLAG_LANES}u;\nconst uint FLAG_LAYOUT = {FLAG_LAYOUT}u;\nconst uint ELEMENTS = {ELEMENTS}u;\n");
    // The GLSL twin of packed_element.
    s += "uint packedElement(uint slot, uint element) { return slot * ELEMENTS + element; }\n";
    s += &format!(
        "const vec3 PROBE_DIR = vec3({:?}, {:?}, {:?});\n",
        PROBE_DIR[0], PROBE_DIR[1], PROBE_DIR[2]
    );
    let zeros: Vec<&str> = RECORD_FIELDS.iter().map(|f| glsl_zero(f.glsl_type)).collect();
    s += &format!("\nRecord emptyRecord() {{\n    return Record({});\n}}\n", zeros.join(", "));
    let args: Vec<String> = RECORD_FIELDS
        .iter()
        .map(|f| match f.glsl_name {
            "flags" => "FLAG_PROBE".into(),
            "slot" | "element" | "value" => f.glsl_name.into(),
            _ => glsl_zero(f.glsl_type).into(),
        })
        .collect();
    s += &format!("\n// A record of a stage that traced no ray (fragment, compute).\nRecord probeRecord(uint slot, uint element, vec4 value) {{\n    return Record({});\n}}\n", args.join(", "));
    s += LANE_SETTER;
    s
}

/// The GLSL that writes a probe's lane evidence into a record (`laneFlag` is [`FLAG_LANES`] or 0;
/// `lanes` = (lane, leader, active mask, active count), as [`lane_evidence_glsl`] computes them).
const LANE_SETTER: &str = "\n// The probed stage's lane evidence into a record (probe::Record's lane words).\nvoid setLanes(inout Record r, uint laneFlag, uvec4 lanes) {\n    r.flags |= laneFlag;\n    r.lane = lanes.x;\n    r.leader = lanes.y;\n    r.activeMask = lanes.z;\n    r.activeCount = lanes.w;\n}\n";

/// GLSL statements (indented) that define `uint probeLaneFlag` and `uvec4 probeLanes` = (lane,
/// leader, active mask, active count) in the probed stage, `px` being the pixel: measured with
/// subgroup ballot where `recorded` ([`LANE_EXTENSION`]; the device must list the stage in
/// `subgroupSupportedStages` and ballot in `subgroupSupportedOperations`,
/// VUID-RuntimeSpirv-None-06343), else zeros without [`FLAG_LANES`].
pub fn lane_evidence_glsl(recorded: bool) -> &'static str {
    if recorded {
        "    uvec4 probeBallot = subgroupBallot(true);\n    uint probeLaneFlag = FLAG_LANES;\n    uvec4 probeLanes = uvec4(gl_SubgroupInvocationID, subgroupBroadcastFirst(px.x + px.y * pc.width), probeBallot.x, subgroupBallotBitCount(probeBallot));\n"
    } else {
        "    uint probeLaneFlag = 0u;\n    uvec4 probeLanes = uvec4(0u);\n"
    }
}

/// The `shaderRecordEXT` block of a probe reading [`ShaderRecordData`] (instance `shaderRecord`).
pub fn glsl_shader_record() -> String {
    let mut s = String::from("// Generated from src/probe.rs (ShaderRecordData).\nlayout(shaderRecordEXT, std430) buffer ShaderRecordData {\n");
    for f in SHADER_RECORD_FIELDS {
        s += &format!("    {} {}; // offset {}\n", f.glsl_type, f.glsl_name, f.offset);
    }
    s += "} shaderRecord;\n";
    s
}

#[cfg(test)]
mod tests;
