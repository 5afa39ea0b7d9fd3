//! `mask` — cut-out opacity over a nested BSDF (leaves, fences, decals).
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `opacity` | float or texture | 0.5 | fraction of the surface that is there (1 = opaque); a colour texture counts by its luminance, clamped to [0, 1] |
//! | (nested) | bsdf | — | the BSDF of the opaque part (exactly one) |
//!
//! Where the opacity is α, a fraction 1 − α of all light passes straight
//! through (Mitsuba's null lobe) and α meets the nested BSDF. On a shape
//! that does not emit, the scene handles the pass-through: camera rays,
//! path rays and light paths go through with probability 1 − α (chosen per
//! ray), and shadow rays (emitter sampling, connections to the camera)
//! carry the transmittance ∏(1 − α) of the masks they cross, so holes let
//! light and shadows through. Elsewhere (nested in another BSDF, or on an
//! emitting shape) the model itself does as Mitsuba's: `eval` and `pdf` are
//! α times the nested ones, and `sample` picks the straight-through delta
//! lobe (weight 1) with probability 1 − α.
//!
//! Mitsuba 3.9.1's `path` handles the null lobe only by BSDF sampling: its
//! shadow rays stop at a mask (its documentation recommends `volpath` for
//! masks). Under area lights and environments both estimate the same image
//! (the leaf test against Mitsuba's `path` checks it), Snell's with far less
//! noise; light from a point, spot or directional emitter seen through the
//! holes reaches the surface behind in Snell but not in Mitsuba's `path`.
//! Passing a mask does not count as a bounce (Mitsuba's `path` counts one).
//!
//! ```xml
//! <bsdf type="mask">
//!     <texture type="bitmap" name="opacity">
//!         <string name="filename" value="leaf_mask.png"/>
//!     </texture>
//!     <bsdf type="twosided"><bsdf type="diffuse"/></bsdf>
//! </bsdf>
//! ```

use super::{Bsdf, BsdfContext, BsdfModel, BsdfSample, Lobe};
use crate::geometry::SurfaceInteraction;
use crate::scene::error::{Result, SceneError};
use crate::scene::loader::PluginLoader;
use crate::scene::props::Props;
use crate::spectrum::{Rgb, Spectrum};
use crate::texture::Texture;
use glam::{Vec2, Vec3};

#[derive(Clone, Debug)]
pub struct Mask {
    pub opacity: Texture,
    pub nested: Box<Bsdf>,
}

impl Mask {
    /// Reads the parameters in the table above.
    pub fn from_props(props: &Props, loader: &dyn PluginLoader) -> Result<Mask> {
        let opacity = loader.texture(props, "opacity", Rgb::new(0.5, 0.5, 0.5))?;
        let mut nested = loader.nested_bsdfs(props)?;
        if nested.len() != 1 {
            let loc = nested.get(1).map_or(&props.node.loc, |(n, _)| &n.loc);
            return Err(SceneError::at(loc, format!("mask takes exactly one nested BSDF, found {}", nested.len())));
        }
        let (_, nested) = nested.remove(0);
        Ok(Mask { opacity, nested: Box::new(nested) })
    }

    /// The opacity α at `si`, in [0, 1].
    #[inline]
    pub fn opacity(&self, si: &SurfaceInteraction) -> f32 {
        let a = self.opacity.eval_1(si);
        if a.is_nan() { 1.0 } else { a.clamp(0.0, 1.0) }
    }
}

impl BsdfModel for Mask {
    fn lobes(&self) -> Lobe {
        self.nested.lobes() | Lobe::NULL
    }

    fn has_mueller_model(&self) -> bool {
        self.nested.has_mueller_model()
    }

    fn needs_tangent_frame(&self) -> bool {
        self.nested.needs_tangent_frame()
    }

    fn disperses(&self) -> bool {
        self.nested.disperses()
    }

    #[inline]
    fn eval<S: Spectrum>(&self, ctx: &BsdfContext, si: &SurfaceInteraction, wi: Vec3, wo: Vec3, wl: &S::Wavelengths) -> S {
        self.nested.eval::<S>(ctx, si, wi, wo, wl) * self.opacity(si)
    }

    #[inline]
    fn pdf<S: Spectrum>(&self, ctx: &BsdfContext, si: &SurfaceInteraction, wi: Vec3, wo: Vec3, wl: &S::Wavelengths) -> f32 {
        let p = self.nested.pdf::<S>(ctx, si, wi, wo, wl);
        if ctx.wants(Lobe::NULL) { p * self.opacity(si) } else { p }
    }

    #[inline]
    fn sample<S: Spectrum>(&self, ctx: &BsdfContext, si: &SurfaceInteraction, wi: Vec3, u1: f32, u2: Vec2, wl: &S::Wavelengths) -> Option<BsdfSample<S>> {
        let alpha = if ctx.wants(Lobe::NULL) { self.opacity(si) } else { 1.0 };
        if u1 < alpha {
            let mut s = self.nested.sample::<S>(ctx, si, wi, (u1 / alpha).min(1.0 - f32::EPSILON), u2, wl)?;
            if !s.lobe.intersects(Lobe::DELTA) {
                s.pdf *= alpha;
            }
            Some(s)
        } else {
            Some(BsdfSample { wo: -wi, weight: S::splat(1.0), pdf: 1.0 - alpha, eta: 1.0, lobe: Lobe::NULL | Lobe::DELTA_TRANSMISSION })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::Diffuse;
    use crate::bsdf::testing::*;

    #[test]
    fn mask_scales_the_nested_bsdf_and_passes_the_rest_straight_through() {
        let nested = Bsdf::Diffuse(Diffuse { reflectance: Texture::constant(Rgb::new(0.8, 0.6, 0.4)) });
        let m = Bsdf::Mask(Mask { opacity: Texture::constant(Rgb::new(0.3, 0.3, 0.3)), nested: Box::new(nested.clone()) });
        let si = dummy_interaction();
        assert_eq!(m.opacity(&si), 0.3);
        assert!(m.passes_through() && m.lobes().contains(Lobe::NULL));
        let (wi, wo) = (incident(0.4, 0.1), incident(0.9, 2.0));
        let f: Rgb = m.eval(&BsdfContext::RADIANCE, &si, wi, wo, &());
        let g: Rgb = nested.eval(&BsdfContext::RADIANCE, &si, wi, wo, &());
        assert!((f[0] - 0.3 * g[0]).abs() < 1e-6);
        // Sampling: the null lobe (straight through, weight 1) with
        // probability 0.7, else the nested diffuse.
        let mut through = 0;
        let n = 1000;
        for i in 0..n {
            let u1 = (i as f32 + 0.5) / n as f32;
            let s = m.sample::<Rgb>(&BsdfContext::RADIANCE, &si, wi, u1, glam::Vec2::new(0.3, 0.7), &()).expect("samples");
            if s.lobe.contains(Lobe::NULL) {
                through += 1;
                assert_eq!(s.wo, -wi);
                assert_eq!(s.weight, Rgb::WHITE);
            } else {
                assert!((s.weight[0] - 0.8).abs() < 1e-5 && s.wo.z > 0.0);
            }
        }
        assert_eq!(through, 700);
        check_sample_consistency(&m, wi, 3);
        // A mask of opacity 1 reads the nested BSDF as its surface.
        assert!(matches!(m.surface(), Bsdf::Diffuse(_)));
    }
}
