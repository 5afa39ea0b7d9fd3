//! `normalmap` — perturbs the shading frame of a nested BSDF by a normal map.
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `normalmap` | texture | — (required) | RGB texture whose value c gives the normal 2c − 1 in the surface's tangent frame (x along ∂p/∂u, z the shading normal); give a bitmap `raw="true"` so its 8-bit values are not sRGB-decoded |
//! | (nested) | bsdf | — | the BSDF seen in the perturbed frame (exactly one) |
//!
//! As in Mitsuba 3.9: at each hit the normal n' = normalize(2c − 1) is
//! read in the shading frame built from ∂p/∂u (so a shape with a normal map
//! builds that frame), the perturbed frame is n' with its tangent ∂p/∂u made
//! perpendicular to n', and the nested BSDF is evaluated, given a density
//! and sampled with both directions expressed in that frame. A direction
//! counts only when it lies on the same side of the unperturbed and the
//! perturbed surface (cos θ · cos θ' > 0): light never leaks through the
//! geometric surface because the normal tilts. (Mitsuba makes the perturbed
//! tangent perpendicular to the world ∂p/∂u mixed with the local normal; the
//! tangent matters only to anisotropic BSDFs, and here it is ∂p/∂u in the
//! shading frame.)
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

use super::{Bsdf, BsdfContext, BsdfModel, BsdfSample, Lobe};
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
}

impl NormalMap {
    /// Reads the parameters in the table above.
    pub fn from_props(props: &Props, loader: &dyn PluginLoader) -> Result<NormalMap> {
        if !props.has("normalmap") && !props.has_child("normalmap") {
            return Err(SceneError::at(&props.node.loc, "normalmap needs a texture named \"normalmap\""));
        }
        let normalmap = loader.texture(props, "normalmap", Rgb::new(0.5, 0.5, 1.0))?;
        let nested = single_nested(props, loader, "normalmap")?;
        Ok(NormalMap { normalmap, nested: Box::new(nested) })
    }

    /// The perturbed frame, in the coordinates of `si`'s shading frame.
    fn frame(&self, si: &SurfaceInteraction) -> Frame {
        let c = self.normalmap.eval(si.uv);
        let n = Vec3::new(2.0 * c[0] - 1.0, 2.0 * c[1] - 1.0, 2.0 * c[2] - 1.0);
        perturbed_frame(si, n)
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

/// The frame about the local normal `n` (unnormalised) whose tangent is ∂p/∂u
/// made perpendicular to it, in the coordinates of `si`'s shading frame;
/// the unperturbed frame if `n` is degenerate.
pub(crate) fn perturbed_frame(si: &SurfaceInteraction, n: Vec3) -> Frame {
    let Some(n) = n.try_normalize() else {
        return Frame { s: Vec3::X, t: Vec3::Y, n: Vec3::Z };
    };
    let dp_du = si.to_local(si.dp_du);
    let dp_du = if dp_du.length_squared() > 0.0 { dp_du } else { Vec3::X };
    Frame::from_normal_and_tangent(n, dp_du)
}

/// Evaluates, gives the density of and samples `nested` in the frame `pf`
/// (local to `si`'s shading frame), with the side rule above.
pub(crate) struct Perturbed<'a> {
    pub si: SurfaceInteraction,
    pub pf: Frame,
    pub nested: &'a Bsdf,
}

impl<'a> Perturbed<'a> {
    pub fn new(si: &SurfaceInteraction, pf: Frame, nested: &'a Bsdf) -> Perturbed<'a> {
        let world = Frame { s: si.to_world(pf.s), t: si.to_world(pf.t), n: si.to_world(pf.n) };
        let psi = SurfaceInteraction { frame: world, wi: pf.to_local(si.wi), ..*si };
        Perturbed { si: psi, pf, nested }
    }

    #[inline]
    pub fn eval<S: Spectrum>(&self, ctx: &BsdfContext, wi: Vec3, wo: Vec3, wl: &S::Wavelengths) -> S {
        let pwo = self.pf.to_local(wo);
        if !(wo.z * pwo.z > 0.0) {
            return S::zero();
        }
        self.nested.eval::<S>(ctx, &self.si, self.pf.to_local(wi), pwo, wl)
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
        Some(BsdfSample { wo, ..s })
    }
}

impl BsdfModel for NormalMap {
    fn lobes(&self) -> Lobe {
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
    fn eval<S: Spectrum>(&self, ctx: &BsdfContext, si: &SurfaceInteraction, wi: Vec3, wo: Vec3, wl: &S::Wavelengths) -> S {
        Perturbed::new(si, self.frame(si), &self.nested).eval(ctx, wi, wo, wl)
    }

    #[inline]
    fn pdf<S: Spectrum>(&self, ctx: &BsdfContext, si: &SurfaceInteraction, wi: Vec3, wo: Vec3, wl: &S::Wavelengths) -> f32 {
        Perturbed::new(si, self.frame(si), &self.nested).pdf::<S>(ctx, wi, wo, wl)
    }

    #[inline]
    fn sample<S: Spectrum>(&self, ctx: &BsdfContext, si: &SurfaceInteraction, wi: Vec3, u1: f32, u2: Vec2, wl: &S::Wavelengths) -> Option<BsdfSample<S>> {
        Perturbed::new(si, self.frame(si), &self.nested).sample(ctx, wi, u1, u2, wl)
    }
}
