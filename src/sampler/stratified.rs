//! `stratified` — jittered stratified samples: every dimension of a pixel's
//! samples is cut into strata, each hit by exactly one sample.
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `sample_count` | integer | 4 | samples per pixel, rounded up to a square (as Mitsuba: 10 → 16) |
//! | `seed` | integer | 0 | seed |
//! | `jitter` | boolean | true | a random position inside each stratum (false: its centre) |
//! | `dimension` | integer | unlimited | draws that are stratified (Mitsuba 0.6's parameter); later draws are independent |
//!
//! ```xml
//! <sampler type="stratified">
//!     <integer name="sample_count" value="16"/>
//!     <boolean name="jitter" value="true"/>
//! </sampler>
//! ```
//!
//! With n = r² samples, a 1-D draw puts sample i in stratum π(i) of n, a 2-D
//! draw in cell π(i) of an r × r grid, where π is a random permutation of the
//! pixel's samples chosen afresh for each draw (so the dimensions are not
//! correlated with each other).

use super::{SampleId, dim_hash, permute, uniform2};
use glam::Vec2;

/// `n` rounded up to a square (Mitsuba's rule).
pub fn round_sample_count(n: u32) -> u32 {
    let r = resolution(n);
    r * r
}

/// The side of the smallest square grid with at least `n` cells.
fn resolution(n: u32) -> u32 {
    let mut r = (n as f64).sqrt() as u32;
    while r * r < n {
        r += 1;
    }
    while r > 1 && (r - 1) * (r - 1) >= n {
        r -= 1;
    }
    r.max(1)
}

pub(crate) struct Stratified {
    id: SampleId,
    res: u32,
    jitter: bool,
    dimension: u32,
    pub(super) dim: u32,
}

impl Stratified {
    pub fn start(id: SampleId, jitter: bool, dimension: u32) -> Stratified {
        Stratified { id, res: resolution(id.count), jitter, dimension, dim: 0 }
    }

    fn offset(&self) -> (f32, f32) {
        if self.jitter { uniform2(self.id.pixel_seed, self.id.index, self.dim) } else { (0.5, 0.5) }
    }

    #[inline(never)]
    pub fn next_1d(&mut self) -> f32 {
        let d = self.dim;
        let v = if d >= self.dimension {
            uniform2(self.id.pixel_seed, self.id.index, d).0
        } else {
            let s = permute(self.id.index, self.id.count, dim_hash(self.id.pixel_seed, d) as u32);
            ((s as f32 + self.offset().0) / self.id.count as f32).min(super::ONE_MINUS_EPSILON)
        };
        self.dim += 1;
        v
    }

    #[inline(never)]
    pub fn next_2d(&mut self) -> Vec2 {
        let d = self.dim;
        let v = if d >= self.dimension {
            let (x, y) = uniform2(self.id.pixel_seed, self.id.index, d);
            Vec2::new(x, y)
        } else {
            // Cells of the r × r grid; with a count that is not a square (a
            // sample count set past the loader) the last row is partial.
            let s = permute(self.id.index, self.id.count, dim_hash(self.id.pixel_seed, d) as u32);
            let (cx, cy) = (s % self.res, s / self.res);
            let rows = self.id.count.div_ceil(self.res);
            let (jx, jy) = self.offset();
            Vec2::new(
                ((cx as f32 + jx) / self.res as f32).min(super::ONE_MINUS_EPSILON),
                ((cy as f32 + jy) / rows as f32).min(super::ONE_MINUS_EPSILON),
            )
        };
        self.dim += 1;
        v
    }
}

#[cfg(test)]
mod tests {
    use super::super::testing::*;
    use super::super::*;

    const KIND: SamplerKind = SamplerKind::Stratified { jitter: true, dimension: u32::MAX };

    #[test]
    fn rounds_the_sample_count_up_to_a_square() {
        assert_eq!([1, 2, 4, 5, 10, 16, 17, 1000].map(super::round_sample_count), [1, 4, 4, 9, 16, 16, 25, 1024]);
    }

    #[test]
    fn every_stratum_is_hit_once_in_every_draw() {
        for n in [4, 16, 25, 64] {
            let spec = spec(KIND, n, 5);
            let r = super::resolution(n);
            for pattern in [&[][..], &[false, true], &[true, false, true, true, false]] {
                for pixel in 0..3 {
                    let pts = points(&spec, pixel, 1, pattern, true);
                    assert_cells(&pts, r, r, 1, "stratified 2-D");
                    let pts = points(&spec, pixel, 1, pattern, false);
                    assert_cells(&pts, n, 1, 1, "stratified 1-D");
                }
            }
        }
    }

    #[test]
    fn without_jitter_samples_sit_at_stratum_centres() {
        let spec = spec(SamplerKind::Stratified { jitter: false, dimension: u32::MAX }, 16, 1);
        for p in points(&spec, 0, 0, &[], true) {
            assert_eq!(((p * 4.0).fract() - 0.5).abs().max_element(), 0.0, "{p}");
        }
    }

    #[test]
    fn draws_past_dimension_are_independent() {
        let spec = spec(SamplerKind::Stratified { jitter: true, dimension: 2 }, 16, 1);
        assert_cells(&points(&spec, 0, 0, &[false], true), 4, 4, 1, "second draw");
        // The third draw is independent: 16 uniform points almost surely miss a cell.
        let missed = (0..20).filter(|&p| hits(&points(&spec, p, 0, &[false, true], true), 4, 4).contains(&0));
        assert!(missed.count() >= 18);
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
