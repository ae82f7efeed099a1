//! A tiny seeded generator (SplitMix64): scenes must be bit-identical for a seed on every
//! machine and every rtprobe version that keeps this file.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(seed ^ 0x7274_7072_6f62_6521)
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in [lo, hi), with 24 bits of resolution so the value is exact in f32.
    pub fn range(&mut self, lo: f32, hi: f32) -> f32 {
        let u = (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32;
        lo + (hi - lo) * u
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn deterministic() {
        let a: Vec<u64> = {
            let mut r = super::Rng::new(7);
            (0..4).map(|_| r.next_u64()).collect()
        };
        let b: Vec<u64> = {
            let mut r = super::Rng::new(7);
            (0..4).map(|_| r.next_u64()).collect()
        };
        assert_eq!(a, b);
        let mut r = super::Rng::new(1);
        assert!((0..1000).map(|_| r.range(-1.0, 1.0)).all(|x| (-1.0..1.0).contains(&x)));
    }
}
