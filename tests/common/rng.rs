//! SplitMix64 uniforms for tests: fixed seeds give the same numbers on every run and machine.
#![allow(dead_code)]

pub struct Rng(pub u64);

impl Rng {
    /// A uniform in [0, 1) with 24 random bits.
    pub fn next(&mut self) -> f32 {
        self.0 = self.0.wrapping_add(0x9E3779B97F4A7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58476D1CE4E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D049BB133111EB);
        ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
    }
}
