//! The polarized path type: a Mueller matrix per colour channel (RGB) or per
//! wavelength (spectral), as in Mitsuba 3's `*_polarized` variants.
//!
//! A camera path's throughput is the product of the Mueller matrices of its
//! interactions, each expressed in the canonical Stokes frames
//! ([`super::mueller::stokes_basis`]) of the directions light travels in, so
//! products chain without carrying frames. Emitted light is unpolarised: a
//! depolarizer whose first column is (L, 0, 0, 0); the radiance arriving at
//! the camera is the first column of the final product, S0 its intensity.
//! Products are taken in the integrators' order, `throughput * weight`:
//! matrices nearer the camera on the left, as light meets them last.

use super::{Rgb, Spectrum, UpliftCache};
use glam::Mat4;
use std::ops::{Add, AddAssign, Div, Mul, MulAssign};

/// `m[row][col]`, each entry an unpolarised spectrum `U`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Polarized<U>(pub [[U; 4]; 4]);

impl<U: Spectrum> Polarized<U> {
    /// `v` times the identity: a non-polarising scale (glass tint, mirror colour).
    pub fn diagonal(v: U) -> Self {
        let mut m = [[U::zero(); 4]; 4];
        for (i, row) in m.iter_mut().enumerate() {
            row[i] = v;
        }
        Polarized(m)
    }

    /// Only S0 passes, scaled by `v`: unpolarised light of intensity v·S0.
    pub fn depolarizer(v: U) -> Self {
        let mut m = [[U::zero(); 4]; 4];
        m[0][0] = v;
        Polarized(m)
    }

    /// The Mueller matrix `m` (the same for all channels) times `scale`.
    pub fn from_mat4(m: Mat4, scale: U) -> Self {
        let mut out = [[U::zero(); 4]; 4];
        for (r, row) in out.iter_mut().enumerate() {
            for (c, v) in row.iter_mut().enumerate() {
                *v = scale * m.col(c)[r];
            }
        }
        Polarized(out)
    }

}

impl<U: Spectrum> Add for Polarized<U> {
    type Output = Self;
    #[inline]
    fn add(mut self, o: Self) -> Self {
        for r in 0..4 {
            for c in 0..4 {
                self.0[r][c] += o.0[r][c];
            }
        }
        self
    }
}

impl<U: Spectrum> AddAssign for Polarized<U> {
    #[inline]
    fn add_assign(&mut self, o: Self) {
        *self = *self + o;
    }
}

impl<U: Spectrum> Mul for Polarized<U> {
    type Output = Self;
    /// The matrix product (per channel).
    #[inline]
    fn mul(self, o: Self) -> Self {
        let mut out = [[U::zero(); 4]; 4];
        for r in 0..4 {
            for c in 0..4 {
                let mut acc = U::zero();
                for k in 0..4 {
                    acc += self.0[r][k] * o.0[k][c];
                }
                out[r][c] = acc;
            }
        }
        Polarized(out)
    }
}

impl<U: Spectrum> MulAssign for Polarized<U> {
    #[inline]
    fn mul_assign(&mut self, o: Self) {
        *self = *self * o;
    }
}

impl<U: Spectrum> Mul<f32> for Polarized<U> {
    type Output = Self;
    #[inline]
    fn mul(mut self, s: f32) -> Self {
        for row in &mut self.0 {
            for v in row {
                *v *= s;
            }
        }
        self
    }
}

impl<U: Spectrum> MulAssign<f32> for Polarized<U> {
    #[inline]
    fn mul_assign(&mut self, s: f32) {
        *self = *self * s;
    }
}

impl<U: Spectrum> Div<f32> for Polarized<U> {
    type Output = Self;
    #[inline]
    fn div(self, s: f32) -> Self {
        self * (1.0 / s)
    }
}

impl<U: Spectrum> Spectrum for Polarized<U> {
    type Wavelengths = U::Wavelengths;
    type Channels = U;

    fn channels(&self) -> U {
        self.0[0][0]
    }
    fn mueller_channels(entry: impl Fn(usize, usize) -> U) -> Self {
        let mut m = [[U::zero(); 4]; 4];
        for (r, row) in m.iter_mut().enumerate() {
            for (c, v) in row.iter_mut().enumerate() {
                *v = entry(r, c);
            }
        }
        Polarized(m)
    }

    fn zero() -> Self {
        Polarized([[U::zero(); 4]; 4])
    }
    fn splat(v: f32) -> Self {
        Self::diagonal(U::splat(v))
    }
    fn sample_wavelengths(u: f32) -> Self::Wavelengths {
        U::sample_wavelengths(u)
    }
    fn hero_wavelength(wl: &Self::Wavelengths) -> Option<f32> {
        U::hero_wavelength(wl)
    }
    fn terminate_secondary(wl: &mut Self::Wavelengths) {
        U::terminate_secondary(wl)
    }
    fn from_reflectance(rgb: Rgb, wl: &Self::Wavelengths) -> Self {
        Self::diagonal(U::from_reflectance(rgb, wl))
    }
    fn from_illuminant(rgb: Rgb, wl: &Self::Wavelengths) -> Self {
        Self::depolarizer(U::from_illuminant(rgb, wl))
    }
    fn from_reflectance_cached(rgb: Rgb, cache: &UpliftCache, wl: &Self::Wavelengths) -> Self {
        Self::diagonal(U::from_reflectance_cached(rgb, cache, wl))
    }
    fn from_illuminant_cached(rgb: Rgb, cache: &UpliftCache, wl: &Self::Wavelengths) -> Self {
        Self::depolarizer(U::from_illuminant_cached(rgb, cache, wl))
    }
    fn from_unbounded(rgb: Rgb, wl: &Self::Wavelengths) -> Self {
        Self::diagonal(U::from_unbounded(rgb, wl))
    }
    fn from_function(rgb: Rgb, f: impl Fn(f32) -> f32, wl: &Self::Wavelengths) -> Self {
        Self::diagonal(U::from_function(rgb, f, wl))
    }
    /// On the diagonals only: the scalar functions BSDFs build this way
    /// (unpolarised Fresnel terms) are non-polarising scales.
    fn zip_map(self, o: Self, f: impl Fn(f32, f32) -> f32) -> Self {
        let mut out = Self::zero();
        for i in 0..4 {
            out.0[i][i] = self.0[i][i].zip_map(o.0[i][i], &f);
        }
        out
    }
    fn to_rgb(&self, wl: &Self::Wavelengths) -> Rgb {
        self.0[0][0].to_rgb(wl)
    }
    fn max_component(&self) -> f32 {
        self.0[0][0].max_component()
    }
    fn is_zero(&self) -> bool {
        self.0.iter().all(|row| row.iter().all(|v| v.is_zero()))
    }
    /// The first column: what the path makes of the unpolarised light
    /// emitters send (integrators multiply the emission's depolarizer last).
    fn stokes(&self) -> [U; 4] {
        [self.0[0][0], self.0[1][0], self.0[2][0], self.0[3][0]]
    }
    fn depolarize(self) -> Self {
        Self::depolarizer(self.0[0][0])
    }
    fn mueller(m: Mat4, scale: Self) -> Self {
        Self::from_mat4(m, scale.0[0][0])
    }
    const POLARIZED: bool = true;
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spectrum::mueller::linear_polarizer;

    type P = Polarized<Rgb>;

    #[test]
    fn products_are_mueller_products_in_path_order() {
        // Camera ← polarizer(θ) ← polarizer(0) ← unpolarised light.
        for deg in [0.0f32, 30.0, 60.0, 90.0] {
            let theta = deg.to_radians();
            let path = P::splat(1.0) * P::mueller(linear_polarizer(theta), P::splat(1.0)) * P::mueller(linear_polarizer(0.0), P::splat(1.0));
            let light = P::from_illuminant(Rgb::WHITE, &());
            let arriving = path * light;
            let malus = 0.5 * theta.cos().powi(2);
            assert!((arriving.to_rgb(&())[0] - malus).abs() < 1e-6, "{deg}°");
        }
        // A depolarizer forgets what came before; scalars commute.
        let d = (P::mueller(linear_polarizer(0.3), P::splat(1.0)) * 2.0).depolarize();
        assert!(d.0[1][0].is_zero() && (d.0[0][0].0[0] - 1.0).abs() < 1e-6);
    }
}
