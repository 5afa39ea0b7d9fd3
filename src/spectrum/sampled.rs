//! Spectral rendering: a path carries radiance at four wavelengths.
//!
//! Hero-wavelength sampling (A. Wilkie et al., "Hero Wavelength Spectral
//! Sampling", EGSR 2014): the first wavelength λ₀ is drawn from u, the
//! others from u + i/4 (mod 1), each through the same importance density
//! over 360–830 nm that Mitsuba's spectral variants use (Radziszewski et al.,
//! "An Improved Technique for Full Spectral Rendering", 2009):
//! p(λ) ∝ 1/cosh²(0.0072 (λ − 538)). The film turns a path's estimate into
//! XYZ = (1/4) Σᵢ L(λᵢ) (x̄, ȳ, z̄)(λᵢ) / p(λᵢ) / ∫ȳ, then into linear sRGB.
//!
//! A dispersive interface can send only one wavelength along the sampled
//! direction; [`Spectrum::terminate_secondary`] then keeps λ₀ alone with
//! density p(λ₀)/4, i.e. the path becomes a one-wavelength estimate, which
//! is unbiased because λ₀ alone is distributed by p.
//!
//! RGB inputs are uplifted by the Jakob–Hanika model (`uplift.rs`).

use super::cie::{cie_xyz, d65_unit, xyz_to_linear_srgb, y_normalization};
use super::uplift::RgbUplift;
use super::{Rgb, Spectrum, UpliftCache};
use glam::Vec4;
use std::ops::{Add, AddAssign, Div, Mul, MulAssign};

/// Wavelengths per path.
pub const N: usize = 4;

/// Where the sampling density is defined (nm).
const LAMBDA_MIN: f32 = 360.0;
const LAMBDA_MAX: f32 = 830.0;

/// Draws a wavelength from the visible-importance density (u in [0, 1)).
pub fn sample_visible(u: f32) -> f32 {
    (538.0 - 138.888_89 * (0.856_910_6 - 1.827_502 * u).atanh()).clamp(LAMBDA_MIN, LAMBDA_MAX)
}

/// The density of [`sample_visible`] (per nm).
pub fn pdf_visible(lambda: f32) -> f32 {
    if !(LAMBDA_MIN..=LAMBDA_MAX).contains(&lambda) {
        return 0.0;
    }
    let c = (0.0072 * (lambda - 538.0)).cosh();
    0.003_939_804 / (c * c)
}

/// The wavelengths (nm) of one path and their densities; a density of 0
/// marks a wavelength dropped at a dispersive interface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Wavelengths {
    pub lambda: [f32; N],
    pub pdf: [f32; N],
}

impl Wavelengths {
    pub fn sample(u: f32) -> Wavelengths {
        let mut w = Wavelengths { lambda: [0.0; N], pdf: [0.0; N] };
        for i in 0..N {
            let ui = (u + i as f32 / N as f32).fract();
            w.lambda[i] = sample_visible(ui);
            w.pdf[i] = pdf_visible(w.lambda[i]);
        }
        w
    }

    pub fn secondary_terminated(&self) -> bool {
        self.pdf[1..].iter().all(|&p| p == 0.0)
    }
}

/// Radiance (or throughput) at the path's four wavelengths.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sampled(pub Vec4);

impl Sampled {
    fn from_fn(f: impl Fn(usize) -> f32) -> Sampled {
        Sampled(Vec4::new(f(0), f(1), f(2), f(3)))
    }
}

impl Add for Sampled {
    type Output = Sampled;
    #[inline]
    fn add(self, o: Sampled) -> Sampled {
        Sampled(self.0 + o.0)
    }
}
impl AddAssign for Sampled {
    #[inline]
    fn add_assign(&mut self, o: Sampled) {
        self.0 += o.0;
    }
}
impl Mul for Sampled {
    type Output = Sampled;
    #[inline]
    fn mul(self, o: Sampled) -> Sampled {
        Sampled(self.0 * o.0)
    }
}
impl MulAssign for Sampled {
    #[inline]
    fn mul_assign(&mut self, o: Sampled) {
        self.0 *= o.0;
    }
}
impl Mul<f32> for Sampled {
    type Output = Sampled;
    #[inline]
    fn mul(self, o: f32) -> Sampled {
        Sampled(self.0 * o)
    }
}
impl MulAssign<f32> for Sampled {
    #[inline]
    fn mul_assign(&mut self, o: f32) {
        self.0 *= o;
    }
}
impl Div<f32> for Sampled {
    type Output = Sampled;
    #[inline]
    fn div(self, o: f32) -> Sampled {
        Sampled(self.0 * (1.0 / o))
    }
}

impl Spectrum for Sampled {
    type Wavelengths = Wavelengths;
    type Channels = Self;

    #[inline]
    fn channels(&self) -> Self {
        *self
    }
    #[inline]
    fn mueller_channels(entry: impl Fn(usize, usize) -> Self) -> Self {
        entry(0, 0)
    }

    #[inline]
    fn zero() -> Self {
        Sampled(Vec4::ZERO)
    }
    #[inline]
    fn splat(v: f32) -> Self {
        Sampled(Vec4::splat(v))
    }
    fn sample_wavelengths(u: f32) -> Wavelengths {
        Wavelengths::sample(u)
    }
    #[inline]
    fn hero_wavelength(wl: &Wavelengths) -> Option<f32> {
        Some(wl.lambda[0])
    }
    fn terminate_secondary(wl: &mut Wavelengths) {
        if wl.secondary_terminated() {
            return;
        }
        for p in &mut wl.pdf[1..] {
            *p = 0.0;
        }
        wl.pdf[0] /= N as f32;
    }
    fn from_reflectance(rgb: Rgb, wl: &Wavelengths) -> Self {
        let s = RgbUplift::get().reflectance(rgb);
        Sampled::from_fn(|i| s.eval(wl.lambda[i]))
    }
    fn from_illuminant(rgb: Rgb, wl: &Wavelengths) -> Self {
        let (scale, s) = RgbUplift::get().illuminant(rgb);
        Sampled::from_fn(|i| scale * s.eval(wl.lambda[i]) * d65_unit(wl.lambda[i]))
    }
    #[inline]
    fn from_reflectance_cached(rgb: Rgb, cache: &UpliftCache, wl: &Wavelengths) -> Self {
        let s = cache.reflectance(rgb);
        Sampled::from_fn(|i| s.eval(wl.lambda[i]))
    }
    #[inline]
    fn from_illuminant_cached(rgb: Rgb, cache: &UpliftCache, wl: &Wavelengths) -> Self {
        let (scale, s) = cache.illuminant(rgb);
        Sampled::from_fn(|i| scale * s.eval(wl.lambda[i]) * d65_unit(wl.lambda[i]))
    }
    fn from_unbounded(rgb: Rgb, wl: &Wavelengths) -> Self {
        let (scale, s) = RgbUplift::get().unbounded(rgb);
        Sampled::from_fn(|i| scale * s.eval(wl.lambda[i]))
    }
    fn from_function(_: Rgb, f: impl Fn(f32) -> f32, wl: &Wavelengths) -> Self {
        Sampled::from_fn(|i| f(wl.lambda[i]))
    }
    #[inline]
    fn zip_map(self, o: Self, f: impl Fn(f32, f32) -> f32) -> Self {
        let (a, b) = (self.0.to_array(), o.0.to_array());
        Sampled::from_fn(|i| f(a[i], b[i]))
    }
    fn to_rgb(&self, wl: &Wavelengths) -> Rgb {
        let v = self.0.to_array();
        let mut xyz = [0.0f32; 3];
        for i in 0..N {
            if wl.pdf[i] > 0.0 && v[i] != 0.0 {
                let c = cie_xyz(wl.lambda[i]);
                let w = v[i] / wl.pdf[i];
                for k in 0..3 {
                    xyz[k] += c[k] * w;
                }
            }
        }
        let scale = y_normalization() / N as f32;
        xyz_to_linear_srgb(xyz.map(|x| x * scale))
    }
    #[inline]
    fn max_component(&self) -> f32 {
        self.0.max_element()
    }
    #[inline]
    fn channel_mean(&self) -> f32 {
        self.0.element_sum() / N as f32
    }
    #[inline]
    fn is_zero(&self) -> bool {
        self.0 == Vec4::ZERO
    }
    #[inline]
    fn to_channels4(&self) -> Option<[f32; 4]> {
        Some(self.0.to_array())
    }
    #[inline]
    fn from_channels4(c: [f32; 4]) -> Option<Self> {
        Some(Sampled(Vec4::from_array(c)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn visible_density_integrates_to_one_and_matches_its_sampler() {
        let total: f32 = (0..4700).map(|i| pdf_visible(360.0 + (i as f32 + 0.5) * 0.1) * 0.1).sum();
        assert!((total - 1.0).abs() < 2e-3, "{total}");
        // The sampler's CDF at λ equals the integral of the density up to λ.
        for u in [0.1f32, 0.3, 0.5, 0.7, 0.9] {
            let l = sample_visible(u);
            let cdf: f32 = (0..1000).map(|i| pdf_visible(360.0 + (i as f32 + 0.5) * (l - 360.0) / 1000.0) * (l - 360.0) / 1000.0).sum();
            assert!((cdf - u).abs() < 2e-3, "u {u}: λ {l}, cdf {cdf}");
        }
        // Mitsuba 3.9.1's sample_rgb_spectrum(0.5) returns 545.903 nm.
        assert!((sample_visible(0.5) - 545.903).abs() < 1e-2);
    }

    #[test]
    fn white_light_and_white_surfaces_render_white() {
        // Averaged over many wavelength samples, RGB white light off a white
        // (and a grey) surface comes back as that RGB.
        for albedo in [1.0f32, 0.5] {
            let mut sum = Rgb::BLACK;
            let n = 20_000;
            for k in 0..n {
                let wl = Wavelengths::sample((k as f32 + 0.5) / n as f32);
                let l = Sampled::from_illuminant(Rgb::WHITE, &wl) * Sampled::from_reflectance(Rgb::new(albedo, albedo, albedo), &wl);
                sum += l.to_rgb(&wl);
            }
            let mean = sum * (1.0 / n as f32);
            for c in mean.0 {
                assert!((c - albedo).abs() < 5e-3 * albedo.max(0.1), "albedo {albedo}: {mean:?}");
            }
        }
    }

    #[test]
    fn coloured_reflectance_under_white_light_keeps_its_colour() {
        let rgb = Rgb::new(0.57, 0.043, 0.044); // the Cornell box's red wall
        let mut sum = Rgb::BLACK;
        let n = 20_000;
        for k in 0..n {
            let wl = Wavelengths::sample((k as f32 + 0.5) / n as f32);
            sum += (Sampled::from_illuminant(Rgb::WHITE, &wl) * Sampled::from_reflectance(rgb, &wl)).to_rgb(&wl);
        }
        let mean = sum * (1.0 / n as f32);
        for k in 0..3 {
            assert!((mean.0[k] - rgb.0[k]).abs() < 6e-3, "{mean:?} vs {rgb:?}");
        }
    }

    #[test]
    fn terminating_secondaries_keeps_the_estimate_unbiased() {
        // A constant spectrum of 1 renders Y = 1 whether or not the path kept
        // all four wavelengths.
        let (mut all, mut hero) = ([0.0f32; 3], [0.0f32; 3]);
        let n = 40_000;
        for k in 0..n {
            let mut wl = Wavelengths::sample((k as f32 + 0.5) / n as f32);
            let a = Sampled::splat(1.0).to_rgb(&wl);
            Sampled::terminate_secondary(&mut wl);
            assert!(wl.secondary_terminated());
            let h = Sampled::splat(1.0).to_rgb(&wl);
            for c in 0..3 {
                all[c] += a.0[c] / n as f32;
                hero[c] += h.0[c] / n as f32;
            }
        }
        for c in 0..3 {
            assert!((all[c] - hero[c]).abs() < 1e-2 * all[c].abs().max(0.1), "{all:?} vs {hero:?}");
        }
    }
}
