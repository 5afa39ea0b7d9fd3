//! BSDFs: how a surface scatters light.
//!
//! # The contract
//! Every BSDF model is a struct in its own file implementing [`BsdfModel`]:
//! the same methods with the same signatures for all of them, dispatched
//! statically through the [`Bsdf`] enum (one `match`, no virtual calls).
//! Everything happens in the local shading frame (z = shading normal):
//! `wi` points from the surface towards where the path came from (the camera
//! side for radiance, the light side for importance), `wo` towards where it
//! goes next.
//!
//! * Every call takes a [`BsdfContext`] — the [`TransportMode`] (radiance on
//!   camera paths, importance on light paths; non-symmetric BSDFs such as
//!   refraction scale differently in each) and the [`Lobe`]s wanted (a BSDF
//!   leaves out lobes the context does not ask for) — and the path's
//!   wavelengths `wl` (`()` in RGB mode).
//! * [`BsdfModel::eval`] returns f(wi, wo) · |cos θ_o| — the BSDF **times
//!   the cosine foreshortening** of `wo` (Mitsuba's convention), so
//!   integrators never multiply by a cosine themselves.
//! * [`BsdfModel::pdf`] is the solid-angle density with which `sample` picks
//!   `wo` (given the same context).
//! * [`BsdfModel::sample`] takes `u1` (picks a lobe) and `u2` (samples the
//!   direction within it) and returns a [`BsdfSample`]: `wo`, weight =
//!   eval / pdf, the pdf, the relative IOR crossed and the lobe sampled; or
//!   `None` if nothing scatters.
//! * `eval` and `pdf` are zero on delta lobes (specular reflection or
//!   refraction); only `sample` produces them, flagged [`Lobe::DELTA`], and
//!   integrators handle those samples explicitly (no emitter sampling, no MIS).
//! * Each model reads its own parameters in `from_props`, beside the
//!   parameter table in its file's doc; `scene/loader.rs` only maps plugin
//!   names to models.

pub mod birefringent;
pub mod blendbsdf;
pub mod bumpmap;
pub mod conductor;
pub mod dielectric;
pub mod diffuse;
pub mod dispersion;
pub mod fresnel;
pub mod ior;
pub mod metal_spectra;
pub mod mask;
pub mod metals;
pub mod microfacet;
pub mod normalmap;
pub mod null;
pub mod plastic;
pub mod polarizer;
pub mod principled;
pub mod principledthin;
pub mod retarder;
pub mod roughconductor;
pub mod roughdielectric;
pub mod pplastic;
pub mod roughplastic;
pub mod thindielectric;
pub mod twosided;

pub use birefringent::Birefringent;
pub use blendbsdf::BlendBsdf;
pub use bumpmap::BumpMap;
pub use conductor::Conductor;
pub use mask::Mask;
pub use normalmap::NormalMap;
pub use null::Null;
pub use dielectric::Dielectric;
pub use diffuse::Diffuse;
pub use plastic::Plastic;
pub use polarizer::Polarizer;
pub use principled::Principled;
pub use principledthin::PrincipledThin;
pub use retarder::Retarder;
pub use roughconductor::RoughConductor;
pub use roughdielectric::RoughDielectric;
pub use pplastic::PolarizedPlastic;
pub use roughplastic::RoughPlastic;
pub use thindielectric::ThinDielectric;
pub use twosided::TwoSided;

use crate::geometry::SurfaceInteraction;
use crate::spectrum::Spectrum;
use bitflags::bitflags;
use glam::{Vec2, Vec3};

bitflags! {
    /// Which kind of scattering a BSDF (or one sample of it) does.
    #[derive(Clone, Copy, Debug, PartialEq, Eq)]
    pub struct Lobe: u8 {
        const DIFFUSE_REFLECTION = 1 << 0;
        const DIFFUSE_TRANSMISSION = 1 << 1;
        const GLOSSY_REFLECTION = 1 << 2;
        const GLOSSY_TRANSMISSION = 1 << 3;
        const DELTA_REFLECTION = 1 << 4;
        const DELTA_TRANSMISSION = 1 << 5;
        /// Straight pass-through (Mitsuba's `Null`): the surface is not
        /// there for this fraction of rays (`mask`, `null`).
        const NULL = 1 << 6;
        /// Marks a delta sample after which the path travels inside a
        /// birefringent crystal as its extraordinary ray (`birefringent`);
        /// integrators hand it back in [`BsdfContext::extraordinary`].
        const EXTRAORDINARY = 1 << 7;
        const DIFFUSE = Self::DIFFUSE_REFLECTION.bits() | Self::DIFFUSE_TRANSMISSION.bits();
        const GLOSSY = Self::GLOSSY_REFLECTION.bits() | Self::GLOSSY_TRANSMISSION.bits();
        const DELTA = Self::DELTA_REFLECTION.bits() | Self::DELTA_TRANSMISSION.bits();
        /// Lobes with a density, where emitter sampling and MIS apply.
        const SMOOTH = Self::DIFFUSE.bits() | Self::GLOSSY.bits();
    }
}

/// Whether the path carries radiance (camera paths) or importance (light
/// paths); non-symmetric BSDFs (refraction) scale differently in each.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum TransportMode {
    #[default]
    Radiance,
    Importance,
}

#[derive(Clone, Copy, Debug)]
pub struct BsdfSample<S> {
    pub wo: Vec3,
    /// f · |cos θ_o| / pdf (for delta lobes: the lobe's total weight).
    pub weight: S,
    pub pdf: f32,
    /// Relative index of refraction crossed (1 for reflection).
    pub eta: f32,
    pub lobe: Lobe,
}

/// What a BSDF query is for: the transport mode and the lobes wanted
/// (Mitsuba's `BSDFContext`). The default is radiance transport with every
/// lobe.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BsdfContext {
    pub mode: TransportMode,
    /// The lobes to evaluate, give a density to, or sample; others are left out.
    pub lobes: Lobe,
    /// Whether the path's segment on the side of `wi` is a birefringent
    /// crystal's extraordinary ray (set by [`BsdfContext::following`]);
    /// only `birefringent` reads it.
    pub extraordinary: bool,
}

impl Default for BsdfContext {
    fn default() -> Self {
        BsdfContext::RADIANCE
    }
}

impl BsdfContext {
    /// Camera paths, every lobe.
    pub const RADIANCE: BsdfContext = BsdfContext { mode: TransportMode::Radiance, lobes: Lobe::all(), extraordinary: false };
    /// Light paths, every lobe.
    pub const IMPORTANCE: BsdfContext = BsdfContext { mode: TransportMode::Importance, lobes: Lobe::all(), extraordinary: false };

    pub const fn new(mode: TransportMode) -> BsdfContext {
        BsdfContext { mode, lobes: Lobe::all(), extraordinary: false }
    }

    /// The same context restricted to `lobes`.
    pub const fn with_lobes(self, lobes: Lobe) -> BsdfContext {
        BsdfContext { mode: self.mode, lobes, extraordinary: self.extraordinary }
    }

    /// The context for the path's next vertex after a sample of `lobe`.
    #[inline]
    pub fn following(self, lobe: Lobe) -> BsdfContext {
        BsdfContext { extraordinary: lobe.contains(Lobe::EXTRAORDINARY), ..self }
    }

    /// Whether any of `lobe` is wanted.
    #[inline]
    pub fn wants(&self, lobe: Lobe) -> bool {
        self.lobes.intersects(lobe)
    }
}

/// The probability of picking the first of two lobes: `p` (the model's
/// own choice) when the context wants both, 1 or 0 when it wants only one,
/// `None` when it wants neither.
#[inline]
pub(crate) fn choose_lobe(ctx: &BsdfContext, first: Lobe, second: Lobe, p: f32) -> Option<f32> {
    match (ctx.wants(first), ctx.wants(second)) {
        (true, true) => Some(p),
        (true, false) => Some(1.0),
        (false, true) => Some(0.0),
        (false, false) => None,
    }
}

/// The contract every BSDF model implements (see the module doc). The
/// methods are generic over the spectral representation `S` (RGB,
/// spectral, polarized), so a model is written once for every mode.
pub trait BsdfModel {
    /// Every lobe this model can scatter into.
    fn lobes(&self) -> Lobe;

    /// f(wi, wo) · |cos θ_o| over the smooth lobes `ctx` wants.
    fn eval<S: Spectrum>(&self, ctx: &BsdfContext, si: &SurfaceInteraction, wi: Vec3, wo: Vec3, wl: &S::Wavelengths) -> S;

    /// The density (solid angle) with which `sample` picks `wo` under `ctx`.
    fn pdf<S: Spectrum>(&self, ctx: &BsdfContext, si: &SurfaceInteraction, wi: Vec3, wo: Vec3, wl: &S::Wavelengths) -> f32;

    /// `eval` and `pdf` at once (an emitter sample weighted by MIS needs
    /// both); models whose two share work (a microfacet's D and G1)
    /// override it. Must equal (`eval`, `pdf`).
    #[inline]
    fn eval_pdf<S: Spectrum>(&self, ctx: &BsdfContext, si: &SurfaceInteraction, wi: Vec3, wo: Vec3, wl: &S::Wavelengths) -> (S, f32) {
        (self.eval::<S>(ctx, si, wi, wo, wl), self.pdf::<S>(ctx, si, wi, wo, wl))
    }

    /// Finishes a sample of a model whose smooth lobes are picked by one-sample
    /// MIS: `wo` was drawn from the one lobe `lobe`, so its density is the
    /// whole mixture's (`pdf`, every lobe `ctx` wants) and its weight is
    /// `eval` over that density. `None` where the density vanishes or is not
    /// finite (a direction no lobe can give).
    #[inline]
    fn mixture_sample<S: Spectrum>(&self, ctx: &BsdfContext, si: &SurfaceInteraction, wi: Vec3, wo: Vec3, lobe: Lobe, wl: &S::Wavelengths) -> Option<BsdfSample<S>> {
        let pdf = self.pdf::<S>(ctx, si, wi, wo, wl);
        if !(pdf > 0.0 && pdf.is_finite()) {
            return None;
        }
        let weight = self.eval::<S>(ctx, si, wi, wo, wl) * (1.0 / pdf);
        Some(BsdfSample { wo, weight, pdf, eta: 1.0, lobe })
    }

    /// A direction `wo` with weight eval / pdf (or the delta lobe's weight);
    /// `u1` picks a lobe, `u2` the direction within it.
    fn sample<S: Spectrum>(
        &self,
        ctx: &BsdfContext,
        si: &SurfaceInteraction,
        wi: Vec3,
        u1: f32,
        u2: Vec2,
        wl: &S::Wavelengths,
    ) -> Option<BsdfSample<S>>;

    /// Whether the polarized modes model this BSDF's effect on polarisation.
    /// No default: each model must say, and the polarized modes refuse
    /// scenes with a BSDF that answers false.
    fn has_mueller_model(&self) -> bool;

    /// Whether the BSDF is oriented within the surface (a polarizer's or a
    /// wave plate's axis, an anisotropic roughness), measured from ∂p/∂u as
    /// in Mitsuba: its shapes then build their shading frames from ∂p/∂u
    /// instead of the normal alone.
    fn needs_tangent_frame(&self) -> bool {
        false
    }

    /// Whether the directions this BSDF samples depend on the wavelength.
    fn disperses(&self) -> bool {
        false
    }
}

#[derive(Clone, Debug)]
pub enum Bsdf {
    Diffuse(Diffuse),
    Conductor(Conductor),
    Dielectric(Dielectric),
    ThinDielectric(ThinDielectric),
    Plastic(Plastic),
    Polarizer(Polarizer),
    Retarder(Retarder),
    TwoSided(TwoSided),
    Null(Null),
    Mask(Mask),
    BlendBsdf(BlendBsdf),
    NormalMap(NormalMap),
    BumpMap(BumpMap),
    RoughConductor(RoughConductor),
    RoughDielectric(RoughDielectric),
    RoughPlastic(RoughPlastic),
    PolarizedPlastic(PolarizedPlastic),
    Principled(Principled),
    PrincipledThin(PrincipledThin),
    Birefringent(Birefringent),
}

/// Static dispatch: `$b` is bound to the model inside each arm.
macro_rules! dispatch {
    ($self:expr, $b:ident => $e:expr) => {
        match $self {
            Bsdf::Diffuse($b) => $e,
            Bsdf::Conductor($b) => $e,
            Bsdf::Dielectric($b) => $e,
            Bsdf::ThinDielectric($b) => $e,
            Bsdf::Plastic($b) => $e,
            Bsdf::Polarizer($b) => $e,
            Bsdf::Retarder($b) => $e,
            Bsdf::TwoSided($b) => $e,
            Bsdf::Null($b) => $e,
            Bsdf::Mask($b) => $e,
            Bsdf::BlendBsdf($b) => $e,
            Bsdf::NormalMap($b) => $e,
            Bsdf::BumpMap($b) => $e,
            Bsdf::RoughConductor($b) => $e,
            Bsdf::RoughDielectric($b) => $e,
            Bsdf::RoughPlastic($b) => $e,
            Bsdf::PolarizedPlastic($b) => $e,
            Bsdf::Principled($b) => $e,
            Bsdf::PrincipledThin($b) => $e,
            Bsdf::Birefringent($b) => $e,
        }
    };
}

impl Bsdf {
    /// The plugin name, for messages.
    pub fn plugin(&self) -> &'static str {
        match self {
            Bsdf::Diffuse(_) => "diffuse",
            Bsdf::Conductor(_) => "conductor",
            Bsdf::Dielectric(_) => "dielectric",
            Bsdf::ThinDielectric(_) => "thindielectric",
            Bsdf::Plastic(_) => "plastic",
            Bsdf::Polarizer(_) => "polarizer",
            Bsdf::Retarder(_) => "retarder",
            Bsdf::TwoSided(_) => "twosided",
            Bsdf::Null(_) => "null",
            Bsdf::Mask(_) => "mask",
            Bsdf::BlendBsdf(_) => "blendbsdf",
            Bsdf::NormalMap(_) => "normalmap",
            Bsdf::BumpMap(_) => "bumpmap",
            Bsdf::RoughConductor(_) => "roughconductor",
            Bsdf::RoughDielectric(_) => "roughdielectric",
            Bsdf::RoughPlastic(_) => "roughplastic",
            Bsdf::PolarizedPlastic(_) => "pplastic",
            Bsdf::Principled(_) => "principled",
            Bsdf::PrincipledThin(_) => "principledthin",
            Bsdf::Birefringent(_) => "birefringent",
        }
    }

    /// This BSDF as placed on a shape by `to_world`, if it depends on the
    /// shape's frame (a crystal's optic axis); `None` if it does not.
    pub fn placed_on(&self, to_world: &crate::math::Transform) -> Option<Bsdf> {
        match self {
            Bsdf::Birefringent(b) => Some(Bsdf::Birefringent(b.placed_on(to_world))),
            _ => None,
        }
    }

    /// The fraction of rays that meet the surface at `si` (1 − the
    /// pass-through of the null lobe): `mask`'s opacity, 0 for `null`, 1
    /// for every BSDF without a null lobe.
    #[inline]
    pub fn opacity(&self, si: &SurfaceInteraction) -> f32 {
        match self {
            Bsdf::Null(_) => 0.0,
            Bsdf::Mask(m) => m.opacity(si),
            _ => 1.0,
        }
    }

    /// Whether rays pass through part of the surface: a `mask` or `null`
    /// as the shape's BSDF (the scene then lets rays through, see
    /// [`crate::geometry::Shape::pass_through`]).
    #[inline]
    pub fn passes_through(&self) -> bool {
        matches!(self, Bsdf::Null(_) | Bsdf::Mask(_))
    }

    /// The BSDF of the part of the surface that is there: `mask`'s nested
    /// BSDF (the integrators have already chosen, with probability
    /// [`Bsdf::opacity`], that the ray meets it), else the BSDF itself.
    #[inline]
    pub fn surface(&self) -> &Bsdf {
        match self {
            Bsdf::Mask(m) => &m.nested,
            b => b,
        }
    }

    /// See [`BsdfModel::lobes`].
    #[inline]
    pub fn lobes(&self) -> Lobe {
        dispatch!(self, b => b.lobes())
    }

    /// See [`BsdfModel::has_mueller_model`].
    pub fn has_mueller_model(&self) -> bool {
        dispatch!(self, b => b.has_mueller_model())
    }

    /// See [`BsdfModel::needs_tangent_frame`].
    pub fn needs_tangent_frame(&self) -> bool {
        dispatch!(self, b => b.needs_tangent_frame())
    }

    /// See [`BsdfModel::disperses`].
    #[inline]
    pub fn disperses(&self) -> bool {
        dispatch!(self, b => b.disperses())
    }

    /// See [`BsdfModel::eval`].
    #[inline]
    pub fn eval<S: Spectrum>(&self, ctx: &BsdfContext, si: &SurfaceInteraction, wi: Vec3, wo: Vec3, wl: &S::Wavelengths) -> S {
        dispatch!(self, b => b.eval::<S>(ctx, si, wi, wo, wl))
    }

    /// See [`BsdfModel::pdf`].
    #[inline]
    pub fn pdf<S: Spectrum>(&self, ctx: &BsdfContext, si: &SurfaceInteraction, wi: Vec3, wo: Vec3, wl: &S::Wavelengths) -> f32 {
        dispatch!(self, b => b.pdf::<S>(ctx, si, wi, wo, wl))
    }

    /// See [`BsdfModel::eval_pdf`].
    #[inline]
    pub fn eval_pdf<S: Spectrum>(&self, ctx: &BsdfContext, si: &SurfaceInteraction, wi: Vec3, wo: Vec3, wl: &S::Wavelengths) -> (S, f32) {
        dispatch!(self, b => b.eval_pdf::<S>(ctx, si, wi, wo, wl))
    }

    /// See [`BsdfModel::sample`].
    #[inline]
    pub fn sample<S: Spectrum>(
        &self,
        ctx: &BsdfContext,
        si: &SurfaceInteraction,
        wi: Vec3,
        u1: f32,
        u2: Vec2,
        wl: &S::Wavelengths,
    ) -> Option<BsdfSample<S>> {
        self.sample_inline::<S>(ctx, si, wi, u1, u2, wl)
    }

    /// [`Bsdf::sample`] always inlined, for the path tracer's bounce loop:
    /// the sample returned through memory was written in pieces and read
    /// back in wider loads (a store-forwarding stall); inlined, it stays in
    /// registers.
    #[inline(always)]
    pub fn sample_inline<S: Spectrum>(
        &self,
        ctx: &BsdfContext,
        si: &SurfaceInteraction,
        wi: Vec3,
        u1: f32,
        u2: Vec2,
        wl: &S::Wavelengths,
    ) -> Option<BsdfSample<S>> {
        dispatch!(self, b => b.sample::<S>(ctx, si, wi, u1, u2, wl))
    }
}

#[cfg(test)]
pub(crate) mod testing;

#[cfg(test)]
mod contract_tests {
    use super::testing::{check_sample_consistency_ctx, dummy_interaction, incident};
    use super::*;
    use crate::bsdf::fresnel::fresnel_dielectric;
    use crate::spectrum::Rgb;
    use crate::texture::Texture;

    fn glass() -> Bsdf {
        Bsdf::Dielectric(Dielectric {
            eta: 1.5,
            dispersion: None,
            specular_reflectance: Texture::constant(Rgb::WHITE),
            specular_transmittance: Texture::constant(Rgb::WHITE),
        })
    }

    #[test]
    fn a_context_restricted_to_one_lobe_samples_only_that_lobe() {
        let si = dummy_interaction();
        let wi = incident(0.6, 0.3);
        let f = fresnel_dielectric(wi.z, 1.5).r;
        let refl = BsdfContext::RADIANCE.with_lobes(Lobe::DELTA_REFLECTION);
        let trans = BsdfContext::IMPORTANCE.with_lobes(Lobe::DELTA_TRANSMISSION);
        for u in [0.0f32, 0.5, 0.99] {
            let s = glass().sample::<Rgb>(&refl, &si, wi, u, Vec2::ZERO, &()).expect("reflects");
            assert_eq!((s.lobe, s.pdf), (Lobe::DELTA_REFLECTION, 1.0));
            assert!((s.weight[0] - f).abs() < 1e-6);
            let s = glass().sample::<Rgb>(&trans, &si, wi, u, Vec2::ZERO, &()).expect("refracts");
            assert_eq!((s.lobe, s.pdf), (Lobe::DELTA_TRANSMISSION, 1.0));
            assert!((s.weight[0] - (1.0 - f)).abs() < 1e-6);
        }
        // Plastic: only the diffuse lobe, sampled with all of the probability.
        let p = Bsdf::Plastic(Plastic::new(Texture::constant(Rgb::new(0.5, 0.4, 0.3)), None, 1.5, false));
        let diffuse = BsdfContext::RADIANCE.with_lobes(Lobe::DIFFUSE_REFLECTION);
        check_sample_consistency_ctx(&p, &diffuse, wi, 7);
        let all = BsdfContext::RADIANCE;
        let wo = incident(0.3, 2.0);
        let (p_all, p_diffuse) = (p.pdf::<Rgb>(&all, &si, wi, wo, &()), p.pdf::<Rgb>(&diffuse, &si, wi, wo, &()));
        assert!(p_diffuse > p_all && (p_diffuse - wo.z / std::f32::consts::PI).abs() < 1e-6);
        // No lobe wanted: nothing is evaluated or sampled.
        let none = BsdfContext::RADIANCE.with_lobes(Lobe::empty());
        assert!(p.eval::<Rgb>(&none, &si, wi, wo, &()).is_zero() && p.pdf::<Rgb>(&none, &si, wi, wo, &()) == 0.0);
        assert!(p.sample::<Rgb>(&none, &si, wi, 0.5, Vec2::splat(0.5), &()).is_none());
        assert!(glass().sample::<Rgb>(&none, &si, wi, 0.5, Vec2::splat(0.5), &()).is_none());
    }
}
