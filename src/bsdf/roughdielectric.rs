//! `roughdielectric` — a rough interface between two dielectrics (frosted
//! or etched glass): the microfacet model of Walter et al. (2007) with
//! reflection and refraction at every facet, as Mitsuba 3's.
//!
//! Each facet of normal m is a smooth `dielectric`: it reflects F(wi·m) and
//! refracts 1 − F(wi·m) of the light. With η the relative index on wi's
//! side crossing to wo's (η = int_ior/ext_ior from outside, 1/η inside),
//!
//! * reflection (wi, wo on the same side), h = (wi + wo)/‖…‖:
//!   f cos θ_o = F D G / (4 |cos θ_i|);
//! * refraction, h = −(wi + η wo)/‖…‖ turned to the outside:
//!   f cos θ_o = (1/η²) (1 − F) D G η² |wi·h| |wo·h| / (|cos θ_i| (wi·h + η wo·h)²),
//!
//! where the 1/η² (radiance is L/η²-conserved across an interface, the
//! smooth dielectric's rule) applies to radiance transport only
//! (`TransportMode::Importance` leaves it out). Sampling draws a facet
//! normal (visible normals by default; with `sample_visible` = false the
//! whole distribution, widened by 1.2 − 0.2 √|cos θ_i| as Walter et al. and
//! Mitsuba do), then reflection with probability F and refraction
//! otherwise. Both sides of the surface scatter. Sample weights are always
//! eval/pdf (Mitsuba's are not with `sample_visible` = false: it omits
//! the ratio of the widened to the true distribution).
//!
//! Dispersion: a dispersive `int_ior`/`ext_ior` (`sellmeier:…`, see
//! `dispersion.rs`) refracts by η(λ) of the hero wavelength in the spectral
//! modes, and the integrators keep the hero wavelength only past such a
//! surface; Mitsuba has no dispersive indices.
//!
//! Polarisation (polarized modes): each facet reflects and refracts by the
//! Fresnel equations in Mueller form (`mueller::specular_reflection`,
//! `specular_transmission`), in the s/p frame of its own plane of
//! incidence, turned to the canonical Stokes frames of the beams.
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `int_ior` | float / string | `bk7` (1.5046) | interior index, a name, or a dispersive form (Snell only) |
//! | `ext_ior` | float / string | `air` (1.000277) | exterior index, or a name |
//! | `specular_reflectance` | rgb / spectrum / float / texture | 1 | scale of reflection (not physical) |
//! | `specular_transmittance` | rgb / spectrum / float / texture | 1 | scale of transmission (not physical) |
//! | `distribution` | string | `beckmann` | `beckmann` or `ggx` |
//! | `alpha` | float / texture | 0.1 | roughness |
//! | `alpha_u`, `alpha_v` | float / texture | — | anisotropic roughness along ∂p/∂u and across it |
//! | `sample_visible` | boolean | true | sample visible normals only |
//!
//! ```xml
//! <bsdf type="roughdielectric">
//!     <string name="distribution" value="ggx"/>
//!     <float name="alpha" value="0.2"/>
//!     <string name="int_ior" value="sellmeier:bk7"/>
//! </bsdf>
//! ```

use super::dielectric::{AIR, BK7, Dielectric};
use super::dispersion::DispersiveInterface;
use super::fresnel::fresnel_dielectric;
use super::microfacet::{Microfacet, MicrofacetParams};
use super::{BsdfContext, BsdfModel, BsdfSample, Lobe, TransportMode, choose_lobe};
use crate::geometry::SurfaceInteraction;
use crate::scene::error::Result;
use crate::scene::loader::PluginLoader;
use crate::scene::props::Props;
use crate::spectrum::mueller::{interface_to_canonical, specular_reflection, specular_transmission};
use crate::spectrum::{Rgb, Spectrum};
use glam::{Vec2, Vec3};

#[derive(Clone, Debug)]
pub struct RoughDielectric {
    /// The facets' interface (index, dispersion, scale textures).
    pub facet: Dielectric,
    pub roughness: MicrofacetParams,
}

/// The distribution sampling draws from: Walter et al.'s widened one when
/// the whole distribution is sampled.
#[inline]
fn sampling_distribution(mf: Microfacet, cos_i: f32) -> Microfacet {
    if mf.sample_visible {
        mf
    } else {
        let s = 1.2 - 0.2 * cos_i.abs().sqrt();
        Microfacet { alpha_u: mf.alpha_u * s, alpha_v: mf.alpha_v * s, ..mf }
    }
}

impl RoughDielectric {
    /// Reads the parameters in the table above.
    pub fn from_props(props: &Props, loader: &dyn PluginLoader) -> Result<RoughDielectric> {
        let int_ior = props.ior_spectrum("int_ior", BK7)?;
        let ext_ior = props.ior_spectrum("ext_ior", AIR)?;
        let specular_reflectance = loader.texture(props, "specular_reflectance", Rgb::WHITE)?;
        let specular_transmittance = loader.texture(props, "specular_transmittance", Rgb::WHITE)?;
        let eta = int_ior.nominal() / ext_ior.nominal();
        let dispersive = int_ior.is_dispersive() || ext_ior.is_dispersive();
        let dispersion = dispersive.then(|| Box::new(DispersiveInterface { int_ior, ext_ior }));
        let roughness = MicrofacetParams::from_props(props, loader)?;
        Ok(RoughDielectric { facet: Dielectric { eta, dispersion, specular_reflectance, specular_transmittance }, roughness })
    }

    /// The facet normal (turned outwards) that scatters wi into wo, and
    /// whether that is a reflection; `None` if degenerate.
    #[inline]
    fn half_vector(wi: Vec3, wo: Vec3, eta: f32) -> Option<(Vec3, bool, f32)> {
        let reflect = wi.z * wo.z > 0.0;
        // η on wi's side crossing to wo's.
        let eta_rel = if wi.z > 0.0 { eta } else { 1.0 / eta };
        let h = wi + wo * if reflect { 1.0 } else { eta_rel };
        let len = h.length();
        if !(len > 0.0) {
            return None;
        }
        let h = h / len;
        Some((if h.z < 0.0 { -h } else { h }, reflect, eta_rel))
    }

    /// The weight of scattering by facet `m` as `S`: the unpolarised
    /// `value` (which holds the lobe's Fresnel factor `fresnel`) times the
    /// scale texture; in the polarized modes the facet's Mueller matrix
    /// scaled to that value.
    #[inline]
    fn weight<S: Spectrum>(&self, si: &SurfaceInteraction, wi: Vec3, wo: Vec3, m: Vec3, eta: f32, reflect: bool, value: f32, fresnel: f32, wl: &S::Wavelengths) -> S {
        let tint = if reflect { &self.facet.specular_reflectance } else { &self.facet.specular_transmittance }.eval_spectrum::<S>(si.uv, wl);
        if S::POLARIZED {
            if !(fresnel > 0.0) {
                return S::zero();
            }
            // Light arrives along −wo and leaves along wi (towards the
            // camera), by the facet of world normal m; the cosine is wo's
            // (the side the light comes from).
            let cos_o = wo.dot(m);
            let mat = if reflect { specular_reflection(cos_o, eta) } else { specular_transmission(cos_o, eta) };
            let mat = interface_to_canonical(mat, si.to_world(m), -si.to_world(wo), si.to_world(wi));
            S::mueller(mat, tint) * (value / fresnel)
        } else {
            tint * value
        }
    }
}

impl BsdfModel for RoughDielectric {
    fn lobes(&self) -> Lobe {
        Lobe::GLOSSY
    }

    fn has_mueller_model(&self) -> bool {
        true
    }

    fn needs_tangent_frame(&self) -> bool {
        self.roughness.is_anisotropic()
    }

    fn disperses(&self) -> bool {
        self.facet.dispersion.is_some()
    }

    #[inline]
    fn eval<S: Spectrum>(&self, ctx: &BsdfContext, si: &SurfaceInteraction, wi: Vec3, wo: Vec3, wl: &S::Wavelengths) -> S {
        if wi.z == 0.0 || wo.z == 0.0 {
            return S::zero();
        }
        let eta = self.facet.eta_at::<S>(wl);
        let Some((m, reflect, eta_rel)) = Self::half_vector(wi, wo, eta) else { return S::zero() };
        if !ctx.wants(if reflect { Lobe::GLOSSY_REFLECTION } else { Lobe::GLOSSY_TRANSMISSION }) {
            return S::zero();
        }
        let mf = self.roughness.at(si);
        let d = mf.d(m);
        let g = mf.g(wi, wo, m);
        if d == 0.0 || g == 0.0 {
            return S::zero();
        }
        let (cos_im, cos_om) = (wi.dot(m), wo.dot(m));
        let f = fresnel_dielectric(cos_im, eta).r;
        if reflect {
            let value = f * d * g / (4.0 * wi.z.abs());
            self.weight::<S>(si, wi, wo, m, eta, true, value, f, wl)
        } else {
            let scale = match ctx.mode {
                TransportMode::Radiance => 1.0 / (eta_rel * eta_rel),
                TransportMode::Importance => 1.0,
            };
            let denom = cos_im + eta_rel * cos_om;
            let value = (scale * (1.0 - f) * d * g * eta_rel * eta_rel * cos_im * cos_om / (wi.z * denom * denom)).abs();
            if !value.is_finite() {
                return S::zero();
            }
            self.weight::<S>(si, wi, wo, m, eta, false, value, 1.0 - f, wl)
        }
    }

    #[inline]
    fn pdf<S: Spectrum>(&self, ctx: &BsdfContext, si: &SurfaceInteraction, wi: Vec3, wo: Vec3, wl: &S::Wavelengths) -> f32 {
        if wi.z == 0.0 || wo.z == 0.0 {
            return 0.0;
        }
        let eta = self.facet.eta_at::<S>(wl);
        let Some((m, reflect, eta_rel)) = Self::half_vector(wi, wo, eta) else { return 0.0 };
        let (has_r, has_t) = (ctx.wants(Lobe::GLOSSY_REFLECTION), ctx.wants(Lobe::GLOSSY_TRANSMISSION));
        if !(if reflect { has_r } else { has_t }) {
            return 0.0;
        }
        let (cos_im, cos_om) = (wi.dot(m), wo.dot(m));
        if cos_im * wi.z <= 0.0 || cos_om * wo.z <= 0.0 {
            return 0.0;
        }
        let jacobian = if reflect {
            1.0 / (4.0 * cos_om)
        } else {
            let denom = cos_im + eta_rel * cos_om;
            eta_rel * eta_rel * cos_om / (denom * denom)
        };
        let mf = sampling_distribution(self.roughness.at(si), wi.z);
        let mut prob = mf.pdf(wi * wi.z.signum(), m);
        if has_r && has_t {
            let f = fresnel_dielectric(cos_im, eta).r;
            prob *= if reflect { f } else { 1.0 - f };
        }
        let p = prob * jacobian.abs();
        if p.is_finite() { p } else { 0.0 }
    }

    #[inline]
    fn sample<S: Spectrum>(&self, ctx: &BsdfContext, si: &SurfaceInteraction, wi: Vec3, u1: f32, u2: Vec2, wl: &S::Wavelengths) -> Option<BsdfSample<S>> {
        if wi.z == 0.0 {
            return None;
        }
        let eta = self.facet.eta_at::<S>(wl);
        let mf = self.roughness.at(si);
        let sampling = sampling_distribution(mf, wi.z);
        let (m, pdf_m) = sampling.sample(wi * wi.z.signum(), u2);
        if !(pdf_m > 0.0) {
            return None;
        }
        let cos_im = wi.dot(m);
        let fr = fresnel_dielectric(cos_im, eta);
        let p_r = choose_lobe(ctx, Lobe::GLOSSY_REFLECTION, Lobe::GLOSSY_TRANSMISSION, fr.r)?;
        let (wo, reflect, lobe_prob, jacobian) = if u1 < p_r {
            let wo = 2.0 * cos_im * m - wi;
            (wo, true, p_r, 1.0 / (4.0 * wo.dot(m)))
        } else {
            if fr.r >= 1.0 {
                return None;
            }
            // Refraction about m: the tangential part scales by η_i/η_t.
            let wo = m * (cos_im * fr.eta_ti + fr.cos_t) - wi * fr.eta_ti;
            let cos_om = wo.dot(m);
            let denom = cos_im + fr.eta_it * cos_om;
            (wo, false, 1.0 - p_r, fr.eta_it * fr.eta_it * cos_om / (denom * denom))
        };
        // The sample must land on the side its lobe scatters to.
        if (wo.z * wi.z > 0.0) != reflect || wo.z == 0.0 {
            return None;
        }
        // eval / pdf: with visible normals G1(wo); with the whole (widened)
        // distribution G (wi·m)/(cos θ_i cos θ_m) D(m)/D_widened(m). Mitsuba
        // 3.9 leaves out the last ratio, so its sample weights there are not
        // its eval/pdf (within −6 %…+57 % per sample, +0.1 % on average at
        // α = 0.4); Snell keeps them consistent.
        let g = if mf.sample_visible {
            mf.g1(wo, m)
        } else {
            mf.g(wi, wo, m) * cos_im / (wi.z * m.z) * (mf.d(m) / sampling.d(m))
        };
        if !(g > 0.0) {
            return None;
        }
        let pdf = pdf_m * lobe_prob * jacobian.abs();
        if !(pdf > 0.0 && pdf.is_finite()) {
            return None;
        }
        // The lobe's Fresnel fraction over the probability of picking it
        // (1 when both lobes are wanted).
        let fresnel = if reflect { fr.r } else { 1.0 - fr.r };
        let mut value = g * fresnel / lobe_prob;
        if !reflect && ctx.mode == TransportMode::Radiance {
            value *= fr.eta_ti * fr.eta_ti;
        }
        let weight = self.weight::<S>(si, wi, wo, m, eta, reflect, value, fresnel, wl);
        let lobe = if reflect { Lobe::GLOSSY_REFLECTION } else { Lobe::GLOSSY_TRANSMISSION };
        Some(BsdfSample { wo, weight, pdf, eta: if reflect { 1.0 } else { fr.eta_it }, lobe })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::microfacet::MicrofacetType;
    use crate::bsdf::testing::*;
    use crate::bsdf::Bsdf;
    use crate::texture::Texture;

    fn glass(kind: MicrofacetType, eta: f32, au: f32, av: Option<f32>, visible: bool) -> RoughDielectric {
        RoughDielectric {
            facet: Dielectric {
                eta,
                dispersion: None,
                specular_reflectance: Texture::constant(Rgb::WHITE),
                specular_transmittance: Texture::constant(Rgb::WHITE),
            },
            roughness: MicrofacetParams {
                kind,
                alpha_u: Texture::constant(Rgb::new(au, au, au)),
                alpha_v: av.map(|a| Texture::constant(Rgb::new(a, a, a))),
                sample_visible: visible,
            },
        }
    }

    fn variants() -> Vec<RoughDielectric> {
        let mut v = vec![];
        for kind in [MicrofacetType::Beckmann, MicrofacetType::Ggx] {
            for visible in [true, false] {
                for (au, av) in [(0.05, None), (0.3, None), (0.8, None), (0.1, Some(0.4))] {
                    v.push(glass(kind, 1.5, au, av, visible));
                }
            }
        }
        v
    }

    #[test]
    fn chi2_sampling_matches_pdf_on_both_sides() {
        let mut seed = 500;
        for g in variants() {
            let b = Bsdf::RoughDielectric(g);
            for theta in [0.1f32, 0.9, 1.45, std::f32::consts::PI - 0.3, std::f32::consts::PI - 1.2] {
                seed += 1;
                // 80 tests at 1 % overall.
                chi2_test_at(&b, incident(theta, 0.6), seed, 0.01 / 80.0);
            }
        }
    }

    #[test]
    fn sample_weight_is_eval_over_pdf_in_both_modes() {
        let mut seed = 600;
        for g in variants() {
            let b = Bsdf::RoughDielectric(g);
            for theta in [0.0f32, 0.8, 1.4, 2.0, 3.0] {
                seed += 1;
                check_sample_consistency(&b, incident(theta, 1.1), seed);
                check_sample_consistency_ctx(&b, &BsdfContext::IMPORTANCE, incident(theta, 1.1), seed);
                check_sample_consistency_ctx(&b, &BsdfContext::RADIANCE.with_lobes(Lobe::GLOSSY_REFLECTION), incident(theta, 1.1), seed);
                // Inside at θ = 2.0 (65° from the normal, past the critical
                // angle) nearly every facet reflects totally: no transmission.
                if theta != 2.0 {
                    check_sample_consistency_ctx(&b, &BsdfContext::RADIANCE.with_lobes(Lobe::GLOSSY_TRANSMISSION), incident(theta, 1.1), seed);
                }
            }
        }
    }

    /// Importance transport's BSDF is the adjoint of radiance transport's,
    /// f_importance(a, c) = f_radiance(c, a), and the radiance BSDF obeys
    /// the generalised reciprocity of refraction f(a, c)/η_a² = f(c, a)/η_c²
    /// (η of the side each direction is on).
    #[test]
    fn reciprocity_and_adjointness() {
        let si = dummy_interaction();
        let mut rng = crate::math::Pcg32::new(8, 8);
        for g in variants() {
            let eta = g.facet.eta;
            let b = Bsdf::RoughDielectric(g);
            for _ in 0..1000 {
                let a = crate::math::sampling::square_to_uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32()));
                let c = crate::math::sampling::square_to_uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32()));
                if a.z.abs() < 1e-2 || c.z.abs() < 1e-2 {
                    continue;
                }
                let f = |ctx: &BsdfContext, x: Vec3, y: Vec3| -> f32 {
                    let v: Rgb = b.eval(ctx, &si, x, y, &());
                    v[0] / y.z.abs()
                };
                let (rad_ac, rad_ca) = (f(&BsdfContext::RADIANCE, a, c), f(&BsdfContext::RADIANCE, c, a));
                let (imp_ac, imp_ca) = (f(&BsdfContext::IMPORTANCE, a, c), f(&BsdfContext::IMPORTANCE, c, a));
                let tol = |x: f32| 2e-3 * (1.0 + x.abs());
                assert!((imp_ac - rad_ca).abs() <= tol(imp_ac), "adjoint: {imp_ac} vs {rad_ca}");
                assert!((imp_ca - rad_ac).abs() <= tol(imp_ca));
                // η² of each side: outside 1, inside η².
                let n2 = |v: Vec3| if v.z > 0.0 { 1.0 } else { eta * eta };
                let (x, y) = (rad_ac / n2(a), rad_ca / n2(c));
                assert!((x - y).abs() <= tol(x), "reciprocity: {x} vs {y} ({a}, {c})");
            }
        }
    }

    #[test]
    fn energy_is_conserved_in_importance_transport() {
        // Without the 1/η² of radiance transport, what leaves is at most what
        // arrives, on both sides (single scattering loses the rest).
        let mut seed = 700;
        for g in variants() {
            let b = Bsdf::RoughDielectric(g);
            for theta in [0.0f32, 1.0, 1.4, 2.2, 3.0] {
                seed += 1;
                let si = SurfaceInteraction { wi: incident(theta, 0.2), ..dummy_interaction() };
                let mut rng = crate::math::Pcg32::new(seed, 1);
                let mut sum = 0.0f64;
                let n = 50_000;
                for _ in 0..n {
                    if let Some(s) = b.sample::<Rgb>(&BsdfContext::IMPORTANCE, &si, si.wi, rng.next_f32(), Vec2::new(rng.next_f32(), rng.next_f32()), &()) {
                        sum += s.weight[0] as f64;
                    }
                }
                let albedo = sum / n as f64;
                assert!(albedo <= 1.01, "θ={theta}: albedo {albedo}");
                assert!(albedo > 0.3, "θ={theta}: albedo {albedo}");
            }
        }
    }

    #[test]
    fn alpha_to_zero_is_the_smooth_dielectric() {
        // Nearly smooth: reflection with probability F and the weights of
        // the smooth dielectric (1, and 1/η² on entering). Beckmann, whose
        // slopes have Gaussian tails (GGX's long tails put a few facets
        // far off even at tiny α).
        let b = Bsdf::RoughDielectric(glass(MicrofacetType::Beckmann, 1.5, 0.0005, None, true));
        let si = dummy_interaction();
        for theta in [0.3f32, 1.0] {
            let wi = incident(theta, 0.5);
            let f = fresnel_dielectric(wi.z, 1.5);
            let mut rng = crate::math::Pcg32::new(4, 4);
            let (mut reflected, mut t_weight, n) = (0usize, 0.0f64, 50_000);
            for _ in 0..n {
                let s = b.sample::<Rgb>(&BsdfContext::RADIANCE, &si, wi, rng.next_f32(), Vec2::new(rng.next_f32(), rng.next_f32()), &()).expect("scatters");
                if s.lobe == Lobe::GLOSSY_REFLECTION {
                    reflected += 1;
                    assert!((s.wo - Vec3::new(-wi.x, -wi.y, wi.z)).length() < 0.01, "{wi} -> {}", s.wo);
                } else {
                    let smooth = crate::bsdf::fresnel::refract(wi, f.cos_t, f.eta_ti);
                    assert!((s.wo - smooth).length() < 0.01, "{wi} -> {} vs {smooth}", s.wo);
                    t_weight += s.weight[0] as f64;
                }
            }
            let frac = reflected as f32 / n as f32;
            assert!((frac - f.r).abs() < 0.01, "{frac} vs {}", f.r);
            let mean_t = t_weight / (n - reflected) as f64;
            assert!((mean_t - 1.0 / 2.25).abs() < 0.01, "{mean_t}");
        }
    }

    #[test]
    fn rotating_the_frame_swaps_alpha_u_and_alpha_v() {
        let a = Bsdf::RoughDielectric(glass(MicrofacetType::Ggx, 1.33, 0.1, Some(0.5), true));
        let b = Bsdf::RoughDielectric(glass(MicrofacetType::Ggx, 1.33, 0.5, Some(0.1), true));
        assert!(a.needs_tangent_frame());
        let rot = |v: Vec3| Vec3::new(-v.y, v.x, v.z);
        let si = dummy_interaction();
        let mut rng = crate::math::Pcg32::new(3, 3);
        for _ in 0..500 {
            let wi = crate::math::sampling::square_to_uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32()));
            let wo = crate::math::sampling::square_to_uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32()));
            let (x, y): (Rgb, Rgb) = (a.eval(&BsdfContext::RADIANCE, &si, wi, wo, &()), b.eval(&BsdfContext::RADIANCE, &si, rot(wi), rot(wo), &()));
            assert!((x[0] - y[0]).abs() <= 1e-3 * x[0].max(1.0), "{x:?} vs {y:?}");
        }
    }

    #[test]
    fn polarized_weights_have_the_unpolarized_intensity_and_brewster_reflection_is_s_polarized() {
        use crate::spectrum::Polarized;
        use crate::spectrum::mueller::degree_of_polarization;
        use glam::Vec4;
        // A surface whose normal is not a coordinate axis.
        let n = Vec3::new(-0.3, 0.25, 0.9).normalize();
        let si = SurfaceInteraction { n, frame: crate::math::Frame::from_normal(n), ..dummy_interaction() };
        let b = Bsdf::RoughDielectric(glass(MicrofacetType::Ggx, 1.5, 0.3, None, true));
        let mut rng = crate::math::Pcg32::new(31, 4);
        for _ in 0..3000 {
            let wi = crate::math::sampling::square_to_uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32()));
            let (u1, u2) = (rng.next_f32(), Vec2::new(rng.next_f32(), rng.next_f32()));
            let x = b.sample::<Rgb>(&BsdfContext::RADIANCE, &si, wi, u1, u2, &());
            let y = b.sample::<Polarized<Rgb>>(&BsdfContext::RADIANCE, &si, wi, u1, u2, &());
            let (Some(x), Some(y)) = (x, y) else {
                assert!(x.is_none() && y.is_none());
                continue;
            };
            assert!(x.wo == y.wo && x.pdf == y.pdf && x.lobe == y.lobe);
            assert!((y.weight.0[0][0][0] - x.weight[0]).abs() <= 1e-4 * (1.0 + x.weight[0]), "{} vs {}", y.weight.0[0][0][0], x.weight[0]);
            let wo = crate::math::sampling::square_to_uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32()));
            let (f, g): (Rgb, Polarized<Rgb>) = (b.eval(&BsdfContext::RADIANCE, &si, wi, wo, &()), b.eval(&BsdfContext::RADIANCE, &si, wi, wo, &()));
            assert!((g.0[0][0][0] - f[0]).abs() <= 1e-4 * (1.0 + f[0]));
        }
        // Nearly smooth glass at Brewster's angle reflects s-polarised light.
        let smooth = Bsdf::RoughDielectric(glass(MicrofacetType::Beckmann, 1.5, 0.001, None, true));
        let wi = incident(1.5f32.atan(), 0.3);
        let ctx = BsdfContext::RADIANCE.with_lobes(Lobe::GLOSSY_REFLECTION);
        let s = smooth.sample::<Polarized<Rgb>>(&ctx, &dummy_interaction(), wi, 0.5, Vec2::new(0.4, 0.6), &()).expect("reflects");
        let st = s.weight.stokes();
        let dop = degree_of_polarization(Vec4::new(st[0][0], st[1][0], st[2][0], st[3][0]));
        assert!(dop > 0.95, "degree of polarization {dop}");
    }

    #[test]
    fn a_dispersive_index_refracts_each_hero_wavelength_its_own_way() {
        use crate::spectrum::Spectrum;
        use crate::spectrum::sampled::Sampled;
        let ior = crate::bsdf::dispersion::parse_ior_expr("sellmeier:bk7").expect("a dispersive form").expect("parses");
        let mut g = glass(MicrofacetType::Beckmann, 1.5, 0.001, None, true);
        g.facet.dispersion = Some(Box::new(DispersiveInterface { int_ior: ior, ext_ior: crate::bsdf::dispersion::IorSpectrum::Constant(1.0) }));
        let b = Bsdf::RoughDielectric(g);
        assert!(b.disperses());
        let si = dummy_interaction();
        let wi = incident(1.0, 0.0);
        let ctx = BsdfContext::RADIANCE.with_lobes(Lobe::GLOSSY_TRANSMISSION);
        // Blue bends more than red: its refracted direction is nearer the normal.
        let (mut cos, mut hero) = (vec![], vec![]);
        for u in [0.05f32, 0.95] {
            let wl = Sampled::sample_wavelengths(u);
            let s = b.sample::<Sampled>(&ctx, &si, wi, 0.5, Vec2::new(0.4, 0.6), &wl).expect("refracts");
            cos.push(-s.wo.z);
            hero.push(Sampled::hero_wavelength(&wl).expect("a hero"));
        }
        assert!(hero[0] < hero[1], "{hero:?}");
        assert!(cos[0] > cos[1] + 1e-4, "{cos:?} at {hero:?}");
    }
}
