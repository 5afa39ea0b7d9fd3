//! `point` — an isotropic point light.
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `intensity` | rgb / spectrum / float | — | radiant intensity I (W/sr) |
//! | `position` | point | — | position (or the origin of `to_world`) |
//! | `to_world` | transform | identity | placement, if `position` is not given |
//!
//! A delta light: the irradiance it gives a surface at distance r is
//! I cos θ / r², reachable only by emitter sampling.
//!
//! ```xml
//! <emitter type="point">
//!     <point name="position" x="0" y="2" z="0"/>
//!     <rgb name="intensity" value="5"/>
//! </emitter>
//! ```

use super::{EmissionSample, EmitterSample, point_light_sample};
use crate::geometry::Ray;
use crate::math::sampling::square_to_uniform_sphere;
use crate::math::{INV_FOUR_PI, PI};
use crate::spectrum::{Emission, Spectrum};
use glam::{Vec2, Vec3};

#[derive(Clone, Debug)]
pub struct PointLight {
    pub position: Vec3,
    pub intensity: Emission,
}

impl PointLight {
    #[inline]
    pub fn sample_direction<S: Spectrum>(&self, p: Vec3, wl: &S::Wavelengths) -> Option<EmitterSample<S>> {
        point_light_sample(p, self.position, |_| 1.0, |_| self.intensity.eval::<S>(wl))
    }

    /// A direction uniformly over the sphere.
    pub fn sample_ray<S: Spectrum>(&self, u_dir: Vec2, wl: &S::Wavelengths) -> EmissionSample<S> {
        let d = square_to_uniform_sphere(u_dir);
        EmissionSample {
            ray: Ray::new(self.position, d),
            p: self.position,
            n: Vec3::ZERO,
            weight: self.intensity.eval::<S>(wl) * (4.0 * PI),
            position_weight: None,
            pdf_pos: 1.0,
            pdf_dir: INV_FOUR_PI,
        }
    }
}
