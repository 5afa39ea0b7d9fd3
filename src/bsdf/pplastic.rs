//! `pplastic` — Mitsuba 3.9.1's polarized plastic (after Baek et al. 2018,
//! "Simultaneous acquisition of polarimetric SVBRDF and normals"): a rough
//! specular reflection plus a diffuse term that enters and leaves through a
//! smooth interface, both acting on polarised light.
//!
//! Unlike `plastic`/`roughplastic` the two lobes are simply added (no
//! internal scattering between coating and base), with h the half vector
//! and F the dielectric Fresnel reflectance of relative index η:
//!
//! f(ω_i, ω_o) = s F(ω_i·h) D(h) G(ω_i, ω_o, h) / (4 cos θ_i cos θ_o)
//!             + (1 − F(cos θ_i)) (1 − F(cos θ_o)) ρ / π.
//!
//! It neither gains energy nor, in general, conserves it (Mitsuba says so
//! too). In the polarized modes the specular lobe is the facet's Fresnel
//! reflection in Mueller form in its s/p frames, and the diffuse lobe is
//! refraction in (Mueller transmission at θ_o), a depolarizer (the
//! subsurface scattering), and refraction out (at the refracted angle of
//! ω_i, from inside), each in the s/p frame of its own plane of incidence:
//! so diffusely reflected light comes out weakly polarised, in the plane
//! perpendicular to a specular highlight's — the cue shape-from-polarization
//! methods read.
//!
//! Sampling: the specular lobe with probability s̄ / (ρ̄ + s̄) (means of the
//! textures, s̄ = 1 when `specular_reflectance` is not given), by the
//! microfacet distribution, else a cosine-weighted direction; the pdf is
//! the mixture's. One-sided (light from below sees nothing), as in Mitsuba.
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `diffuse_reflectance` | rgb / spectrum / float / texture | 0.5 | albedo ρ of the diffuse term |
//! | `specular_reflectance` | rgb / spectrum / float / texture | 1 | scale s of the specular term |
//! | `int_ior` | float / string | `polypropylene` (1.49) | index inside |
//! | `ext_ior` | float / string | `air` | index outside |
//! | `distribution` | string | `beckmann` | `beckmann` or `ggx` |
//! | `alpha` or `alpha_u`, `alpha_v` | float / texture | 0.1 | roughness (anisotropic with two) |
//! | `sample_visible` | boolean | true | sample visible normals only |
//!
//! ```xml
//! <bsdf type="pplastic">
//!     <rgb name="diffuse_reflectance" value="0.05, 0.03, 0.1"/>
//!     <float name="alpha" value="0.06"/>
//! </bsdf>
//! ```

use super::dielectric::AIR;
use super::fresnel::fresnel_dielectric;
use super::microfacet::MicrofacetParams;
use super::plastic::POLYPROPYLENE;
use super::{BsdfContext, BsdfModel, BsdfSample, Lobe, TransportMode, choose_lobe};
use crate::geometry::SurfaceInteraction;
use crate::math::sampling::cosine_hemisphere_pdf;
use crate::scene::error::Result;
use crate::scene::loader::PluginLoader;
use crate::scene::props::Props;
use crate::spectrum::mueller::{depolarizer, interface_to_canonical, rotate_mueller_basis, specular_reflection, specular_transmission, stokes_basis};
use crate::spectrum::{Rgb, Spectrum};
use crate::texture::Texture;
use glam::{Vec2, Vec3};
use std::f32::consts::FRAC_1_PI;

#[derive(Clone, Debug)]
pub struct PolarizedPlastic {
    pub diffuse_reflectance: Texture,
    /// `None`: 1 (Mitsuba's default, which it leaves out of the sampling weight).
    pub specular_reflectance: Option<Texture>,
    pub microfacet: MicrofacetParams,
    /// η_int / η_ext.
    pub eta: f32,
    specular_sampling_weight: f32,
}

impl PolarizedPlastic {
    /// Reads the parameters in the table above.
    pub fn from_props(props: &Props, loader: &dyn PluginLoader) -> Result<PolarizedPlastic> {
        let int_ior = props.ior("int_ior", POLYPROPYLENE)?;
        let ext_ior = props.ior("ext_ior", AIR)?;
        if int_ior == ext_ior {
            return Err(props.error_at("int_ior", "the interior and exterior indices of refraction must differ"));
        }
        let microfacet = MicrofacetParams::from_props(props, loader)?;
        let diffuse = loader.reflectance(props, "diffuse_reflectance", Rgb::new(0.5, 0.5, 0.5))?;
        let specular = if props.has("specular_reflectance") || props.has_child("specular_reflectance") {
            Some(loader.reflectance(props, "specular_reflectance", Rgb::WHITE)?)
        } else {
            None
        };
        Ok(PolarizedPlastic::new(microfacet, int_ior / ext_ior, diffuse, specular))
    }

    pub fn new(microfacet: MicrofacetParams, eta: f32, diffuse_reflectance: Texture, specular_reflectance: Option<Texture>) -> PolarizedPlastic {
        let d_mean = diffuse_reflectance.mean();
        let s_mean = specular_reflectance.as_ref().map_or(1.0, Texture::mean);
        let w = s_mean / (d_mean + s_mean);
        PolarizedPlastic {
            diffuse_reflectance,
            specular_reflectance,
            microfacet,
            eta,
            specular_sampling_weight: if w.is_finite() { w } else { 0.5 },
        }
    }

    fn prob_specular(&self, ctx: &BsdfContext) -> Option<f32> {
        choose_lobe(ctx, Lobe::GLOSSY_REFLECTION, Lobe::DIFFUSE_REFLECTION, self.specular_sampling_weight)
    }
}

impl BsdfModel for PolarizedPlastic {
    fn lobes(&self) -> Lobe {
        Lobe::GLOSSY_REFLECTION | Lobe::DIFFUSE_REFLECTION
    }

    fn has_mueller_model(&self) -> bool {
        true
    }

    fn needs_tangent_frame(&self) -> bool {
        self.microfacet.is_anisotropic()
    }

    #[inline]
    fn eval<S: Spectrum>(&self, ctx: &BsdfContext, si: &SurfaceInteraction, wi: Vec3, wo: Vec3, wl: &S::Wavelengths) -> S {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return S::zero();
        }
        // Light arrives along −wo_hat and leaves along wi_hat.
        let (wo_hat, wi_hat) = if ctx.mode == TransportMode::Radiance { (wo, wi) } else { (wi, wo) };
        let mut result = S::zero();
        if ctx.wants(Lobe::GLOSSY_REFLECTION) {
            let h = (wi + wo).normalize();
            let mf = self.microfacet.at(si);
            let value = mf.d(h) * mf.g(wi, wo, h) / (4.0 * wi.z);
            if value > 0.0 && value.is_finite() {
                let scale: S = match &self.specular_reflectance {
                    Some(t) => t.eval_spectrum(si, wl),
                    None => S::splat(1.0),
                };
                result = if S::POLARIZED {
                    let m = specular_reflection(wo_hat.dot(h), self.eta);
                    let m = interface_to_canonical(m, si.to_world(h), -si.to_world(wo_hat), si.to_world(wi_hat));
                    S::mueller(m, scale) * value
                } else {
                    scale * (fresnel_dielectric(wi.dot(h), self.eta).r * value)
                };
            }
        }
        if ctx.wants(Lobe::DIFFUSE_REFLECTION) {
            let rho: S = self.diffuse_reflectance.eval_spectrum(si, wl);
            let diffuse = if S::POLARIZED {
                // In at θ of wo_hat; out from inside, along the refracted
                // direction of wi_hat (whose transmittance equals that of
                // wi_hat from outside, but whose Mueller matrix is the one
                // for light leaving).
                let t_in = specular_transmission(wo_hat.z, self.eta);
                let cos_inside = fresnel_dielectric(wi_hat.z, self.eta).cos_t.abs();
                let t_out = specular_transmission(-cos_inside, self.eta);
                let m = t_out * depolarizer(1.0) * t_in;
                let (n, from, to) = (si.to_world(Vec3::Z), -si.to_world(wo_hat), si.to_world(wi_hat));
                let axis = |forward: Vec3| {
                    let s = forward.cross(n);
                    if s.length_squared() > 1e-12 { s.normalize() } else { stokes_basis(forward) }
                };
                let m = rotate_mueller_basis(m, from, axis(from), stokes_basis(from), to, axis(to), stokes_basis(to));
                S::mueller(m, rho)
            } else {
                let t = (1.0 - fresnel_dielectric(wi.z, self.eta).r) * (1.0 - fresnel_dielectric(wo.z, self.eta).r);
                rho * t
            };
            result = result + diffuse * (FRAC_1_PI * wo.z);
        }
        result
    }

    #[inline]
    fn pdf<S: Spectrum>(&self, ctx: &BsdfContext, si: &SurfaceInteraction, wi: Vec3, wo: Vec3, _wl: &S::Wavelengths) -> f32 {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return 0.0;
        }
        let Some(p_s) = self.prob_specular(ctx) else { return 0.0 };
        let mut pdf = (1.0 - p_s) * cosine_hemisphere_pdf(wo);
        if p_s > 0.0 {
            let h = (wi + wo).normalize();
            if wi.dot(h) > 0.0 && wo.dot(h) > 0.0 {
                let p = self.microfacet.at(si).pdf(wi, h) / (4.0 * wo.dot(h));
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
        let p_s = self.prob_specular(ctx)?;
        let (wo, lobe) = self.microfacet.at(si).sample_over_diffuse(wi, p_s, u1, u2);
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
    use crate::bsdf::microfacet::MicrofacetType;
    use crate::bsdf::testing::*;
    use crate::spectrum::Polarized;

    fn pplastic(kind: MicrofacetType, alpha: f32, eta: f32, rho: Rgb) -> Bsdf {
        let mf = MicrofacetParams { kind, alpha_u: Texture::constant(Rgb::new(alpha, alpha, alpha)), alpha_v: None, sample_visible: true };
        Bsdf::PolarizedPlastic(PolarizedPlastic::new(mf, eta, Texture::constant(rho), None))
    }

    fn dir(theta: f32, phi: f32) -> Vec3 {
        Vec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos())
    }

    #[test]
    fn eval_and_pdf_match_mitsuba() {
        // Mitsuba 3.9.1 scalar_rgb (Python bindings, computed once):
        // diffuse_reflectance (0.8, 0.4, 0.1), wi at (θ_i, φ = 0.2), wo at
        // (θ_o, φ = 2.5): eval R, eval B, pdf.
        use MicrofacetType::{Beckmann, Ggx};
        let mitsuba = [
            (Beckmann, 0.1, 1.49, [(0.4, 1.2, 0.074994, 0.009374, 0.034871), (1.3, 0.2, 0.182181, 0.022773, 0.094315), (0.0, 0.9, 0.143148, 0.017894, 0.05982)]),
            (Ggx, 0.3, 1.49, [(0.4, 1.2, 0.078206, 0.012586, 0.089801), (1.3, 0.2, 0.189097, 0.029689, 0.201282), (0.0, 0.9, 0.147121, 0.021867, 0.132518)]),
            (Ggx, 0.6, 1.9, [(0.4, 1.2, 0.074128, 0.016679, 0.114703), (1.3, 0.2, 0.180559, 0.040807, 0.234716), (0.0, 0.9, 0.13665, 0.026425, 0.146177)]),
        ];
        let si = dummy_interaction();
        let close = |a: f32, b: f32| (a - b).abs() <= 2e-3 * b.abs() + 2e-6;
        for (kind, alpha, eta, rows) in mitsuba {
            let b = pplastic(kind, alpha, eta, Rgb::new(0.8, 0.4, 0.1));
            for (ti, to, f_r, f_b, p) in rows {
                let (wi, wo) = (dir(ti, 0.2), dir(to, 2.5));
                let f: Rgb = b.eval(&BsdfContext::RADIANCE, &si, wi, wo, &());
                let pdf = b.pdf::<Rgb>(&BsdfContext::RADIANCE, &si, wi, wo, &());
                assert!(close(f[0], f_r) && close(f[2], f_b) && close(pdf, p), "{kind:?} α={alpha} θ=({ti},{to}): f {f:?} pdf {pdf}, Mitsuba {f_r} {f_b} {p}");
            }
        }
    }

    #[test]
    fn mueller_matrices_match_mitsuba() {
        // Mitsuba 3.9.1 scalar_spectral_polarized, GGX α = 0.3, int_ior 1.5,
        // diffuse_reflectance 0.5 (a flat spectrum), identity shading frame:
        // the full Mueller matrix (rows), and the diffuse component alone.
        type M = [[f32; 4]; 4];
        let cases: [((f32, f32, f32, f32), M, M); 3] = [
            (
                (0.9, 0.2, 0.7, 2.5),
                [[0.118532, -0.005741, 0.003319, 0.0], [0.000755, 0.007853, -0.003415, 0.0], [0.006553, -0.005286, -0.005404, 0.0], [0.0, 0.0, 0.0, -0.00657]],
                [[1.090994e-01, 1.024600e-03, 3.463675e-03, 0.0], [6.290501e-03, 5.907679e-05, 1.997100e-04, 0.0], [2.659577e-03, 2.497723e-05, 8.443590e-05, 0.0], [0.0; 4]],
            ),
            (
                (1.1, 0.0, 1.1, std::f32::consts::PI),
                [[2.351264e-01, -1.593969e-01, 0.0, 0.0], [-1.593969e-01, 1.781737e-01, 0.0, 0.0], [0.0, 0.0, 6.326357e-02, 0.0], [0.0, 0.0, 0.0, 6.326357e-02]],
                [[5.766426e-02, 6.405819e-03, 0.0, 0.0], [6.405822e-03, 7.116114e-04, 0.0, 0.0], [0.0; 4], [0.0; 4]],
            ),
            (
                (0.3, 1.0, 1.3, 4.0),
                [[0.034362, -0.000201, -0.003028, 0.0], [0.000385, 0.001842, 0.000127, 0.0], [-0.002719, -0.000499, -0.003368, 0.0], [0.0, 0.0, 0.0, -0.001788]],
                [[3.095470e-02, -8.606125e-04, -5.851911e-03, 0.0], [-6.664457e-05, 1.852874e-06, 1.259899e-05, 0.0], [1.456209e-04, -4.048599e-06, -2.752928e-05, 0.0], [0.0; 4]],
            ),
        ];
        let b = pplastic(MicrofacetType::Ggx, 0.3, 1.5, Rgb::new(0.5, 0.5, 0.5));
        let si = dummy_interaction();
        for ((ti, pi, to, po), full, diffuse) in cases {
            let (wi, wo) = (dir(ti, pi), dir(to, po));
            for (ctx, expected) in [(BsdfContext::RADIANCE, full), (BsdfContext::RADIANCE.with_lobes(Lobe::DIFFUSE_REFLECTION), diffuse)] {
                let f: Polarized<Rgb> = b.eval(&ctx, &si, wi, wo, &());
                for r in 0..4 {
                    for c in 0..4 {
                        let (got, want) = (f.0[r][c][0], expected[r][c]);
                        assert!((got - want).abs() <= 3e-3 * expected[0][0], "({ti},{pi})→({to},{po}) {:?}: m{r}{c} {got} vs Mitsuba {want}\n{f:?}", ctx.lobes);
                    }
                }
            }
        }
    }

    #[test]
    fn sampling_matches_the_pdf_and_weights_are_consistent() {
        let mut seed = 700;
        for (kind, alpha) in [(MicrofacetType::Beckmann, 0.05), (MicrofacetType::Ggx, 0.3), (MicrofacetType::Ggx, 1.0)] {
            let b = pplastic(kind, alpha, 1.49, Rgb::new(0.6, 0.3, 0.1));
            for theta in [0.1f32, 0.9, 1.45] {
                seed += 1;
                chi2_test_at(&b, incident(theta, 0.6), seed, 0.01 / 9.0);
                check_sample_consistency(&b, incident(theta, 0.6), seed + 50);
            }
            check_reciprocity(&b, seed + 90);
            // Neither lobe gains energy: with a white base the albedo stays
            // below one (the sum is not energy conserving, but it loses).
            let w = pplastic(kind, alpha, 1.49, Rgb::WHITE);
            for theta in [0.0f32, 0.8, 1.4] {
                let a = estimate_albedo_sampled(&w, incident(theta, 1.1), 50_000, seed + 7);
                assert!(a[0] <= 1.0 + 0.01, "{kind:?} α={alpha} θ={theta}: albedo {a:?}");
            }
        }
    }

    #[test]
    fn unpolarized_intensity_is_the_mueller_m00() {
        let b = pplastic(MicrofacetType::Ggx, 0.2, 1.5, Rgb::new(0.3, 0.5, 0.7));
        let si = dummy_interaction();
        let mut rng = crate::math::Pcg32::new(8, 4);
        for _ in 0..2000 {
            let wi = square_to_cosine_hemisphere(Vec2::new(rng.next_f32(), rng.next_f32()));
            let wo = square_to_cosine_hemisphere(Vec2::new(rng.next_f32(), rng.next_f32()));
            let f: Rgb = b.eval(&BsdfContext::RADIANCE, &si, wi, wo, &());
            let g: Polarized<Rgb> = b.eval(&BsdfContext::RADIANCE, &si, wi, wo, &());
            for c in 0..3 {
                // Equal up to the rounding of the two ways of computing it.
                assert!((g.0[0][0][c] - f[c]).abs() <= 1e-3 * f[c] + 1e-7, "{f:?} vs {g:?}");
            }
        }
    }
}
