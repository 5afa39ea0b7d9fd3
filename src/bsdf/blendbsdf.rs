//! `blendbsdf` — a linear blend of two BSDFs.
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `weight` | float or texture | — (required) | blend weight w in [0, 1] (a colour texture counts by its luminance); 0 = the first BSDF only, 1 = the second only |
//! | (nested) | bsdf ×2 | — | the two BSDFs, in document order |
//!
//! f = (1 − w) f₀ + w f₁, and the pdf the same blend of the two pdfs.
//! Sampling picks the second BSDF with probability w and samples it. Unlike
//! Mitsuba 3.9, whose sample reports the chosen BSDF's own pdf and weight,
//! a smooth sample here reports the blended pdf and f / pdf (what `pdf`
//! returns, so the path tracer's MIS weights sum to one); both estimate
//! the same image.
//!
//! ```xml
//! <bsdf type="blendbsdf">
//!     <float name="weight" value="0.3"/>
//!     <bsdf type="diffuse"/>
//!     <bsdf type="conductor"/>
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
pub struct BlendBsdf {
    pub weight: Texture,
    pub nested: Box<[Bsdf; 2]>,
}

impl BlendBsdf {
    /// Reads the parameters in the table above.
    pub fn from_props(props: &Props, loader: &dyn PluginLoader) -> Result<BlendBsdf> {
        if !props.has("weight") && !props.has_child("weight") {
            return Err(SceneError::at(&props.node.loc, "blendbsdf needs a \"weight\" (a float or a texture)"));
        }
        let weight = loader.texture(props, "weight", Rgb::BLACK)?;
        let nested = loader.nested_bsdfs(props)?;
        if nested.len() != 2 {
            let loc = nested.get(2).map_or(&props.node.loc, |(n, _)| &n.loc);
            return Err(SceneError::at(loc, format!("blendbsdf takes exactly two nested BSDFs, found {}", nested.len())));
        }
        let mut it = nested.into_iter().map(|(_, b)| b);
        let (a, b) = (it.next(), it.next());
        match (a, b) {
            (Some(a), Some(b)) => Ok(BlendBsdf { weight, nested: Box::new([a, b]) }),
            _ => Err(SceneError::at(&props.node.loc, "blendbsdf takes exactly two nested BSDFs")),
        }
    }

    /// The weight of the second BSDF at `si`, in [0, 1].
    #[inline]
    pub fn weight(&self, si: &SurfaceInteraction) -> f32 {
        let w = self.weight.eval_1(si);
        if w.is_nan() { 0.0 } else { w.clamp(0.0, 1.0) }
    }
}

impl BsdfModel for BlendBsdf {
    fn lobes(&self) -> Lobe {
        self.nested[0].lobes() | self.nested[1].lobes()
    }

    fn has_mueller_model(&self) -> bool {
        self.nested[0].has_mueller_model() && self.nested[1].has_mueller_model()
    }

    fn needs_tangent_frame(&self) -> bool {
        self.nested[0].needs_tangent_frame() || self.nested[1].needs_tangent_frame()
    }

    fn disperses(&self) -> bool {
        self.nested[0].disperses() || self.nested[1].disperses()
    }

    #[inline]
    fn eval<S: Spectrum>(&self, ctx: &BsdfContext, si: &SurfaceInteraction, wi: Vec3, wo: Vec3, wl: &S::Wavelengths) -> S {
        let w = self.weight(si);
        let mut f = S::zero();
        if w < 1.0 {
            f += self.nested[0].eval::<S>(ctx, si, wi, wo, wl) * (1.0 - w);
        }
        if w > 0.0 {
            f += self.nested[1].eval::<S>(ctx, si, wi, wo, wl) * w;
        }
        f
    }

    #[inline]
    fn pdf<S: Spectrum>(&self, ctx: &BsdfContext, si: &SurfaceInteraction, wi: Vec3, wo: Vec3, wl: &S::Wavelengths) -> f32 {
        let w = self.weight(si);
        let mut p = 0.0;
        if w < 1.0 {
            p += self.nested[0].pdf::<S>(ctx, si, wi, wo, wl) * (1.0 - w);
        }
        if w > 0.0 {
            p += self.nested[1].pdf::<S>(ctx, si, wi, wo, wl) * w;
        }
        p
    }

    #[inline]
    fn sample<S: Spectrum>(&self, ctx: &BsdfContext, si: &SurfaceInteraction, wi: Vec3, u1: f32, u2: Vec2, wl: &S::Wavelengths) -> Option<BsdfSample<S>> {
        let w = self.weight(si);
        let (first, u1) = if u1 >= w { (true, (u1 - w) / (1.0 - w)) } else { (false, u1 / w) };
        let u1 = if u1.is_finite() { u1.clamp(0.0, 1.0 - f32::EPSILON) } else { 0.0 };
        let chosen = &self.nested[if first { 0 } else { 1 }];
        let s = chosen.sample::<S>(ctx, si, wi, u1, u2, wl)?;
        if s.lobe.intersects(Lobe::DELTA) {
            // The choice's probability cancels the blend weight.
            return Some(s);
        }
        let pdf = self.pdf::<S>(ctx, si, wi, s.wo, wl);
        if !(pdf > 0.0) {
            return None;
        }
        let f = self.eval::<S>(ctx, si, wi, s.wo, wl);
        Some(BsdfSample { weight: f * (1.0 / pdf), pdf, ..s })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::testing::*;
    use crate::bsdf::{Conductor, Diffuse, Plastic};

    fn diffuse(r: f32, g: f32, b: f32) -> Bsdf {
        Bsdf::Diffuse(Diffuse { reflectance: Texture::constant(Rgb::new(r, g, b)) })
    }

    fn blend(w: f32, a: Bsdf, b: Bsdf) -> Bsdf {
        Bsdf::BlendBsdf(BlendBsdf { weight: Texture::constant(Rgb::new(w, w, w)), nested: Box::new([a, b]) })
    }

    #[test]
    fn blend_of_two_diffuse_is_the_diffuse_of_the_blended_albedo() {
        let b = blend(0.3, diffuse(0.9, 0.5, 0.1), diffuse(0.1, 0.2, 0.8));
        let wi = incident(0.5, 0.4);
        let albedo = estimate_albedo(&b, wi, 100_000, 3);
        let expect = [0.7 * 0.9 + 0.3 * 0.1, 0.7 * 0.5 + 0.3 * 0.2, 0.7 * 0.1 + 0.3 * 0.8];
        for c in 0..3 {
            assert!((albedo[c] - expect[c]).abs() < 0.01, "{albedo:?} vs {expect:?}");
        }
        let si = dummy_interaction();
        let f: Rgb = b.eval(&BsdfContext::RADIANCE, &si, wi, Vec3::Z, &());
        assert!((f[0] - expect[0] / std::f32::consts::PI).abs() < 1e-5);
        chi2_test(&b, wi, 5);
        check_sample_consistency(&b, wi, 7);
    }

    /// E[sample weight]: the albedo including delta lobes.
    fn sampled_albedo(b: &Bsdf, wi: Vec3, n: usize, seed: u64) -> [f64; 3] {
        let si = SurfaceInteraction { wi, ..dummy_interaction() };
        let mut rng = crate::math::Pcg32::new(seed, 3);
        let mut sum = [0.0f64; 3];
        for _ in 0..n {
            let u1 = rng.next_f32();
            let u2 = Vec2::new(rng.next_f32(), rng.next_f32());
            if let Some(s) = b.sample::<Rgb>(&BsdfContext::RADIANCE, &si, wi, u1, u2, &()) {
                for c in 0..3 {
                    sum[c] += s.weight[c] as f64;
                }
            }
        }
        sum.map(|v| v / n as f64)
    }

    #[test]
    fn blend_with_a_delta_lobe_keeps_both_parts() {
        // 40 % gold-coloured mirror, 60 % plastic (diffuse + delta coat).
        let mirror = Bsdf::Conductor(Conductor { eta: Rgb::new(0.2, 0.4, 1.4), k: Rgb::new(3.9, 2.4, 1.8), spectra: None, specular_reflectance: Texture::constant(Rgb::WHITE), given: Default::default() });
        let plastic = Bsdf::Plastic(Plastic::new(Texture::constant(Rgb::new(0.5, 0.4, 0.3)), None, 1.5, false));
        let wi = incident(0.7, 1.0);
        let a_plastic = sampled_albedo(&plastic, wi, 400_000, 11);
        let a_mirror = sampled_albedo(&mirror, wi, 1000, 12);
        let b = blend(0.4, plastic, mirror);
        let a = sampled_albedo(&b, wi, 400_000, 13);
        for c in 0..3 {
            let expect = 0.6 * a_plastic[c] + 0.4 * a_mirror[c];
            assert!((a[c] - expect).abs() < 0.006, "channel {c}: {} vs {expect}", a[c]);
        }
        check_sample_consistency(&b, wi, 17);
    }
}
