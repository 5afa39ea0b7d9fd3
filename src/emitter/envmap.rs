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
//! **Sampling** (as Mitsuba's): a continuous 2-D density over the texel
//! grid, bilinear between the texels' luminance × sin θ, so that within a
//! cell it follows the bilinearly interpolated radiance it is sampled for
//! (a piecewise-constant density per cell leaves the ratio of radiance to
//! density varying across a cell by the contrast of its four texels). A
//! cell is chosen by descending a pyramid of the cells' integrals
//! ([`CellHierarchy`]), which keeps stratified samples spread over the map
//! (choosing a row, then a column in it, does not: on Mitsuba's textured
//! material-preview scene that cost 1.2× the error of stratified
//! samplers); within the cell, x by the patch's linear marginal, then y
//! given x. The density per unit solid angle is the texel-space density
//! over sin θ · 2π²/((H−1)W), finite at the poles, where the weights vanish
//! with sin θ. A sample's radiance is interpolated at the sampled texel
//! coordinates, with no round trip through the direction.
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
use crate::geometry::accel::SimdLevel;
use crate::math::sampling::CellHierarchy;
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
    /// Per texel, row 0 at the top (θ = 0): its radiance (scale applied)
    /// and, fourth, its luminance × sin θ, the sampling density's value
    /// there (bilinear in between). Together, so that a lookup of both
    /// reads one 16-byte slot a corner.
    texels: Vec<[f32; 4]>,
    to_world: Transform,
    /// The cells between texels, each weighted by its integral (the mean
    /// of its corners' weights), for choosing one.
    cells: CellHierarchy,
    /// 1 / (the weight's integral over texel space × 2π²/((H−1)W)): the
    /// factor from a bilinear weight over sin θ to solid-angle density.
    density_scale: f32,
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
        // sin θ of each texel row, exactly 0 at the poles.
        let sin_theta = |j: usize| if j == 0 || j == rows { 0.0 } else { (PI * j as f32 / rows as f32).sin().max(0.0) };
        let weight: Vec<f32> = texels.iter().enumerate().map(|(k, &t)| luminance(t) * sin_theta(k / width)).collect();
        let texels: Vec<[f32; 4]> = texels.iter().zip(&weight).map(|(t, &w)| [t[0], t[1], t[2], w]).collect();
        // Cell (i, j) spans texel columns i, i + 1 (wrapping) and rows j, j + 1.
        let corner = |i: usize, j: usize| weight[j * width + i % width];
        let cells = CellHierarchy::new(width, rows, |i, j| 0.25 * (corner(i, j) + corner(i + 1, j) + corner(i, j + 1) + corner(i + 1, j + 1)));
        let total = cells.sum() as f64;
        let jacobian = 2.0 * std::f64::consts::PI * std::f64::consts::PI / (rows * width) as f64;
        let density_scale = if total > 0.0 { (1.0 / (total * jacobian)) as f32 } else { 0.0 };
        Ok(EnvironmentMap { width, height, texels, to_world, cells, density_scale, uplift: OnceLock::new() })
    }

    pub fn resolution(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// Continuous texel coordinates (x along the width, shifted half a
    /// texel so that integers are texel centres, in [0, W); y in [0, H−1])
    /// of the map-frame unit direction `l`.
    #[inline]
    fn texel_coords(&self, l: Vec3) -> Vec2 {
        let u = crate::math::trig::atan2(l.x, -l.z) * (0.5 / PI) - 0.5 / self.width as f32;
        let u = u - u.floor();
        let v = l.y.clamp(-1.0, 1.0).acos() * (1.0 / PI);
        Vec2::new((u * self.width as f32).min(self.width as f32 * (1.0 - f32::EPSILON)), v * (self.height - 1) as f32)
    }

    /// The map-frame unit direction of world direction `d`.
    #[inline]
    fn local(&self, d: Vec3) -> Vec3 {
        self.to_world.inverse_vector(d).normalize_or_zero()
    }

    /// The cell holding texel coordinates `c`, and the offsets within it.
    #[inline]
    fn cell(&self, c: Vec2) -> (usize, usize, f32, f32) {
        let i = (c.x.max(0.0) as usize).min(self.width - 1);
        let j = (c.y.max(0.0) as usize).min(self.height - 2);
        (i, j, (c.x - i as f32).clamp(0.0, 1.0), (c.y - j as f32).clamp(0.0, 1.0))
    }

    /// The four texels of cell (i, j) and their bilinear weights at
    /// offsets (fx, fy).
    #[inline]
    fn corners(&self, i: usize, j: usize, fx: f32, fy: f32) -> ([usize; 4], [f32; 4]) {
        let i1 = if i + 1 == self.width { 0 } else { i + 1 };
        let w = self.width;
        ([j * w + i, j * w + i1, (j + 1) * w + i, (j + 1) * w + i1], [(1.0 - fx) * (1.0 - fy), fx * (1.0 - fy), (1.0 - fx) * fy, fx * fy])
    }

    /// Radiance arriving along a ray travelling in world direction `d` (it
    /// comes from −d... i.e. the map is looked up at `d`, the direction the
    /// ray escapes to).
    #[inline]
    pub fn eval<S: Spectrum>(&self, d: Vec3, wl: &S::Wavelengths) -> S {
        let (i, j, fx, fy) = self.cell(self.texel_coords(self.local(d)));
        self.eval_cell(i, j, fx, fy, wl)
    }

    #[inline]
    fn rgb(&self, k: usize) -> Rgb {
        let [r, g, b, _] = self.texels[k];
        Rgb::new(r, g, b)
    }

    /// [`EnvironmentMap::eval`] and [`EnvironmentMap::pdf_direction`] of
    /// the world direction `d` in one lookup (for rays that escaped).
    #[inline]
    pub fn eval_pdf<S: Spectrum>(&self, d: Vec3, wl: &S::Wavelengths) -> (S, f32) {
        let l = self.local(d);
        let (i, j, fx, fy) = self.cell(self.texel_coords(l));
        (self.eval_cell(i, j, fx, fy, wl), self.density_cell(i, j, fx, fy, (l.x * l.x + l.z * l.z).sqrt()))
    }

    /// Radiance at offsets (fx, fy) in cell (i, j), bilinear between its texels.
    #[inline]
    fn eval_cell<S: Spectrum>(&self, i: usize, j: usize, fx: f32, fy: f32, wl: &S::Wavelengths) -> S {
        let (idx, wt) = self.corners(i, j, fx, fy);
        let rgb = self.rgb(idx[0]) * wt[0] + self.rgb(idx[1]) * wt[1] + self.rgb(idx[2]) * wt[2] + self.rgb(idx[3]) * wt[3];
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
                .map(|&[r, g, b, _]| {
                    let t = Rgb::new(r, g, b);
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

    /// Solid-angle density at offsets (fx, fy) in cell (i, j) of a
    /// direction with `sin_theta`.
    #[inline]
    fn density_cell(&self, i: usize, j: usize, fx: f32, fy: f32, sin_theta: f32) -> f32 {
        let (idx, wt) = self.corners(i, j, fx, fy);
        let w = self.texels[idx[0]][3] * wt[0] + self.texels[idx[1]][3] * wt[1] + self.texels[idx[2]][3] * wt[2] + self.texels[idx[3]][3] * wt[3];
        if sin_theta > 0.0 { w * self.density_scale / sin_theta } else { 0.0 }
    }

    /// Solid-angle density of [`EnvironmentMap::sample_direction`] for the
    /// world direction `d`.
    #[inline]
    pub fn pdf_direction(&self, d: Vec3) -> f32 {
        let l = self.local(d);
        let (i, j, fx, fy) = self.cell(self.texel_coords(l));
        self.density_cell(i, j, fx, fy, (l.x * l.x + l.z * l.z).sqrt())
    }

    /// The cells [`EnvironmentMap::sample_direction`] picks for each of
    /// `us`, all at once ([`CellHierarchy::sample_batch`]), for
    /// [`EnvironmentMap::sample_direction_in`]; their texels are
    /// prefetched.
    pub fn sample_cells(&self, level: SimdLevel, us: &[Vec2], out: &mut [Option<(usize, usize, Vec2)>]) {
        self.cells.sample_batch(level, us, out);
        for &(i, j, _) in out.iter().flatten() {
            let (idx, _) = self.corners(i, j, 0.0, 0.0);
            for k in idx {
                crate::geometry::prefetch(self.texels.get(k));
            }
        }
    }

    /// A direction by the density of luminance (bilinear over the texels)
    /// per unit solid angle.
    pub fn sample_direction<S: Spectrum>(&self, u: Vec2, wl: &S::Wavelengths) -> Option<EmitterSample<S>> {
        self.sample_direction_in(self.cells.sample(u), wl)
    }

    /// [`EnvironmentMap::sample_direction`] from the cell it picks and the
    /// sample re-scaled within it ([`EnvironmentMap::sample_cells`]).
    #[inline]
    pub fn sample_direction_in<S: Spectrum>(&self, cell: Option<(usize, usize, Vec2)>, wl: &S::Wavelengths) -> Option<EmitterSample<S>> {
        if !(self.density_scale > 0.0) {
            return None;
        }
        let (i, j, r) = cell?;
        // Within the cell, the bilinear patch of its corners' weights: x by
        // its marginal (linear), then y given x (linear).
        let (idx, _) = self.corners(i, j, 0.0, 0.0);
        let v = idx.map(|k| self.texels[k][3]);
        let fx = sample_linear(r.x, v[0] + v[2], v[1] + v[3]);
        let fy = sample_linear(r.y, (1.0 - fx) * v[0] + fx * v[1], (1.0 - fx) * v[2] + fx * v[3]);
        let w = self.width;

        let (sin_theta, cos_theta) = (PI * (j as f32 + fy) / (self.height - 1) as f32).sin_cos();
        let phi = 2.0 * PI * (i as f32 + fx + 0.5) / w as f32;
        let (sin_phi, cos_phi) = phi.sin_cos();
        let pdf = self.density_cell(i, j, fx, fy, sin_theta);
        if !(pdf > 0.0 && pdf.is_finite()) {
            return None;
        }
        let local = Vec3::new(sin_phi * sin_theta, cos_theta, -cos_phi * sin_theta);
        let d = self.to_world.vector(local).normalize_or_zero();
        if d == Vec3::ZERO {
            return None;
        }
        let value: S = self.eval_cell(i, j, fx, fy, wl);
        Some(EmitterSample { d, dist: f32::INFINITY, p: None, n: Vec3::ZERO, weight: value / pdf, pdf, delta: false })
    }
}

/// The position in [0, 1] of `u` under the density that falls linearly
/// from `a` at 0 to `b` at 1 (both ≥ 0): the root of a t + (b − a) t²/2 =
/// u (a + b)/2, in the form without cancellation.
#[inline]
fn sample_linear(u: f32, a: f32, b: f32) -> f32 {
    let sum = a + b;
    if !(sum > 0.0) {
        return u;
    }
    let denom = a + ((1.0 - u) * a * a + u * b * b).sqrt();
    if !(denom > 0.0) {
        return 0.0;
    }
    (u * sum / denom).clamp(0.0, 1.0)
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
    fn sample_linear_inverts_the_linear_distribution() {
        for (a, b) in [(1.0f32, 1.0f32), (0.0, 2.0), (3.0, 0.0), (1e-6, 5.0), (7.0, 0.25)] {
            for k in 0..=20 {
                let u = k as f32 / 20.0;
                let t = sample_linear(u, a, b);
                assert!((0.0..=1.0).contains(&t));
                // The distribution function at t, normalized.
                let cdf = (a * t + 0.5 * (b - a) * t * t) / (0.5 * (a + b));
                assert!((cdf - u).abs() < 1e-5, "a={a} b={b} u={u}: t={t}, F(t)={cdf}");
            }
        }
    }

    /// The density follows the bilinearly interpolated luminance, so each
    /// sample's radiance over its density is nearly the map's integral
    /// (away from the poles, where sin θ is not linear between texel
    /// rows); a density constant per cell varies it by the cells' contrast.
    #[test]
    fn radiance_over_density_is_nearly_constant() {
        let (w, h) = (64, 33);
        let mut rng = Pcg32::new(5, 9);
        let texels: Vec<Rgb> = (0..w * h)
            .map(|_| {
                let v = 10f32.powf(4.0 * rng.next_f32() - 2.0);
                Rgb::new(v, 0.8 * v, 0.6 * v)
            })
            .collect();
        let m = EnvironmentMap::new(w, h, texels, 1.0, turned()).unwrap();
        let (mut lo, mut hi, mut count) = (f32::INFINITY, 0.0f32, 0);
        for _ in 0..20000 {
            let s = m.sample_direction::<Rgb>(Vec2::new(rng.next_f32(), rng.next_f32()), &()).unwrap();
            let l = m.local(s.d);
            if l.y.abs() > std::f32::consts::FRAC_1_SQRT_2 {
                continue;
            }
            let r = luminance(s.weight);
            lo = lo.min(r);
            hi = hi.max(r);
            count += 1;
        }
        assert!(count > 5000);
        assert!(hi / lo < 1.3, "radiance / density spans {lo} to {hi}");
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
        const N: usize = 8_000_000;
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
