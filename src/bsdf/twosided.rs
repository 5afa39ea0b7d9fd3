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

use super::{Bsdf, BsdfContext, BsdfModel, BsdfSample, Lobe};
use crate::geometry::SurfaceInteraction;
use crate::scene::error::{Result, SceneError};
use crate::scene::loader::PluginLoader;
use crate::scene::props::Props;
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
    /// Reads the nested BSDF (or two: front and back).
    pub fn from_props(props: &Props, loader: &dyn PluginLoader) -> Result<TwoSided> {
        let node = props.node;
        let nested = loader.nested_bsdfs(props)?;
        if nested.is_empty() || nested.len() > 2 {
            return Err(SceneError::at(&node.loc, "twosided takes one nested BSDF (or two: front and back)"));
        }
        let mut sides = vec![];
        for (n, b) in nested {
            if let Bsdf::TwoSided(_) = b {
                return Err(SceneError::at(&n.loc, "twosided cannot nest another twosided"));
            }
            if b.lobes().intersects(Lobe::DIFFUSE_TRANSMISSION | Lobe::GLOSSY_TRANSMISSION | Lobe::DELTA_TRANSMISSION) {
                return Err(SceneError::at(&n.loc, format!("twosided cannot nest a transmitting BSDF (\"{}\"); it already scatters on both sides", n.plugin)));
            }
            sides.push(b);
        }
        let front = sides.remove(0);
        let back = sides.pop().unwrap_or_else(|| front.clone());
        Ok(TwoSided { front: Box::new(front), back: Box::new(back) })
    }
}

impl BsdfModel for TwoSided {
    fn has_mueller_model(&self) -> bool {
        self.front.has_mueller_model() && self.back.has_mueller_model()
    }

    fn lobes(&self) -> Lobe {
        self.front.lobes() | self.back.lobes()
    }

    fn needs_tangent_frame(&self) -> bool {
        self.front.needs_tangent_frame() || self.back.needs_tangent_frame()
    }

    #[inline]
    fn eval<S: Spectrum>(&self, ctx: &BsdfContext, si: &SurfaceInteraction, wi: Vec3, wo: Vec3, wl: &S::Wavelengths) -> S {
        if wi.z >= 0.0 { self.front.eval(ctx, si, wi, wo, wl) } else { self.back.eval(ctx, si, flip(wi), flip(wo), wl) }
    }

    #[inline]
    fn pdf<S: Spectrum>(&self, ctx: &BsdfContext, si: &SurfaceInteraction, wi: Vec3, wo: Vec3, wl: &S::Wavelengths) -> f32 {
        if wi.z >= 0.0 { self.front.pdf::<S>(ctx, si, wi, wo, wl) } else { self.back.pdf::<S>(ctx, si, flip(wi), flip(wo), wl) }
    }

    #[inline]
    fn sample<S: Spectrum>(&self, ctx: &BsdfContext, si: &SurfaceInteraction, wi: Vec3, u1: f32, u2: Vec2, wl: &S::Wavelengths) -> Option<BsdfSample<S>> {
        if wi.z >= 0.0 {
            self.front.sample(ctx, si, wi, u1, u2, wl)
        } else {
            let mut s = self.back.sample(ctx, si, flip(wi), u1, u2, wl)?;
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
        let f: Rgb = b.eval(&BsdfContext::RADIANCE, &si, back, flip(Vec3::Z), &());
        assert!((f[0] - 0.7 / std::f32::consts::PI).abs() < 1e-5);
    }
}
