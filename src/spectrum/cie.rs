//! Colorimetry for the spectral film: the CIE 1931 2° standard observer
//! (x̄, ȳ, z̄), illuminant D65 (the white of sRGB) and the XYZ ↔ linear sRGB
//! matrices (IEC 61966-2-1, Rec. 709 primaries, D65 white).
//!
//! A spectral radiance L(λ) has tristimulus values X = k∫L x̄ dλ (Y, Z alike)
//! with k = 1/∫ȳ dλ, so that a constant spectrum of value 1 has Y = 1, as in
//! Mitsuba's spectral variants. The tables (`cie_data.rs`) run 360–830 nm.

use super::cie_data::{CIE_X, CIE_Y, CIE_Z, D65, LAMBDA_MAX, LAMBDA_MIN, SAMPLES};
use super::Rgb;
use std::sync::OnceLock;

pub use super::cie_data::{LAMBDA_MAX as CIE_MAX, LAMBDA_MIN as CIE_MIN};

/// Linear interpolation in a 1 nm table; zero outside 360–830 nm.
#[inline]
fn lerp_table(table: &[f32; SAMPLES], lambda: f32) -> f32 {
    if !(LAMBDA_MIN..=LAMBDA_MAX).contains(&lambda) {
        return 0.0;
    }
    let x = lambda - LAMBDA_MIN;
    let i = (x as usize).min(SAMPLES - 2);
    let t = x - i as f32;
    table[i] + (table[i + 1] - table[i]) * t
}

/// (x̄, ȳ, z̄) at `lambda` (nm).
#[inline]
pub fn cie_xyz(lambda: f32) -> [f32; 3] {
    [lerp_table(&CIE_X, lambda), lerp_table(&CIE_Y, lambda), lerp_table(&CIE_Z, lambda)]
}

/// D65's relative spectral power at `lambda` (nm), 100 at 560 nm.
#[inline]
pub fn d65(lambda: f32) -> f32 {
    lerp_table(&D65, lambda)
}

/// Integrals over 360–830 nm by the trapezoid rule on the 1 nm tables.
struct Integrals {
    /// ∫ȳ dλ.
    y: f64,
    /// ∫D65·ȳ dλ / ∫ȳ dλ: the luminance of the D65 table (≈ 100).
    d65_y: f64,
}

fn integrals() -> &'static Integrals {
    static I: OnceLock<Integrals> = OnceLock::new();
    I.get_or_init(|| {
        let trapezoid = |f: &dyn Fn(usize) -> f64| (0..SAMPLES).map(|i| if i == 0 || i == SAMPLES - 1 { 0.5 } else { 1.0 } * f(i)).sum::<f64>();
        let y = trapezoid(&|i| CIE_Y[i] as f64);
        let d65_y = trapezoid(&|i| (D65[i] * CIE_Y[i]) as f64) / y;
        Integrals { y, d65_y }
    })
}

/// 1/∫ȳ dλ: scales ∫L x̄ dλ so that L = 1 has Y = 1.
pub fn y_normalization() -> f32 {
    (1.0 / integrals().y) as f32
}

/// D65 scaled to unit luminance (Y = 1): the spectrum of RGB white light.
#[inline]
pub fn d65_unit(lambda: f32) -> f32 {
    d65(lambda) * d65_normalization()
}

/// 1/Y of the D65 table.
pub fn d65_normalization() -> f32 {
    (1.0 / integrals().d65_y) as f32
}

/// XYZ → linear sRGB (Rec. 709 primaries, D65 white).
pub fn xyz_to_linear_srgb(xyz: [f32; 3]) -> Rgb {
    let [x, y, z] = xyz;
    Rgb::new(
        3.240_479 * x - 1.537_150 * y - 0.498_535 * z,
        -0.969_256 * x + 1.875_991 * y + 0.041_556 * z,
        0.055_648 * x - 0.204_043 * y + 1.057_311 * z,
    )
}

/// Linear sRGB → XYZ, the inverse of [`xyz_to_linear_srgb`].
pub fn linear_srgb_to_xyz(rgb: Rgb) -> [f32; 3] {
    let [r, g, b] = rgb.0;
    [
        0.412_453 * r + 0.357_580 * g + 0.180_423 * b,
        0.212_671 * r + 0.715_160 * g + 0.072_169 * b,
        0.019_334 * r + 0.119_193 * g + 0.950_227 * b,
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tables_match_the_standard() {
        // ȳ peaks at 555 nm with value 1; ∫ȳ ≈ 106.857 (the CIE's 1 nm
        // table; 5 nm interpolation moves it by < 0.1 %).
        assert_eq!(cie_xyz(555.0)[1], 1.0);
        assert!((1.0 / y_normalization() as f64 - 106.857).abs() < 0.1, "{}", 1.0 / y_normalization());
        assert!((d65(560.0) - 100.0).abs() < 1e-4);
        // D65's white point: x = 0.3127, y = 0.3290.
        let mut xyz = [0.0f64; 3];
        for l in 360..=830 {
            let c = cie_xyz(l as f32);
            for k in 0..3 {
                xyz[k] += (d65(l as f32) * c[k]) as f64;
            }
        }
        let sum = xyz[0] + xyz[1] + xyz[2];
        assert!((xyz[0] / sum - 0.3127).abs() < 2e-4 && (xyz[1] / sum - 0.3290).abs() < 2e-4, "{:?}", [xyz[0] / sum, xyz[1] / sum]);
        assert_eq!(cie_xyz(300.0), [0.0; 3]);
        assert_eq!(d65(900.0), 0.0);
    }

    #[test]
    fn unit_d65_is_srgb_white() {
        let mut xyz = [0.0f32; 3];
        for l in 360..=830 {
            let c = cie_xyz(l as f32);
            for k in 0..3 {
                xyz[k] += d65_unit(l as f32) * c[k] * y_normalization();
            }
        }
        let rgb = xyz_to_linear_srgb(xyz);
        for c in rgb.0 {
            assert!((c - 1.0).abs() < 3e-3, "{rgb:?}");
        }
    }

    #[test]
    fn matrices_are_inverse() {
        for rgb in [Rgb::new(1.0, 0.0, 0.0), Rgb::new(0.2, 0.5, 0.9), Rgb::new(1.0, 1.0, 1.0)] {
            let back = xyz_to_linear_srgb(linear_srgb_to_xyz(rgb));
            for k in 0..3 {
                assert!((back.0[k] - rgb.0[k]).abs() < 1e-5, "{rgb:?} -> {back:?}");
            }
        }
    }
}
