//! `envmap` — an environment map: radiance arriving from every direction,
//! read from a latitude-longitude (equirectangular) image, as Mitsuba 3's
//! `envmap`.
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `filename` | string | — | radiance image: OpenEXR, Radiance RGBE (`.hdr`), PFM, PNG or JPEG (8-bit images are sRGB-decoded) |
//! | `scale` | float | 1 | factor on the image's radiance |
//! | `to_world` | transform | identity | orientation of the map (a rotation) |
//! | `mis_compensation` | boolean | false | accepted for Mitsuba compatibility (sampling is not compensated) |
//!
//! **Mapping** (Mitsuba's): a direction d = (x, y, z) in the map's frame has
//! u = atan2(x, −z) / 2π along the image's width and v = acos(y) / π down
//! its height, so +Y is up (the image's top row), the image's centre column
//! looks along +Z, and u grows towards +X… i.e. d = (sin φ sin θ, cos θ,
//! −cos φ sin θ) with φ = 2πu, θ = πv. As in Mitsuba, texel column i is
//! centred at u = (i + ½)/W (wrapping around), while rows are spread so that
//! the first and last rows sit exactly at the poles (row j at θ = jπ/(H−1));
//! radiance is interpolated bilinearly between them.
//!
//! **Sampling**: a 2-D piecewise-constant distribution over the W × (H−1)
//! cells between texel centres, each weighted by its mean luminance times
//! its solid angle (∫ sin θ dθ dφ), chosen by a marginal distribution over
//! rows and a conditional one within the row; inside a cell the direction
//! is uniform in φ and in cos θ, so the density per unit solid angle is the
//! cell's probability over its solid angle — finite at the poles.
//!
//! **Spectral modes**: each texel is uplifted as an illuminant, as Mitsuba's
//! envmap does it: colour c becomes 2 max(c) · s(λ) · D65(λ), with s the
//! smooth reflectance spectrum of c / (2 max c) (largest channel ½, where
//! the fits are smooth; uplifting c / max c instead, as Snell's `constant`
//! does, puts the shape at the gamut's edge); and, as Mitsuba does, the
//! shapes s and the scales are interpolated bilinearly *separately* and
//! multiplied, so between texels of different brightness the spectral
//! image is not the RGB image's interpolation (Mitsuba's spectral and RGB
//! renders of one map differ there, by 15 % in blue at a sky/ground edge of
//! the test map; Snell follows Mitsuba's spectral variant). Emission is
//! unpolarized.
//! Light paths (`ptracer`, `bdpt`) start on it from the disk of the scene's
//! bounding sphere facing a direction it samples ([`super::Emitter::sample_ray`]).
//!
//! ```xml
//! <emitter type="envmap">
//!     <string name="filename" value="textures/museum.exr"/>
//!     <float name="scale" value="2"/>
//!     <transform name="to_world"><rotate y="1" angle="90"/></transform>
//! </emitter>
//! ```

use super::EmitterSample;
use crate::math::sampling::DiscreteDistribution;
use crate::math::{PI, Transform};
use crate::spectrum::cie::d65_unit;
use crate::spectrum::uplift::{RgbUplift, SigmoidPolynomial};
use crate::spectrum::{Rgb, Spectrum};
use glam::{Vec2, Vec3};
use std::sync::OnceLock;

/// Linear sRGB luminance (Rec. 709 Y).
#[inline]
fn luminance(c: Rgb) -> f32 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

#[derive(Clone, Debug)]
pub struct EnvironmentMap {
    width: usize,
    height: usize,
    /// Radiance (scale applied), row 0 at the top (θ = 0).
    texels: Vec<Rgb>,
    to_world: Transform,
    /// cos θ of each texel row.
    cos_theta: Vec<f32>,
    /// Row choice (H − 1 rows of cells), then the cell within the row.
    marginal: DiscreteDistribution,
    conditional: Vec<DiscreteDistribution>,
    /// Probability of each cell divided by its solid angle (row-major).
    cell_density: Vec<f32>,
    /// Per texel, the illuminant uplift (scale, shape), made on first
    /// spectral use.
    uplift: OnceLock<Vec<(f32, SigmoidPolynomial)>>,
}

impl EnvironmentMap {
    /// A map of `width` × `height` linear RGB texels (row 0 at the top),
    /// times `scale`. Errors on maps smaller than 2 × 3 (Mitsuba's limit)
    /// or non-finite values; negative values are clamped to zero.
    pub fn new(width: usize, height: usize, texels: Vec<Rgb>, scale: f32, to_world: Transform) -> Result<EnvironmentMap, String> {
        if width < 2 || height < 3 || texels.len() != width * height {
            return Err(format!("the environment map must be at least 2×3 pixels (it is {width}×{height})"));
        }
        if !scale.is_finite() || scale < 0.0 {
            return Err(format!("scale must be a finite non-negative number, not {scale}"));
        }
        if texels.iter().any(|t| !t.is_finite()) {
            return Err("the environment map contains NaN or infinite values".into());
        }
        let texels: Vec<Rgb> = texels.into_iter().map(|t| t.map(|v| v.max(0.0) * scale)).collect();
        let rows = height - 1;
        let d_theta = PI / rows as f32;
        let cos_theta: Vec<f32> = (0..height).map(|j| if j == rows { -1.0 } else { (j as f32 * d_theta).cos() }).collect();
        let d_phi = 2.0 * PI / width as f32;
        let lum: Vec<f32> = texels.iter().map(|&t| luminance(t)).collect();
        // Cell (i, j) spans texel columns i, i+1 (wrapping) and rows j, j+1.
        let mut weights = vec![0.0f32; width * rows];
        let mut solid_angle = vec![0.0f32; rows];
        for j in 0..rows {
            solid_angle[j] = d_phi * (cos_theta[j] - cos_theta[j + 1]);
            for i in 0..width {
                let i1 = (i + 1) % width;
                let mean = 0.25 * (lum[j * width + i] + lum[j * width + i1] + lum[(j + 1) * width + i] + lum[(j + 1) * width + i1]);
                weights[j * width + i] = mean * solid_angle[j];
            }
        }
        let conditional: Vec<DiscreteDistribution> =
            (0..rows).map(|j| DiscreteDistribution::new(weights[j * width..(j + 1) * width].iter().copied())).collect();
        let marginal = DiscreteDistribution::new(conditional.iter().map(|c| c.sum()));
        let total = marginal.sum();
        let cell_density = weights
            .iter()
            .enumerate()
            .map(|(k, &w)| if total > 0.0 && solid_angle[k / width] > 0.0 { w / total / solid_angle[k / width] } else { 0.0 })
            .collect();
        Ok(EnvironmentMap { width, height, texels, to_world, cos_theta, marginal, conditional, cell_density, uplift: OnceLock::new() })
    }

    pub fn resolution(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// Continuous texel coordinates (x along the width, shifted half a
    /// texel so that integers are texel centres, in [0, W); y in [0, H−1])
    /// of the world direction `d`.
    #[inline]
    fn texel_coords(&self, d: Vec3) -> Vec2 {
        let l = self.to_world.inverse_vector(d).normalize_or_zero();
        let u = crate::math::trig::atan2(l.x, -l.z) * (0.5 / PI) - 0.5 / self.width as f32;
        let u = u - u.floor();
        let v = l.y.clamp(-1.0, 1.0).acos() * (1.0 / PI);
        Vec2::new((u * self.width as f32).min(self.width as f32 * (1.0 - f32::EPSILON)), v * (self.height - 1) as f32)
    }

    /// The cell holding texel coordinates `c`, and the offsets within it.
    #[inline]
    fn cell(&self, c: Vec2) -> (usize, usize, f32, f32) {
        let i = (c.x.max(0.0) as usize).min(self.width - 1);
        let j = (c.y.max(0.0) as usize).min(self.height - 2);
        (i, j, (c.x - i as f32).clamp(0.0, 1.0), (c.y - j as f32).clamp(0.0, 1.0))
    }

    /// Radiance arriving along a ray travelling in world direction `d` (it
    /// comes from −d... i.e. the map is looked up at `d`, the direction the
    /// ray escapes to).
    #[inline]
    pub fn eval<S: Spectrum>(&self, d: Vec3, wl: &S::Wavelengths) -> S {
        let (i, j, fx, fy) = self.cell(self.texel_coords(d));
        let i1 = (i + 1) % self.width;
        let w = self.width;
        let idx = [j * w + i, j * w + i1, (j + 1) * w + i, (j + 1) * w + i1];
        let wt = [(1.0 - fx) * (1.0 - fy), fx * (1.0 - fy), (1.0 - fx) * fy, fx * fy];
        let rgb = self.texels[idx[0]] * wt[0] + self.texels[idx[1]] * wt[1] + self.texels[idx[2]] * wt[2] + self.texels[idx[3]] * wt[3];
        if S::hero_wavelength(wl).is_none() {
            return S::from_illuminant(rgb, wl);
        }
        let uplift = self.uplift.get_or_init(|| {
            // As Mitsuba's envmap: the shape of colour c is the reflectance
            // fit of c / (2 max c) (whose largest channel is ½, where the
            // fits are smooth), scaled back by 2 max c.
            let table = RgbUplift::get();
            self.texels
                .iter()
                .map(|&t| {
                    let scale = 2.0 * t[0].max(t[1]).max(t[2]);
                    if scale > 0.0 { (scale, table.reflectance(t * (1.0 / scale))) } else { (0.0, table.reflectance(Rgb::BLACK)) }
                })
                .collect()
        });
        let c = idx.map(|k| uplift[k]);
        // Mitsuba interpolates the shapes and the scales separately.
        let scale: f32 = (0..4).map(|k| wt[k] * c[k].0).sum();
        S::from_function(rgb, |l| (0..4).map(|k| wt[k] * c[k].1.eval(l)).sum::<f32>() * scale * d65_unit(l), wl).depolarize()
    }

    /// Solid-angle density of [`EnvironmentMap::sample_direction`] for the
    /// world direction `d`.
    #[inline]
    pub fn pdf_direction(&self, d: Vec3) -> f32 {
        let (i, j, _, _) = self.cell(self.texel_coords(d));
        self.cell_density[j * self.width + i]
    }

    /// A direction by the luminance × solid-angle distribution.
    pub fn sample_direction<S: Spectrum>(&self, u: Vec2, wl: &S::Wavelengths) -> Option<EmitterSample<S>> {
        if !(self.marginal.sum() > 0.0) {
            return None;
        }
        let (j, uy) = self.marginal.sample_reuse(u.y);
        let (i, ux) = self.conditional[j].sample_reuse(u.x);
        let pdf = self.cell_density[j * self.width + i];
        if !(pdf > 0.0) {
            return None;
        }
        let cos_theta = self.cos_theta[j] + uy * (self.cos_theta[j + 1] - self.cos_theta[j]);
        let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
        let phi = 2.0 * PI * (i as f32 + ux + 0.5) / self.width as f32;
        let (sin_phi, cos_phi) = phi.sin_cos();
        let local = Vec3::new(sin_phi * sin_theta, cos_theta, -cos_phi * sin_theta);
        let d = self.to_world.vector(local).normalize_or_zero();
        if d == Vec3::ZERO {
            return None;
        }
        let value: S = self.eval(d, wl);
        Some(EmitterSample { d, dist: f32::INFINITY, p: None, n: Vec3::ZERO, weight: value / pdf, pdf, delta: false })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Pcg32;
    use crate::math::sampling::square_to_uniform_sphere;

    /// A small map with a bright sun near the top, a gradient and a black
    /// band (cells of zero density), turned by `to_world`.
    fn test_map(to_world: Transform) -> EnvironmentMap {
        let (w, h) = (16, 9);
        let mut texels = vec![Rgb::BLACK; w * h];
        for j in 0..h {
            for i in 0..w {
                let v = if (5..7).contains(&j) { 0.0 } else { 0.2 + i as f32 / w as f32 };
                texels[j * w + i] = Rgb::new(v, 0.5 * v, 0.25 + j as f32 * 0.1 * (j < 5 || j > 6) as u8 as f32);
            }
        }
        texels[w + 3] = Rgb::new(40.0, 30.0, 20.0);
        texels[5 * w + 9] = Rgb::new(0.0, 0.0, 5.0);
        EnvironmentMap::new(w, h, texels, 1.5, to_world).unwrap()
    }

    fn turned() -> Transform {
        Transform::rotate(Vec3::new(1.0, 2.0, 0.5).normalize(), 37.0).unwrap()
    }

    #[test]
    fn mapping_follows_mitsuba_convention() {
        // Mitsuba: +Y is the top row; u = atan2(x, -z)/2π, so −Z is u = 0
        // (the left edge), +X is u = ¼ and +Z is the centre column.
        let (w, h) = (4, 3);
        let mut texels = vec![Rgb::BLACK; w * h];
        texels[0] = Rgb::new(1.0, 0.0, 0.0); // top row: +Y
        for i in 0..w {
            texels[w + i] = Rgb::new(0.0, i as f32, 0.0);
            texels[2 * w + i] = Rgb::new(0.0, 0.0, 1.0); // bottom row: −Y
        }
        let m = EnvironmentMap::new(w, h, texels, 1.0, Transform::IDENTITY).unwrap();
        let e = |d: Vec3| m.eval::<Rgb>(d, &());
        assert_eq!(e(Vec3::NEG_Y), Rgb::new(0.0, 0.0, 1.0));
        // On the equator, column i is centred at φ = 2π(i + ½)/4.
        for i in 0..w {
            let phi = 2.0 * PI * (i as f32 + 0.5) / w as f32;
            let g = e(Vec3::new(phi.sin(), 0.0, -phi.cos()))[1];
            assert!((g - i as f32).abs() < 1e-4, "column {i}: {g}");
        }
        // +Z (φ = π) lies midway between columns 1 and 2.
        assert!((e(Vec3::Z)[1] - 1.5).abs() < 1e-4);
    }

    #[test]
    fn pdf_integrates_to_one_and_matches_samples() {
        for to_world in [Transform::IDENTITY, turned()] {
            let m = test_map(to_world);
            // ∫ pdf dω by uniform sphere sampling (stratified).
            let n = 400;
            let mut sum = 0.0f64;
            for a in 0..n {
                for b in 0..n {
                    let u = Vec2::new((a as f32 + 0.5) / n as f32, (b as f32 + 0.5) / n as f32);
                    sum += m.pdf_direction(square_to_uniform_sphere(u)) as f64;
                }
            }
            let integral = sum * 4.0 * std::f64::consts::PI / (n * n) as f64;
            assert!((integral - 1.0).abs() < 2e-3, "∫pdf = {integral}");

            // Every sample's pdf and weight agree with pdf_direction and eval.
            let mut rng = Pcg32::new(7, 1);
            for _ in 0..2000 {
                let s = m.sample_direction::<Rgb>(Vec2::new(rng.next_f32(), rng.next_f32()), &()).unwrap();
                let pdf = m.pdf_direction(s.d);
                assert!((s.pdf - pdf).abs() <= 2e-3 * pdf, "{} vs {}", s.pdf, pdf);
                let expect = m.eval::<Rgb>(s.d, &()) * (1.0 / pdf);
                for c in 0..3 {
                    assert!((s.weight[c] - expect[c]).abs() <= 2e-3 * expect[c].abs() + 1e-6);
                }
            }

            // χ² of the sample histogram against the pdf.
            let mut rng = Pcg32::new(11, 3);
            chi2_sphere(
                |_| m.sample_direction::<Rgb>(Vec2::new(rng.next_f32(), rng.next_f32()), &()).map(|s| s.d),
                |d| m.pdf_direction(d) as f64,
            );
        }
        // The test has power: the same samples against a uniform density fail it.
        let m = test_map(Transform::IDENTITY);
        let mut rng = Pcg32::new(11, 3);
        let wrong = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            chi2_sphere(
                |_| m.sample_direction::<Rgb>(Vec2::new(rng.next_f32(), rng.next_f32()), &()).map(|s| s.d),
                |_| 0.25 / std::f64::consts::PI,
            )
        }));
        assert!(wrong.is_err(), "χ² accepted samples against the wrong density");
    }

    /// χ² goodness of fit of sampled directions against `pdf` over a
    /// θ × φ grid of the sphere (bins of small expectation pooled).
    pub(crate) fn chi2_sphere(mut sample: impl FnMut(usize) -> Option<Vec3>, pdf: impl Fn(Vec3) -> f64) {
        const THETA: usize = 24;
        const PHI: usize = 48;
        const N: usize = 1_000_000;
        const SUB: usize = 32;
        let dir = |theta: f64, phi: f64| Vec3::new((theta.sin() * phi.cos()) as f32, (theta.sin() * phi.sin()) as f32, theta.cos() as f32);
        let mut observed = vec![0.0f64; THETA * PHI];
        for k in 0..N {
            let Some(d) = sample(k) else { continue };
            let theta = d.z.clamp(-1.0, 1.0).acos();
            let phi = d.y.atan2(d.x).rem_euclid(2.0 * PI);
            let ti = ((theta / PI) * THETA as f32).min(THETA as f32 - 1.0) as usize;
            let pi = ((phi / (2.0 * PI)) * PHI as f32).min(PHI as f32 - 1.0) as usize;
            observed[ti * PHI + pi] += 1.0;
        }
        let mut expected = vec![0.0f64; THETA * PHI];
        for ti in 0..THETA {
            for pi in 0..PHI {
                let mut sum = 0.0;
                for a in 0..SUB {
                    for b in 0..SUB {
                        let theta = (ti as f64 + (a as f64 + 0.5) / SUB as f64) * std::f64::consts::PI / THETA as f64;
                        let phi = (pi as f64 + (b as f64 + 0.5) / SUB as f64) * 2.0 * std::f64::consts::PI / PHI as f64;
                        sum += pdf(dir(theta, phi)) * theta.sin();
                    }
                }
                let d_area = (std::f64::consts::PI / THETA as f64) * (2.0 * std::f64::consts::PI / PHI as f64) / (SUB * SUB) as f64;
                expected[ti * PHI + pi] = sum * d_area * N as f64;
            }
        }
        let (mut chsq, mut dof, mut pool_e, mut pool_o) = (0.0f64, 0i32, 0.0, 0.0);
        for i in 0..expected.len() {
            if expected[i] < 5.0 {
                pool_e += expected[i];
                pool_o += observed[i];
                continue;
            }
            chsq += (observed[i] - expected[i]).powi(2) / expected[i];
            dof += 1;
        }
        if pool_e > 0.0 {
            chsq += (pool_o - pool_e).powi(2) / pool_e;
            dof += 1;
        }
        dof -= 1;
        let p_value = 1.0 - crate::bsdf::testing::gamma_p(dof as f64 / 2.0, chsq / 2.0);
        assert!(p_value > 0.01, "χ² rejected the sampling: χ²={chsq:.1}, dof={dof}, p={p_value:.2e}");
    }
}
