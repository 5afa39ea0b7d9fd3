//! `zsobol` — Owen-scrambled Sobol points with sample indices laid along a
//! Morton (Z-order) curve over the pixels (Snell's own; the design of
//! pbrt-v4's `ZSobolSampler`, after Ahmed and Wonka 2020, "Screen-space
//! blue-noise diffusion of Monte Carlo sampling error via hierarchical
//! ordering of pixels").
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `sample_count` | integer | 4 | samples per pixel; powers of two give the full net property |
//! | `seed` | integer | 0 | seed |
//!
//! ```xml
//! <sampler type="zsobol">
//!     <integer name="sample_count" value="64"/>
//! </sampler>
//! ```
//!
//! Sample i of pixel (x, y) is number (Morton(x, y) · 2^m + i) of one global
//! Sobol sequence (2^m ≥ the sample count). Before each draw, the base-4
//! digits of that number are shuffled, each by one of the 24 permutations
//! of four chosen by hashing the digits above it and the draw's number: a
//! pixel's samples stay an aligned block of 2^m consecutive points — a
//! (0,m,2)-net, as with `sobol` — while the blocks of neighbouring pixels
//! are well-spread parts of the same bigger net. So neighbouring pixels get
//! complementary samples, and the error looks like blue noise rather than
//! white noise. One Owen scramble per draw randomizes the whole sequence.
//!
//! The pixel's place needs the film size (set by the loader); pixel numbers
//! off the film (light tracing numbers its paths as pixels) fall back to
//! `sobol`'s per-pixel padded sequence. The scramble sees 32 bits of the
//! number: films with more than 2^32 samples in all repeat dimension 0.

use super::sobol::{owen_scramble, sobol0, sobol1};
use super::{hash, unit};
use crate::math::rng::mix64;
use glam::Vec2;

/// The 24 permutations of {0, 1, 2, 3}.
const PERMUTATIONS: [[u8; 4]; 24] = [
    [0, 1, 2, 3], [0, 1, 3, 2], [0, 2, 1, 3], [0, 2, 3, 1], [0, 3, 1, 2], [0, 3, 2, 1],
    [1, 0, 2, 3], [1, 0, 3, 2], [1, 2, 0, 3], [1, 2, 3, 0], [1, 3, 0, 2], [1, 3, 2, 0],
    [2, 0, 1, 3], [2, 0, 3, 1], [2, 1, 0, 3], [2, 1, 3, 0], [2, 3, 0, 1], [2, 3, 1, 0],
    [3, 0, 1, 2], [3, 0, 2, 1], [3, 1, 0, 2], [3, 1, 2, 0], [3, 2, 0, 1], [3, 2, 1, 0],
];

/// log2 of the film's larger side, rounded up.
pub fn log2_res(width: u32, height: u32) -> u32 {
    width.max(height).max(1).next_power_of_two().trailing_zeros()
}

/// Interleaves the bits of x (even bits) and y (odd bits).
fn morton2(x: u32, y: u32) -> u64 {
    fn spread(v: u32) -> u64 {
        let mut v = v as u64;
        v = (v | (v << 16)) & 0x0000_ffff_0000_ffff;
        v = (v | (v << 8)) & 0x00ff_00ff_00ff_00ff;
        v = (v | (v << 4)) & 0x0f0f_0f0f_0f0f_0f0f;
        v = (v | (v << 2)) & 0x3333_3333_3333_3333;
        (v | (v << 1)) & 0x5555_5555_5555_5555
    }
    spread(x) | (spread(y) << 1)
}

pub(crate) struct ZSobol {
    /// Morton(x, y) · 2^m + index.
    morton_index: u64,
    /// Bits of `morton_index` that are shuffled: 2·log2_res + m.
    bits: u32,
    seed: u64,
    pub(super) dim: u32,
}

impl ZSobol {
    /// `None` for a pixel off the film's Morton square or an index past the
    /// pixel's block.
    pub fn start(seed: u64, count: u32, log2_res: u32, x: u32, y: u32, index: u32) -> Option<ZSobol> {
        let m = count.max(1).next_power_of_two().trailing_zeros();
        let side = 1u64 << log2_res.min(31);
        if x as u64 >= side || y as u64 >= side || index >= 1 << m || 2 * log2_res + m > 62 {
            return None;
        }
        Some(ZSobol {
            morton_index: (morton2(x, y) << m) | index as u64,
            bits: 2 * log2_res + m,
            seed: mix64(seed ^ 0x2b7e_1516_28ae_d2a6),
            dim: 0,
        })
    }

    /// The Sobol index of this draw: the shuffled digits of `morton_index`.
    #[inline]
    fn index(&self) -> u64 {
        let salt = hash(self.seed, self.dim as u64);
        let odd = self.bits & 1;
        let mut out = 0u64;
        // Base-4 digits from the most significant down, each permuted by a
        // hash of the (unpermuted) digits above it.
        for k in (0..self.bits / 2).rev() {
            let shift = odd + 2 * k;
            let digit = (self.morton_index >> shift) & 3;
            let higher = self.morton_index >> (shift + 2);
            // Multiplicative hashing: the top bits depend on all of the input.
            let p = (((higher ^ salt).wrapping_mul(0x9e37_79b9_7f4a_7c15) >> 32) * 24) >> 32;
            out |= (PERMUTATIONS[p as usize][digit as usize] as u64) << shift;
        }
        if odd == 1 {
            // An odd number of bits: the lowest is a base-2 digit.
            let flip = mix64((self.morton_index >> 1) ^ salt.rotate_left(17)) & 1;
            out |= (self.morton_index & 1) ^ flip;
        }
        out
    }

    #[inline]
    fn draw(&mut self) -> (u64, u64) {
        let i = self.index();
        let h = hash(self.seed ^ 0x0e3e, self.dim as u64);
        self.dim += 1;
        (i, h)
    }

    #[inline]
    pub fn next_1d(&mut self) -> f32 {
        let (i, h) = self.draw();
        unit(owen_scramble(sobol0(i), h as u32))
    }

    #[inline]
    pub fn next_2d(&mut self) -> Vec2 {
        let (i, h) = self.draw();
        Vec2::new(unit(owen_scramble(sobol0(i), h as u32)), unit(owen_scramble(sobol1(i), (h >> 32) as u32)))
    }
}

#[cfg(test)]
mod tests {
    use super::super::testing::*;
    use super::super::*;
    use super::*;

    const KIND: SamplerKind = SamplerKind::ZSobol { log2_res: 6 };

    #[test]
    fn morton_order() {
        assert_eq!([(0, 0), (1, 0), (0, 1), (1, 1), (2, 0), (3, 3)].map(|(x, y)| morton2(x, y)), [0, 1, 2, 3, 4, 15]);
        assert_eq!(log2_res(64, 48), 6);
        assert_eq!(log2_res(65, 3), 7);
    }

    #[test]
    fn the_digit_shuffle_is_a_permutation() {
        // All samples of all pixels of an 8×8 film, 8 spp (odd m): distinct indices.
        let mut seen = std::collections::HashSet::new();
        for y in 0..8 {
            for x in 0..8 {
                for i in 0..8 {
                    let z = ZSobol::start(5, 8, 3, x, y, i).unwrap();
                    assert!(seen.insert(z.index()));
                }
            }
        }
        assert_eq!(seen.len(), 512);
        assert!(seen.iter().all(|&i| i < 512));
    }

    #[test]
    fn every_draw_of_a_pixel_is_a_net() {
        for n in [4, 8, 16, 64, 256] {
            let spec = spec(KIND, n, 5);
            for pattern in [&[][..], &[false, true], &[true, false, true, true]] {
                for (x, y) in [(0, 0), (5, 9), (63, 63)] {
                    assert_net(&points(&spec, x, y, pattern, true), "zsobol 2-D draw");
                    assert_cells(&points(&spec, x, y, pattern, false), n, 1, 1, "zsobol 1-D draw");
                }
            }
        }
    }

    #[test]
    fn neighbouring_pixels_share_a_bigger_net() {
        // The 4 pixels of an aligned 2×2 Morton quad, 16 spp each: their 64
        // first draws together are a (0,6,2)-net.
        let spec = spec(KIND, 16, 8);
        for (qx, qy) in [(0, 0), (6, 2), (30, 14)] {
            let mut pts = Vec::new();
            for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                pts.extend(points(&spec, qx + dx, qy + dy, &[false], true));
            }
            assert_net(&pts, "zsobol 2×2 quad");
        }
    }

    #[test]
    fn pixels_off_the_film_fall_back_to_sobol() {
        let spec = spec(KIND, 16, 8);
        let mut s = Sampler::start(&spec, 3, 0x8000_0000, 0);
        assert!((0.0..1.0).contains(&s.next_1d()));
        assert!(matches!(s.method, super::super::Method::Sobol(_)));
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
