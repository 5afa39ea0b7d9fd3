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
//!
//! Most matrices on a path are scalars (tints, unpolarised Fresnel scales)
//! or depolarizers (diffuse surfaces, emission), so each value remembers
//! which of these forms it has and products skip the entries known to be
//! zero: a product with a depolarizer costs 4 channel multiplications
//! instead of 64.

use super::{Rgb, Spectrum, UpliftCache};
use glam::Mat4;
use std::ops::{Add, AddAssign, Div, Mul, MulAssign};

/// `m[row][col]`, each entry an unpolarised spectrum `U`, and the form of
/// the matrix (which entries may be non-zero).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Polarized<U>(pub [[U; 4]; 4], Form);

/// What is known about a Mueller matrix's entries.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Form {
    /// v·I: every diagonal entry equal, the rest zero.
    Scalar,
    /// Only m₀₀ may be non-zero.
    Depolarizer,
    /// Anything.
    General,
}

impl<U: Spectrum> Polarized<U> {
    /// `v` times the identity: a non-polarising scale (glass tint, mirror colour).
    pub fn diagonal(v: U) -> Self {
        let mut m = [[U::zero(); 4]; 4];
        for (i, row) in m.iter_mut().enumerate() {
            row[i] = v;
        }
        Polarized(m, Form::Scalar)
    }

    /// Only S0 passes, scaled by `v`: unpolarised light of intensity v·S0.
    pub fn depolarizer(v: U) -> Self {
        let mut m = [[U::zero(); 4]; 4];
        m[0][0] = v;
        Polarized(m, Form::Depolarizer)
    }

    pub fn form(&self) -> Form {
        self.1
    }

    /// Every entry times the channel values `v` (a scalar matrix's product).
    #[inline]
    fn scaled(mut self, v: U) -> Self {
        match self.1 {
            Form::Scalar => {
                let d = self.0[0][0] * v;
                for i in 0..4 {
                    self.0[i][i] = d;
                }
            }
            Form::Depolarizer => self.0[0][0] *= v,
            Form::General => {
                for row in &mut self.0 {
                    for e in row {
                        *e *= v;
                    }
                }
            }
        }
        self
    }

    /// The Mueller matrix `m` (the same for all channels) times `scale`.
    pub fn from_mat4(m: Mat4, scale: U) -> Self {
        let mut out = [[U::zero(); 4]; 4];
        for (r, row) in out.iter_mut().enumerate() {
            for (c, v) in row.iter_mut().enumerate() {
                *v = scale * m.col(c)[r];
            }
        }
        Polarized(out, Form::General)
    }

}

impl<U: Spectrum> Add for Polarized<U> {
    type Output = Self;
    #[inline]
    fn add(mut self, o: Self) -> Self {
        match (self.1, o.1) {
            (Form::Depolarizer, Form::Depolarizer) => self.0[0][0] += o.0[0][0],
            (Form::Scalar, Form::Scalar) => {
                let d = self.0[0][0] + o.0[0][0];
                for i in 0..4 {
                    self.0[i][i] = d;
                }
            }
            _ => {
                for r in 0..4 {
                    for c in 0..4 {
                        self.0[r][c] += o.0[r][c];
                    }
                }
                self.1 = Form::General;
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
    /// The matrix product (per channel), skipping known zeros.
    #[inline]
    fn mul(self, o: Self) -> Self {
        let mut out = [[U::zero(); 4]; 4];
        match (self.1, o.1) {
            (_, Form::Scalar) => return self.scaled(o.0[0][0]),
            (Form::Scalar, _) => return o.scaled(self.0[0][0]),
            (Form::Depolarizer, Form::Depolarizer) => return Self::depolarizer(self.0[0][0] * o.0[0][0]),
            // Only column 0 of the right factor is non-zero.
            (Form::General, Form::Depolarizer) => {
                for r in 0..4 {
                    out[r][0] = self.0[r][0] * o.0[0][0];
                }
            }
            // Only row 0 of the left factor is non-zero.
            (Form::Depolarizer, Form::General) => {
                for c in 0..4 {
                    out[0][c] = self.0[0][0] * o.0[0][c];
                }
            }
            (Form::General, Form::General) => {
                for r in 0..4 {
                    for c in 0..4 {
                        let mut acc = self.0[r][0] * o.0[0][c];
                        for k in 1..4 {
                            acc += self.0[r][k] * o.0[k][c];
                        }
                        out[r][c] = acc;
                    }
                }
            }
        }
        Polarized(out, Form::General)
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
    fn mul(self, s: f32) -> Self {
        self.scaled(U::splat(s))
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
        Polarized(m, Form::General)
    }

    fn zero() -> Self {
        Self::depolarizer(U::zero())
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
        out.1 = if self.1 == Form::Scalar && o.1 == Form::Scalar { Form::Scalar } else { Form::General };
        out
    }
    fn to_rgb(&self, wl: &Self::Wavelengths) -> Rgb {
        self.0[0][0].to_rgb(wl)
    }
    fn max_component(&self) -> f32 {
        self.0[0][0].max_component()
    }
    fn channel_mean(&self) -> f32 {
        self.0[0][0].channel_mean()
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

    /// The same matrix declared general, so products take the full path.
    fn general(p: P) -> P {
        Polarized(p.0, Form::General)
    }

    #[test]
    fn products_of_special_forms_equal_full_products() {
        let mut rng = crate::math::Pcg32::new(3, 5);
        let mut rgb = || Rgb::new(rng.next_f32() - 0.3, rng.next_f32(), rng.next_f32() + 0.2);
        for _ in 0..200 {
            let entries: Vec<Rgb> = (0..16).map(|_| rgb()).collect();
            let full = P::mueller_channels(|r, c| entries[4 * r + c]);
            let forms = [P::diagonal(rgb()), P::depolarizer(rgb()), full, P::zero()];
            for a in forms {
                for b in forms {
                    let fast = a * b + b * 0.5;
                    let slow = general(a) * general(b) + general(b) * 0.5;
                    for r in 0..4 {
                        for c in 0..4 {
                            for k in 0..3 {
                                assert!((fast.0[r][c][k] - slow.0[r][c][k]).abs() < 1e-5, "{:?} × {:?}: entry ({r},{c})", a.form(), b.form());
                            }
                        }
                    }
                    // Special forms stay special only when they must be.
                    if a.form() == Form::Depolarizer && b.form() == Form::Depolarizer {
                        assert_eq!((a * b).form(), Form::Depolarizer);
                    }
                }
            }
        }
    }
}
