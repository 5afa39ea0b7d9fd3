//! `null` — no surface at all: light passes straight through.
//!
//! No parameters. A shape with a `null` BSDF is invisible: camera rays,
//! path rays and shadow rays pass through it (the scene skips it; see
//! [`crate::geometry::Shape::pass_through`]). If the shape emits, it stays
//! a light source: rays stop on it to see its emission and then continue
//! straight on, as Mitsuba's `null` does (a delta transmission of weight 1).
//!
//! ```xml
//! <shape type="sphere">
//!     <bsdf type="null"/>
//! </shape>
//! ```

use super::{BsdfContext, BsdfModel, BsdfSample, Lobe};
use crate::geometry::SurfaceInteraction;
use crate::spectrum::Spectrum;
use glam::{Vec2, Vec3};

#[derive(Clone, Debug)]
pub struct Null;

impl BsdfModel for Null {
    fn lobes(&self) -> Lobe {
        Lobe::NULL
    }

    fn has_mueller_model(&self) -> bool {
        // Passing straight through leaves the polarisation as it is.
        true
    }

    #[inline]
    fn eval<S: Spectrum>(&self, _ctx: &BsdfContext, _si: &SurfaceInteraction, _wi: Vec3, _wo: Vec3, _wl: &S::Wavelengths) -> S {
        S::zero()
    }

    #[inline]
    fn pdf<S: Spectrum>(&self, _ctx: &BsdfContext, _si: &SurfaceInteraction, _wi: Vec3, _wo: Vec3, _wl: &S::Wavelengths) -> f32 {
        0.0
    }

    #[inline]
    fn sample<S: Spectrum>(&self, ctx: &BsdfContext, _si: &SurfaceInteraction, wi: Vec3, _u1: f32, _u2: Vec2, _wl: &S::Wavelengths) -> Option<BsdfSample<S>> {
        if !ctx.wants(Lobe::NULL) {
            return None;
        }
        Some(BsdfSample { wo: -wi, weight: S::splat(1.0), pdf: 1.0, eta: 1.0, lobe: Lobe::NULL | Lobe::DELTA_TRANSMISSION })
    }
}
