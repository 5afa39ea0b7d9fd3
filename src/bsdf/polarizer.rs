//! `polarizer` — an ideal linear polarizer sheet, as Mitsuba's.
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `theta` | float or constant spectrum | 0 | angle (degrees) of the transmission axis from the surface's ∂p/∂u, clockwise about its normal (Mitsuba's tutorials write `<spectrum name="theta" value="45"/>`) |
//! | `transmittance` | rgb / spectrum / float | 1 | scale on what passes |
//! | `polarizing` | boolean | true | false: a neutral filter of the same transmittance |
//!
//! ∂p/∂u is that of Mitsuba's parametrisation of the shape (a rectangle's
//! local x axis, a mesh's texture coordinates), so a sheet's axis turns with
//! its `to_world` as in Mitsuba. θ turns the axis clockwise as seen from the
//! side the normal points to (counter-clockwise from the back), which is
//! what Mitsuba 3.9's polarizer does (its `retarder` turns the other way);
//! either way the axis is a line fixed in the sheet.
//!
//! Light passes straight through (a delta transmission); of unpolarised
//! light half does, polarised along the axis. In the polarized modes the
//! sheet's Mueller matrix is that of a linear polarizer at θ, expressed in
//! the canonical Stokes frame of the direction light travels; the
//! unpolarised modes see only its effect on unpolarised light, ½ (as
//! Mitsuba's non-polarized variants do). Two sheets crossed at θ pass
//! ½cos²θ of unpolarised light in the polarized modes (Malus's law).
//!
//! ```xml
//! <shape type="rectangle">
//!     <bsdf type="polarizer"><float name="theta" value="45"/></bsdf>
//! </shape>
//! ```

use super::{BsdfContext, BsdfModel, BsdfSample, Lobe};
use crate::geometry::SurfaceInteraction;
use crate::scene::error::Result;
use crate::scene::loader::PluginLoader;
use crate::scene::props::Props;
use crate::spectrum::mueller::{linear_polarizer, sheet_to_canonical};
use crate::spectrum::{Rgb, Spectrum};
use crate::texture::Texture;
use glam::{Mat4, Vec2, Vec3};

#[derive(Clone, Debug)]
pub struct Polarizer {
    /// Transmission axis angle about the normal, radians.
    pub theta: f32,
    pub transmittance: Texture,
    pub polarizing: bool,
}

impl Polarizer {
    /// Reads the parameters in the table above.
    pub fn from_props(props: &Props, loader: &dyn PluginLoader) -> Result<Polarizer> {
        Ok(Polarizer {
            theta: angle_degrees(props, "theta", 0.0)?.to_radians(),
            transmittance: loader.reflectance(props, "transmittance", Rgb::WHITE)?,
            polarizing: props.bool("polarizing", true)?,
        })
    }
}

/// An angle in degrees given as a `float`/`integer` or, as Mitsuba (which
/// reads it as a texture) also accepts, a constant `<spectrum>` or a grey
/// `<rgb>`.
pub(crate) fn angle_degrees(props: &Props, name: &str, default: f32) -> Result<f32> {
    let Some(c) = props.color_opt(name)? else { return Ok(default) };
    if c[0] != c[1] || c[1] != c[2] || !c[0].is_finite() {
        return Err(props.error_at(name, format!("\"{name}\" must be one angle in degrees (a float, or a constant spectrum such as value=\"45\")")));
    }
    Ok(c[0])
}

impl BsdfModel for Polarizer {
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
        let wo = -wi;
        let scale: S = self.transmittance.eval_spectrum(si.uv, wl);
        let weight = if !self.polarizing {
            scale
        } else {
            // Light travels from the wo side to the wi side: along w = wi.
            // Grazing along the axis, nothing sensible passes.
            let f = si.to_world(wi);
            let m = transmission_axis(si, f, self.theta).and_then(|axis| sheet_to_canonical(linear_polarizer(0.0), f, axis)).unwrap_or(Mat4::ZERO);
            S::mueller(m, scale)
        };
        Some(BsdfSample { wo, weight, pdf: 1.0, eta: 1.0, lobe: Lobe::DELTA_TRANSMISSION })
    }
}

/// The transmission axis across light travelling along `f` (world, unit)
/// through the sheet at `si` whose in-sheet axis is at `theta` clockwise
/// from ∂p/∂u. At oblique incidence the axis is found as Korger et al.
/// (2013) do for a tilted polarizer, and Mitsuba 3 with them: the in-sheet
/// absorbing axis projected across the beam, the transmission axis
/// perpendicular to it and to the beam. `None` if the beam runs along the
/// absorbing axis.
fn transmission_axis(si: &SurfaceInteraction, f: Vec3, theta: f32) -> Option<Vec3> {
    let (sin, cos) = theta.sin_cos();
    let absorbing = si.frame.s * sin + si.frame.t * cos;
    let absorbing = (absorbing - f * absorbing.dot(f)).try_normalize()?;
    Some(f.cross(absorbing))
}
