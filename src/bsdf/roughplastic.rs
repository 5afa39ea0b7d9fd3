//! `roughplastic` — a rough dielectric coating over a diffuse base, as
//! Mitsuba 3.9.1 models it (a rough counterpart of `plastic`).
//!
//! The coating reflects as a rough dielectric interface (Walter et al.
//! 2007, distributions from `microfacet.rs`), with h the half vector:
//!
//! f_s(ω_i, ω_o) = s F(ω_i·h, η) D(h) G(ω_i, ω_o, h) / (4 cos θ_i cos θ_o).
//!
//! Light not reflected enters, scatters diffusely at the base of albedo ρ and
//! leaves through the coating. As in Mitsuba, the coating's transmittance
//! for a direction, T(θ), is the albedo of a rough dielectric's refraction
//! lobe ((1 − F) G1 averaged over the visible normals), and the light the
//! coating reflects back down is the cosine-weighted average
//! R_int = 2 ∫₀¹ R(μ, 1/η) μ dμ, seen from inside, of the reflection lobe's
//! albedo R (F G1 averaged likewise):
//!
//! f_d(ω_i, ω_o) = T(θ_i) T(θ_o) / η² · ρ' / π,
//! ρ' = ρ / (1 − R_int)        (`nonlinear` = false),
//! ρ' = ρ / (1 − ρ R_int)      (`nonlinear` = true).
//!
//! T and R are computed at load time the way Mitsuba does it: by Gauss–Legendre
//! quadrature (32² nodes for η > 1, 128² otherwise) over the unit square
//! mapped to visible normals; T is tabulated at 64 values of cos θ (the
//! first clamped to 10⁻⁶) and interpolated linearly, and R_int is twice
//! the mean of R(μ, 1/η) μ over the same 64 values.
//!
//! Sampling picks the specular lobe with probability
//! p_s = (1 − T_i) w / ((1 − T_i) w + T_i (1 − w)), w = s̄ / (ρ̄ + s̄) from the
//! mean specular scale and mean albedo; it then draws a microfacet normal
//! and reflects, or a cosine-weighted direction. As in Mitsuba the sample's
//! pdf is the mixture's and its weight f / pdf of both lobes. One-sided.
//!
//! Roughness is a float and isotropic, as in Mitsuba 3.9.1 (whose
//! roughplastic rejects textures and `alpha_u`/`alpha_v`): the tables depend
//! on α.
//!
//! Polarisation (polarized modes): the specular lobe is the coating's
//! Fresnel reflection in Mueller form in the s/p frame of each facet (as in
//! `roughdielectric`), the diffuse lobe a depolarizer (the base forgets
//! polarisation), like `plastic`. Mitsuba 3.9.1 depolarises both lobes.
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `distribution` | string | `beckmann` | `beckmann` or `ggx` |
//! | `alpha` | float | 0.1 | roughness of the coating |
//! | `sample_visible` | boolean | true | sample visible normals only |
//! | `int_ior` | float / string | `polypropylene` (1.49) | index of the coating |
//! | `ext_ior` | float / string | `air` | index outside |
//! | `diffuse_reflectance` | rgb / spectrum / float / texture | 0.5 | base albedo ρ |
//! | `specular_reflectance` | rgb / spectrum / float / texture | 1 | scale s of the coating's reflection |
//! | `nonlinear` | boolean | false | account for the colour shift of internal scattering |
//!
//! ```xml
//! <bsdf type="roughplastic">
//!     <string name="distribution" value="ggx"/>
//!     <float name="alpha" value="0.2"/>
//!     <rgb name="diffuse_reflectance" value="0.1, 0.27, 0.36"/>
//! </bsdf>
//! ```

use super::dielectric::AIR;
use super::fresnel::fresnel_dielectric;
use super::microfacet::{Microfacet, MicrofacetType};
use super::plastic::POLYPROPYLENE;
use super::{BsdfContext, BsdfModel, BsdfSample, Lobe, choose_lobe};
use crate::geometry::SurfaceInteraction;
use crate::math::sampling::cosine_hemisphere_pdf;
use crate::scene::error::Result;
use crate::scene::loader::PluginLoader;
use crate::scene::props::Props;
use crate::spectrum::mueller::{interface_to_canonical, specular_reflection};
use crate::spectrum::{Rgb, Spectrum};
use crate::texture::Texture;
use glam::{Vec2, Vec3};

/// Entries of the transmittance table (Mitsuba's `MI_ROUGH_TRANSMITTANCE_RES`).
const TABLE: usize = 64;

#[derive(Clone, Debug)]
pub struct RoughPlastic {
    pub diffuse_reflectance: Texture,
    pub specular_reflectance: Texture,
    pub kind: MicrofacetType,
    pub alpha: f32,
    pub sample_visible: bool,
    pub eta: f32,
    pub nonlinear: bool,
    inv_eta2: f32,
    specular_sampling_weight: f32,
    /// T(μ, η) at μ = i / 63.
    external_transmittance: [f32; TABLE],
    /// R_int.
    internal_reflectance: f32,
}

impl RoughPlastic {
    /// Reads the parameters in the table above.
    pub fn from_props(props: &Props, loader: &dyn PluginLoader) -> Result<RoughPlastic> {
        let int_ior = props.ior("int_ior", POLYPROPYLENE)?;
        let ext_ior = props.ior("ext_ior", AIR)?;
        if int_ior == ext_ior {
            return Err(props.error_at("int_ior", "the interior and exterior indices of refraction must differ"));
        }
        let kind = match props.choice("distribution", "beckmann", &["beckmann", "ggx"])? {
            "ggx" => MicrofacetType::Ggx,
            _ => MicrofacetType::Beckmann,
        };
        for name in ["alpha_u", "alpha_v"] {
            if props.has(name) || props.has_child(name) {
                return Err(props.error_at(name, "roughplastic is isotropic (as in Mitsuba): give \"alpha\", not \"alpha_u\"/\"alpha_v\""));
            }
        }
        if props.has_child("alpha") {
            return Err(props.error_at("alpha", "roughplastic's \"alpha\" must be a float (as in Mitsuba; its tables depend on it), not a texture"));
        }
        let alpha = props.float("alpha", 0.1)?;
        if !(alpha.is_finite() && alpha >= 0.0) {
            return Err(props.error_at("alpha", "roughness \"alpha\" must be a non-negative number"));
        }
        let sample_visible = props.bool("sample_visible", true)?;
        let diffuse = loader.reflectance(props, "diffuse_reflectance", Rgb::new(0.5, 0.5, 0.5))?;
        let specular = loader.reflectance(props, "specular_reflectance", Rgb::WHITE)?;
        let nonlinear = props.bool("nonlinear", false)?;
        Ok(RoughPlastic::new(kind, alpha, sample_visible, int_ior / ext_ior, diffuse, specular, nonlinear))
    }

    pub fn new(
        kind: MicrofacetType,
        alpha: f32,
        sample_visible: bool,
        eta: f32,
        diffuse_reflectance: Texture,
        specular_reflectance: Texture,
        nonlinear: bool,
    ) -> RoughPlastic {
        let (d_mean, s_mean) = (diffuse_reflectance.mean(), specular_reflectance.mean());
        let w = s_mean / (d_mean + s_mean);
        // The tables always use visible normals (as Mitsuba's).
        let mf = Microfacet::new(kind, alpha, alpha, true);
        let mut external_transmittance = [0.0; TABLE];
        let mut internal = 0.0f64;
        for (i, t) in external_transmittance.iter_mut().enumerate() {
            let mu = (i as f32 / (TABLE - 1) as f32).max(1e-6);
            *t = rough_transmittance(&mf, mu, eta) as f32;
            internal += rough_reflectance(&mf, mu, 1.0 / eta) * mu as f64;
        }
        RoughPlastic {
            diffuse_reflectance,
            specular_reflectance,
            kind,
            alpha,
            sample_visible,
            eta,
            nonlinear,
            inv_eta2: 1.0 / (eta * eta),
            specular_sampling_weight: if w.is_finite() { w } else { 0.5 },
            external_transmittance,
            internal_reflectance: (2.0 * internal / TABLE as f64) as f32,
        }
    }

    /// The distribution (isotropic, constant).
    #[inline]
    fn microfacet(&self) -> Microfacet {
        Microfacet::new(self.kind, self.alpha, self.alpha, self.sample_visible)
    }

    /// T(θ) interpolated linearly in the table at cos θ = `mu`.
    #[inline]
    fn transmittance(&self, mu: f32) -> f32 {
        let x = mu * (TABLE - 1) as f32;
        let i = (x.max(0.0) as usize).min(TABLE - 2);
        let w1 = x - i as f32;
        (1.0 - w1) * self.external_transmittance[i] + w1 * self.external_transmittance[i + 1]
    }

    /// Probability of the specular lobe given T(θ_i).
    #[inline]
    fn prob_specular(&self, ctx: &BsdfContext, t_i: f32) -> Option<f32> {
        let s = (1.0 - t_i) * self.specular_sampling_weight;
        let d = t_i * (1.0 - self.specular_sampling_weight);
        let p = if s + d > 0.0 { s / (s + d) } else { 0.0 };
        choose_lobe(ctx, Lobe::GLOSSY_REFLECTION, Lobe::DIFFUSE_REFLECTION, p)
    }
}

/// R(μ, η): the albedo of a rough dielectric interface's reflection lobe
/// (Fresnel times masking, over the visible normals) for incidence cos θ = μ,
/// by Gauss–Legendre quadrature over the sampling square (Mitsuba's
/// `eval_reflectance`).
pub fn rough_reflectance(mf: &Microfacet, mu: f32, eta: f32) -> f64 {
    let n = if eta > 1.0 { 32 } else { 128 };
    let (nodes, weights) = gauss_legendre(n);
    let wi = Vec3::new((1.0 - mu * mu).max(0.0).sqrt(), 0.0, mu);
    let mut sum = 0.0f64;
    for (x, wx) in nodes.iter().zip(&weights) {
        for (y, wy) in nodes.iter().zip(&weights) {
            let u = Vec2::new((0.5 * x + 0.5) as f32, (0.5 * y + 0.5) as f32);
            let (m, _) = mf.sample(wi, u);
            let c = wi.dot(m);
            let wo = 2.0 * c * m - wi;
            if wo.z <= 0.0 || wi.z <= 0.0 {
                continue;
            }
            let f = fresnel_dielectric(c, eta).r;
            let v = (mf.g1(wo, m) * f) as f64;
            if v.is_finite() {
                sum += v * wx * wy * 0.25;
            }
        }
    }
    sum
}

/// T(μ, η): the albedo of a rough dielectric interface's transmission lobe
/// ((1 − F) times the masking of the refracted direction, over the visible
/// normals) for incidence cos θ = μ, by the same quadrature (Mitsuba's
/// `eval_transmittance`). Less than 1 − R(μ, η): the masking of the
/// refracted light is lost too.
pub fn rough_transmittance(mf: &Microfacet, mu: f32, eta: f32) -> f64 {
    let n = if eta > 1.0 { 32 } else { 128 };
    let (nodes, weights) = gauss_legendre(n);
    let wi = Vec3::new((1.0 - mu * mu).max(0.0).sqrt(), 0.0, mu);
    let mut sum = 0.0f64;
    for (x, wx) in nodes.iter().zip(&weights) {
        for (y, wy) in nodes.iter().zip(&weights) {
            let u = Vec2::new((0.5 * x + 0.5) as f32, (0.5 * y + 0.5) as f32);
            let (m, _) = mf.sample(wi, u);
            let c = wi.dot(m);
            let fr = fresnel_dielectric(c, eta);
            // Refraction about m (cos_t carries the side).
            let wo = m * (c * fr.eta_ti + fr.cos_t) - wi * fr.eta_ti;
            if wo.z * wi.z >= 0.0 {
                continue;
            }
            let v = (mf.g1(wo, m) * (1.0 - fr.r)) as f64;
            if v.is_finite() {
                sum += v * wx * wy * 0.25;
            }
        }
    }
    sum
}

/// Nodes and weights of the n-point Gauss–Legendre rule on [−1, 1] (Newton
/// iteration on the Legendre polynomial from Chebyshev starting points).
pub fn gauss_legendre(n: usize) -> (Vec<f64>, Vec<f64>) {
    let (mut nodes, mut weights) = (vec![0.0; n], vec![0.0; n]);
    for i in 0..n {
        let mut x = (std::f64::consts::PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
        let mut dp = 1.0;
        for _ in 0..100 {
            // P_n(x) and P_n'(x) by the three-term recurrence.
            let (mut p0, mut p1) = (1.0f64, x);
            for k in 2..=n {
                let p2 = ((2 * k - 1) as f64 * x * p1 - (k - 1) as f64 * p0) / k as f64;
                p0 = p1;
                p1 = p2;
            }
            dp = n as f64 * (x * p1 - p0) / (x * x - 1.0);
            let dx = p1 / dp;
            x -= dx;
            if dx.abs() < 1e-15 {
                break;
            }
        }
        nodes[i] = x;
        weights[i] = 2.0 / ((1.0 - x * x) * dp * dp);
    }
    (nodes, weights)
}

impl BsdfModel for RoughPlastic {
    fn lobes(&self) -> Lobe {
        Lobe::GLOSSY_REFLECTION | Lobe::DIFFUSE_REFLECTION
    }

    fn has_mueller_model(&self) -> bool {
        true
    }

    #[inline]
    fn eval<S: Spectrum>(&self, ctx: &BsdfContext, si: &SurfaceInteraction, wi: Vec3, wo: Vec3, wl: &S::Wavelengths) -> S {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return S::zero();
        }
        let mut result = S::zero();
        if ctx.wants(Lobe::GLOSSY_REFLECTION) {
            let h = (wi + wo).normalize();
            let mf = self.microfacet();
            let dg = mf.d(h) * mf.g(wi, wo, h);
            if dg > 0.0 && dg.is_finite() {
                let scale: S = self.specular_reflectance.eval_spectrum(si.uv, wl);
                let c = wi.dot(h);
                let value = dg / (4.0 * wi.z);
                result = if S::POLARIZED {
                    // Light arrives along −wo and leaves along wi (towards the
                    // camera), reflected by the facet of world normal h.
                    let m = specular_reflection(wo.dot(h), self.eta);
                    let m = interface_to_canonical(m, si.to_world(h), -si.to_world(wo), si.to_world(wi));
                    S::mueller(m, scale) * value
                } else {
                    scale * (fresnel_dielectric(c, self.eta).r * value)
                };
            }
        }
        if ctx.wants(Lobe::DIFFUSE_REFLECTION) {
            let r = self.internal_reflectance;
            let rho: S = if self.nonlinear {
                self.diffuse_reflectance.eval_spectrum_map(si.uv, wl, |d| d / (1.0 - d * r))
            } else {
                self.diffuse_reflectance.eval_spectrum_map(si.uv, wl, |d| d / (1.0 - r))
            };
            let t = self.transmittance(wi.z) * self.transmittance(wo.z);
            result = result + rho.depolarize() * (self.inv_eta2 * t * cosine_hemisphere_pdf(wo));
        }
        result
    }

    #[inline]
    fn pdf<S: Spectrum>(&self, ctx: &BsdfContext, _si: &SurfaceInteraction, wi: Vec3, wo: Vec3, _wl: &S::Wavelengths) -> f32 {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return 0.0;
        }
        let Some(p_s) = self.prob_specular(ctx, self.transmittance(wi.z)) else {
            return 0.0;
        };
        let mut pdf = (1.0 - p_s) * cosine_hemisphere_pdf(wo);
        if p_s > 0.0 {
            let h = (wi + wo).normalize();
            if wi.dot(h) > 0.0 && wo.dot(h) > 0.0 {
                let p = self.microfacet().pdf(wi, h) / (4.0 * wo.dot(h));
                if p.is_finite() {
                    pdf += p_s * p;
                }
            }
        }
        pdf
    }

    #[inline]
    fn sample<S: Spectrum>(&self, ctx: &BsdfContext, si: &SurfaceInteraction, wi: Vec3, u1: f32, u2: Vec2, wl: &S::Wavelengths) -> Option<BsdfSample<S>> {
        if wi.z <= 0.0 {
            return None;
        }
        let p_s = self.prob_specular(ctx, self.transmittance(wi.z))?;
        let (wo, lobe) = self.microfacet().sample_over_diffuse(wi, p_s, u1, u2);
        if !(wo.z > 0.0) {
            return None;
        }
        self.mixture_sample::<S>(ctx, si, wi, wo, lobe, wl)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::sampling::square_to_cosine_hemisphere;
    use crate::bsdf::Bsdf;
    use crate::bsdf::testing::*;

    fn plastic(kind: MicrofacetType, alpha: f32, eta: f32, nonlinear: bool, visible: bool, rho: Rgb) -> RoughPlastic {
        RoughPlastic::new(kind, alpha, visible, eta, Texture::constant(rho), Texture::constant(Rgb::WHITE), nonlinear)
    }

    fn all_kinds() -> Vec<RoughPlastic> {
        let mut v = vec![];
        for kind in [MicrofacetType::Beckmann, MicrofacetType::Ggx] {
            for visible in [true, false] {
                for (alpha, eta, nl) in [(0.03, 1.49, false), (0.1, 1.49, true), (0.4, 1.9, false), (1.0, 1.33, true)] {
                    v.push(plastic(kind, alpha, eta, nl, visible, Rgb::new(0.8, 0.4, 0.1)));
                }
            }
        }
        v
    }

    fn dir(theta: f32, phi: f32) -> Vec3 {
        Vec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos())
    }

    #[test]
    fn gauss_legendre_integrates_polynomials_exactly() {
        for n in [1usize, 5, 32, 128] {
            let (x, w) = gauss_legendre(n);
            // ∫₋₁¹ x^k dx = 2/(k+1) for even k, 0 for odd, exact up to degree 2n − 1.
            for k in 0..(2 * n).min(40) {
                let q: f64 = x.iter().zip(&w).map(|(x, w)| w * x.powi(k as i32)).sum();
                let exact = if k % 2 == 0 { 2.0 / (k as f64 + 1.0) } else { 0.0 };
                assert!((q - exact).abs() < 1e-12, "n={n} k={k}: {q} vs {exact}");
            }
        }
    }

    #[test]
    fn rough_reflectance_tends_to_the_smooth_fresnel_reflectance() {
        // As α → 0 the lobe's albedo is the smooth interface's F(θ).
        let mf = Microfacet::new(MicrofacetType::Ggx, 1e-4, 1e-4, true);
        for mu in [0.1f32, 0.5, 0.9, 1.0] {
            for eta in [1.5f32, 1.0 / 1.5] {
                let r = rough_reflectance(&mf, mu, eta);
                let f = fresnel_dielectric(mu, eta).r as f64;
                assert!((r - f).abs() < 2e-3, "μ={mu} η={eta}: {r} vs {f}");
            }
        }
    }

    #[test]
    fn eval_pdf_and_albedo_match_mitsuba() {
        // Mitsuba 3.9.1 (scalar_rgb, Python bindings, computed once):
        // diffuse_reflectance (0.8, 0.4, 0.1), wi at (θ_i, φ = 0.2), wo at
        // (θ_o, φ = 2.5): the diffuse lobe's eval (R and B), both lobes'
        // eval (R) and pdf; and the mean sample weight (100 000 samples) at
        // θ_i = 0.2 and 1.2 (φ = 0).
        type Row = (MicrofacetType, f32, f32, bool, [(f32, f32, f32, f32, f32, f32); 3], [(f32, [f32; 3]); 2]);
        use MicrofacetType::{Beckmann, Ggx};
        let mitsuba: [Row; 4] = [
            (Beckmann, 0.1, 1.49, false,
             [(0.4, 1.2, 0.079362, 0.00992, 0.079362, 0.105401), (1.3, 0.2, 0.194197, 0.024275, 0.194197, 0.182115), (0.0, 0.9, 0.151485, 0.018936, 0.151485, 0.181055)],
             [(0.2, [0.78164, 0.4105, 0.13215]), (1.2, [0.80621, 0.4801, 0.23552])]),
            (Ggx, 0.3, 1.49, false,
             [(0.4, 1.2, 0.056428, 0.007053, 0.05964, 0.111423), (1.3, 0.2, 0.146014, 0.018252, 0.15293, 0.255018), (0.0, 0.9, 0.105418, 0.013177, 0.109391, 0.18859)],
             [(0.2, [0.56201, 0.29833, 0.10058]), (1.2, [0.54507, 0.31174, 0.13674])]),
            (Beckmann, 0.35, 1.9, true,
             [(0.4, 1.2, 0.041154, 0.002492, 0.050148, 0.109548), (1.3, 0.2, 0.107279, 0.006496, 0.11932, 0.233301), (0.0, 0.9, 0.07641, 0.004627, 0.090708, 0.187801)],
             [(0.2, [0.47978, 0.21582, 0.11992]), (1.2, [0.49067, 0.25501, 0.16939])]),
            (Ggx, 0.8, 1.5, true,
             [(0.4, 1.2, 0.027536, 0.003033, 0.030467, 0.112293), (1.3, 0.2, 0.068204, 0.007513, 0.075863, 0.221619), (0.0, 0.9, 0.058141, 0.006405, 0.061561, 0.179785)],
             [(0.2, [0.31083, 0.15383, 0.05006]), (1.2, [0.24419, 0.13111, 0.05637])]),
        ];
        let si = dummy_interaction();
        let diffuse = BsdfContext::RADIANCE.with_lobes(Lobe::DIFFUSE_REFLECTION);
        let close = |a: f32, b: f32, tol: f32| (a - b).abs() <= tol * b.abs() + 1e-6;
        for (kind, alpha, eta, nl, evals, albedos) in mitsuba {
            let b = Bsdf::RoughPlastic(plastic(kind, alpha, eta, nl, true, Rgb::new(0.8, 0.4, 0.1)));
            for (ti, to, fd_r, fd_b, f_r, p) in evals {
                let (wi, wo) = (dir(ti, 0.2), dir(to, 2.5));
                let fd: Rgb = b.eval(&diffuse, &si, wi, wo, &());
                let f: Rgb = b.eval(&BsdfContext::RADIANCE, &si, wi, wo, &());
                let pdf = b.pdf::<Rgb>(&BsdfContext::RADIANCE, &si, wi, wo, &());
                eprintln!("{kind:?} α={alpha} θ=({ti},{to}): f_d {} {} f {} pdf {pdf} vs Mitsuba {fd_r} {fd_b} {f_r} {p}", fd[0], fd[2], f[0]);
                assert!(close(fd[0], fd_r, 2e-3) && close(fd[2], fd_b, 2e-3), "{kind:?} α={alpha}: diffuse {fd:?} vs {fd_r}, {fd_b}");
                assert!(close(f[0], f_r, 3e-3), "{kind:?} α={alpha}: {} vs {f_r}", f[0]);
                assert!(close(pdf, p, 3e-3), "{kind:?} α={alpha}: pdf {pdf} vs {p}");
            }
            for (ti, expected) in albedos {
                let a = estimate_albedo_sampled(&b, dir(ti, 0.0), 200_000, 5);
                eprintln!("{kind:?} α={alpha} θ={ti}: albedo {a:?} vs Mitsuba {expected:?}");
                for c in 0..3 {
                    assert!((a[c] - expected[c]).abs() < 0.01, "{kind:?} α={alpha} θ={ti}: {a:?} vs {expected:?}");
                }
            }
        }
    }

    #[test]
    fn chi2_sampling_matches_pdf() {
        let mut seed = 500;
        let kinds = all_kinds();
        let n = kinds.len() * 3;
        for m in kinds {
            let (m_kind, m_alpha, m_visible) = (m.kind, m.alpha, m.sample_visible);
            let b = Bsdf::RoughPlastic(m);
            for theta in [0.1f32, 0.9, 1.45] {
                seed += 1;
                eprintln!("χ² {:?} α={} visible={} θ={theta}", m_kind, m_alpha, m_visible);
                chi2_test_at(&b, incident(theta, 0.6), seed, 0.01 / n as f64);
            }
        }
    }

    #[test]
    fn reciprocal_consistent_and_energy_conserving() {
        let mut seed = 600;
        for m in all_kinds() {
            let b = Bsdf::RoughPlastic(m);
            seed += 1;
            check_reciprocity(&b, seed);
            for theta in [0.0f32, 0.8, 1.4] {
                check_sample_consistency(&b, incident(theta, 1.1), seed + 50);
                let a = estimate_albedo_sampled(&b, incident(theta, 1.1), 50_000, seed + 90);
                for c in 0..3 {
                    assert!(a[c] <= 1.0 + 0.01, "albedo {a:?}");
                }
            }
            // Each lobe alone, too.
            for lobe in [Lobe::GLOSSY_REFLECTION, Lobe::DIFFUSE_REFLECTION] {
                check_sample_consistency_ctx(&b, &BsdfContext::RADIANCE.with_lobes(lobe), incident(0.7, 0.3), seed + 70);
            }
        }
        // White furnace: a white base with `nonlinear`. The light lost is the
        // rough coating's single-scattering loss (masking on the way in and
        // out) and the bias of Mitsuba's R_int (a plain mean over the 64 table
        // values); Mitsuba 3.9.1 (scalar_rgb, 200 000 samples, computed once
        // with its Python bindings) gives 0.9089 at θ = 0.2 and 0.9079 at 1.0.
        let b = Bsdf::RoughPlastic(plastic(MicrofacetType::Ggx, 0.1, 1.5, true, true, Rgb::WHITE));
        for (theta, mitsuba) in [(0.2f32, 0.9089f32), (1.0, 0.9079)] {
            let a = estimate_albedo_sampled(&b, incident(theta, 0.0), 200_000, 9)[0];
            eprintln!("white rough plastic θ={theta}: albedo {a} (Mitsuba {mitsuba})");
            assert!((a - mitsuba).abs() < 0.004, "θ={theta}: {a} vs Mitsuba {mitsuba}");
        }
    }

    #[test]
    fn alpha_to_zero_is_the_smooth_plastic() {
        // Nearly smooth, the coating's tabulated transmittance is the smooth
        // interface's 1 − F(θ), R_int is the diffuse Fresnel reflectance F_dr
        // (up to the bias of Mitsuba's plain mean over the table and the
        // < 0.6 % error of the smooth model's fit), so the diffuse lobe is
        // the smooth plastic's times (1 − F_dr)/(1 − R_int); the glossy
        // lobe's albedo is F(θ_i).
        use crate::bsdf::Plastic;
        use crate::bsdf::fresnel::fresnel_diffuse_reflectance;
        let rho = Rgb::new(0.6, 0.3, 0.2);
        let m = plastic(MicrofacetType::Beckmann, 0.001, 1.5, false, true, rho);
        for mu in [0.05f32, 0.3, 0.7, 1.0] {
            let t = m.transmittance(mu);
            let f = 1.0 - fresnel_dielectric(mu, 1.5).r;
            assert!((t - f).abs() < 2e-3, "μ={mu}: T {t} vs 1 − F {f}");
        }
        let f_dr = fresnel_diffuse_reflectance(1.0 / 1.5);
        eprintln!("R_int {} vs F_dr {f_dr}", m.internal_reflectance);
        assert!((m.internal_reflectance - f_dr).abs() < 0.015, "R_int {} vs F_dr {f_dr}", m.internal_reflectance);
        let scale = (1.0 - f_dr) / (1.0 - m.internal_reflectance);
        let rough = Bsdf::RoughPlastic(m);
        let smooth = Bsdf::Plastic(Plastic::new(Texture::constant(rho), None, 1.5, false));
        let si = dummy_interaction();
        let diffuse = BsdfContext::RADIANCE.with_lobes(Lobe::DIFFUSE_REFLECTION);
        for (ti, to) in [(0.2f32, 0.5f32), (1.0, 0.3), (0.6, 1.2)] {
            let (wi, wo) = (dir(ti, 0.0), dir(to, 2.0));
            let (a, b): (Rgb, Rgb) = (rough.eval(&diffuse, &si, wi, wo, &()), smooth.eval(&diffuse, &si, wi, wo, &()));
            for c in 0..3 {
                assert!((a[c] - b[c] * scale).abs() < 5e-3 * b[c], "θ=({ti},{to}): {} vs {}", a[c], b[c] * scale);
            }
            let glossy = BsdfContext::RADIANCE.with_lobes(Lobe::GLOSSY_REFLECTION);
            let mut sum = 0.0f64;
            let mut rng = crate::math::Pcg32::new(3, 1);
            let n = 20_000;
            for _ in 0..n {
                if let Some(s) = rough.sample::<Rgb>(&glossy, &si, wi, 0.5, Vec2::new(rng.next_f32(), rng.next_f32()), &()) {
                    sum += s.weight[0] as f64;
                }
            }
            let f = fresnel_dielectric(wi.z, 1.5).r as f64;
            assert!((sum / n as f64 - f).abs() < 0.005, "θ={ti}: {} vs F {f}", sum / n as f64);
        }
    }

    #[test]
    fn polarized_weights_have_the_unpolarized_intensity() {
        use crate::spectrum::Polarized;
        use crate::spectrum::mueller::degree_of_polarization;
        use glam::Vec4;
        let n = Vec3::new(0.2, -0.4, 0.9).normalize();
        let si = SurfaceInteraction { n, frame: crate::math::Frame::from_normal(n), ..dummy_interaction() };
        let b = Bsdf::RoughPlastic(plastic(MicrofacetType::Ggx, 0.2, 1.5, true, true, Rgb::new(0.3, 0.5, 0.7)));
        let mut rng = crate::math::Pcg32::new(8, 4);
        let (mut max_dop, mut diffuse_dop) = (0.0f32, 0.0f32);
        let dop = |w: &Polarized<Rgb>| {
            let st = w.stokes();
            degree_of_polarization(Vec4::new(st[0][0], st[1][0], st[2][0], st[3][0]))
        };
        for _ in 0..3000 {
            let wi = square_to_cosine_hemisphere(Vec2::new(rng.next_f32(), rng.next_f32()));
            let (u1, u2) = (rng.next_f32(), Vec2::new(rng.next_f32(), rng.next_f32()));
            let x = b.sample::<Rgb>(&BsdfContext::RADIANCE, &si, wi, u1, u2, &());
            let y = b.sample::<Polarized<Rgb>>(&BsdfContext::RADIANCE, &si, wi, u1, u2, &());
            let (Some(x), Some(y)) = (x, y) else {
                assert!(x.is_none() && y.is_none());
                continue;
            };
            assert!(x.wo == y.wo && x.pdf == y.pdf);
            for c in 0..3 {
                assert!((y.weight.0[0][0][c] - x.weight[c]).abs() <= 1e-4 * (1.0 + x.weight[c]));
            }
            max_dop = max_dop.max(dop(&y.weight));
            let d: Polarized<Rgb> = b.eval(&BsdfContext::RADIANCE.with_lobes(Lobe::DIFFUSE_REFLECTION), &si, wi, x.wo, &());
            diffuse_dop = diffuse_dop.max(dop(&d));
        }
        eprintln!("largest degree of polarisation of a sample weight {max_dop}, of the diffuse lobe {diffuse_dop}");
        // The coat polarises (strongly near Brewster's angle); the base does not.
        assert!(max_dop > 0.3, "{max_dop}");
        assert!(diffuse_dop < 1e-5, "{diffuse_dop}");
    }
}
