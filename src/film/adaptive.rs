//! The per-pixel error estimate of adaptive sampling: which pixels of a
//! render still need samples ([`crate::render::Adaptive`]).
//!
//! An adaptive render keeps two films: every sample (image `I`), and the
//! first half of each round's samples of each pixel (image `H`, half the
//! samples). With `I = (H + O)/2` for the other half `O`, independent of
//! `H`, `I − H = (O − H)/2` has mean 0 and variance `Var(I)`: `|I − H|` is
//! an estimate, from the pixel's own samples, of the standard error of
//! the image (as Cycles' "odd samples" pass).
//!
//! The error measured is relative, per channel `c`:
//! `e_c = |I_c − H_c| / √(I_c² + 0.01)` — the measure of the relative mean
//! squared error (relMSE) that renders are compared by, so that `e²` is a
//! pixel's share of it; the 0.01 makes dark pixels (below 0.1) count by
//! their absolute error. One estimate `|I − H|` is a single draw, so a
//! pixel's error is the root mean square of `e_c` over its channels and
//! its 3 × 3 neighbourhood, and a pixel keeps sampling while that error is
//! above the threshold anywhere in its 3 × 3 neighbourhood: a pixel whose
//! own estimate happens to be small is not stopped beside noisy ones.
//!
//! Everything is computed from the developed images, themselves functions
//! of the exact film sums: the decisions, like the image, do not depend on
//! the thread count.

use super::Image;

/// The relative-error floor's square (the relMSE's `0.01`).
const DARK: f32 = 0.01;

/// The mean squared relative error of each pixel's channels between the
/// image of all samples `all` and that of half of them `half` (the same size).
pub fn squared_errors(all: &Image, half: &Image) -> Vec<f32> {
    all.pixels
        .iter()
        .zip(&half.pixels)
        .map(|(i, h)| {
            let e: f32 = (0..3).map(|c| (i[c] - h[c]).powi(2) / (i[c] * i[c] + DARK)).sum::<f32>() / 3.0;
            // A non-finite pixel (none reach the film; a guard) keeps sampling.
            if e.is_finite() { e } else { f32::MAX }
        })
        .collect()
}

/// The relative error estimate of each pixel of a `width` × `height`
/// image from its [`squared_errors`]: the root of their mean over the
/// pixel's 3 × 3 neighbourhood (clipped at the borders).
pub fn smoothed_errors(squared: &[f32], width: usize, height: usize) -> Vec<f32> {
    let mut out = vec![0.0; width * height];
    for y in 0..height {
        for x in 0..width {
            let (mut sum, mut n) = (0.0f32, 0u32);
            for ny in y.saturating_sub(1)..(y + 2).min(height) {
                for nx in x.saturating_sub(1)..(x + 2).min(width) {
                    sum += squared[ny * width + nx];
                    n += 1;
                }
            }
            out[y * width + x] = (sum / n as f32).sqrt();
        }
    }
    out
}

/// Which pixels keep sampling: those that are `active` and have a pixel of
/// their 3 × 3 neighbourhood whose error (from [`smoothed_errors`]) is
/// above `threshold`.
pub fn still_active(errors: &[f32], active: &[bool], width: usize, height: usize, threshold: f32) -> Vec<bool> {
    let mut out = vec![false; width * height];
    for y in 0..height {
        for x in 0..width {
            let i = y * width + x;
            if !active[i] {
                continue;
            }
            out[i] = (y.saturating_sub(1)..(y + 2).min(height))
                .any(|ny| (x.saturating_sub(1)..(x + 2).min(width)).any(|nx| errors[ny * width + nx] > threshold));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spectrum::Rgb;

    #[test]
    fn the_error_is_relative_with_a_floor_for_dark_pixels() {
        let all = Image::new(2, 1, vec![Rgb::new(1.0, 1.0, 1.0), Rgb::new(0.0, 0.0, 0.0)]);
        let half = Image::new(2, 1, vec![Rgb::new(1.1, 1.1, 1.1), Rgb::new(0.01, 0.01, 0.01)]);
        let e = squared_errors(&all, &half);
        assert!((e[0] - 0.01 / 1.01).abs() < 1e-5, "{e:?}");
        assert!((e[1] - 0.0001 / 0.01).abs() < 1e-5, "{e:?}");
    }

    #[test]
    fn a_noisy_pixel_keeps_its_neighbours_active() {
        let (w, h) = (5, 5);
        let mut sq = vec![0.0; w * h];
        sq[2 * w + 2] = 9.0 * 0.25; // smoothed over 3 × 3: an error of 0.5
        let errors = smoothed_errors(&sq, w, h);
        assert!((errors[2 * w + 2] - 0.5).abs() < 1e-6);
        assert!((errors[w + 1] - 0.5).abs() < 1e-6);
        assert_eq!(errors[0], 0.0);
        let active = still_active(&errors, &vec![true; w * h], w, h, 0.1);
        // Errors reach 1 pixel from the centre; activity another pixel.
        for y in 0..h {
            for x in 0..w {
                assert!(active[y * w + x], "({x}, {y})");
            }
        }
        let mut sq = vec![0.0; 7 * 7];
        sq[3 * 7 + 3] = 9.0;
        let errors = smoothed_errors(&sq, 7, 7);
        let active = still_active(&errors, &vec![true; 49], 7, 7, 0.1);
        assert!(active[3 * 7 + 1] && active[3 * 7 + 5] && !active[3 * 7] && !active[0]);
        // A stopped pixel stays stopped.
        let mut was = vec![true; 49];
        was[3 * 7 + 3] = false;
        assert!(!still_active(&errors, &was, 7, 7, 0.1)[3 * 7 + 3]);
    }
}
