//! `retarder` — an ideal linear retarder (wave plate) sheet, as Mitsuba's.
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `theta` | float or constant spectrum | 0 | angle (degrees) of the fast axis from the surface's ∂p/∂u, counter-clockwise about its normal (as Mitsuba's; its polarizer turns the other way) |
//! | `delta` | float or constant spectrum | 90 | retardance in degrees: 90 a quarter-wave plate, 180 a half-wave plate |
//! | `transmittance` | rgb / spectrum / float | 1 | scale on what passes |
//!
//! Light passes straight through (a delta transmission), the component
//! along the slow axis delayed by δ: a quarter-wave plate at 45° turns
//! linear polarisation into circular, a half-wave plate at θ mirrors it
//! about the fast axis. Intensity is unchanged, so the unpolarised modes see
//! a clear sheet of the given transmittance.
//!
//! ```xml
//! <shape type="rectangle">
//!     <bsdf type="retarder"><float name="theta" value="45"/><float name="delta" value="90"/></bsdf>
//! </shape>
//! ```

use super::{BsdfContext, BsdfModel, BsdfSample, Lobe};
use crate::geometry::SurfaceInteraction;
use crate::scene::error::Result;
use crate::scene::loader::PluginLoader;
use crate::scene::props::Props;
use crate::spectrum::mueller::{linear_retarder, sheet_to_canonical, stokes_basis};
use crate::spectrum::{Rgb, Spectrum};
use crate::texture::Texture;
use glam::{Mat4, Vec2, Vec3};

#[derive(Clone, Debug)]
pub struct Retarder {
    /// Fast axis angle about the normal, radians.
    pub theta: f32,
    /// Retardance, radians.
    pub delta: f32,
    pub transmittance: Texture,
}

impl Retarder {
    /// Reads the parameters in the table above.
    pub fn from_props(props: &Props, loader: &dyn PluginLoader) -> Result<Retarder> {
        Ok(Retarder {
            theta: super::polarizer::angle_degrees(props, "theta", 0.0)?.to_radians(),
            delta: super::polarizer::angle_degrees(props, "delta", 90.0)?.to_radians(),
            transmittance: loader.reflectance(props, "transmittance", Rgb::WHITE)?,
        })
    }
}

impl BsdfModel for Retarder {
    fn lobes(&self) -> Lobe {
        Lobe::DELTA_TRANSMISSION
    }

    fn has_mueller_model(&self) -> bool {
        true
    }

    fn needs_tangent_frame(&self) -> bool {
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
    fn sample<S: Spectrum>(&self, ctx: &BsdfContext, si: &SurfaceInteraction, wi: Vec3, _u1: f32, _u2: Vec2, wl: &S::Wavelengths) -> Option<BsdfSample<S>> {
        if !ctx.wants(Lobe::DELTA_TRANSMISSION) {
            return None;
        }
        let scale: S = self.transmittance.eval_spectrum(si.uv, wl);
        let weight = if S::POLARIZED {
            // Light travels along wi; the plate's retardance falls off as
            // |cos θ_i| at oblique incidence, as Mitsuba 3 models a tilted plate.
            let axis = si.to_world(fast_axis(wi, self.theta));
            let m = sheet_to_canonical(linear_retarder(0.0, self.delta * wi.z.abs()), si.to_world(wi), axis).unwrap_or(Mat4::IDENTITY);
            S::mueller(m, scale)
        } else {
            scale
        };
        Some(BsdfSample { wo: -wi, weight, pdf: 1.0, eta: 1.0, lobe: Lobe::DELTA_TRANSMISSION })
    }
}

/// The fast axis (local, across the beam) for light travelling along local
/// `wi`, as Mitsuba 3 places it: its reference is the u tangent (local x)
/// turned onto the plane across the beam by the angle in space between x and
/// the beam's canonical Stokes basis (not the angle of x's projection; the
/// two agree at normal incidence), and θ turns the axis from there about the
/// beam, counter-clockwise as seen from the normal's side.
fn fast_axis(wi: Vec3, theta: f32) -> Vec3 {
    let b = stokes_basis(wi);
    let phi = Vec3::X.cross(b).dot(wi).signum() * b.x.clamp(-1.0, 1.0).acos();
    let reference = b * phi.cos() - wi.cross(b) * phi.sin();
    let side = if wi.z >= 0.0 { 1.0 } else { -1.0 };
    reference * theta.cos() + wi.cross(reference) * (side * theta.sin())
}
