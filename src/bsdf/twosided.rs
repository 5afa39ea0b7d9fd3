//! `twosided` — makes a one-sided BSDF scatter on both sides.
//!
//! On the back (cos θ_i < 0) the nested BSDF is evaluated with both
//! directions mirrored through the surface. One nested BSDF serves both
//! sides; a second one, if given, serves the back.
//!
//! ```xml
//! <bsdf type="twosided">
//!     <bsdf type="diffuse"><rgb name="reflectance" value="0.5"/></bsdf>
//! </bsdf>
//! ```

use super::{Bsdf, BsdfSample, Lobe, TransportMode};
use crate::geometry::SurfaceInteraction;
use crate::spectrum::Spectrum;
use glam::{Vec2, Vec3};

#[derive(Clone, Debug)]
pub struct TwoSided {
    pub front: Box<Bsdf>,
    pub back: Box<Bsdf>,
}

#[inline]
fn flip(v: Vec3) -> Vec3 {
    Vec3::new(v.x, v.y, -v.z)
}

impl TwoSided {
    pub fn has_mueller_model(&self) -> bool {
        self.front.has_mueller_model() && self.back.has_mueller_model()
    }

    pub fn lobes(&self) -> Lobe {
        self.front.lobes() | self.back.lobes()
    }

    #[inline]
    pub fn eval<S: Spectrum>(&self, si: &SurfaceInteraction, wi: Vec3, wo: Vec3, wl: &S::Wavelengths) -> S {
        if wi.z >= 0.0 { self.front.eval(si, wi, wo, wl) } else { self.back.eval(si, flip(wi), flip(wo), wl) }
    }

    #[inline]
    pub fn pdf(&self, si: &SurfaceInteraction, wi: Vec3, wo: Vec3) -> f32 {
        if wi.z >= 0.0 { self.front.pdf(si, wi, wo) } else { self.back.pdf(si, flip(wi), flip(wo)) }
    }

    #[inline]
    pub fn sample<S: Spectrum>(&self, si: &SurfaceInteraction, wi: Vec3, u1: f32, u2: Vec2, mode: TransportMode, wl: &S::Wavelengths) -> Option<BsdfSample<S>> {
        if wi.z >= 0.0 {
            self.front.sample(si, wi, u1, u2, mode, wl)
        } else {
            let mut s = self.back.sample(si, flip(wi), u1, u2, mode, wl)?;
            s.wo = flip(s.wo);
            Some(s)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::Diffuse;
    use crate::bsdf::testing::*;
    use crate::spectrum::Rgb;
    use crate::texture::Texture;

    #[test]
    fn back_side_scatters_like_the_front() {
        let d = Bsdf::Diffuse(Diffuse { reflectance: Texture::constant(Rgb::new(0.7, 0.7, 0.7)) });
        let b = Bsdf::TwoSided(TwoSided { front: Box::new(d.clone()), back: Box::new(d) });
        let back = flip(incident(0.6, 0.2));
        chi2_test(&b, back, 23);
        check_reciprocity(&b, 29);
        let albedo = estimate_albedo(&b, back, 100_000, 31);
        assert!((albedo[0] - 0.7).abs() < 0.01, "{albedo:?}");
        let si = dummy_interaction();
        let f: Rgb = b.eval(&si, back, flip(Vec3::Z), &());
        assert!((f[0] - 0.7 / std::f32::consts::PI).abs() < 1e-5);
    }
}
