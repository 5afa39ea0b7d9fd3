//! Sine and cosine of small angles, and the arc tangent, by polynomials.
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
//! [`atan2`] replaces the C library's `atan2f` where it runs per hit or per
//! sample (the texture coordinates of spheres, disks and cylinders, an environment
//! map's lookup, a rectangle light's solid angle): libm's took 2.9 % of the
//! caustic Cornell box's CPU time (perf), most of it for the texture
//! coordinates of the two spheres. It folds the angle into [0, π/8] with
//! one division (Cephes' `atanf` reduction: t or (t − 1)/(t + 1) of
//! t = min/max of the two magnitudes) and evaluates Cephes' degree-9 odd
//! polynomial; the error is below 2.5 ulp of the result (tested against
//! `f64` over all quadrants), and signed zeros, infinities and NaN give what
//! libm gives.
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

/// (sin 2πu, cos 2πu) for any finite `u` (turns): the nearest quarter turn
/// is folded out and the rest, within ±π/4, goes to [`sin_cos_quarter`].
/// For the warps that draw an azimuth 2πu (uniform sphere and cone,
/// microfacet normals): libm's `sincosf` took 3.7 % of a sky-lit mesh's
/// render (perf). Absolute error below 4·10⁻⁷ (tested against `f64`).
#[inline(always)]
pub fn sin_cos_turn(u: f32) -> (f32, f32) {
    let q = (u * 4.0).round();
    let (s, c) = sin_cos_quarter((u - 0.25 * q) * std::f32::consts::TAU);
    // Quarter k turns (s, c) into (s, c), (c, −s), (−s, −c), (−c, s): by
    // bit operations, not a `match`: k is random in the warps, and a jump on
    // it was mispredicted three times in four (the polynomial's lines took
    // 6 % of a sky-lit mesh's render in perf).
    let k = q as i64 as u32;
    let swap = 0u32.wrapping_sub(k & 1);
    let (sb, cb) = (s.to_bits(), c.to_bits());
    let diff = (sb ^ cb) & swap;
    let sin_sign = (k & 2) << 30;
    let cos_sign = (k.wrapping_add(1) & 2) << 30;
    (f32::from_bits((sb ^ diff) ^ sin_sign), f32::from_bits((cb ^ diff) ^ cos_sign))
}

/// atan2(y, x) in (−π, π], as `f32::atan2` to within 2.5 ulp (see the module
/// documentation).
#[inline(always)]
pub fn atan2(y: f32, x: f32) -> f32 {
    use std::f32::consts::{FRAC_PI_2, FRAC_PI_4, PI};
    let (ax, ay) = (x.abs(), y.abs());
    // Zeros, infinities and NaN: the C library's conventions. (Tested
    // before `min`/`max`, which pass over a NaN.)
    if !(ax > 0.0 && ay > 0.0 && ax < f32::INFINITY && ay < f32::INFINITY) {
        return y.atan2(x);
    }
    let (lo, hi) = (ax.min(ay), ax.max(ay));
    // t = lo/hi in (0, 1]; above tan(π/8) the angle is π/4 + atan((t − 1)/(t + 1)).
    let fold = lo > 0.414_213_57 * hi;
    let r = if fold { (lo - hi) / (lo + hi) } else { lo / hi };
    let z = r * r;
    let p = (((8.053_744_5e-2 * z - 1.387_768_6e-1) * z + 1.997_771_1e-1) * z - 3.333_294_9e-1) * z * r + r;
    // The constants' rounding errors (π/4 − f32(π/4) etc.) added to the
    // small term first: the sums below cancel up to a bit of the result.
    let mut a = if fold { FRAC_PI_4 + (p - 2.185_569_5e-8) } else { p };
    if ay > ax {
        a = FRAC_PI_2 + (-4.371_139e-8 - a);
    }
    if x.is_sign_negative() {
        a = PI + (-8.742_278e-8 - a);
    }
    a.copysign(y)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn atan2_matches_f64_within_two_and_a_half_ulp_in_every_quadrant() {
        let mut rng = crate::math::Pcg32::new(7, 3);
        let ulp = |v: f32| (f32::from_bits(v.abs().to_bits() + 1) - v.abs()).max(f32::MIN_POSITIVE);
        let mut worst = 0.0f64;
        let mut check = |y: f32, x: f32| {
            let (a, e) = (atan2(y, x), (y as f64).atan2(x as f64));
            let err = (a as f64 - e).abs() / ulp(e as f32) as f64;
            assert!(err <= 2.5, "atan2({y:e}, {x:e}) = {a:e}, f64 {e:e}: {err} ulp");
            worst = worst.max(err);
        };
        for _ in 0..2_000_000 {
            // Magnitudes over many octaves, both signs, near the axes and the diagonals.
            let m = |r: &mut crate::math::Pcg32| (r.next_f32() - 0.5) * 2f32.powi((r.next_f32() * 40.0) as i32 - 20);
            let (y, x) = (m(&mut rng), m(&mut rng));
            check(y, x);
            check(y, y * (1.0 + 1e-3 * (rng.next_f32() - 0.5)));
        }
        for k in 0..=10_000 {
            // The fold at tan(π/8) and the diagonal, swept finely.
            let t = k as f32 / 10_000.0;
            check(t, 1.0);
            check(1.0, t);
            check(-t, -1.0);
        }
        assert!(worst > 0.0);
        // The C library's conventions at zeros, infinities and NaN.
        for (y, x) in [(0.0f32, 0.0f32), (-0.0, 0.0), (0.0, -0.0), (-0.0, -0.0), (1.0, 0.0), (-1.0, -0.0), (0.0, -1.0), (-0.0, -1.0), (f32::INFINITY, 1.0), (1.0, f32::NEG_INFINITY), (f32::INFINITY, f32::INFINITY)] {
            assert_eq!(atan2(y, x).to_bits(), y.atan2(x).to_bits(), "atan2({y}, {x})");
        }
        assert!(atan2(f32::NAN, 1.0).is_nan() && atan2(1.0, f32::NAN).is_nan());
        // Exact on the diagonal.
        assert_eq!(atan2(1.0, 1.0), std::f32::consts::FRAC_PI_4);
    }

    #[test]
    fn turns_match_f64_over_whole_and_negative_turns() {
        let n = 1_000_000;
        let mut worst = 0.0f64;
        for i in 0..=n {
            for u in [i as f32 / n as f32, -(i as f32) / n as f32, 3.0 + i as f32 / n as f32] {
                let (s, c) = sin_cos_turn(u);
                let a = std::f64::consts::TAU * u as f64;
                worst = worst.max((s as f64 - a.sin()).abs()).max((c as f64 - a.cos()).abs());
            }
        }
        assert!(worst < 4e-7, "absolute error {worst:e}");
        assert_eq!(sin_cos_turn(0.0), (0.0, 1.0));
        assert_eq!(sin_cos_turn(0.25), (1.0, -0.0));
        assert_eq!(sin_cos_turn(0.5), (-0.0, -1.0));
        assert_eq!(sin_cos_turn(0.75), (-1.0, 0.0));
    }

    /// The branch-free quadrant fold gives the bits of the plain rule
    /// (signed zeros included), for negative and large turns too.
    #[test]
    fn quadrant_fold_is_the_rotation_by_quarter_turns() {
        for i in -40_000..=40_000 {
            for u in [i as f32 / 10_000.0, i as f32 / 7.0, i as f32 * 0.25] {
                let q = (u * 4.0).round();
                let (s, c) = sin_cos_quarter((u - 0.25 * q) * std::f32::consts::TAU);
                let want = match q as i64 & 3 {
                    0 => (s, c),
                    1 => (c, -s),
                    2 => (-s, -c),
                    _ => (-c, s),
                };
                let got = sin_cos_turn(u);
                assert_eq!((got.0.to_bits(), got.1.to_bits()), (want.0.to_bits(), want.1.to_bits()), "u = {u}");
            }
        }
    }

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
