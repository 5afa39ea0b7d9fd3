//! `polarizer` — an ideal linear polarizer sheet, as Mitsuba's.
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `theta` | float | 0 | angle (degrees) of the transmission axis from the surface's tangent, about its normal |
//!
//! The tangent is that of Snell's shading frame, a function of the normal
//! alone; Mitsuba measures θ from ∂p/∂u instead, so the same θ on a rotated
//! shape can point elsewhere (relative angles between sheets of one
//! orientation agree). Following ∂p/∂u is part of finishing the polarized modes.
//!
//! | `transmittance` | rgb / spectrum / float | 1 | scale on what passes |
//! | `polarizing` | boolean | true | false: a neutral filter of the same transmittance |
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

use super::{BsdfSample, Lobe};
use crate::geometry::SurfaceInteraction;
use crate::spectrum::mueller::{linear_polarizer, sheet_to_canonical};
use crate::spectrum::Spectrum;
use crate::texture::Texture;
use glam::{Mat4, Vec3};

#[derive(Clone, Debug)]
pub struct Polarizer {
    /// Transmission axis angle about the normal, radians.
    pub theta: f32,
    pub transmittance: Texture,
    pub polarizing: bool,
}

impl Polarizer {
    #[inline]
    pub fn sample<S: Spectrum>(&self, si: &SurfaceInteraction, wi: Vec3, wl: &S::Wavelengths) -> Option<BsdfSample<S>> {
        let wo = -wi;
        let scale: S = self.transmittance.eval_spectrum(si.uv, wl);
        let weight = if !self.polarizing {
            scale
        } else {
            // Light travels from the wo side to the wi side: along w = wi.
            // Grazing along the axis, nothing sensible passes.
            let axis = si.to_world(Vec3::new(self.theta.cos(), self.theta.sin(), 0.0));
            let m = sheet_to_canonical(linear_polarizer(0.0), si.to_world(wi), axis).unwrap_or(Mat4::ZERO);
            S::mueller(m, scale)
        };
        Some(BsdfSample { wo, weight, pdf: 1.0, eta: 1.0, lobe: Lobe::DELTA_TRANSMISSION })
    }
}
