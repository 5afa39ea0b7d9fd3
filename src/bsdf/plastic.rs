//! `plastic` — a smooth dielectric coating over a diffuse base (plastic,
//! varnished wood, glazed ceramics), as Mitsuba 3 models it.
//!
//! At the coating, light is reflected specularly with the exact Fresnel
//! reflectance F(θ_i) (a delta lobe). The rest enters, scatters
//! diffusely at the base of albedo ρ, and leaves through the coating with
//! probability 1 − F(θ_o); light reflected back down by the coating from
//! inside bounces again. Radiance inside is η² higher, hence 1/η² on the
//! way out. Summing the internal bounces, the diffuse lobe is
//!
//! f_d(ω_i, ω_o) = (1 − F(θ_i)) (1 − F(θ_o)) / η² · ρ' / π,
//! ρ' = ρ / (1 − F_dr)        (`nonlinear` = false, keeps the base colour),
//! ρ' = ρ / (1 − ρ F_dr)      (`nonlinear` = true, the physical colour shift),
//!
//! where F_dr is the diffuse Fresnel reflectance of the coating seen from
//! inside (`fresnel::fresnel_diffuse_reflectance(1/η)`).
//!
//! Sampling picks the specular lobe with probability
//! p_s = F_i w / (F_i w + (1 − F_i)(1 − w)), with w = s̄ / (ρ̄ + s̄) from the
//! mean specular scale s̄ and mean albedo ρ̄, and otherwise samples the
//! diffuse lobe by cosine. `eval`/`pdf` cover the diffuse lobe only (the
//! specular one is a delta). One-sided: the back is black.
//!
//! Polarisation (polarized modes): the coating reflects by the Fresnel
//! equations in Mueller form, like `dielectric`'s reflection
//! (`mueller::specular_reflection`, whose m₀₀ is F_i; at Brewster's angle
//! it reflects s-polarised light only); the diffuse lobe is a depolarizer
//! scaled by f_d cos θ_o above, since the base forgets the polarisation of
//! what it scatters. Mitsuba 3 depolarises both lobes. Not modelled: the
//! partial p-polarisation that the coating's transmission (T_p > T_s) gives
//! the diffuse light on its way out, and on its way in. S0 of unpolarised
//! input is the unpolarised value in both lobes.
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `diffuse_reflectance` | rgb / spectrum / float / texture | 0.5 | base albedo ρ |
//! | `specular_reflectance` | rgb / spectrum / float / texture | 1 | scale of the coating's reflection |
//! | `int_ior` | float / string | `polypropylene` (1.49) | index of the coating |
//! | `ext_ior` | float / string | `air` | index outside |
//! | `nonlinear` | boolean | false | account for the colour shift of internal scattering |
//!
//! ```xml
//! <bsdf type="plastic">
//!     <rgb name="diffuse_reflectance" value="0.1, 0.27, 0.36"/>
//!     <float name="int_ior" value="1.9"/>
//! </bsdf>
//! ```

use super::fresnel::{fresnel_dielectric, fresnel_diffuse_reflectance, reflect};
use super::dielectric::AIR;
use super::{BsdfContext, BsdfModel, BsdfSample, Lobe, choose_lobe};
use crate::geometry::SurfaceInteraction;
use crate::math::sampling::{cosine_hemisphere_pdf, square_to_cosine_hemisphere};
use crate::scene::error::Result;
use crate::scene::loader::PluginLoader;
use crate::scene::props::Props;
use crate::spectrum::{Rgb, Spectrum};
use crate::spectrum::mueller::{interface_to_canonical, specular_reflection};
use crate::texture::Texture;
use glam::{Vec2, Vec3};

#[derive(Clone, Debug)]
pub struct Plastic {
    pub diffuse_reflectance: Texture,
    /// `None` when not given (scale 1; then s̄ = 1 in the sampling weight).
    pub specular_reflectance: Option<Texture>,
    pub eta: f32,
    pub nonlinear: bool,
    inv_eta2: f32,
    fdr_int: f32,
    specular_sampling_weight: f32,
}

/// Mitsuba's default coating index, `polypropylene`.
pub const POLYPROPYLENE: f32 = 1.49;

impl Plastic {
    /// Reads the parameters in the table above.
    pub fn from_props(props: &Props, loader: &dyn PluginLoader) -> Result<Plastic> {
        let int_ior = props.ior("int_ior", POLYPROPYLENE)?;
        let ext_ior = props.ior("ext_ior", AIR)?;
        let diffuse = loader.reflectance(props, "diffuse_reflectance", Rgb::new(0.5, 0.5, 0.5))?;
        let specular = if props.has("specular_reflectance") || props.has_child("specular_reflectance") {
            Some(loader.reflectance(props, "specular_reflectance", Rgb::WHITE)?)
        } else {
            None
        };
        let nonlinear = props.bool("nonlinear", false)?;
        Ok(Plastic::new(diffuse, specular, int_ior / ext_ior, nonlinear))
    }

    pub fn new(diffuse_reflectance: Texture, specular_reflectance: Option<Texture>, eta: f32, nonlinear: bool) -> Plastic {
        let d_mean = diffuse_reflectance.mean();
        let s_mean = specular_reflectance.as_ref().map_or(1.0, |t| t.mean());
        let w = s_mean / (d_mean + s_mean);
        Plastic {
            diffuse_reflectance,
            specular_reflectance,
            eta,
            nonlinear,
            inv_eta2: 1.0 / (eta * eta),
            fdr_int: fresnel_diffuse_reflectance(1.0 / eta),
            specular_sampling_weight: if w.is_finite() { w } else { 0.5 },
        }
    }

    /// Probability of sampling the specular lobe given F(θ_i).
    #[inline]
    fn prob_specular(&self, f_i: f32) -> f32 {
        let s = f_i * self.specular_sampling_weight;
        let d = (1.0 - f_i) * (1.0 - self.specular_sampling_weight);
        if s + d > 0.0 { s / (s + d) } else { 0.0 }
    }

    /// ρ' (the base albedo with the internal bounces summed), times
    /// (1 − F_i)(1 − F_o)/η²; a depolarizer in the polarized modes.
    #[inline]
    fn diffuse_albedo<S: Spectrum>(&self, si: &SurfaceInteraction, f_i: f32, f_o: f32, wl: &S::Wavelengths) -> S {
        let fdr = self.fdr_int;
        let rho: S = if self.nonlinear {
            self.diffuse_reflectance.eval_spectrum_map(si.uv, wl, |r| r / (1.0 - r * fdr))
        } else {
            self.diffuse_reflectance.eval_spectrum_map(si.uv, wl, |r| r / (1.0 - fdr))
        };
        rho.depolarize() * (self.inv_eta2 * (1.0 - f_i) * (1.0 - f_o))
    }

}

impl BsdfModel for Plastic {
    fn lobes(&self) -> Lobe {
        Lobe::DELTA_REFLECTION | Lobe::DIFFUSE_REFLECTION
    }

    fn has_mueller_model(&self) -> bool {
        true
    }

    #[inline]
    fn eval<S: Spectrum>(&self, ctx: &BsdfContext, si: &SurfaceInteraction, wi: Vec3, wo: Vec3, wl: &S::Wavelengths) -> S {
        if wi.z <= 0.0 || wo.z <= 0.0 || !ctx.wants(Lobe::DIFFUSE_REFLECTION) {
            return S::zero();
        }
        let f_i = fresnel_dielectric(wi.z, self.eta).r;
        let f_o = fresnel_dielectric(wo.z, self.eta).r;
        self.diffuse_albedo::<S>(si, f_i, f_o, wl) * cosine_hemisphere_pdf(wo)
    }

    #[inline]
    fn pdf<S: Spectrum>(&self, ctx: &BsdfContext, _si: &SurfaceInteraction, wi: Vec3, wo: Vec3, _wl: &S::Wavelengths) -> f32 {
        if wi.z <= 0.0 || wo.z <= 0.0 || !ctx.wants(Lobe::DIFFUSE_REFLECTION) {
            return 0.0;
        }
        let f_i = fresnel_dielectric(wi.z, self.eta).r;
        let p_s = if ctx.wants(Lobe::DELTA_REFLECTION) { self.prob_specular(f_i) } else { 0.0 };
        (1.0 - p_s) * cosine_hemisphere_pdf(wo)
    }

    #[inline]
    fn sample<S: Spectrum>(&self, ctx: &BsdfContext, si: &SurfaceInteraction, wi: Vec3, u1: f32, u2: Vec2, wl: &S::Wavelengths) -> Option<BsdfSample<S>> {
        if wi.z <= 0.0 {
            return None;
        }
        let f_i = fresnel_dielectric(wi.z, self.eta).r;
        let p_s = choose_lobe(ctx, Lobe::DELTA_REFLECTION, Lobe::DIFFUSE_REFLECTION, self.prob_specular(f_i))?;
        if u1 < p_s {
            let scale: S = self.specular_reflectance.as_ref().map_or(S::splat(1.0), |t| t.eval_spectrum(si.uv, wl));
            let wo = reflect(wi);
            let weight = if S::POLARIZED {
                // The coating's Fresnel matrix (m₀₀ = F_i); light arrives
                // along −wo and leaves along wi (towards the camera).
                let m = specular_reflection(wo.z, self.eta);
                let m = interface_to_canonical(m, si.frame.n, -si.to_world(wo), si.to_world(wi));
                S::mueller(m, scale) * (1.0 / p_s)
            } else {
                scale * (f_i / p_s)
            };
            return Some(BsdfSample {
                wo,
                weight,
                pdf: p_s,
                eta: 1.0,
                lobe: Lobe::DELTA_REFLECTION,
            });
        }
        let wo = square_to_cosine_hemisphere(u2);
        let p_d = 1.0 - p_s;
        if wo.z <= 0.0 || p_d <= 0.0 {
            return None;
        }
        let f_o = fresnel_dielectric(wo.z, self.eta).r;
        Some(BsdfSample {
            wo,
            weight: self.diffuse_albedo::<S>(si, f_i, f_o, wl) * (1.0 / p_d),
            pdf: p_d * cosine_hemisphere_pdf(wo),
            eta: 1.0,
            lobe: Lobe::DIFFUSE_REFLECTION,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::testing::*;
    use crate::spectrum::Rgb;
    use crate::bsdf::{Bsdf, BsdfContext};
    use crate::math::Pcg32;
    use crate::spectrum::Polarized;
    use crate::spectrum::mueller::degree_of_polarization;
    use glam::Vec4;

    fn plastic(rho: Rgb, eta: f32, nonlinear: bool) -> Bsdf {
        Bsdf::Plastic(Plastic::new(Texture::constant(rho), None, eta, nonlinear))
    }

    /// A tinted coating over a coloured base, on a surface whose normal is
    /// not a coordinate axis (the canonical Stokes frames turn against s/p).
    fn tinted() -> (Plastic, SurfaceInteraction) {
        let p = Plastic::new(Texture::constant(Rgb::new(0.7, 0.4, 0.1)), Some(Texture::constant(Rgb::new(0.8, 0.9, 1.0))), 1.49, true);
        let n = Vec3::new(-0.4, 0.2, 0.9).normalize();
        (p, SurfaceInteraction { n, frame: crate::math::Frame::from_normal(n), ..dummy_interaction() })
    }

    fn stokes(w: &Polarized<Rgb>) -> Vec4 {
        let s = w.stokes();
        Vec4::new(s[0][0], s[1][0], s[2][0], s[3][0])
    }

    /// Every entry but m₀₀ is zero: a depolarizer.
    fn is_depolarizer(w: &Polarized<Rgb>) -> bool {
        (0..4).all(|r| (0..4).all(|c| (r == 0 && c == 0) || w.0[r][c].is_zero())) && !w.0[0][0].is_zero()
    }

    #[test]
    fn polarized_weights_have_the_unpolarized_intensity() {
        let (p, si) = tinted();
        let mut rng = Pcg32::new(21, 4);
        let (mut worst, mut polarizing, mut lobes) = (0.0f32, 0, [0; 2]);
        for _ in 0..4000 {
            let wi = square_to_cosine_hemisphere(Vec2::new(rng.next_f32(), rng.next_f32()));
            let (u1, u2) = (rng.next_f32(), Vec2::new(rng.next_f32(), rng.next_f32()));
            let a = p.sample::<Rgb>(&BsdfContext::RADIANCE, &si, wi, u1, u2, &());
            let b = p.sample::<Polarized<Rgb>>(&BsdfContext::RADIANCE, &si, wi, u1, u2, &());
            let (Some(a), Some(b)) = (a, b) else {
                assert!(a.is_none() && b.is_none());
                continue;
            };
            assert!(a.lobe == b.lobe && a.pdf == b.pdf && a.wo == b.wo);
            for c in 0..3 {
                worst = worst.max((b.weight.0[0][0][c] - a.weight[c]).abs());
            }
            if a.lobe == Lobe::DELTA_REFLECTION {
                lobes[0] += 1;
                if degree_of_polarization(stokes(&b.weight)) > 0.05 {
                    polarizing += 1;
                }
            } else {
                lobes[1] += 1;
                assert!(is_depolarizer(&b.weight), "{:?}", b.weight);
            }
            // Next-event estimation's side: eval of a random direction.
            let wo = square_to_cosine_hemisphere(Vec2::new(rng.next_f32(), rng.next_f32()));
            let (fa, fb): (Rgb, Polarized<Rgb>) = (p.eval(&BsdfContext::RADIANCE, &si, wi, wo, &()), p.eval(&BsdfContext::RADIANCE, &si, wi, wo, &()));
            for c in 0..3 {
                worst = worst.max((fb.0[0][0][c] - fa[c]).abs());
            }
            assert!(fa.is_zero() || is_depolarizer(&fb), "{fb:?}");
        }
        eprintln!("largest |m00 − unpolarised value| {worst:e}; lobes {lobes:?}, {polarizing} specular samples polarise by > 5 %");
        assert!(worst < 1e-5, "{worst}");
        assert!(lobes[0] > 200 && lobes[1] > 200 && polarizing > lobes[0] / 2, "{lobes:?} {polarizing}");
    }

    #[test]
    fn coating_reflects_s_polarized_light_at_brewsters_angle() {
        let (p, si) = tinted();
        let brewster = p.eta.atan();
        for phi in [0.0f32, 1.3, 3.0, 5.0] {
            let wi = incident(brewster, phi);
            let s = p.sample::<Polarized<Rgb>>(&BsdfContext::RADIANCE, &si, wi, 0.0, Vec2::splat(0.5), &()).expect("front side");
            assert_eq!(s.lobe, Lobe::DELTA_REFLECTION);
            let dop = degree_of_polarization(stokes(&s.weight));
            eprintln!("φ {phi}: DoP of the specular reflection {dop:.6}");
            assert!((dop - 1.0).abs() < 1e-4, "φ {phi}: {dop}");
            // The diffuse lobe at the same angle: unpolarised whatever comes in.
            let s = p.sample::<Polarized<Rgb>>(&BsdfContext::RADIANCE, &si, wi, 0.999_999, Vec2::new(0.3, 0.6), &()).expect("front side");
            assert_eq!(s.lobe, Lobe::DIFFUSE_REFLECTION);
            assert!(is_depolarizer(&s.weight), "{:?}", s.weight);
            assert!(is_depolarizer(&p.eval::<Polarized<Rgb>>(&BsdfContext::RADIANCE, &si, wi, s.wo, &())));
        }
        // Off Brewster's angle the coating only partly polarises.
        let s = p.sample::<Polarized<Rgb>>(&BsdfContext::RADIANCE, &si, incident(0.5, 0.0), 0.0, Vec2::splat(0.5), &()).expect("front side");
        assert_eq!(s.lobe, Lobe::DELTA_REFLECTION);
        assert!(degree_of_polarization(stokes(&s.weight)) < 0.95);
    }

    #[test]
    fn chi2_sampling_matches_pdf() {
        let b = plastic(Rgb::new(0.6, 0.3, 0.1), 1.49, false);
        for (i, &theta) in [0.0f32, 0.6, 1.2, 1.5].iter().enumerate() {
            chi2_test(&b, incident(theta, 0.8), 70 + i as u64);
        }
        chi2_test(&plastic(Rgb::new(0.05, 0.05, 0.05), 2.0, true), incident(1.0, 0.1), 80);
    }

    #[test]
    fn reciprocal_consistent_and_delta_free_eval() {
        let b = plastic(Rgb::new(0.8, 0.5, 0.2), 1.6, true);
        check_reciprocity(&b, 5);
        for theta in [0.1f32, 0.9, 1.4] {
            check_sample_consistency(&b, incident(theta, 2.0), 6);
        }
        let si = dummy_interaction();
        let wi = incident(0.7, 0.0);
        // The mirror direction has no special value in eval/pdf: the delta lobe is excluded.
        let mirror = reflect(wi);
        let near = incident(0.7 + 1e-3, std::f32::consts::PI);
        let (a, c): (Rgb, Rgb) = (b.eval(&BsdfContext::RADIANCE, &si, wi, mirror, &()), b.eval(&BsdfContext::RADIANCE, &si, wi, near, &()));
        assert!((a[0] - c[0]).abs() < 1e-3 * c[0]);
        assert!(b.eval::<Rgb>(&BsdfContext::RADIANCE, &si, Vec3::new(wi.x, wi.y, -wi.z), Vec3::Z, &()).is_zero(), "one-sided");
    }

    #[test]
    fn energy_is_conserved_and_matches_the_coating_model() {
        // Total albedo = F_i (specular) + diffuse albedo, estimated from samples; ≤ 1,
        // and for a white base with `nonlinear` the closed form of the series,
        // (1 − F_i) (1 − F̄_dr,ext)/η² / (1 − F_dr,int) with hemispherical averages,
        // where energy conservation at the interface makes (1 − F_dr,ext)/η² = 1 − F_dr,int: albedo → 1.
        for (rho, eta) in [(0.5f32, 1.49f32), (1.0, 1.5), (0.9, 1.33)] {
            let b = plastic(Rgb::new(rho, rho, rho), eta, true);
            let si = dummy_interaction();
            for theta in [0.2f32, 1.0] {
                let wi = incident(theta, 0.3);
                let si = SurfaceInteraction { wi, ..si };
                let mut rng = Pcg32::new(11, theta.to_bits() as u64);
                let n = 400_000;
                let mut sum = 0.0f64;
                for _ in 0..n {
                    if let Some(s) = b.sample::<Rgb>(&BsdfContext::RADIANCE, &si, wi, rng.next_f32(), Vec2::new(rng.next_f32(), rng.next_f32()), &()) {
                        sum += s.weight[0] as f64;
                    }
                }
                let albedo = sum / n as f64;
                assert!(albedo <= 1.0 + 3e-3, "ρ={rho} η={eta}: albedo {albedo}");
                if rho == 1.0 {
                    // White base: only the fit error of F_dr (< 1 %) keeps it from exactly 1.
                    assert!((albedo - 1.0).abs() < 0.02, "white plastic albedo {albedo}");
                }
                let f_i = fresnel_dielectric(wi.z, eta).r as f64;
                assert!(albedo > f_i, "more than the specular part");
            }
        }
    }
}
