//! `sobol` — Owen-scrambled Sobol points, padded per dimension (Snell's own;
//! the design of pbrt-v4's `PaddedSobolSampler` with Burley's hash-based
//! Owen scrambling, "Practical Hash-based Owen Scrambling", JCGT 2020).
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `sample_count` | integer | 4 | samples per pixel; powers of two give the full net property |
//! | `seed` | integer | 0 | seed |
//!
//! ```xml
//! <sampler type="sobol">
//!     <integer name="sample_count" value="64"/>
//! </sampler>
//! ```
//!
//! Every draw takes the first two dimensions of the Sobol sequence — a
//! (0,2)-sequence, so the pixel's 2^m samples of each 2-D draw form a
//! (0,m,2)-net: every elementary interval of area 2^−m holds one point. The
//! draw's own random permutation of the pixel's samples (the padding)
//! decorrelates the draws; an Owen scramble per draw and pixel randomizes the
//! points while keeping the net. Every dimension is supported this way; a
//! 1-D draw is the scrambled van der Corput point.

use super::{SampleId, dim_hash, permute, unit};
#[cfg(test)]
use crate::math::rng::mix64;
use glam::Vec2;

/// Columns of the generator matrix of Sobol dimension 1 (dimension 0 is the
/// identity: the bit-reversed index). From the degree-1 primitive polynomial
/// x + 1 with m₁ = 1: v₀ = 2³¹, v_k = v_{k−1} ⊕ (v_{k−1} ≫ 1) — the Pascal
/// matrix mod 2, truncated to 32 bits of precision (64 columns, for 64-bit
/// indices).
#[cfg(test)]
pub(crate) const SOBOL1: [u32; 64] = {
    let mut v = [0u32; 64];
    v[0] = 1 << 31;
    let mut k = 1;
    while k < 64 {
        v[k] = v[k - 1] ^ (v[k - 1] >> 1);
        k += 1;
    }
    v
};

/// Sobol dimension 0 of `index` as 32 fraction bits (the definition; the
/// draws take [`sobol01`] or reverse scrambled bits).
#[cfg(test)]
pub(crate) fn sobol0(index: u64) -> u32 {
    (index as u32).reverse_bits()
}

/// Sobol dimension 1 of `index` as 32 fraction bits, without a loop over
/// the index's bits. Column k of the matrix has fraction bit j (counted from
/// the top) set iff C(k, j) is odd, i.e. iff j ⊆ k as bit sets (Lucas), so
/// result bit j is the parity of the index bits at the supersets of j: the
/// GF(2) superset transform of the index, six shift-and-xor steps (the
/// Pascal matrix mod 2 is the 6-fold Kronecker power of [[1,1],[0,1]]).
#[cfg(test)]
pub(crate) fn sobol1(index: u64) -> u32 {
    sobol1_reversed(index).reverse_bits()
}

/// [`sobol1`] with its bits reversed (the fraction's top bit as bit 0).
#[inline]
pub(crate) const fn sobol1_reversed(index: u64) -> u32 {
    let mut z = index;
    z ^= (z >> 1) & 0x5555_5555_5555_5555;
    z ^= (z >> 2) & 0x3333_3333_3333_3333;
    z ^= (z >> 4) & 0x0f0f_0f0f_0f0f_0f0f;
    z ^= (z >> 8) & 0x00ff_00ff_00ff_00ff;
    z ^= (z >> 16) & 0x0000_ffff_0000_ffff;
    z ^= z >> 32;
    z as u32
}

/// [`sobol1_reversed`] of indices below 256 (a pixel's samples up to 256
/// spp): the transform keeps an index's bits within its byte.
const SOBOL1_REVERSED_BYTE: [u8; 256] = {
    let mut t = [0u8; 256];
    let mut i = 0;
    while i < 256 {
        t[i] = sobol1_reversed(i as u64) as u8;
        i += 1;
    }
    t
};

/// [`sobol1_reversed`], by a table lookup for indices below 256.
#[inline(always)]
fn sobol1_reversed_small(index: u64) -> u32 {
    if index < 256 { SOBOL1_REVERSED_BYTE[index as usize] as u32 } else { sobol1_reversed(index) }
}

/// Sobol dimensions 0 and 1 of indices below 256, the top byte of each
/// (the rest is zero): what a 2-D draw of a pixel with up to 256 samples
/// takes without any bit reversal.
const SOBOL01_BYTES: [[u8; 2]; 256] = {
    let mut t = [[0u8; 2]; 256];
    let mut i = 0;
    while i < 256 {
        t[i] = [(i as u8).reverse_bits(), (sobol1_reversed(i as u64) as u8).reverse_bits()];
        i += 1;
    }
    t
};

/// Sobol dimension 0 of `index` in the low 32 bits and dimension 1 in the
/// high 32, from a table for indices below 256, else by one 64-bit bit
/// reversal (x86 has no bit-reverse instruction: a reversal is a dozen
/// shifts and masks).
#[inline(always)]
pub(crate) fn sobol01(index: u64) -> u64 {
    if index < 256 {
        let [d0, d1] = SOBOL01_BYTES[index as usize];
        ((d1 as u64) << 56) | ((d0 as u64) << 24)
    } else {
        ((index << 32) | sobol1_reversed(index) as u64).reverse_bits()
    }
}

/// [`sobol1`] by the matrix's columns, one per index bit (the definition;
/// kept for the test that the two agree).
#[cfg(test)]
fn sobol1_by_columns(mut index: u64) -> u32 {
    let mut v = 0;
    let mut k = 0;
    while index != 0 {
        if index & 1 != 0 {
            v ^= SOBOL1[k];
        }
        index >>= 1;
        k += 1;
    }
    v
}

/// Owen scrambling of 32 fraction bits by a hash (Burley 2020, with the
/// Laine–Karras style hash on the reversed bits: each output bit is flipped
/// by a function of the seed and the bits above it only). The definition:
/// the draws apply [`laine_karras`] to bit-reversed values directly.
#[cfg(test)]
pub(crate) fn owen_scramble(x: u32, seed: u32) -> u32 {
    laine_karras(x.reverse_bits(), seed).reverse_bits()
}

/// The scramble of [`owen_scramble`] on bit-reversed input and output:
/// each bit flipped by a function of the seed and the bits below it.
#[inline]
pub(crate) fn laine_karras(mut v: u32, seed: u32) -> u32 {
    v = v.wrapping_add(seed);
    v ^= v.wrapping_mul(0x6c50_b47c);
    v ^= v.wrapping_mul(0xb82f_1e52);
    v ^= v.wrapping_mul(0xc7af_e638);
    v ^= v.wrapping_mul(0x8d22_f6e6);
    v
}

pub(crate) struct Sobol {
    id: SampleId,
    pub(super) dim: u32,
}

impl Sobol {
    pub fn start(id: SampleId) -> Sobol {
        Sobol { id, dim: 0 }
    }

    /// The permuted index of this draw and its two scramble seeds.
    #[inline]
    fn draw(&mut self) -> (u64, u32, u32) {
        // The permutation seed and two scramble seeds from the draw's hash.
        let h = dim_hash(self.id.pixel_seed, self.dim);
        let i = permute(self.id.index, self.id.count, h as u32);
        // The scramble seeds from the same hash (an odd multiplier is a bijection).
        let g = (h ^ (h >> 32)).wrapping_mul(0xd6e8_feb8_6659_fd93);
        self.dim += 1;
        (i as u64, g as u32, (g >> 32) as u32)
    }

    #[inline(never)]
    pub fn next_1d(&mut self) -> f32 {
        let (i, a, _) = self.draw();
        // owen_scramble(sobol0(i), a) without its two cancelling bit reversals.
        unit(laine_karras(i as u32, a).reverse_bits())
    }

    #[inline(never)]
    pub fn next_2d(&mut self) -> Vec2 {
        let (i, a, b) = self.draw();
        // owen_scramble of dimensions 0 and 1 on reversed bits (dimension
        // 0's reversal cancels, dimension 1's superset transform comes out
        // reversed), and one 64-bit reversal for the two.
        let both = (((laine_karras(i as u32, a) as u64) << 32) | laine_karras(sobol1_reversed_small(i), b) as u64).reverse_bits();
        Vec2::new(unit(both as u32), unit((both >> 32) as u32))
    }
}

#[cfg(test)]
mod tests {
    use super::super::testing::*;
    use super::super::*;
    use super::*;

    #[test]
    fn the_unscrambled_sequence_is_sobol() {
        // The first points of Sobol's sequence in dimensions 0 and 1.
        let expect = [(0.0, 0.0), (0.5, 0.5), (0.25, 0.75), (0.75, 0.25), (0.125, 0.625), (0.625, 0.125)];
        for (i, (x, y)) in expect.into_iter().enumerate() {
            assert_eq!((unit(sobol0(i as u64)), unit(sobol1(i as u64))), (x, y), "index {i}");
        }
        for m in 1..=10 {
            let pts: Vec<Vec2> = (0..1u64 << m).map(|i| Vec2::new(unit(sobol0(i)), unit(sobol1(i)))).collect();
            assert_net(&pts, "Sobol");
        }
    }

    #[test]
    fn sobol1_transform_equals_the_matrix_product() {
        let mut x = 0x1234_5678_9abc_def0u64;
        for i in 0..20000u64 {
            x = mix64(x ^ i);
            // Indices of every size: all 64 bits, and the small ones pixels use.
            for idx in [i, x, x >> (x % 64), x & 0xfffff] {
                assert_eq!(sobol1(idx), sobol1_by_columns(idx), "index {idx:#x}");
            }
        }
    }

    #[test]
    fn both_dimensions_at_once_are_sobol0_and_sobol1() {
        let mut x = 0x9e37_79b9_7f4a_7c15u64;
        for i in (0..1024u64).chain((0..2000).map(|k| {
            x = mix64(x ^ k);
            x >> (x % 64)
        })) {
            // Indices below 256 from the table, the others by the reversal.
            assert_eq!(sobol01(i), ((sobol1(i) as u64) << 32) | sobol0(i) as u64, "index {i:#x}");
        }
    }

    #[test]
    fn the_byte_table_is_the_transform() {
        for i in 0..1024u64 {
            assert_eq!(sobol1_reversed_small(i), sobol1_reversed(i), "index {i}");
        }
        assert!((0..256u64).all(|i| sobol1_reversed(i) < 256));
    }

    #[test]
    fn draws_equal_the_scrambled_definition() {
        // next_1d / next_2d skip bit reversals that cancel: the same points
        // as owen_scramble(sobol0/1(i)) of the draw's index and seeds.
        let spec = spec(SamplerKind::Sobol, 64, 4);
        for index in [0u32, 1, 17, 63, 64, 200] {
            let id = SampleId::new(super::super::pixel_seed(spec.seed, 5, 6), 64, index);
            let (mut fast, mut slow) = (Sobol::start(id), Sobol::start(id));
            for d in 0..40 {
                let (i, a, b) = slow.draw();
                if d % 3 == 1 {
                    assert_eq!(fast.next_1d(), unit(owen_scramble(sobol0(i), a)));
                } else {
                    assert_eq!(fast.next_2d(), Vec2::new(unit(owen_scramble(sobol0(i), a)), unit(owen_scramble(sobol1(i), b))));
                }
            }
        }
    }

    #[test]
    fn owen_scrambling_keeps_every_net() {
        for seed in [1u32, 0xdead_beef, 77] {
            for m in [2, 5, 8] {
                let pts: Vec<Vec2> = (0..1u64 << m)
                    .map(|i| Vec2::new(unit(owen_scramble(sobol0(i), seed)), unit(owen_scramble(sobol1(i), !seed))))
                    .collect();
                assert_net(&pts, "scrambled Sobol");
            }
        }
        // And changes the points.
        assert_ne!(owen_scramble(sobol0(3), 1), sobol0(3));
    }

    #[test]
    fn every_draw_of_a_pixel_is_a_net() {
        for n in [4, 16, 64, 256] {
            let spec = spec(SamplerKind::Sobol, n, 21);
            for pattern in [&[][..], &[false, true], &[true, true, false, true]] {
                for pixel in 0..3 {
                    assert_net(&points(&spec, pixel, 0, pattern, true), "sobol 2-D draw");
                    assert_cells(&points(&spec, pixel, 0, pattern, false), n, 1, 1, "sobol 1-D draw");
                }
            }
        }
    }

    #[test]
    fn a_sample_is_a_function_of_seed_pixel_and_index() {
        assert_addressable(SamplerKind::Sobol);
    }

    #[test]
    fn converges_to_the_integral() {
        assert_unbiased(SamplerKind::Sobol);
    }

    #[test]
    fn discrepancy_below_independent() {
        assert_below_independent(SamplerKind::Sobol, 64);
    }
}
