//! `independent` — the sampler: independent uniform random numbers.
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `sample_count` | integer | 4 | samples per pixel |
//! | `seed` | integer | 0 | seed; a render is a function of (scene, seed) only |
//!
//! Samples are addressable: [`Sampler::start`] gives the sampler of sample
//! `index` of pixel (x, y), and the numbers it draws are a pure function of
//! (seed, pixel, index, dimension). So any sample can be rendered on its own:
//! the image does not depend on the thread count, the order of the work, or
//! how the sample range is split into passes (or over machines).

use crate::math::rng::{Pcg32, mix64};
use glam::Vec2;

#[derive(Clone, Copy, Debug)]
pub struct SamplerSpec {
    pub sample_count: u32,
    pub seed: u64,
}

pub struct Sampler {
    rng: Pcg32,
}

impl Sampler {
    /// The sampler of sample `index` of pixel (`x`, `y`) (pixel coordinates
    /// in the full film, so a crop renders the same samples as the full
    /// render there). Light tracing addresses its paths the same way, with
    /// its own pixel numbering.
    pub fn start(spec: &SamplerSpec, x: u32, y: u32, index: u32) -> Sampler {
        let pixel = ((y as u64) << 32) | x as u64;
        let seed = mix64(mix64(spec.seed ^ 0x5eed_0000_0000_0000) ^ pixel);
        Sampler { rng: Pcg32::new(seed, mix64(index as u64 ^ 0x1dea_0000)) }
    }

    #[inline]
    pub fn next_1d(&mut self) -> f32 {
        self.rng.next_f32()
    }

    #[inline]
    pub fn next_2d(&mut self) -> Vec2 {
        let x = self.rng.next_f32();
        Vec2::new(x, self.rng.next_f32())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sample_is_a_function_of_seed_pixel_and_index() {
        let spec = SamplerSpec { sample_count: 16, seed: 7 };
        let draw = |x, y, i| {
            let mut s = Sampler::start(&spec, x, y, i);
            (s.next_1d(), s.next_2d())
        };
        assert_eq!(draw(3, 5, 9), draw(3, 5, 9));
        assert_ne!(draw(3, 5, 9), draw(3, 5, 10));
        assert_ne!(draw(3, 5, 9), draw(5, 3, 9));
        let other = SamplerSpec { seed: 8, ..spec };
        let mut s = Sampler::start(&other, 3, 5, 9);
        assert_ne!((s.next_1d(), s.next_2d()), draw(3, 5, 9));
    }
}
