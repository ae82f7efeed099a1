//! A pipeline's identity across runs: rtprobe's own 128-bit hash (FNV-1a, stable across builds,
//! processes and machines, unlike `std`'s hasher) of everything that makes the pipeline — its
//! kind, each stage's role, SPIR-V and specialization data, the shader groups (fixed by the roles
//! present), the ray recursion depth, the create flags of its descriptor model, its pipeline
//! layout's contents and, for heap pipelines, every set/binding → heap mapping struct. Stored
//! pipeline binaries are filed under it: the Vulkan spec ignores the mapping structs (and shader
//! modules) when binaries are given ("Pipeline Binaries", VkPipelineBinaryInfoKHR), so an identity
//! without them would hand a binary built for one mapping to a pipeline of another.
use super::pipeline::{self, Desc};

/// FNV-1a over 128 bits: every value is written as little-endian bytes, each variable-length one
/// after its length, so two different sequences of writes never meet by concatenation.
#[derive(Clone, Copy, Debug)]
pub struct StableHash(u128);

const OFFSET: u128 = 0x6c62_272e_07bb_0142_62b8_2175_6295_c58d;
const PRIME: u128 = 0x0000_0000_0100_0000_0000_0000_0000_013b;

impl Default for StableHash {
    fn default() -> Self {
        StableHash(OFFSET)
    }
}

impl StableHash {
    fn byte(&mut self, b: u8) {
        self.0 ^= b as u128;
        self.0 = self.0.wrapping_mul(PRIME);
    }

    pub fn u32(&mut self, v: u32) -> &mut Self {
        v.to_le_bytes().iter().for_each(|&b| self.byte(b));
        self
    }

    pub fn u64(&mut self, v: u64) -> &mut Self {
        v.to_le_bytes().iter().for_each(|&b| self.byte(b));
        self
    }

    pub fn bytes(&mut self, v: &[u8]) -> &mut Self {
        self.u64(v.len() as u64);
        v.iter().for_each(|&b| self.byte(b));
        self
    }

    pub fn words(&mut self, v: &[u32]) -> &mut Self {
        self.u64(v.len() as u64);
        v.iter().for_each(|&w| {
            self.u32(w);
        });
        self
    }

    pub fn str(&mut self, v: &str) -> &mut Self {
        self.bytes(v.as_bytes())
    }

    pub fn finish(&self) -> u128 {
        self.0
    }
}

/// The version of what [`StableHash`] is fed for a pipeline: bumped when the inputs change
/// meaning, so older stored binaries are never matched.
pub const FORMAT: u32 = 1;

/// The identity of the pipeline `d` describes, its layout's contents hashed as `layout`
/// ([`super::bindings::Binding::digest`]; heap pipelines have none: their mapping is hashed). The
/// shader record data is not part of it: it is written into the SBT, not compiled.
pub(super) fn of(d: &Desc, layout: u128) -> u128 {
    let mut h = StableHash::default();
    h.u32(FORMAT).str(&format!("{:?}", d.shaders.kind));
    for (s, words) in d.shaders.shaders.iter().zip(d.spirv) {
        h.str(s.role.file_name()).words(words);
    }
    h.bytes(d.specialization.data());
    h.u32(d.shaders.recursion_depth).str(d.model.as_str());
    h.u64(pipeline::flags2(d.model, d.heap.is_some()).as_raw());
    h.u64(layout as u64).u64((layout >> 64) as u64);
    match d.heap {
        Some(m) => h.u32(1).words(&m.words()),
        None => h.u32(0),
    };
    h.finish()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_vectors_and_no_collision_by_concatenation() {
        // FNV-1a 128 of the empty input is its offset basis; of "a", the published vector.
        assert_eq!(StableHash::default().finish(), OFFSET);
        let mut h = StableHash::default();
        h.byte(b'a');
        assert_eq!(h.finish(), 0xd228_cb69_6f1a_8caf_7891_2b70_4e4a_8964);
        // "ab" + "c" and "a" + "bc" differ: lengths are hashed.
        let a = StableHash::default().str("ab").str("c").finish();
        let b = StableHash::default().str("a").str("bc").finish();
        assert_ne!(a, b);
        // One changed word changes the hash; the same input gives the same hash.
        let w1 = StableHash::default().words(&[1, 2, 3]).finish();
        assert_eq!(w1, StableHash::default().words(&[1, 2, 3]).finish());
        assert_ne!(w1, StableHash::default().words(&[1, 2, 4]).finish());
    }
}
