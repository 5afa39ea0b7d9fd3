//! `retarder` — an ideal linear retarder (wave plate) sheet, as Mitsuba's.
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `theta` | float | 0 | angle (degrees) of the fast axis from the surface's tangent, about its normal (the tangent as for `polarizer`) |
//! | `delta` | float | 90 | retardance in degrees: 90 a quarter-wave plate, 180 a half-wave plate |
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

use super::{BsdfSample, Lobe};
use crate::geometry::SurfaceInteraction;
use crate::spectrum::mueller::{linear_retarder, sheet_to_canonical};
use crate::spectrum::Spectrum;
use crate::texture::Texture;
use glam::{Mat4, Vec3};

#[derive(Clone, Debug)]
pub struct Retarder {
    /// Fast axis angle about the normal, radians.
    pub theta: f32,
    /// Retardance, radians.
    pub delta: f32,
    pub transmittance: Texture,
}

impl Retarder {
    #[inline]
    pub fn sample<S: Spectrum>(&self, si: &SurfaceInteraction, wi: Vec3, wl: &S::Wavelengths) -> Option<BsdfSample<S>> {
        let scale: S = self.transmittance.eval_spectrum(si.uv, wl);
        let weight = if S::POLARIZED {
            // Light travels along w = wi; the plate's axes projected across it.
            let axis = si.to_world(Vec3::new(self.theta.cos(), self.theta.sin(), 0.0));
            let m = sheet_to_canonical(linear_retarder(0.0, self.delta), si.to_world(wi), axis).unwrap_or(Mat4::IDENTITY);
            S::mueller(m, scale)
        } else {
            scale
        };
        Some(BsdfSample { wo: -wi, weight, pdf: 1.0, eta: 1.0, lobe: Lobe::DELTA_TRANSMISSION })
    }
}
