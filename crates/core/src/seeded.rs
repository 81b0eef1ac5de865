//! [`SplitMix`]: the fixed-seed number stream behind the randomised ferns, the descriptor
//! pattern, RANSAC's samples, the scan registration's point sampling and the tests' fuzz
//! replay (splitmix64, Steele, Lea and Flood 2014): repeatable on every machine and
//! backend, no dependency for a few thousand numbers, not for security.

/// A splitmix64 stream from a seed.
#[derive(Debug, Clone)]
pub struct SplitMix(pub u64);

impl SplitMix {
    /// A stream started at `seed`.
    pub fn new(seed: u64) -> Self {
        SplitMix(seed)
    }

    /// The next 64 bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in `[0, n)` (`n > 0`), by widening multiply (bias below 2^-32 for clouds
    /// under 4 billion points): the scan registration's sampling.
    pub fn below_wide(&mut self, n: usize) -> usize {
        ((self.next_u64() as u128 * n as u128) >> 64) as usize
    }

    /// Uniform in `[0, n)` (`n > 0`; the modulo bias is below 2^-40 for the sizes here).
    pub fn below(&mut self, n: u64) -> u64 {
        self.next_u64() % n
    }

    /// Uniform in `[lo, hi)`, 24 bits of resolution.
    pub fn between(&mut self, lo: f32, hi: f32) -> f32 {
        let unit = (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32;
        lo + (hi - lo) * unit
    }

    /// Uniform in `[0, 1)`, 53 bits of resolution (test data).
    pub fn unit_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
}
