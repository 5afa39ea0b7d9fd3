//! BSDFs: how a surface scatters light.
//!
//! # The contract
//! Everything happens in the local shading frame (z = shading normal):
//! `wi` points from the surface towards where the path came from (the camera
//! side), `wo` towards where it goes next (the light side).
//!
//! * [`Bsdf::eval`] returns f(wi, wo) · |cos θ_o| — the BSDF **times the
//!   cosine foreshortening** of `wo` (Mitsuba's convention), so integrators
//!   never multiply by a cosine themselves.
//! * [`Bsdf::pdf`] is the solid-angle density with which `sample` picks `wo`.
//! * [`Bsdf::sample`] returns `wo` with weight = eval / pdf, the pdf, the
//!   relative IOR crossed and the lobe sampled.
//! * `eval` and `pdf` are zero on delta lobes (specular reflection or
//!   refraction); only `sample` produces them, flagged [`Lobe::DELTA`], and
//!   integrators handle those samples explicitly (no emitter sampling, no MIS).

pub mod conductor;
pub mod dielectric;
pub mod diffuse;
pub mod dispersion;
pub mod fresnel;
pub mod ior;
pub mod metal_spectra;
pub mod metals;
pub mod plastic;
pub mod polarizer;
pub mod retarder;
pub mod thindielectric;
pub mod twosided;

pub use conductor::Conductor;
pub use dielectric::Dielectric;
pub use diffuse::Diffuse;
pub use plastic::Plastic;
pub use polarizer::Polarizer;
pub use retarder::Retarder;
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
}

impl Bsdf {
    #[inline]
    pub fn lobes(&self) -> Lobe {
        match self {
            Bsdf::Diffuse(_) => Lobe::DIFFUSE_REFLECTION,
            Bsdf::Conductor(_) => Lobe::DELTA_REFLECTION,
            Bsdf::Dielectric(_) | Bsdf::ThinDielectric(_) => Lobe::DELTA,
            Bsdf::Polarizer(_) | Bsdf::Retarder(_) => Lobe::DELTA_TRANSMISSION,
            Bsdf::Plastic(_) => Lobe::DELTA_REFLECTION | Lobe::DIFFUSE_REFLECTION,
            Bsdf::TwoSided(t) => t.lobes(),
        }
    }

    /// Whether the polarized modes model this BSDF's effect on polarisation
    /// (diffuse surfaces depolarise, polarizers and retarders polarise and
    /// retard, smooth dielectrics and conductors reflect and refract by the
    /// Fresnel equations in Mueller form, thin dielectrics by the same summed
    /// over the slab's internal bounces, plastic's coating reflects by them
    /// over a depolarising base). Every BSDF has one now; the match is
    /// exhaustive so that a new BSDF must say whether it has one, and the
    /// polarized modes refuse scenes with a BSDF that answers false.
    pub fn has_mueller_model(&self) -> bool {
        match self {
            Bsdf::Diffuse(_) | Bsdf::Polarizer(_) | Bsdf::Retarder(_) => true,
            Bsdf::Dielectric(_) | Bsdf::Conductor(_) => true,
            Bsdf::ThinDielectric(_) | Bsdf::Plastic(_) => true,
            Bsdf::TwoSided(t) => t.has_mueller_model(),
        }
    }

    /// Whether the BSDF is oriented within the surface (a polarizer's or a
    /// wave plate's axis), measured from ∂p/∂u as in Mitsuba: its shapes
    /// then build their shading frames from ∂p/∂u instead of the normal alone.
    pub fn needs_tangent_frame(&self) -> bool {
        match self {
            Bsdf::Polarizer(_) | Bsdf::Retarder(_) => true,
            Bsdf::TwoSided(t) => t.front.needs_tangent_frame() || t.back.needs_tangent_frame(),
            _ => false,
        }
    }

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
        }
    }

    /// Whether the directions this BSDF samples depend on the wavelength.
    #[inline]
    pub fn disperses(&self) -> bool {
        matches!(self, Bsdf::Dielectric(d) if d.dispersion.is_some())
    }

    #[inline]
    pub fn eval<S: Spectrum>(&self, si: &SurfaceInteraction, wi: Vec3, wo: Vec3, wl: &S::Wavelengths) -> S {
        match self {
            Bsdf::Diffuse(d) => d.eval(si, wi, wo, wl),
            Bsdf::Plastic(p) => p.eval(si, wi, wo, wl),
            Bsdf::Conductor(_) | Bsdf::Dielectric(_) | Bsdf::ThinDielectric(_) | Bsdf::Polarizer(_) | Bsdf::Retarder(_) => S::zero(),
            Bsdf::TwoSided(t) => t.eval(si, wi, wo, wl),
        }
    }

    #[inline]
    pub fn pdf(&self, si: &SurfaceInteraction, wi: Vec3, wo: Vec3) -> f32 {
        match self {
            Bsdf::Diffuse(d) => d.pdf(wi, wo),
            Bsdf::Plastic(p) => p.pdf(wi, wo),
            Bsdf::Conductor(_) | Bsdf::Dielectric(_) | Bsdf::ThinDielectric(_) | Bsdf::Polarizer(_) | Bsdf::Retarder(_) => 0.0,
            Bsdf::TwoSided(t) => t.pdf(si, wi, wo),
        }
    }

    /// `u1` picks a lobe, `u2` samples the direction within it; `mode` says
    /// whether the path carries radiance (camera paths) or importance.
    #[inline]
    pub fn sample<S: Spectrum>(
        &self,
        si: &SurfaceInteraction,
        wi: Vec3,
        u1: f32,
        u2: Vec2,
        mode: TransportMode,
        wl: &S::Wavelengths,
    ) -> Option<BsdfSample<S>> {
        match self {
            Bsdf::Diffuse(d) => d.sample(si, wi, u2, wl),
            Bsdf::Conductor(c) => c.sample(si, wi, wl),
            Bsdf::Dielectric(d) => d.sample(si, wi, u1, mode, wl),
            Bsdf::ThinDielectric(d) => d.sample(si, wi, u1, wl),
            Bsdf::Plastic(p) => p.sample(si, wi, u1, u2, wl),
            Bsdf::Polarizer(p) => p.sample(si, wi, wl),
            Bsdf::Retarder(r) => r.sample(si, wi, wl),
            Bsdf::TwoSided(t) => t.sample(si, wi, u1, u2, mode, wl),
        }
    }
}

#[cfg(test)]
pub(crate) mod testing;
