//! `diffuse` — the ideal diffuse (Lambertian) BRDF, f = ρ/π.
//!
//! Reflected radiance is L_r = (ρ/π) ∫ L_i cos θ_i dω_i = ρ E / π: the surface
//! looks equally bright from every direction, and with ρ ≤ 1 it reflects at
//! most the energy it receives (∫ f cos θ dω = ρ). Directions are sampled
//! proportionally to cos θ, which cancels f·cos/pdf down to ρ.
//!
//! One-sided, like Mitsuba's: light arriving at or leaving through the back
//! (cos θ ≤ 0 in the shading frame) is not reflected; use `twosided` for a
//! surface that is diffuse on both sides.
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `reflectance` | rgb / spectrum / float / texture | 0.5 | albedo ρ |
//!
//! ```xml
//! <bsdf type="diffuse">
//!     <rgb name="reflectance" value="0.2, 0.25, 0.7"/>
//! </bsdf>
//! ```

use super::{BsdfContext, BsdfModel, BsdfSample, Lobe};
use crate::geometry::SurfaceInteraction;
use crate::math::INV_PI;
use crate::math::sampling::{cosine_hemisphere_pdf, square_to_cosine_hemisphere};
use crate::scene::error::Result;
use crate::scene::loader::PluginLoader;
use crate::scene::props::Props;
use crate::spectrum::{Rgb, Spectrum};
use crate::texture::Texture;
use glam::{Vec2, Vec3};

#[derive(Clone, Debug)]
pub struct Diffuse {
    pub reflectance: Texture,
}

impl Diffuse {
    /// Reads the parameters in the table above.
    pub fn from_props(props: &Props, loader: &dyn PluginLoader) -> Result<Diffuse> {
        Ok(Diffuse { reflectance: loader.reflectance(props, "reflectance", Rgb::new(0.5, 0.5, 0.5))? })
    }
}

impl BsdfModel for Diffuse {
    fn lobes(&self) -> Lobe {
        Lobe::DIFFUSE_REFLECTION
    }

    fn has_mueller_model(&self) -> bool {
        true
    }

    #[inline]
    fn eval<S: Spectrum>(&self, ctx: &BsdfContext, si: &SurfaceInteraction, wi: Vec3, wo: Vec3, wl: &S::Wavelengths) -> S {
        if wi.z <= 0.0 || wo.z <= 0.0 || !ctx.wants(Lobe::DIFFUSE_REFLECTION) {
            return S::zero();
        }
        self.reflectance.eval_spectrum::<S>(si, wl).depolarize() * (INV_PI * wo.z)
    }

    #[inline]
    fn pdf<S: Spectrum>(&self, ctx: &BsdfContext, _si: &SurfaceInteraction, wi: Vec3, wo: Vec3, _wl: &S::Wavelengths) -> f32 {
        if wi.z <= 0.0 || !ctx.wants(Lobe::DIFFUSE_REFLECTION) { 0.0 } else { cosine_hemisphere_pdf(wo) }
    }

    // Always inlined: returned through memory, the sample's direction was
    // stored in pieces and read back in one wider load (a store-forwarding
    // stall in the path tracer's bounce loop).
    #[inline(always)]
    fn sample<S: Spectrum>(&self, ctx: &BsdfContext, si: &SurfaceInteraction, wi: Vec3, _u1: f32, u: Vec2, wl: &S::Wavelengths) -> Option<BsdfSample<S>> {
        if wi.z <= 0.0 || !ctx.wants(Lobe::DIFFUSE_REFLECTION) {
            return None;
        }
        let wo = square_to_cosine_hemisphere(u);
        let pdf = cosine_hemisphere_pdf(wo);
        if pdf <= 0.0 {
            return None;
        }
        Some(BsdfSample {
            wo,
            weight: self.reflectance.eval_spectrum::<S>(si, wl).depolarize(),
            pdf,
            eta: 1.0,
            lobe: Lobe::DIFFUSE_REFLECTION,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::Bsdf;
    use crate::bsdf::testing::*;
    use crate::spectrum::Rgb;

    fn lambert(r: f32) -> Bsdf {
        Bsdf::Diffuse(Diffuse { reflectance: Texture::constant(Rgb::new(r, r * 0.5, r * 0.25)) })
    }

    #[test]
    fn chi2_sampling_matches_pdf() {
        // Each direction gets its own random stream: one significance-1 %
        // test per direction, not one test repeated.
        for (i, &theta) in [0.0f32, 0.5, 1.2, 1.5].iter().enumerate() {
            chi2_test(&lambert(0.8), incident(theta, 0.3), 40 + i as u64);
        }
    }

    #[test]
    fn reciprocal_and_energy_conserving() {
        let b = lambert(0.9);
        check_reciprocity(&b, 13);
        let albedo = estimate_albedo(&b, incident(0.7, 0.0), 200_000, 17);
        assert!((albedo[0] - 0.9).abs() < 0.01, "albedo {albedo:?}");
        assert!(albedo[0] <= 1.0 + 0.01);
    }

    #[test]
    fn sample_weight_is_eval_over_pdf() {
        check_sample_consistency(&lambert(0.6), incident(0.4, 1.0), 19);
    }

    #[test]
    fn back_side_is_black() {
        let b = lambert(0.5);
        let si = dummy_interaction();
        let wi = Vec3::new(0.0, 0.0, -1.0);
        assert!(b.eval::<Rgb>(&BsdfContext::RADIANCE, &si, wi, Vec3::Z, &()).is_zero());
        assert!(b.sample::<Rgb>(&BsdfContext::RADIANCE, &si, wi, 0.5, Vec2::splat(0.5), &()).is_none());
    }
}
