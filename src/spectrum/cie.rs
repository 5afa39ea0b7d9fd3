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

/// Linear sRGB of a spectrum given as (wavelength nm, value) pairs with
/// increasing wavelengths, linear in between and zero outside (Mitsuba's
/// irregular spectrum). A reflectance (`illuminant = false`) is seen under
/// D65, so the constant 1 gives (1, 1, 1); an emission spectrum is taken as
/// is, so the constant 1 gives the equal-energy white with Y = 1. This is the
/// conversion Mitsuba's RGB variants make when they read such a spectrum.
pub fn spectrum_to_linear_srgb(samples: &[(f32, f32)], illuminant: bool) -> Rgb {
    let Some(listed) = super::ListedSpectrum::new(samples.to_vec()) else { return Rgb::BLACK };
    let value = |lambda: f32| listed.eval(lambda);
    let mut xyz = [0.0f64; 3];
    let mut norm = 0.0f64;
    for i in 0..SAMPLES {
        let lambda = 360.0 + i as f32;
        let w = if i == 0 || i == SAMPLES - 1 { 0.5 } else { 1.0 };
        let light = if illuminant { 1.0 } else { d65(lambda) };
        let cmf = cie_xyz(lambda);
        let v = value(lambda) * light;
        for c in 0..3 {
            xyz[c] += w * (v * cmf[c]) as f64;
        }
        norm += w * (light * cmf[1]) as f64;
    }
    xyz_to_linear_srgb(xyz.map(|v| (v / norm) as f32))
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

    #[test]
    fn listed_spectra_convert_like_mitsubas_rgb_variants() {
        let flat = [(360.0, 0.5), (830.0, 0.5)];
        let r = spectrum_to_linear_srgb(&flat, false);
        assert!((0..3).all(|c| (r[c] - 0.5).abs() < 2e-3), "{r:?}");
        let e = spectrum_to_linear_srgb(&[(360.0, 1.0), (830.0, 1.0)], true);
        let ee = crate::scene::props::EQUAL_ENERGY_WHITE;
        assert!((0..3).all(|c| (e[c] - ee[c]).abs() < 2e-3), "{e:?}");
        // A red-only reflectance is red; one outside the visible is black.
        let red = spectrum_to_linear_srgb(&[(590.0, 0.0), (600.0, 1.0), (830.0, 1.0)], false);
        assert!(red[0] > 0.5 && red[2].abs() < 0.05, "{red:?}");
        // Mitsuba 3.9.1 (scalar_rgb) reads value="400:0.1, 500:0.4, 600:0.8,
        // 700:0.3" as these colours (reflectance of a diffuse BSDF, radiance of
        // a constant emitter), printed with mi.traverse.
        let list = [(400.0, 0.1), (500.0, 0.4), (600.0, 0.8), (700.0, 0.3)];
        let (r, e) = (spectrum_to_linear_srgb(&list, false), spectrum_to_linear_srgb(&list, true));
        eprintln!("reflectance {r:?}, emission {e:?}");
        for (got, want) in [(r, [0.779078, 0.582128, 0.216829]), (e, [0.90726, 0.55894, 0.187656])] {
            assert!((0..3).all(|c| (got[c] - want[c]).abs() < 3e-3), "{got:?} vs Mitsuba {want:?}");
        }
        let uv = spectrum_to_linear_srgb(&[(300.0, 1.0), (355.0, 1.0)], false);
        assert!((0..3).all(|c| uv[c] == 0.0));
    }
}
