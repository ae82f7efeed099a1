//! A 128-bit hash that is the same in every build, process and machine (FNV-1a; `std`'s hasher
//! promises neither): the identity of a group library (`exec::pipeline_library`: its stages'
//! SPIR-V, the layout's contents, the heap mapping structs), of a pipeline layout's contents
//! (`exec::bindings::layout::digest`), and the key and checksum of a GLSL compile kept on disk
//! (`shadergen::disk_cache`). Data layer: it uses nothing else of the crate.

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
