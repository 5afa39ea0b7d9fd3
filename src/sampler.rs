//! `independent` — the sampler: independent uniform random numbers.
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `sample_count` | integer | 4 | samples per pixel |
//! | `seed` | integer | 0 | seed; a render is a function of (scene, seed) only |
//!
//! Each pixel gets its own PCG32 stream derived from (seed, pixel), so the
//! image does not depend on how many threads render it or in which order.

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
    pub fn for_pixel(seed: u64, x: u32, y: u32) -> Sampler {
        let pixel = ((y as u64) << 32) | x as u64;
        Sampler { rng: Pcg32::new(mix64(seed ^ 0x5eed_0000_0000_0000), mix64(pixel)) }
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
