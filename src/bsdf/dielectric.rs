//! `dielectric` — a smooth interface between two dielectrics (glass, water):
//! ideal specular reflection plus ideal specular refraction by Snell's law.
//!
//! The exact unpolarised Fresnel reflectance F_r (see `fresnel.rs`) splits
//! the light: F_r is reflected into the mirror direction, 1 − F_r refracted
//! into ω_t with η₁ sin θ₁ = η₂ sin θ₂, and beyond the critical angle
//! everything is reflected (total internal reflection). `sample` picks
//! reflection with probability F_r and refraction otherwise, so both
//! samples carry weight 1 (times the optional scale textures).
//!
//! Radiance is not conserved across the interface — L/η² is. A camera path
//! that refracts from the side of index η_i (where it came from) into η_t
//! carries radiance scaled by (η_i/η_t)², the seed's η₁²/η₂² BTDF factor
//! with light travelling from medium t to medium i. Importance (light-tracing
//! paths, `TransportMode::Importance`) is not scaled.
//!
//! Dispersion: if `int_ior` or `ext_ior` depends on the wavelength
//! (`dispersion.rs`), spectral mode refracts by η(λ) of the path's hero
//! wavelength and the integrator then drops the other wavelengths (they
//! would leave in other directions); RGB mode uses η at the d line.
//!
//! `eta` = int_ior / ext_ior; the normal points outside. Both sides refract,
//! so the surface of a closed object is the boundary of a solid of glass.
//! Both lobes are deltas: `eval` and `pdf` are zero.
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `int_ior` | float / string | `bk7` (1.5046) | interior index, a name (`water`, `diamond`, `crown glass`, …), or a dispersive form (`sellmeier:bk7`, see `dispersion.rs`; Snell only) |
//! | `ext_ior` | float / string | `air` (1.000277) | exterior index, or a name |
//! | `specular_reflectance` | rgb / spectrum / float / texture | 1 | scale of reflection (not physical) |
//! | `specular_transmittance` | rgb / spectrum / float / texture | 1 | scale of transmission (not physical) |
//!
//! ```xml
//! <bsdf type="dielectric">
//!     <string name="int_ior" value="water"/>
//!     <float name="ext_ior" value="1.0"/>
//! </bsdf>
//! ```

use super::dispersion::DispersiveInterface;
use super::fresnel::{fresnel_dielectric, reflect, refract};
use super::{BsdfContext, BsdfModel, BsdfSample, Lobe, TransportMode, choose_lobe};
use crate::geometry::SurfaceInteraction;
use crate::scene::error::Result;
use crate::scene::loader::PluginLoader;
use crate::scene::props::Props;
use crate::spectrum::mueller::{interface_to_canonical, specular_reflection, specular_transmission};
use crate::spectrum::{Rgb, Spectrum};
use crate::texture::Texture;
use glam::{Vec2, Vec3};

/// Mitsuba's default interior index, `bk7`.
pub const BK7: f32 = 1.5046;
/// Mitsuba's default exterior index, `air`.
pub const AIR: f32 = 1.000_277;

#[derive(Clone, Debug)]
pub struct Dielectric {
    /// int_ior / ext_ior (at the d line if dispersive).
    pub eta: f32,
    /// The indices as functions of the wavelength, if either disperses
    /// (`bsdf/dispersion.rs`); RGB mode uses `eta`.
    pub dispersion: Option<Box<DispersiveInterface>>,
    pub specular_reflectance: Texture,
    pub specular_transmittance: Texture,
}

impl Dielectric {
    /// Reads the parameters in the table above.
    pub fn from_props(props: &Props, loader: &dyn PluginLoader) -> Result<Dielectric> {
        let int_ior = props.ior_spectrum("int_ior", BK7)?;
        let ext_ior = props.ior_spectrum("ext_ior", AIR)?;
        let specular_reflectance = loader.reflectance(props, "specular_reflectance", Rgb::WHITE)?;
        let specular_transmittance = loader.reflectance(props, "specular_transmittance", Rgb::WHITE)?;
        let eta = int_ior.nominal() / ext_ior.nominal();
        let dispersive = int_ior.is_dispersive() || ext_ior.is_dispersive();
        let dispersion = dispersive.then(|| Box::new(DispersiveInterface { int_ior, ext_ior }));
        Ok(Dielectric { eta, dispersion, specular_reflectance, specular_transmittance })
    }

    /// int_ior / ext_ior at the path's hero wavelength (spectral modes) or
    /// at the d line.
    #[inline]
    pub fn eta_at<S: Spectrum>(&self, wl: &S::Wavelengths) -> f32 {
        match (&self.dispersion, S::hero_wavelength(wl)) {
            (Some(d), Some(lambda)) => d.eta(lambda),
            _ => self.eta,
        }
    }
}

impl BsdfModel for Dielectric {
    fn lobes(&self) -> Lobe {
        Lobe::DELTA
    }

    fn has_mueller_model(&self) -> bool {
        true
    }

    fn disperses(&self) -> bool {
        self.dispersion.is_some()
    }

    #[inline]
    fn eval<S: Spectrum>(&self, _ctx: &BsdfContext, _si: &SurfaceInteraction, _wi: Vec3, _wo: Vec3, _wl: &S::Wavelengths) -> S {
        S::zero()
    }

    #[inline]
    fn pdf<S: Spectrum>(&self, _ctx: &BsdfContext, _si: &SurfaceInteraction, _wi: Vec3, _wo: Vec3, _wl: &S::Wavelengths) -> f32 {
        0.0
    }

    /// Reflection with probability F, refraction otherwise; a context that
    /// wants only one of them gets that one with probability 1, weighted by
    /// its Fresnel factor.
    #[inline]
    fn sample<S: Spectrum>(&self, ctx: &BsdfContext, si: &SurfaceInteraction, wi: Vec3, u: f32, _u2: Vec2, wl: &S::Wavelengths) -> Option<BsdfSample<S>> {
        let eta = self.eta_at::<S>(wl);
        let f = fresnel_dielectric(wi.z, eta);
        let p_r = choose_lobe(ctx, Lobe::DELTA_REFLECTION, Lobe::DELTA_TRANSMISSION, f.r)?;
        if u < p_r {
            let wo = reflect(wi);
            let scale = self.specular_reflectance.eval_spectrum::<S>(si.uv, wl);
            let weight = if S::POLARIZED {
                // Light arrives along −wo and leaves along wi (towards the camera).
                let m = specular_reflection(wo.z, eta);
                let m = interface_to_canonical(m, si.frame.n, -si.to_world(wo), si.to_world(wi));
                S::mueller(m, scale) / p_r
            } else {
                scale * (f.r / p_r)
            };
            Some(BsdfSample { wo, weight, pdf: p_r, eta: 1.0, lobe: Lobe::DELTA_REFLECTION })
        } else {
            if f.r >= 1.0 {
                // Total internal reflection, and the context wants no reflection.
                return None;
            }
            let p_t = 1.0 - p_r;
            let scale = match ctx.mode {
                TransportMode::Radiance => f.eta_ti * f.eta_ti,
                TransportMode::Importance => 1.0,
            };
            let wo = refract(wi, f.cos_t, f.eta_ti);
            let tint = self.specular_transmittance.eval_spectrum::<S>(si.uv, wl);
            let weight = if S::POLARIZED {
                // Light crosses from wo's side into wi's: the Fresnel terms of
                // that crossing, T = 1 − F for unpolarised light.
                let m = specular_transmission(wo.z, eta);
                let m = interface_to_canonical(m, si.frame.n, -si.to_world(wo), si.to_world(wi));
                S::mueller(m, tint) * (scale / p_t)
            } else {
                tint * (scale * ((1.0 - f.r) / p_t))
            };
            Some(BsdfSample { wo, weight, pdf: p_t, eta: f.eta_it, lobe: Lobe::DELTA_TRANSMISSION })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::Bsdf;
    use crate::bsdf::testing::*;
    use crate::spectrum::Rgb;
    use glam::Vec2;

    fn glass(eta: f32) -> Bsdf {
        Bsdf::Dielectric(Dielectric {
            eta,
            dispersion: None,
            specular_reflectance: Texture::constant(Rgb::WHITE),
            specular_transmittance: Texture::constant(Rgb::WHITE),
        })
    }

    #[test]
    fn reflects_with_probability_fresnel() {
        let b = glass(1.5);
        let si = dummy_interaction();
        for theta in [0.0f32, 0.7, 1.3] {
            let wi = incident(theta, 0.4);
            let f = fresnel_dielectric(wi.z, 1.5);
            let n = 100_000;
            let mut reflected = 0;
            let mut rng = crate::math::Pcg32::new(9, theta.to_bits() as u64);
            for _ in 0..n {
                let s = b.sample::<Rgb>(&BsdfContext::RADIANCE, &si, wi, rng.next_f32(), Vec2::ZERO, &()).expect("always scatters");
                match s.lobe {
                    Lobe::DELTA_REFLECTION => {
                        reflected += 1;
                        assert!((s.weight[0] - 1.0).abs() < 1e-6 && (s.pdf - f.r).abs() < 1e-6);
                    }
                    Lobe::DELTA_TRANSMISSION => {
                        // η_i/η_t squared: entering glass from air divides radiance by 1.5².
                        assert!((s.weight[0] - 1.0 / (1.5 * 1.5)).abs() < 1e-5);
                        assert!((s.eta - 1.5).abs() < 1e-6 && s.wo.z < 0.0);
                    }
                    other => panic!("unexpected lobe {other:?}"),
                }
            }
            let frac = reflected as f32 / n as f32;
            let sigma = (f.r * (1.0 - f.r) / n as f32).sqrt();
            assert!((frac - f.r).abs() < 5.0 * sigma + 1e-4, "θ={theta}: reflected {frac} vs F={}", f.r);
        }
    }

    #[test]
    fn importance_transport_is_not_scaled() {
        let b = glass(1.5);
        let si = dummy_interaction();
        let s = b.sample::<Rgb>(&BsdfContext::IMPORTANCE, &si, Vec3::Z, 0.99, Vec2::ZERO, &()).expect("scatters");
        assert_eq!(s.lobe, Lobe::DELTA_TRANSMISSION);
        assert!((s.weight[0] - 1.0).abs() < 1e-6);
    }

    #[test]
    fn total_internal_reflection_inside() {
        let b = glass(1.5);
        let si = dummy_interaction();
        // 60° inside glass is past the critical angle 41.8°: every sample reflects.
        let wi = Vec3::new((60f32).to_radians().sin(), 0.0, -(60f32).to_radians().cos());
        for u in [0.0f32, 0.5, 0.999_999] {
            let s = b.sample::<Rgb>(&BsdfContext::RADIANCE, &si, wi, u, Vec2::ZERO, &()).expect("scatters");
            assert_eq!(s.lobe, Lobe::DELTA_REFLECTION);
            assert!(s.wo.z < 0.0 && (s.weight[0] - 1.0).abs() < 1e-6);
        }
        // Leaving the glass at normal incidence multiplies radiance by 1.5².
        let s = b.sample::<Rgb>(&BsdfContext::RADIANCE, &si, -Vec3::Z, 0.99, Vec2::ZERO, &()).expect("scatters");
        assert!((s.weight[0] - 2.25).abs() < 1e-5 && (s.eta - 1.0 / 1.5).abs() < 1e-6);
    }

    #[test]
    fn eval_and_pdf_vanish() {
        let b = glass(1.33);
        let si = dummy_interaction();
        check_sample_consistency(&b, incident(0.5, 0.1), 4);
        let wi = incident(0.5, 0.1);
        let f = fresnel_dielectric(wi.z, 1.33);
        for wo in [reflect(wi), refract(wi, f.cos_t, f.eta_ti)] {
            assert!(b.eval::<Rgb>(&BsdfContext::RADIANCE, &si, wi, wo, &()).is_zero());
            assert_eq!(b.pdf::<Rgb>(&BsdfContext::RADIANCE, &si, wi, wo, &()), 0.0);
        }
    }
}
