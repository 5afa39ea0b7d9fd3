//! Microfacet distributions for the rough BSDFs (`roughconductor`,
//! `roughdielectric`, …): a rough surface is a field of tiny mirrors whose
//! normals m follow a distribution D(m) (Walter et al. 2007, "Microfacet
//! Models for Refraction through Rough Surfaces").
//!
//! * **Beckmann** (Gaussian slopes, RMS slope α):
//!   D(m) = exp(−(m_x²/α_u² + m_y²/α_v²)/m_z²) / (π α_u α_v m_z⁴).
//! * **GGX** / Trowbridge–Reitz (long tails):
//!   D(m) = 1 / (π α_u α_v (m_x²/α_u² + m_y²/α_v² + m_z²)²).
//!
//! Both are normalised as projected areas: ∫ D(m) cos θ_m dω_m = 1.
//! `alpha_u` is the roughness along the shading frame's tangent (x, which
//! follows ∂p/∂u as in Mitsuba) and `alpha_v` along the bitangent (y);
//! `alpha` sets both. Roughness is clamped to ≥ 10⁻⁴ as in Mitsuba.
//!
//! Shadowing and masking is Smith's separable form G = G1(wi) G1(wo): exact
//! for GGX, G1 = 2 / (1 + √(1 + α²tan²θ)); for Beckmann Mitsuba's rational
//! approximation of the error-function form (< 0.35 % error), which Snell
//! uses too so that images match.
//!
//! Sampling: with `sample_visible` (the default) only the normals visible
//! from wi are drawn, with density D_wi(m) = G1(wi, m) |wi·m| D(m) / cos θ_i
//! (Heitz and d'Eon 2014; Heitz 2018's exact GGX routine; Jakob's Newton
//! inversion for Beckmann); otherwise the whole distribution, density
//! D(m) cos θ_m.
//!
//! Parameters shared by every rough BSDF (read by [`MicrofacetParams::from_props`]):
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `distribution` | string | `beckmann` | `beckmann` or `ggx` |
//! | `alpha` | float / texture | 0.1 | roughness in both directions |
//! | `alpha_u`, `alpha_v` | float / texture | — | roughness along ∂p/∂u and across it (both or neither, not with `alpha`) |
//! | `sample_visible` | boolean | true | sample visible normals only |
//!
//! ```xml
//! <bsdf type="roughconductor">
//!     <string name="distribution" value="ggx"/>
//!     <float name="alpha_u" value="0.05"/>
//!     <float name="alpha_v" value="0.3"/>
//! </bsdf>
//! ```

use crate::geometry::SurfaceInteraction;
use crate::bsdf::Lobe;
use crate::math::PI;
use crate::math::sampling::{square_to_cosine_hemisphere, square_to_uniform_disk_concentric};
use crate::scene::error::{Result, SceneError};
use crate::scene::loader::PluginLoader;
use crate::scene::props::Props;
use crate::spectrum::Rgb;
use crate::texture::Texture;
use glam::{Vec2, Vec3};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MicrofacetType {
    Beckmann,
    Ggx,
}

/// A microfacet distribution at one surface point.
#[derive(Clone, Copy, Debug)]
pub struct Microfacet {
    pub kind: MicrofacetType,
    pub alpha_u: f32,
    pub alpha_v: f32,
    pub sample_visible: bool,
}

impl Microfacet {
    pub fn new(kind: MicrofacetType, alpha_u: f32, alpha_v: f32, sample_visible: bool) -> Microfacet {
        Microfacet { kind, alpha_u: alpha_u.max(1e-4), alpha_v: alpha_v.max(1e-4), sample_visible }
    }

    /// D(m), the density of normals m per unit solid angle and unit projected area.
    #[inline]
    pub fn d(&self, m: Vec3) -> f32 {
        let cos2 = m.z * m.z;
        let (x, y) = (m.x / self.alpha_u, m.y / self.alpha_v);
        let result = match self.kind {
            MicrofacetType::Beckmann => (-(x * x + y * y) / cos2).exp() / (PI * self.alpha_u * self.alpha_v * cos2 * cos2),
            MicrofacetType::Ggx => {
                let t = x * x + y * y + cos2;
                1.0 / (PI * self.alpha_u * self.alpha_v * t * t)
            }
        };
        // Below 10⁻²⁰ (and on the lower hemisphere), nothing: keeps the
        // later quotients finite, as Mitsuba does.
        if result * m.z > 1e-20 { result } else { 0.0 }
    }

    /// Smith's masking function G1(v, m): the fraction of normal-m facets
    /// visible from v. Zero when v sees the facet's back.
    #[inline]
    pub fn g1(&self, v: Vec3, m: Vec3) -> f32 {
        if v.dot(m) * v.z <= 0.0 {
            return 0.0;
        }
        let xy = (self.alpha_u * v.x) * (self.alpha_u * v.x) + (self.alpha_v * v.y) * (self.alpha_v * v.y);
        if xy == 0.0 {
            return 1.0;
        }
        let tan2 = xy / (v.z * v.z);
        match self.kind {
            MicrofacetType::Beckmann => {
                let a = 1.0 / tan2.sqrt();
                if a >= 1.6 { 1.0 } else { (3.535 * a + 2.181 * a * a) / (1.0 + 2.276 * a + 2.577 * a * a) }
            }
            MicrofacetType::Ggx => 2.0 / (1.0 + (1.0 + tan2).sqrt()),
        }
    }

    /// Smith's separable shadowing-masking G1(wi) G1(wo).
    #[inline]
    pub fn g(&self, wi: Vec3, wo: Vec3, m: Vec3) -> f32 {
        self.g1(wi, m) * self.g1(wo, m)
    }

    /// The density (per solid angle of m) with which [`Microfacet::sample`] draws m.
    #[inline]
    pub fn pdf(&self, wi: Vec3, m: Vec3) -> f32 {
        let d = self.d(m);
        if self.sample_visible { d * self.g1(wi, m) * wi.dot(m).abs() / wi.z } else { d * m.z }
    }

    /// One-sample choice of the plastics' two lobes: with probability
    /// `p_specular` a reflection about a sampled microfacet normal (the
    /// coating), else a cosine-weighted direction (the diffuse base). `u1`
    /// picks the lobe, `u2` the direction; `wo` may fall below the surface
    /// (the caller rejects it). Shared by `roughplastic` and `pplastic`.
    pub fn sample_over_diffuse(&self, wi: Vec3, p_specular: f32, u1: f32, u2: Vec2) -> (Vec3, Lobe) {
        if u1 < p_specular {
            let (m, _) = self.sample(wi, u2);
            (2.0 * wi.dot(m) * m - wi, Lobe::GLOSSY_REFLECTION)
        } else {
            (square_to_cosine_hemisphere(u2), Lobe::DIFFUSE_REFLECTION)
        }
    }

    /// A microfacet normal and its density [`Microfacet::pdf`]; `wi` must be
    /// in the upper hemisphere for visible-normal sampling.
    #[inline]
    pub fn sample(&self, wi: Vec3, u: Vec2) -> (Vec3, f32) {
        if self.sample_visible {
            // Stretch wi to the α = 1 configuration, sample the slopes of
            // the visible normals there, rotate and unstretch.
            let w = Vec3::new(self.alpha_u * wi.x, self.alpha_v * wi.y, wi.z).normalize();
            let r = (w.x * w.x + w.y * w.y).sqrt();
            let (sin_phi, cos_phi) = if r > 0.0 { (w.y / r, w.x / r) } else { (0.0, 1.0) };
            let s = self.sample_visible_11(w.z, u);
            let slope = Vec2::new((cos_phi * s.x - sin_phi * s.y) * self.alpha_u, (sin_phi * s.x + cos_phi * s.y) * self.alpha_v);
            let m = Vec3::new(-slope.x, -slope.y, 1.0).normalize();
            (m, self.pdf(wi, m))
        } else {
            // Azimuth (shared by both distributions), then elevation.
            let (sin_phi, cos_phi, alpha2) = if self.alpha_u == self.alpha_v {
                let (s, c) = crate::math::trig::sin_cos_turn(u.y);
                (s, c, self.alpha_u * self.alpha_u)
            } else {
                let ratio = self.alpha_v / self.alpha_u;
                let tmp = ratio * (2.0 * PI * u.y).tan();
                let cos_phi = (1.0 / (tmp * tmp + 1.0).sqrt()).copysign((u.y - 0.5).abs() - 0.25);
                let sin_phi = cos_phi * tmp;
                let a2 = 1.0 / ((cos_phi / self.alpha_u).powi(2) + (sin_phi / self.alpha_v).powi(2));
                (sin_phi, cos_phi, a2)
            };
            let tan2 = match self.kind {
                MicrofacetType::Beckmann => -alpha2 * (1.0 - u.x).ln(),
                MicrofacetType::Ggx => alpha2 * u.x / (1.0 - u.x),
            };
            let cos_theta = 1.0 / (1.0 + tan2).sqrt();
            let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
            let m = Vec3::new(cos_phi * sin_theta, sin_phi * sin_theta, cos_theta);
            (m, self.d(m) * m.z)
        }
    }

    /// Slopes of a visible normal for α = 1 and incidence cosine `cos_i`.
    fn sample_visible_11(&self, cos_i: f32, u: Vec2) -> Vec2 {
        match self.kind {
            MicrofacetType::Ggx => {
                // Heitz 2018: a point on the disk, pushed onto the half of it
                // the projected hemisphere covers, lifted onto the hemisphere.
                let mut p = square_to_uniform_disk_concentric(u);
                let s = 0.5 * (1.0 + cos_i);
                let h = (1.0 - p.x * p.x).max(0.0).sqrt();
                p.y = h + (p.y - h) * s;
                let z = (1.0 - p.length_squared()).max(0.0).sqrt();
                let sin_i = (1.0 - cos_i * cos_i).max(0.0).sqrt();
                let norm = 1.0 / (sin_i * p.y + cos_i * z);
                Vec2::new((cos_i * p.y - sin_i * z) * norm, p.x * norm)
            }
            MicrofacetType::Beckmann => {
                // Invert the CDF of the visible slope along the incidence
                // plane by Newton's method in the erf domain (Jakob 2014),
                // then sample the other slope as a Gaussian.
                let tan_i = (1.0 - cos_i * cos_i).max(0.0).sqrt() / cos_i;
                let cot_i = 1.0 / tan_i;
                let maxval = erf_f32(cot_i);
                let u = u.clamp(Vec2::splat(1e-6), Vec2::splat(1.0 - 1e-6));
                let mut x = maxval - (maxval + 1.0) * erf_f32((-u.x.ln()).sqrt());
                let target = u.x * (1.0 + maxval + FRAC_1_SQRT_PI * tan_i * (-cot_i * cot_i).exp());
                for _ in 0..3 {
                    let slope = erfinv(x);
                    let value = 1.0 + x + FRAC_1_SQRT_PI * tan_i * (-slope * slope).exp() - target;
                    let derivative = 1.0 - slope * tan_i;
                    x -= value / derivative;
                }
                Vec2::new(erfinv(x), erfinv(2.0 * u.y - 1.0))
            }
        }
    }
}

const FRAC_1_SQRT_PI: f32 = 0.564_189_6;

/// The error function (Abramowitz and Stegun 7.1.26, |error| < 1.5·10⁻⁷).
pub fn erf(x: f32) -> f32 {
    let xa = (x as f64).abs();
    let t = 1.0 / (1.0 + 0.327_591_1 * xa);
    let poly = t * (0.254_829_592 + t * (-0.284_496_736 + t * (1.421_413_741 + t * (-1.453_152_027 + t * 1.061_405_429))));
    let y = 1.0 - poly * (-xa * xa).exp();
    (if x < 0.0 { -y } else { y }) as f32
}

/// [`erf`] in single precision, for sampling (the Newton iterations that
/// follow absorb its rounding; `erf`'s f64 exp costs more than the rest).
#[inline]
fn erf_f32(x: f32) -> f32 {
    let xa = x.abs();
    let t = 1.0 / (1.0 + 0.327_591_1 * xa);
    let poly = t * (0.254_829_6 + t * (-0.284_496_74 + t * (1.421_413_7 + t * (-1.453_152 + t * 1.061_405_4))));
    let y = 1.0 - poly * (-xa * xa).exp();
    if x < 0.0 { -y } else { y }
}

/// The inverse error function on (−1, 1): Giles' single-precision
/// polynomial ("Approximating the erfinv function", 2010).
pub fn erfinv(x: f32) -> f32 {
    let w = -((1.0 - x) * (1.0 + x)).ln();
    let p = if w < 5.0 {
        let w = w - 2.5;
        let mut p = 2.810_226_4e-8f32;
        for c in [3.432_739_4e-7, -3.523_387_7e-6, -4.391_506_5e-6, 2.185_808_7e-4, -1.253_725e-3, -4.177_681_6e-3, 0.246_640_73, 1.501_409_4] {
            p = c + p * w;
        }
        p
    } else {
        let w = w.sqrt() - 3.0;
        let mut p = -2.002_142_6e-4f32;
        for c in [1.009_505_6e-4, 1.349_343_2e-3, -3.673_428_4e-3, 5.739_507_7e-3, -7.622_461_3e-3, 9.438_870_5e-3, 1.001_674_1, 2.832_976_8] {
            p = c + p * w;
        }
        p
    };
    p * x
}

/// The roughness parameters of a rough BSDF, as read from the scene: the
/// distribution's type, α along u and v (constants or textures) and the
/// sampling method. [`MicrofacetParams::at`] gives the distribution at a point.
#[derive(Clone, Debug)]
pub struct MicrofacetParams {
    pub kind: MicrofacetType,
    pub alpha_u: Texture,
    /// `None`: isotropic (α_v = α_u).
    pub alpha_v: Option<Texture>,
    pub sample_visible: bool,
}

/// A texture's value as a scalar (a float's value; a colour's luminance),
/// as Mitsuba's `eval_1` ([`Texture::eval_1`], which also gives Mitsuba's
/// checkerboard quirk). Pass the surface interaction so that a
/// `mesh_attribute` finds its mesh.
#[inline]
pub(crate) fn scalar(t: &Texture, at: impl Into<crate::texture::TexPoint>) -> f32 {
    match t {
        Texture::Constant(c, _) => c.0[0],
        _ => t.eval_1(at),
    }
}

impl MicrofacetParams {
    /// Reads the parameters in the table at the top of this file.
    pub fn from_props(props: &Props, loader: &dyn PluginLoader) -> Result<MicrofacetParams> {
        let kind = match props.choice("distribution", "beckmann", &["beckmann", "ggx"])? {
            "ggx" => MicrofacetType::Ggx,
            _ => MicrofacetType::Beckmann,
        };
        let given = |n: &str| props.has(n) || props.has_child(n);
        let (alpha_u, alpha_v) = if given("alpha_u") || given("alpha_v") {
            if given("alpha") {
                return Err(props.error_at("alpha", "give either \"alpha\" or \"alpha_u\"/\"alpha_v\", not both"));
            }
            if !(given("alpha_u") && given("alpha_v")) {
                let missing = if given("alpha_u") { "alpha_v" } else { "alpha_u" };
                return Err(SceneError::at(&props.node.loc, format!("anisotropic roughness needs both \"alpha_u\" and \"alpha_v\" (\"{missing}\" is missing)")));
            }
            (read_alpha(props, loader, "alpha_u")?, Some(read_alpha(props, loader, "alpha_v")?))
        } else {
            (read_alpha(props, loader, "alpha")?, None)
        };
        let sample_visible = props.bool("sample_visible", true)?;
        Ok(MicrofacetParams { kind, alpha_u, alpha_v, sample_visible })
    }

    /// Whether the roughness differs along u and v (then the shading frame
    /// must follow ∂p/∂u).
    pub fn is_anisotropic(&self) -> bool {
        self.alpha_v.is_some()
    }

    /// The distribution at the point `si`.
    #[inline]
    pub fn at(&self, si: &SurfaceInteraction) -> Microfacet {
        let a_u = scalar(&self.alpha_u, si);
        let a_v = self.alpha_v.as_ref().map_or(a_u, |t| scalar(t, si));
        Microfacet::new(self.kind, a_u, a_v, self.sample_visible)
    }
}

/// A roughness: a non-negative finite float or a texture.
fn read_alpha(props: &Props, loader: &dyn PluginLoader, name: &str) -> Result<Texture> {
    let t = loader.texture(props, name, Rgb::new(0.1, 0.1, 0.1))?;
    if let Texture::Constant(c, _) = &t {
        if !(c.0.iter().all(|v| v.is_finite() && *v >= 0.0)) {
            return Err(props.error_at(name, format!("roughness \"{name}\" must be a non-negative number")));
        }
    }
    Ok(t)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::testing::{chi2_directions, incident};
    use crate::math::Pcg32;

    const KINDS: [MicrofacetType; 2] = [MicrofacetType::Beckmann, MicrofacetType::Ggx];

    /// ∫ f(m) dω_m over the upper hemisphere by the midpoint rule in
    /// (t, φ) with θ = t² π/2 (dense where narrow lobes peak).
    fn integrate_hemisphere(f: impl Fn(Vec3) -> f64) -> f64 {
        const NT: usize = 2000;
        const NP: usize = 256;
        let mut sum = 0.0;
        for i in 0..NT {
            let t = (i as f64 + 0.5) / NT as f64;
            let theta = t * t * std::f64::consts::FRAC_PI_2;
            let dtheta = t * std::f64::consts::PI / NT as f64;
            for j in 0..NP {
                let phi = (j as f64 + 0.5) / NP as f64 * 2.0 * std::f64::consts::PI;
                let m = incident(theta as f32, phi as f32);
                sum += f(m) * theta.sin() * dtheta * 2.0 * std::f64::consts::PI / NP as f64;
            }
        }
        sum
    }

    #[test]
    fn d_is_normalised_as_projected_area() {
        for kind in KINDS {
            for (au, av) in [(0.01, 0.01), (0.1, 0.1), (0.5, 0.5), (1.0, 1.0), (0.05, 0.4), (0.6, 0.15)] {
                let mf = Microfacet::new(kind, au, av, true);
                let total = integrate_hemisphere(|m| mf.d(m) as f64 * m.z as f64);
                assert!((total - 1.0).abs() < 5e-3, "{kind:?} α=({au},{av}): ∫D cos = {total}");
            }
        }
    }

    #[test]
    fn visible_normal_pdf_integrates_to_one() {
        // ∫ G1(wi, m) |wi·m| D(m) dω_m = cos θ_i: exact for GGX's Smith G1,
        // within the 0.35 % of Mitsuba's rational Beckmann G1.
        for kind in KINDS {
            for (au, av) in [(0.1, 0.1), (0.5, 0.5), (1.0, 1.0), (0.1, 0.5)] {
                for theta in [0.0f32, 0.7, 1.3, 1.52] {
                    let wi = incident(theta, 0.4);
                    let mf = Microfacet::new(kind, au, av, true);
                    let total = integrate_hemisphere(|m| mf.pdf(wi, m) as f64);
                    let tol = if kind == MicrofacetType::Ggx { 5e-3 } else { 1e-2 };
                    assert!((total - 1.0).abs() < tol, "{kind:?} α=({au},{av}) θ={theta}: ∫pdf = {total}");
                }
            }
        }
    }

    #[test]
    fn g1_is_one_at_normal_incidence_and_falls_at_grazing() {
        for kind in KINDS {
            let mf = Microfacet::new(kind, 0.3, 0.3, true);
            assert_eq!(mf.g1(Vec3::Z, Vec3::Z), 1.0);
            let grazing = incident(1.55, 0.0);
            assert!(mf.g1(grazing, Vec3::Z) < 0.3);
            // The back of a facet is never visible.
            assert_eq!(mf.g1(Vec3::new(0.0, 0.0, 1.0), Vec3::new(0.0, 0.0, -1.0)), 0.0);
        }
        // GGX's exact form: tan θ = 1, α = 1 gives 2 / (1 + √2).
        let mf = Microfacet::new(MicrofacetType::Ggx, 1.0, 1.0, true);
        let v = Vec3::new(1.0, 0.0, 1.0).normalize();
        assert!((mf.g1(v, Vec3::Z) - 2.0 / (1.0 + 2f32.sqrt())).abs() < 1e-6);
    }

    #[test]
    fn erf_f32_is_erf() {
        for i in -300..=300 {
            let x = i as f32 * 0.01;
            assert!((erf_f32(x) - erf(x)).abs() < 3e-7, "{x}: {} vs {}", erf_f32(x), erf(x));
        }
    }

    #[test]
    fn erf_and_erfinv_are_inverse() {
        assert!((erf(0.5) - 0.520_499_9).abs() < 1e-6 && (erf(-1.0) + 0.842_700_8).abs() < 1e-6);
        for i in 1..200 {
            let y = -0.995 + i as f32 * 0.00995;
            assert!((erf(erfinv(y)) - y).abs() < 2e-6, "{y}");
        }
    }

    /// χ² of the sampled normals against `pdf`, over a polar cap sized to
    /// the roughness (everything beyond it pooled in one bin).
    fn chi2_normals(mf: Microfacet, wi: Vec3, seed: u64, significance: f64) {
        let cap = (8.0 * mf.alpha_u.max(mf.alpha_v)).atan().max(0.05).min(std::f32::consts::FRAC_PI_2);
        let mut rng = Pcg32::new(seed, 3);
        chi2_directions(
            || {
                let (m, pdf) = mf.sample(wi, Vec2::new(rng.next_f32(), rng.next_f32()));
                (pdf > 0.0).then_some(m)
            },
            |m| mf.pdf(wi, m) as f64,
            cap,
            significance,
        );
    }

    #[test]
    fn sampling_matches_the_pdf() {
        let mut seed = 100;
        for kind in KINDS {
            for visible in [true, false] {
                for (au, av) in [(0.01, 0.01), (0.1, 0.1), (0.5, 0.5), (1.0, 1.0), (0.08, 0.4), (0.7, 0.2)] {
                    for theta in [0.0f32, 0.8, 1.45] {
                        seed += 1;
                        // 72 tests at 1 % overall.
                        chi2_normals(Microfacet::new(kind, au, av, visible), incident(theta, 0.9), seed, 0.01 / 72.0);
                    }
                }
            }
        }
    }

    #[test]
    fn anisotropy_turns_with_the_frame() {
        // Rotating the frame by 90° about the normal (x → y) is swapping α_u, α_v.
        let rot = |v: Vec3| Vec3::new(-v.y, v.x, v.z);
        for kind in KINDS {
            let a = Microfacet::new(kind, 0.1, 0.4, true);
            let b = Microfacet::new(kind, 0.4, 0.1, true);
            let mut rng = Pcg32::new(5, 5);
            for _ in 0..200 {
                let m = crate::math::sampling::square_to_cosine_hemisphere(Vec2::new(rng.next_f32(), rng.next_f32()));
                let wi = crate::math::sampling::square_to_cosine_hemisphere(Vec2::new(rng.next_f32(), rng.next_f32()));
                let (x, y) = (a.d(m), b.d(rot(m)));
                assert!((x - y).abs() <= 1e-4 * x.max(1.0), "D {x} vs {y}");
                let (x, y) = (a.pdf(wi, m), b.pdf(rot(wi), rot(m)));
                assert!((x - y).abs() <= 1e-4 * x.max(1.0), "pdf {x} vs {y}");
            }
            // The rougher direction spreads more normals: α_v > α_u puts them along y.
            let mut spread = Vec2::ZERO;
            for i in 0..1000 {
                let (m, _) = a.sample(Vec3::Z, Vec2::new((i as f32 + 0.5) / 1000.0, rng.next_f32()));
                spread += Vec2::new(m.x * m.x, m.y * m.y);
            }
            assert!(spread.y > 4.0 * spread.x, "{spread}");
        }
    }
}
