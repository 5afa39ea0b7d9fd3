//! `multijitter` — correlated multi-jittered samples (Kensler 2013): each 2-D
//! draw is stratified on an m × k grid *and* in each coordinate on m·k strata.
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `sample_count` | integer | 4 | samples per pixel, rounded up as Mitsuba does (to r0·r1², r1 = ⌊∛n⌋, r0 = ⌈n/r1²⌉: 10 → 12, 100 → 112, 256 → 288) |
//! | `seed` | integer | 0 | seed |
//! | `jitter` | boolean | true | a random position inside each sub-stratum (false: its centre) |
//!
//! ```xml
//! <sampler type="multijitter">
//!     <integer name="sample_count" value="64"/>
//! </sampler>
//! ```
//!
//! Sample i of a pixel goes to cell (cx, cy) = π(i) of the grid (m the largest
//! divisor of the count not above its square root); inside the cell, its x
//! sub-stratum is σ(cy) and its y sub-stratum τ(cx), with σ and τ one
//! permutation each for the whole grid (the "correlated" shuffle that keeps
//! the points from clumping). 1-D draws are stratified on all n strata.
//! π, σ, τ are chosen afresh for every draw.

use super::{ONE_MINUS_EPSILON, SampleId, dim_hash, permute, uniform2};
use glam::Vec2;

/// Mitsuba's rounding: r1 = ⌊∛n⌋, r0 = ⌈n / r1²⌉, count r0·r1².
pub fn round_sample_count(n: u32) -> u32 {
    let mut r1 = (n as f64).cbrt() as u32;
    while (r1 + 1).pow(3) <= n {
        r1 += 1;
    }
    while r1 > 1 && r1.pow(3) > n {
        r1 -= 1;
    }
    let r1 = r1.max(1) as u64;
    let r0 = (n as u64).div_ceil(r1 * r1);
    (r0 * r1 * r1).min(u32::MAX as u64) as u32
}

/// Columns m and rows k of the grid of `n` cells: m the largest divisor of n
/// not above √n.
fn grid(n: u32) -> (u32, u32) {
    let mut m = (n as f64).sqrt() as u32;
    while m > 1 && n % m != 0 {
        m -= 1;
    }
    let m = m.max(1);
    (m, n / m)
}

pub(crate) struct Multijitter {
    id: SampleId,
    cols: u32,
    rows: u32,
    /// 1/cols, 1/rows and 1/count when all three are powers of two (then
    /// multiplying by them is exactly dividing), else `None`.
    inverses: Option<(f32, f32, f32)>,
    jitter: bool,
    pub(super) dim: u32,
}

impl Multijitter {
    pub fn start(id: SampleId, jitter: bool) -> Multijitter {
        let (cols, rows) = grid(id.count);
        let inverses = (cols.is_power_of_two() && rows.is_power_of_two())
            .then(|| (1.0 / cols as f32, 1.0 / rows as f32, 1.0 / id.count as f32));
        Multijitter { id, cols, rows, inverses, jitter, dim: 0 }
    }

    fn offset(&self) -> (f32, f32) {
        if self.jitter { uniform2(self.id.pixel_seed, self.id.index, self.dim) } else { (0.5, 0.5) }
    }

    #[inline(never)]
    pub fn next_1d(&mut self) -> f32 {
        let s = permute(self.id.index, self.id.count, dim_hash(self.id.pixel_seed, self.dim) as u32);
        let t = s as f32 + self.offset().0;
        let v = match self.inverses {
            Some((_, _, inv_n)) => t * inv_n,
            None => t / self.id.count as f32,
        };
        let v = v.min(ONE_MINUS_EPSILON);
        self.dim += 1;
        v
    }

    /// Inlined where `Sampler::next_2d` is (see there).
    #[inline(always)]
    pub fn next_2d(&mut self) -> Vec2 {
        // Three permutation seeds from one hash of the draw.
        let h = dim_hash(self.id.pixel_seed, self.dim);
        let s = permute(self.id.index, self.id.count, h as u32);
        let (m, k) = (self.cols, self.rows);
        // m a power of two: the cell by a mask and a shift, not a division.
        let (cx, cy) = if m.is_power_of_two() { (s & (m - 1), s >> m.trailing_zeros()) } else { (s % m, s / m) };
        let sx = permute(cy, k, (h >> 32) as u32);
        let sy = permute(cx, m, ((h >> 16) as u32).wrapping_mul(0x68bc_21eb));
        let (jx, jy) = self.offset();
        let (x, y) = match self.inverses {
            // Powers of two: multiplying by the exact inverse is the division.
            Some((inv_m, inv_k, _)) => ((cx as f32 + (sx as f32 + jx) * inv_k) * inv_m, (cy as f32 + (sy as f32 + jy) * inv_m) * inv_k),
            None => ((cx as f32 + (sx as f32 + jx) / k as f32) / m as f32, (cy as f32 + (sy as f32 + jy) / m as f32) / k as f32),
        };
        self.dim += 1;
        Vec2::new(x.min(ONE_MINUS_EPSILON), y.min(ONE_MINUS_EPSILON))
    }
}

#[cfg(test)]
mod tests {
    use super::super::testing::*;
    use super::super::*;

    const KIND: SamplerKind = SamplerKind::Multijitter { jitter: true };

    #[test]
    fn rounds_the_sample_count_as_mitsuba() {
        assert_eq!([1, 4, 8, 10, 16, 64, 100, 256].map(super::round_sample_count), [1, 4, 8, 12, 16, 64, 112, 288]);
        assert_eq!(super::grid(112), (8, 14));
        assert_eq!(super::grid(64), (8, 8));
        assert_eq!(super::round_sample_count(26), 28);
    }

    #[test]
    fn every_cell_and_every_1d_stratum_is_hit_once() {
        // 26 rounds to 28, which a second rounding would take to 36.
        for n in [4, 16, 26, 64, 112] {
            let spec = spec(KIND, n, 9);
            let (m, k) = super::grid(spec.sample_count);
            for pattern in [&[][..], &[false, true, false]] {
                for pixel in 0..3 {
                    let pts = points(&spec, pixel, 2, pattern, true);
                    assert_cells(&pts, m, k, 1, "multijitter cells");
                    assert_cells(&pts, m * k, 1, 1, "multijitter x strata");
                    assert_cells(&pts, 1, m * k, 1, "multijitter y strata");
                    assert_cells(&points(&spec, pixel, 2, pattern, false), m * k, 1, 1, "multijitter 1-D");
                }
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
