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
//! digits of the pixel's part of that number are shuffled, each by one of
//! the 24 permutations of four chosen by hashing the digits above it and
//! the draw's number, and the sample's m bits by a nested binary scramble
//! (each bit flipped by a hash of the bits above it, the pixel and the
//! draw): a pixel's samples stay an aligned block of 2^m consecutive points
//! — a (0,m,2)-net, as with `sobol` — while the blocks of neighbouring
//! pixels are well-spread parts of the same bigger net. So neighbouring
//! pixels get complementary samples, and the error looks like blue noise
//! rather than white noise. One Owen scramble per draw randomizes the whole
//! sequence.
//!
//! Cost: the pixel digits' shuffle is the same for every sample of a pixel
//! in a given draw, and the samples of a pixel are rendered together, so
//! each thread memoizes the last shuffles (a pure cache); the sample's
//! scramble is four multiplications (the Laine–Karras hash). A draw costs
//! about a third of the per-digit shuffle of every digit.
//!
//! The pixel's place needs the film size (set by the loader); pixel numbers
//! off the film (light tracing numbers its paths as pixels) fall back to
//! `sobol`'s per-pixel padded sequence. The scramble sees 32 bits of the
//! number: films with more than 2^32 samples in all repeat dimension 0.

use super::sobol::{laine_karras, sobol1_reversed};
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
    /// Morton(x, y): the pixel's digits.
    pixel: u64,
    /// The sample's index within the pixel's block, < 2^m.
    index: u32,
    /// log2 of the pixel's block of indices.
    m: u32,
    /// Bits of `pixel` that are shuffled: 2·log2_res.
    pixel_bits: u32,
    seed: u64,
    pub(super) dim: u32,
}

/// 8-bit reversal (the sample digits of pixels with up to 256 samples).
const REV8: [u8; 256] = {
    let mut t = [0u8; 256];
    let mut i = 0;
    while i < 256 {
        t[i] = (i as u8).reverse_bits();
        i += 1;
    }
    t
};

/// One memoized pixel-digit shuffle: (draw hash, pixel, pixel bits) → the
/// shuffled pixel digits.
#[derive(Clone, Copy)]
struct Memo {
    salt: u64,
    pixel: u64,
    bits: u32,
    out: u64,
}

const MEMO_SIZE: usize = 256;

const MEMO_EMPTY: Memo = Memo { salt: 0, pixel: u64::MAX, bits: u32::MAX, out: 0 };

thread_local! {
    /// The shuffled pixel digits of recent (draw, pixel) pairs, per thread:
    /// a pixel's samples are rendered together, and every one of them makes
    /// the same shuffle in a given draw. A pure cache: results do not depend
    /// on it.
    static MEMO: [std::cell::Cell<Memo>; MEMO_SIZE] = const { [const { std::cell::Cell::new(MEMO_EMPTY) }; MEMO_SIZE] };
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
        Some(ZSobol { pixel: morton2(x, y), index, m, pixel_bits: 2 * log2_res, seed: mix64(seed ^ 0x2b7e_1516_28ae_d2a6), dim: 0 })
    }

    /// The pixel's digits shuffled for the draw of hash `salt`: base-4
    /// digits from the most significant down, each permuted by one of the
    /// 24 permutations, chosen by a hash of the (unpermuted) digits above
    /// it and the draw.
    #[inline]
    fn shuffle_pixel(pixel: u64, bits: u32, salt: u64) -> u64 {
        let mut out = 0u64;
        let mut k = bits / 2;
        while k > 0 {
            k -= 1;
            let t = pixel >> (2 * k);
            // Multiplicative hashing: the top bits depend on all of the input.
            let p = ((((t >> 2) ^ salt).wrapping_mul(0x9e37_79b9_7f4a_7c15) >> 32) * 24) >> 32;
            out = (out << 2) | PERMUTATIONS[p as usize][(t & 3) as usize] as u64;
        }
        out
    }

    /// [`ZSobol::shuffle_pixel`] through the thread's memo.
    #[inline(always)]
    fn pixel_block(&self, salt: u64) -> u64 {
        let (pixel, bits) = (self.pixel, self.pixel_bits);
        let slot = ((pixel ^ salt).wrapping_mul(0x9e37_79b9_7f4a_7c15) >> 56) as usize % MEMO_SIZE;
        let hit = MEMO.with(|memo| {
            let e = memo[slot].get();
            (e.salt == salt && e.pixel == pixel && e.bits == bits).then_some(e.out)
        });
        match hit {
            Some(out) => out,
            None => Self::memoize(slot, pixel, bits, salt),
        }
    }

    #[inline(never)]
    fn memoize(slot: usize, pixel: u64, bits: u32, salt: u64) -> u64 {
        let out = Self::shuffle_pixel(pixel, bits, salt);
        MEMO.with(|memo| memo[slot].set(Memo { salt, pixel, bits, out }));
        out
    }

    /// The sample's index within the pixel's block shuffled for the draw:
    /// each bit flipped by a hash of the bits above it, of the pixel and of
    /// the draw (a nested scramble of the index, most significant bit
    /// first: the Laine–Karras hash on the reversed bits).
    #[inline(always)]
    fn shuffle_sample(&self, salt: u64) -> u64 {
        let m = self.m;
        if m == 0 {
            return 0;
        }
        let seed = ((self.pixel ^ salt.rotate_left(23)).wrapping_mul(0xd6e8_feb8_6659_fd93) >> 32) as u32;
        let rev = |v: u32| if m <= 8 { (REV8[v as usize] >> (8 - m)) as u32 } else { v.reverse_bits() >> (32 - m) };
        let mask = (1u32 << m) - 1;
        rev(laine_karras(rev(self.index), seed) & mask) as u64
    }

    /// The Sobol index of a draw whose hash is `salt`: the pixel's shuffled
    /// digits above the sample's.
    #[inline(always)]
    fn index(&self, salt: u64) -> u64 {
        (self.pixel_block(salt) << self.m) | self.shuffle_sample(salt)
    }

    /// This draw's Sobol index and its two 32-bit scramble seeds: one hash
    /// of (seed, draw) drives both the digit shuffle and (through an odd
    /// multiplier, a bijection) the Owen scrambles.
    #[inline(always)]
    fn draw(&mut self) -> (u64, u32, u32) {
        let salt = hash(self.seed, self.dim as u64);
        self.dim += 1;
        let i = self.index(salt);
        let h = (salt ^ (salt >> 32)).wrapping_mul(0xd6e8_feb8_6659_fd93);
        (i, h as u32, (h >> 32) as u32)
    }

    #[inline(never)]
    pub fn next_1d(&mut self) -> f32 {
        let (i, a, _) = self.draw();
        // owen_scramble(sobol0(i)) without its two cancelling bit reversals.
        unit(laine_karras(i as u32, a).reverse_bits())
    }

    #[inline(never)]
    pub fn next_2d(&mut self) -> Vec2 {
        let (i, a, b) = self.draw();
        // Both dimensions scrambled on reversed bits (dimension 0's reversal
        // cancels, dimension 1's superset transform comes out reversed), and
        // one 64-bit reversal for the two.
        let both = (((laine_karras(i as u32, a) as u64) << 32) | laine_karras(sobol1_reversed(i), b) as u64).reverse_bits();
        Vec2::new(unit(both as u32), unit((both >> 32) as u32))
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
                    assert!(seen.insert(z.index(hash(z.seed, 3))));
                }
            }
        }
        assert_eq!(seen.len(), 512);
        assert!(seen.iter().all(|&i| i < 512));
    }

    #[test]
    fn the_memo_is_transparent() {
        // Pixels and draws interleaved (many more pairs than the memo holds),
        // and two film sizes: the memoized shuffle is always the direct one.
        for round in 0..3u32 {
            for x in 0..40u32 {
                for d in 0..24u64 {
                    for log2_res in [6, 7] {
                        let z = ZSobol::start(9 + round as u64 % 2, 16, log2_res, x, (x * 7) % 64, 3).unwrap();
                        let salt = hash(z.seed, d);
                        assert_eq!(z.pixel_block(salt), ZSobol::shuffle_pixel(z.pixel, z.pixel_bits, salt));
                    }
                }
            }
        }
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
