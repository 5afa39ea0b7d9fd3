//! `independent` — independent uniform random numbers (Mitsuba's default
//! sampler, and Snell's for scenes that name none).
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `sample_count` | integer | 4 | samples per pixel |
//! | `seed` | integer | 0 | seed; a render is a function of (scene, seed) only |
//!
//! ```xml
//! <sampler type="independent">
//!     <integer name="sample_count" value="64"/>
//! </sampler>
//! ```
//!
//! Each sample has its own PCG32 stream, seeded by (seed, pixel, index): the
//! value of draw d is the stream's d-th number, a pure function of the four.

use crate::math::rng::{Pcg32, mix64};
use glam::Vec2;

pub(crate) struct Independent {
    rng: Pcg32,
}

impl Independent {
    /// Sample `index` of the pixel whose sequence seed is `pixel`
    /// (`super::pixel_seed` of the seed and the pixel).
    pub fn start(pixel: u64, index: u32) -> Independent {
        Independent { rng: Pcg32::new(pixel, mix64(index as u64 ^ 0x1dea_0000)) }
    }

    #[inline]
    pub fn next_1d(&mut self) -> f32 {
        self.rng.next_f32()
    }

    /// Advances the stream by one number without converting it.
    #[inline]
    pub fn skip_1d(&mut self) {
        self.rng.next_u32();
    }

    #[inline]
    pub fn next_2d(&mut self) -> Vec2 {
        let x = self.rng.next_f32();
        Vec2::new(x, self.rng.next_f32())
    }
}

#[cfg(test)]
mod tests {
    use super::super::testing::*;
    use super::super::*;
    use crate::math::rng::{Pcg32, mix64};

    #[test]
    fn a_sample_is_a_function_of_seed_pixel_and_index() {
        assert_addressable(SamplerKind::Independent);
    }

    #[test]
    fn converges_to_the_integral() {
        assert_unbiased(SamplerKind::Independent);
    }

    #[test]
    fn draws_the_same_numbers_as_before_addressable_samplers() {
        // The independent sampler keeps its numbers (the same images as before
        // the other samplers came): seed, pixel and index seed one PCG32 stream.
        let spec = SamplerSpec { sample_count: 16, seed: 7, kind: SamplerKind::Independent };
        let mut s = Sampler::start(&spec, 3, 5, 9);
        let pixel = mix64(mix64(7 ^ 0x5eed_0000_0000_0000) ^ ((5u64 << 32) | 3));
        let mut rng = Pcg32::new(pixel, mix64(9 ^ 0x1dea_0000));
        assert_eq!(s.next_1d(), rng.next_f32());
        let p = s.next_2d();
        assert_eq!((p.x, p.y), (rng.next_f32(), rng.next_f32()));
    }
}
