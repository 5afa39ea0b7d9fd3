//! `normalmap` — perturbs the shading frame of a nested BSDF by a normal map.
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `normalmap` | texture | — (required) | RGB texture whose value c gives the normal 2c − 1 in the surface's tangent frame (x along ∂p/∂u, z the shading normal); give a bitmap `raw="true"` so its 8-bit values are not sRGB-decoded |
//! | (nested) | bsdf | — | the BSDF seen in the perturbed frame (exactly one) |
//!
//! | `flip_invalid_normals` | boolean | true | mirror the normal's tilt when the incident direction would see the perturbed surface from behind (Schüssler et al. 2017) |
//! | `use_shadowing_function` | boolean | true | attenuate by the microfacet shadowing term of Estevez Conty and Kulla (Ray Tracing Gems 2019) against the bump terminator |
//!
//! As in Mitsuba 3.9.1 (its `PerturbedBSDF`, shared with `bumpmap`): at
//! each hit the normal n' = 2c − 1 is read in the shading frame whose
//! tangent is ∂p/∂u (so a shape with a normal map builds that frame). If
//! the incident direction lies on the other side of n' than of the shading
//! normal, n' is mirrored about the normal (−x, −y, z). The perturbed frame
//! is n' normalised with the frame's x axis made perpendicular to it; the
//! nested BSDF is evaluated, given a density and sampled with both
//! directions expressed in that frame. A direction counts only when it
//! lies on the same side of the unperturbed and the perturbed surface
//! (cos θ · cos θ' > 0). `eval` and the sample weight (not the pdf) are
//! multiplied by the shadowing term
//! G = 2 / (1 + √(1 + α² tan²θ_o)), α² = min(tan²θ' / 8, 1),
//! θ' the tilt of n', θ_o that of the outgoing direction from the
//! unperturbed normal.
//!
//! ```xml
//! <bsdf type="normalmap">
//!     <texture name="normalmap" type="bitmap">
//!         <boolean name="raw" value="true"/>
//!         <string name="filename" value="textures/normalmap.jpg"/>
//!     </texture>
//!     <bsdf type="diffuse"/>
//! </bsdf>
//! ```

use super::{Bsdf, BsdfContext, BsdfSample};
use crate::geometry::SurfaceInteraction;
use crate::math::Frame;
use crate::scene::error::{Result, SceneError};
use crate::scene::loader::PluginLoader;
use crate::scene::props::Props;
use crate::spectrum::{Rgb, Spectrum};
use crate::texture::Texture;
use glam::{Vec2, Vec3};

#[derive(Clone, Debug)]
pub struct NormalMap {
    pub normalmap: Texture,
    pub nested: Box<Bsdf>,
    pub options: PerturbOptions,
}

/// The options `normalmap` and `bumpmap` share.
#[derive(Clone, Copy, Debug)]
pub struct PerturbOptions {
    pub flip_invalid_normals: bool,
    pub use_shadowing_function: bool,
}

impl PerturbOptions {
    pub(crate) fn from_props(props: &Props) -> Result<PerturbOptions> {
        Ok(PerturbOptions {
            flip_invalid_normals: props.bool("flip_invalid_normals", true)?,
            use_shadowing_function: props.bool("use_shadowing_function", true)?,
        })
    }
}

impl NormalMap {
    /// Reads the parameters in the table above.
    pub fn from_props(props: &Props, loader: &dyn PluginLoader) -> Result<NormalMap> {
        if !props.has("normalmap") && !props.has_child("normalmap") {
            return Err(SceneError::at(&props.node.loc, "normalmap needs a texture named \"normalmap\""));
        }
        let normalmap = loader.texture(props, "normalmap", Rgb::new(0.5, 0.5, 1.0))?;
        let nested = single_nested(props, loader, "normalmap")?;
        Ok(NormalMap { normalmap, nested: Box::new(nested), options: PerturbOptions::from_props(props)? })
    }

    /// The perturbed normal (unnormalised), in `si`'s shading frame.
    fn perturbation(&self, si: &SurfaceInteraction) -> Vec3 {
        let c = self.normalmap.eval(si);
        Vec3::new(2.0 * c[0] - 1.0, 2.0 * c[1] - 1.0, 2.0 * c[2] - 1.0)
    }
}

/// The one nested BSDF of an adapter (`normalmap`, `bumpmap`).
pub(crate) fn single_nested(props: &Props, loader: &dyn PluginLoader, plugin: &str) -> Result<Bsdf> {
    let mut nested = loader.nested_bsdfs(props)?;
    if nested.len() != 1 {
        let loc = nested.get(1).map_or(&props.node.loc, |(n, _)| &n.loc);
        return Err(SceneError::at(loc, format!("{plugin} takes exactly one nested BSDF, found {}", nested.len())));
    }
    Ok(nested.remove(0).1)
}

/// tan²θ of a local direction (infinite on the horizon).
#[inline]
fn tan_theta_2(v: Vec3) -> f32 {
    (1.0 - v.z * v.z).max(0.0) / (v.z * v.z)
}

/// The bump-terminator shadowing term for perturbed normal `n` and
/// outgoing direction `wo`, both local to the unperturbed frame.
#[inline]
pub(crate) fn shadow_terminator(n: Vec3, wo: Vec3) -> f32 {
    let alpha2 = (0.125 * tan_theta_2(n)).min(1.0);
    let g = 2.0 / (1.0 + (1.0 + alpha2 * tan_theta_2(wo)).sqrt());
    if g.is_finite() { g } else { 0.0 }
}

/// The nested BSDF seen in the perturbed frame `pf` (local to `si`'s
/// shading frame), with the side rule and shadowing term above.
pub(crate) struct Perturbed<'a> {
    pub si: SurfaceInteraction,
    pub pf: Frame,
    pub nested: &'a Bsdf,
    pub shadowing: bool,
}

impl<'a> Perturbed<'a> {
    /// The perturbed frame for the unnormalised local normal `n`.
    pub fn new(si: &SurfaceInteraction, n: Vec3, options: PerturbOptions, nested: &'a Bsdf) -> Perturbed<'a> {
        let mut n = n;
        if options.flip_invalid_normals && si.wi.z * si.wi.dot(n) <= 0.0 {
            n = Vec3::new(-n.x, -n.y, n.z);
        }
        let n = match n.try_normalize() {
            Some(n) => n,
            None => Vec3::Z,
        };
        let s = (Vec3::X - n * n.x).try_normalize().unwrap_or(Vec3::Y);
        let pf = Frame { s, t: n.cross(s), n };
        let world = Frame { s: si.to_world(pf.s), t: si.to_world(pf.t), n: si.to_world(pf.n) };
        let psi = SurfaceInteraction { frame: world, wi: pf.to_local(si.wi), ..*si };
        Perturbed { si: psi, pf, nested, shadowing: options.use_shadowing_function }
    }

    #[inline]
    fn shadow(&self, wo: Vec3) -> f32 {
        if self.shadowing { shadow_terminator(self.pf.n, wo) } else { 1.0 }
    }

    #[inline]
    pub fn eval<S: Spectrum>(&self, ctx: &BsdfContext, wi: Vec3, wo: Vec3, wl: &S::Wavelengths) -> S {
        let pwo = self.pf.to_local(wo);
        if !(wo.z * pwo.z > 0.0) {
            return S::zero();
        }
        self.nested.eval::<S>(ctx, &self.si, self.pf.to_local(wi), pwo, wl) * self.shadow(wo)
    }

    #[inline]
    pub fn pdf<S: Spectrum>(&self, ctx: &BsdfContext, wi: Vec3, wo: Vec3, wl: &S::Wavelengths) -> f32 {
        let pwo = self.pf.to_local(wo);
        if !(wo.z * pwo.z > 0.0) {
            return 0.0;
        }
        self.nested.pdf::<S>(ctx, &self.si, self.pf.to_local(wi), pwo, wl)
    }

    #[inline]
    pub fn sample<S: Spectrum>(&self, ctx: &BsdfContext, wi: Vec3, u1: f32, u2: Vec2, wl: &S::Wavelengths) -> Option<BsdfSample<S>> {
        let s = self.nested.sample::<S>(ctx, &self.si, self.pf.to_local(wi), u1, u2, wl)?;
        let wo = self.pf.to_world(s.wo);
        if !(wo.z * s.wo.z > 0.0) {
            return None;
        }
        Some(BsdfSample { wo, weight: s.weight * self.shadow(wo), ..s })
    }
}

/// The [`BsdfModel`] of a BSDF that perturbs the shading frame of its
/// `nested` BSDF by the normal its `perturbation(si)` gives (`normalmap`,
/// `bumpmap`): every call goes through [`Perturbed`] with its `options`.
macro_rules! perturbed_bsdf_model {
    ($model:ty) => {
        impl $crate::bsdf::BsdfModel for $model {
            fn lobes(&self) -> $crate::bsdf::Lobe {
                self.nested.lobes()
            }

            fn has_mueller_model(&self) -> bool {
                self.nested.has_mueller_model()
            }

            fn needs_tangent_frame(&self) -> bool {
                true
            }

            fn disperses(&self) -> bool {
                self.nested.disperses()
            }

            #[inline]
            fn eval<S: $crate::spectrum::Spectrum>(
                &self,
                ctx: &$crate::bsdf::BsdfContext,
                si: &$crate::geometry::SurfaceInteraction,
                wi: glam::Vec3,
                wo: glam::Vec3,
                wl: &S::Wavelengths,
            ) -> S {
                $crate::bsdf::normalmap::Perturbed::new(si, self.perturbation(si), self.options, &self.nested).eval(ctx, wi, wo, wl)
            }

            #[inline]
            fn pdf<S: $crate::spectrum::Spectrum>(
                &self,
                ctx: &$crate::bsdf::BsdfContext,
                si: &$crate::geometry::SurfaceInteraction,
                wi: glam::Vec3,
                wo: glam::Vec3,
                wl: &S::Wavelengths,
            ) -> f32 {
                $crate::bsdf::normalmap::Perturbed::new(si, self.perturbation(si), self.options, &self.nested).pdf::<S>(ctx, wi, wo, wl)
            }

            #[inline]
            fn sample<S: $crate::spectrum::Spectrum>(
                &self,
                ctx: &$crate::bsdf::BsdfContext,
                si: &$crate::geometry::SurfaceInteraction,
                wi: glam::Vec3,
                u1: f32,
                u2: glam::Vec2,
                wl: &S::Wavelengths,
            ) -> Option<$crate::bsdf::BsdfSample<S>> {
                $crate::bsdf::normalmap::Perturbed::new(si, self.perturbation(si), self.options, &self.nested).sample(ctx, wi, u1, u2, wl)
            }
        }
    };
}
pub(crate) use perturbed_bsdf_model;

perturbed_bsdf_model!(NormalMap);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::Diffuse;
    use crate::bsdf::testing::*;
    use std::f32::consts::PI;

    fn tilted(n: Vec3, shadowing: bool) -> Bsdf {
        let c = (n.normalize() + Vec3::ONE) * 0.5;
        Bsdf::NormalMap(NormalMap {
            normalmap: Texture::constant(Rgb::new(c.x, c.y, c.z)),
            nested: Box::new(Bsdf::Diffuse(Diffuse { reflectance: Texture::constant(Rgb::new(0.8, 0.8, 0.8)) })),
            options: PerturbOptions { flip_invalid_normals: true, use_shadowing_function: shadowing },
        })
    }

    #[test]
    fn diffuse_under_a_tilted_normal_follows_the_tilted_cosine() {
        let n = Vec3::new(0.5, 0.2, 1.0).normalize();
        let b = tilted(n, false);
        let wi = incident(0.3, 0.5);
        let si = SurfaceInteraction { wi, ..dummy_interaction() };
        for wo in [incident(0.2, 1.0), incident(1.0, 0.3), incident(1.3, 3.5), incident(0.9, -2.0)] {
            let f: Rgb = b.eval(&BsdfContext::RADIANCE, &si, wi, wo, &());
            let expect = if wo.z > 0.0 && n.dot(wo) > 0.0 { 0.8 / PI * n.dot(wo) } else { 0.0 };
            assert!((f[0] - expect).abs() < 1e-5, "wo {wo}: {} vs {expect}", f[0]);
        }
        chi2_test(&b, wi, 3);
        check_sample_consistency(&b, wi, 5);
    }

    #[test]
    fn shadowing_term_matches_mitsuba() {
        // Values read from Mitsuba 3.9.1 (bumpmap over diffuse: eval / (ρ/π · cos θ'))
        // for a perturbed normal (0.869, -0.0117, 0.494) in the shading frame.
        let n = Vec3::new(0.869_427_7, -0.011_696_9, 0.493_921_6);
        for (wo, g) in [(Vec3::new(0.707_107, 0.0, 0.707_107), 0.9183), (Vec3::new(0.948_683, 0.0, 0.316_228), 0.6414), (Vec3::new(0.989, 0.104, 0.104), 0.2845)] {
            let got = shadow_terminator(n, wo.normalize());
            assert!((got - g).abs() < 2e-3, "{got} vs {g}");
        }
        assert_eq!(shadow_terminator(Vec3::Z, Vec3::new(0.6, 0.0, 0.8)), 1.0);
        // On: eval carries the term; the pdf does not.
        let b = tilted(n, true);
        let wi = incident(0.2, 0.0);
        let si = SurfaceInteraction { wi, ..dummy_interaction() };
        let wo = Vec3::new(0.707_107, 0.0, 0.707_107);
        let f: Rgb = b.eval(&BsdfContext::RADIANCE, &si, wi, wo, &());
        let nn = n.normalize();
        assert!((f[0] - 0.8 / PI * nn.dot(wo) * shadow_terminator(nn, wo)).abs() < 1e-5);
        assert!((b.pdf::<Rgb>(&BsdfContext::RADIANCE, &si, wi, wo, &()) - nn.dot(wo) / PI).abs() < 1e-5);
        check_sample_consistency(&b, wi, 9);
    }

    #[test]
    fn a_normal_facing_away_from_the_viewer_is_mirrored() {
        // Seen from the +x side at a grazing angle, a normal tilted far to -x
        // would hide the surface; Mitsuba mirrors its tilt instead.
        let n = Vec3::new(-0.9, 0.0, 0.3).normalize();
        let b = tilted(n, false);
        let wi = incident(1.4, 0.0);
        assert!(wi.dot(n) < 0.0);
        let si = SurfaceInteraction { wi, ..dummy_interaction() };
        let mirrored = Vec3::new(-n.x, -n.y, n.z);
        let wo = incident(0.5, 0.0);
        let f: Rgb = b.eval(&BsdfContext::RADIANCE, &si, wi, wo, &());
        assert!((f[0] - 0.8 / PI * mirrored.dot(wo)).abs() < 1e-5);
    }
}
