//! `conductor` — a smooth metal: ideal mirror reflection weighted by the
//! exact Fresnel reflectance of a complex index of refraction η + ik.
//!
//! The seed's ideal specular BRDF f_r = F_r(ω_i) δ(ω_r − R(ω_i, n)) / cos θ_i
//! with R(ω, n) = 2(n·ω)n − ω: all reflected light leaves in the mirror
//! direction, the cosine in the denominator cancelling the one of the
//! reflection equation, so L_r = F_r L_i. F_r is evaluated per colour
//! channel from the conductor Fresnel equations (no Schlick). The lobe is a
//! delta: `eval` and `pdf` are zero and only `sample` produces it.
//!
//! η and k are relative to the exterior medium; they are given directly or
//! by `material` name: the metals Mitsuba 3 accepts, with Mitsuba's RGB
//! values of their measured spectral data (see `metals.rs` for the source),
//! or `none`, a perfect mirror (η = 0, k = 1, F = 1 at every angle).
//! One-sided like Mitsuba's: the back is black (use `twosided`).
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `material` | string | `none` | named metal (`Au`, `Ag`, `Al`, `Cu`, `Cr`, …) |
//! | `eta`, `k` | rgb / spectrum / float | 0, 1 | complex index, instead of `material` |
//! | `specular_reflectance` | rgb / spectrum / float / texture | 1 | scale (not physical; leave at 1) |
//!
//! ```xml
//! <bsdf type="conductor"><string name="material" value="Au"/></bsdf>
//! ```

use super::fresnel::{fresnel_conductor, reflect};
use super::{BsdfSample, Lobe};
use crate::geometry::SurfaceInteraction;
use crate::spectrum::{Rgb, Spectrum};
use crate::texture::Texture;
use glam::Vec3;

#[derive(Clone, Debug)]
pub struct Conductor {
    pub eta: Rgb,
    pub k: Rgb,
    pub specular_reflectance: Texture,
}

impl Conductor {
    /// The Fresnel reflectance per channel for incidence cosine `cos_i`.
    pub fn fresnel<S: Spectrum>(&self, cos_i: f32, wl: &S::Wavelengths) -> S {
        let eta = S::from_unbounded(self.eta, wl);
        let k = S::from_unbounded(self.k, wl);
        eta.zip_map(k, |e, k| fresnel_conductor(cos_i, e, k))
    }

    #[inline]
    pub fn sample<S: Spectrum>(&self, si: &SurfaceInteraction, wi: Vec3, wl: &S::Wavelengths) -> Option<BsdfSample<S>> {
        if wi.z <= 0.0 {
            return None;
        }
        let weight = self.fresnel::<S>(wi.z, wl) * S::from_reflectance(self.specular_reflectance.eval(si.uv), wl);
        Some(BsdfSample { wo: reflect(wi), weight, pdf: 1.0, eta: 1.0, lobe: Lobe::DELTA_REFLECTION })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::testing::*;
    use crate::bsdf::{Bsdf, TransportMode};
    use glam::Vec2;

    fn gold() -> Bsdf {
        Bsdf::Conductor(Conductor {
            eta: Rgb::new(0.2, 0.45, 1.4),
            k: Rgb::new(3.6, 2.5, 1.9),
            specular_reflectance: Texture::Constant(Rgb::WHITE),
        })
    }

    #[test]
    fn mirror_direction_with_fresnel_weight() {
        let b = gold();
        let si = dummy_interaction();
        for theta in [0.0f32, 0.5, 1.0, 1.5] {
            let wi = incident(theta, 0.7);
            let s = b.sample::<Rgb>(&si, wi, 0.3, Vec2::new(0.2, 0.9), TransportMode::Radiance, &()).expect("front side reflects");
            assert!((s.wo - Vec3::new(-wi.x, -wi.y, wi.z)).length() < 1e-6);
            assert!(s.lobe == Lobe::DELTA_REFLECTION);
            for c in 0..3 {
                let Bsdf::Conductor(g) = &b else { unreachable!() };
                let f = fresnel_conductor(wi.z, g.eta[c], g.k[c]);
                assert!((s.weight[c] - f).abs() < 1e-6 && f > 0.3 && f <= 1.0);
            }
        }
    }

    #[test]
    fn delta_lobe_has_no_density_and_back_is_black() {
        let b = gold();
        let si = dummy_interaction();
        let wi = incident(0.4, 0.0);
        check_sample_consistency(&b, wi, 3);
        assert!(b.eval::<Rgb>(&si, wi, Vec3::new(-wi.x, -wi.y, wi.z), &()).is_zero());
        assert_eq!(b.pdf(&si, wi, Vec3::new(-wi.x, -wi.y, wi.z)), 0.0);
        let back = Vec3::new(wi.x, wi.y, -wi.z);
        assert!(b.sample::<Rgb>(&si, back, 0.5, Vec2::splat(0.5), TransportMode::Radiance, &()).is_none());
    }
}
