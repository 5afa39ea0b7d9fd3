//! Sine and cosine of small angles by polynomials, for the sample warps.
//!
//! The warps that need a sine-cosine pair (the concentric disk, hence the
//! cosine-weighted hemisphere of every diffuse lobe) only ever ask for
//! angles within [−π/4, π/4] once their octant is folded out: there the
//! pair is two short polynomials in x² (the single-precision minimax
//! polynomials of Cephes' `sinf`/`cosf`, degree 7 and 8), with no range
//! reduction, no call into the C library and no branch. The relative error
//! is below 2·10⁻⁷ over the interval (tested against `f64`), at the level
//! of `f32` rounding, so the warps' densities stay exact to rounding.
//!
//! No parameters.

/// (sin x, cos x) for |x| ≤ π/4 (outside that interval the error grows:
/// callers fold the octant out first).
#[inline(always)]
pub fn sin_cos_quarter(x: f32) -> (f32, f32) {
    let z = x * x;
    let s = x + x * z * (-1.666_665_5e-1 + z * (8.332_161e-3 + z * -1.951_529_6e-4));
    let c = 1.0 - 0.5 * z + z * z * (4.166_664_6e-2 + z * (-1.388_731_6e-3 + z * 2.443_315_7e-5));
    (s, c)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_f64_within_rounding_on_the_quarter() {
        let quarter = std::f64::consts::FRAC_PI_4;
        let n = 1_000_000;
        let (mut worst_s, mut worst_c) = (0.0f64, 0.0f64);
        for i in 0..=n {
            let x = (-quarter + 2.0 * quarter * i as f64 / n as f64) as f32;
            let (s, c) = sin_cos_quarter(x);
            let (es, ec) = ((x as f64).sin(), (x as f64).cos());
            if es != 0.0 {
                worst_s = worst_s.max(((s as f64 - es) / es).abs());
            } else {
                assert_eq!(s, 0.0);
            }
            worst_c = worst_c.max(((c as f64 - ec) / ec).abs());
        }
        assert!(worst_s < 2e-7 && worst_c < 2e-7, "relative error sin {worst_s:e}, cos {worst_c:e}");
        // Exact at the centre; odd and even.
        assert_eq!(sin_cos_quarter(0.0), (0.0, 1.0));
        for x in [0.1f32, 0.5, 0.78] {
            let ((s, c), (sn, cn)) = (sin_cos_quarter(x), sin_cos_quarter(-x));
            assert_eq!((s, c), (-sn, cn));
        }
    }
}
