//! `ldsampler` — Mitsuba's low-discrepancy sampler (Kollig and Keller 2002,
//! "Efficient multidimensional sampling"): every draw takes the same
//! (0,2)-sequence (van der Corput × Sobol), shuffled and digitally shifted.
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `sample_count` | integer | 4 | samples per pixel, rounded up to a power-of-two square (4, 16, 64, 256, …) as Mitsuba does |
//! | `seed` | integer | 0 | seed |
//! | `dimension` | integer | unlimited | draws taken from the sequence (Mitsuba 0.6's parameter); later draws are independent |
//!
//! ```xml
//! <sampler type="ldsampler">
//!     <integer name="sample_count" value="64"/>
//! </sampler>
//! ```
//!
//! A draw permutes the pixel's samples at random, takes the permuted index's
//! point of the (0,2)-sequence and XORs it with a random 32-bit shift (a
//! digital shift keeps the (0,m,2)-net property and makes each point uniform).
//! Mitsuba shifts all draws of a pixel alike; here each draw has its own
//! shift.

use super::sobol::sobol01;
use super::{SampleId, dim_hash, mix64, permute, uniform2, unit};
use glam::Vec2;

/// Mitsuba's rounding: the smallest r² ≥ n with r a power of two ≥ 2.
pub fn round_sample_count(n: u32) -> u32 {
    let mut r = 2u32;
    while (r as u64 * r as u64) < n as u64 {
        r *= 2;
    }
    r.saturating_mul(r)
}

pub(crate) struct LdSampler {
    id: SampleId,
    dimension: u32,
    pub(super) dim: u32,
}

impl LdSampler {
    pub fn start(id: SampleId, dimension: u32) -> LdSampler {
        LdSampler { id, dimension, dim: 0 }
    }

    #[inline(always)]
    fn draw(&mut self) -> Option<(u64, u64)> {
        let d = self.dim;
        self.dim += 1;
        if d >= self.dimension {
            return None;
        }
        let h = dim_hash(self.id.pixel_seed, d);
        let i = permute(self.id.index, self.id.count, h as u32);
        // The digital shift: 64 more bits of the draw's hash.
        Some((i as u64, mix64(h)))
    }

    #[inline(never)]
    pub fn next_1d(&mut self) -> f32 {
        match self.draw() {
            Some((i, shift)) => unit(sobol01(i) as u32 ^ shift as u32),
            None => uniform2(self.id.pixel_seed, self.id.index, self.dim).0,
        }
    }

    /// Inlined where `Sampler::next_2d` is (see there).
    #[inline(always)]
    pub fn next_2d(&mut self) -> Vec2 {
        match self.draw() {
            Some((i, shift)) => {
                // sobol0(i) in the low half and sobol1(i) in the high half.
                let both = sobol01(i) ^ shift;
                Vec2::new(unit(both as u32), unit((both >> 32) as u32))
            }
            None => {
                let (x, y) = uniform2(self.id.pixel_seed, self.id.index, self.dim);
                Vec2::new(x, y)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::testing::*;
    use super::super::*;

    const KIND: SamplerKind = SamplerKind::LdSampler { dimension: u32::MAX };

    #[test]
    fn rounds_the_sample_count_to_a_power_of_two_square() {
        assert_eq!([1, 4, 5, 16, 17, 64, 100, 256].map(super::round_sample_count), [4, 4, 16, 16, 64, 64, 256, 256]);
    }

    #[test]
    fn every_draw_of_a_pixel_is_a_net() {
        for n in [4, 16, 64, 256] {
            let spec = spec(KIND, n, 2);
            for pattern in [&[][..], &[true, false], &[false, false, true]] {
                for pixel in 0..3 {
                    assert_net(&points(&spec, pixel, 7, pattern, true), "ldsampler 2-D draw");
                    assert_cells(&points(&spec, pixel, 7, pattern, false), n, 1, 1, "ldsampler 1-D draw");
                }
            }
        }
    }

    /// The 2-D draw is Sobol's dimensions 0 and 1 of the permuted index,
    /// digitally shifted: the definition, for indices below 256 (the
    /// table) and above, every draw of a few samples.
    #[test]
    fn the_2d_draw_is_the_shifted_sobol_point() {
        use crate::sampler::sobol::{sobol0, sobol1};
        for (count, index) in [(4, 3), (64, 17), (256, 255), (1024, 700), (1 << 20, 987_654)] {
            let id = SampleId::new(0x1234_5678_9abc_def0 ^ index as u64, count, index);
            let mut s = super::LdSampler::start(id, u32::MAX);
            for d in 0..12 {
                let h = dim_hash(id.pixel_seed, d);
                let i = permute(id.index, id.count, h as u32) as u64;
                let shift = mix64(h);
                let want = Vec2::new(unit(sobol0(i) ^ shift as u32), unit(sobol1(i) ^ (shift >> 32) as u32));
                assert_eq!(s.next_2d(), want, "count {count}, index {index}, draw {d}");
            }
        }
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
        assert_below_independent(KIND, 64);
    }
}
