//! `orthogonal` — orthogonal-array samples (Jarosz et al. 2019, "Orthogonal
//! Array Sampling for Monte Carlo Rendering"): projected onto any `strength`
//! of its dimensions, the samples of a pixel are stratified, and each
//! dimension alone is stratified on all n strata (multi-jitter style).
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `sample_count` | integer | 4 | samples per pixel, rounded up to p^strength with p prime (strength 2: 10 → 25) |
//! | `seed` | integer | 0 | seed |
//! | `jitter` | boolean | true | a random position inside each sub-stratum (false: its centre) |
//! | `strength` | integer | 2 | the array's strength t (2 to 6): every t-D projection is stratified |
//!
//! ```xml
//! <sampler type="orthogonal">
//!     <integer name="sample_count" value="25"/>
//!     <integer name="strength" value="2"/>
//! </sampler>
//! ```
//!
//! Bush's construction: sample i (randomly permuted) has base-p digits
//! a₀ … a_{t−1}; its coordinate in column j (0 ≤ j < p) is the polynomial
//! Σ a_l j^l mod p, a stratum of p; the remaining digits (i / p) pick the
//! sub-stratum, so the column is stratified on all n = p^t strata. Symbols
//! and sub-strata are permuted per column. An array has p columns: further
//! draws use the next array, with a new random permutation of the samples
//! (padding). Unlike Mitsuba, every draw (also a 2-D one) takes columns, and
//! for strength > 2 the count is p^t (Mitsuba keeps p²).

use super::{ONE_MINUS_EPSILON, SampleId, dim_hash, permute, uniform};
use glam::Vec2;

/// The strengths the loader accepts.
pub const STRENGTHS: std::ops::RangeInclusive<u32> = 2..=6;

fn is_prime(p: u32) -> bool {
    p >= 2 && (2..).take_while(|d| d * d <= p).all(|d| p % d != 0)
}

/// The smallest prime p with p^t ≥ n.
fn prime_base(n: u32, strength: u32) -> u32 {
    let t = strength.max(1);
    let mut p = 2u32;
    while (p as u64).pow(t) < n as u64 || !is_prime(p) {
        p += 1;
    }
    p
}

/// `n` rounded up to p^strength, p prime.
pub fn round_sample_count(n: u32, strength: u32) -> u32 {
    let p = prime_base(n, strength) as u64;
    p.pow(strength.max(1)).min(u32::MAX as u64) as u32
}

pub(crate) struct Orthogonal {
    id: SampleId,
    p: u32,
    strength: u32,
    /// p^strength: the array's rows (the samples of a pattern).
    n: u32,
    jitter: bool,
    /// Coordinates drawn so far.
    pub(super) coord: u32,
    /// The array whose row is cached below (`u32::MAX`: none yet). A draw
    /// takes p columns of one array, all from the same permuted row.
    array: u32,
    /// The cached row: the sample's index under the array's permutation.
    row: u32,
}

impl Orthogonal {
    pub fn start(id: SampleId, jitter: bool, strength: u32) -> Orthogonal {
        let strength = strength.max(1);
        let p = prime_base(id.count, strength);
        let n = p.pow(strength);
        Orthogonal { id, p, strength, n, jitter, coord: 0, array: u32::MAX, row: 0 }
    }

    /// The sample's row in array `array` (its index under the array's
    /// permutation), cached.
    #[inline]
    fn row(&mut self, array: u32) -> u32 {
        if array != self.array {
            self.row = permute(self.id.index, self.n, (dim_hash(self.id.pixel_seed ^ 0x0a77_a700, array) >> 32) as u32);
            self.array = array;
        }
        self.row
    }

    #[inline(never)]
    pub fn next_1d(&mut self) -> f32 {
        let c = self.coord;
        self.coord += 1;
        let (p, n, seed) = (self.p, self.n, self.id.pixel_seed);
        if self.id.count != n {
            // A sample count set past the loader that is not p^t: no array.
            return uniform(seed, self.id.index, c);
        }
        let (array, column) = (c / p, c % p);
        let i = self.row(array);
        // The polynomial Σ a_l column^l mod p over the row's base-p digits
        // a_l, least significant first.
        let (pp, column) = (p as u64, column as u64);
        let (mut symbol, mut power, mut rest) = (0u64, 1u64, i as u64);
        for _ in 0..self.strength {
            symbol = (symbol + (rest % pp) * power) % pp;
            power = power * column % pp;
            rest /= pp;
        }
        let sub_n = n / p;
        let h = dim_hash(seed, c);
        let stratum = permute(symbol as u32, p, h as u32);
        let sub = permute(i / p, sub_n, (h >> 32) as u32);
        let j = if self.jitter { uniform(seed, self.id.index, c) } else { 0.5 };
        ((stratum as f32 + (sub as f32 + j) / sub_n as f32) / p as f32).min(ONE_MINUS_EPSILON)
    }

    #[inline(never)]
    pub fn next_2d(&mut self) -> Vec2 {
        let x = self.next_1d();
        Vec2::new(x, self.next_1d())
    }
}

#[cfg(test)]
mod tests {
    use super::super::testing::*;
    use super::super::*;

    const KIND: SamplerKind = SamplerKind::Orthogonal { jitter: true, strength: 2 };

    #[test]
    fn rounds_the_sample_count_to_a_prime_power() {
        assert_eq!([1, 4, 5, 10, 25, 26, 64].map(|n| super::round_sample_count(n, 2)), [4, 4, 9, 25, 25, 49, 121]);
        assert_eq!(super::round_sample_count(27, 3), 27);
        assert_eq!(super::round_sample_count(28, 3), 125);
    }

    /// Coordinates `c` of every sample of a pixel.
    fn coords(spec: &SamplerSpec, pixel: u32, c: usize) -> Vec<Vec<f32>> {
        (0..spec.sample_count)
            .map(|i| {
                let mut s = Sampler::start(spec, pixel, 0, i);
                (0..c).map(|_| s.next_1d()).collect()
            })
            .collect()
    }

    #[test]
    fn every_pair_of_columns_is_stratified() {
        for (n, t) in [(25, 2), (49, 2), (27, 3)] {
            let spec = spec(SamplerKind::Orthogonal { jitter: true, strength: t }, n, 4);
            let p = super::prime_base(n, t);
            let c = coords(&spec, 1, 2 * p as usize);
            for a in 0..p as usize {
                let xs: Vec<Vec2> = c.iter().map(|v| Vec2::new(v[a], 0.5)).collect();
                assert_cells(&xs, n, 1, 1, "orthogonal 1-D");
                for b in a + 1..p as usize {
                    let pts: Vec<Vec2> = c.iter().map(|v| Vec2::new(v[a], v[b])).collect();
                    assert_cells(&pts, p, p, n / (p * p), "orthogonal 2-D");
                }
            }
            // The next array (padding) is stratified in 1-D and 2-D too.
            let pts: Vec<Vec2> = c.iter().map(|v| Vec2::new(v[p as usize], v[p as usize + 1])).collect();
            assert_cells(&pts, p, p, n / (p * p), "orthogonal padding 2-D");
        }
    }

    #[test]
    fn strength_three_stratifies_every_triple() {
        let spec = spec(SamplerKind::Orthogonal { jitter: true, strength: 3 }, 27, 2);
        let c = coords(&spec, 0, 3);
        let mut hits = vec![0; 27];
        for v in &c {
            let cell = |x: f32| (x * 3.0) as usize;
            hits[cell(v[0]) * 9 + cell(v[1]) * 3 + cell(v[2])] += 1;
        }
        assert!(hits.iter().all(|&h| h == 1), "{hits:?}");
    }

    #[test]
    fn a_sample_is_a_function_of_seed_pixel_and_index() {
        assert_addressable(KIND);
    }

    #[test]
    fn converges_to_the_integral() {
        assert_unbiased(KIND);
    }

    #[test]
    fn discrepancy_below_independent() {
        assert_below_independent(KIND, 49);
    }
}
