//! `depth`: the distance from the camera to the first surface along each
//! camera ray, 0 where the ray leaves the scene (Mitsuba 3's debugging
//! integrator). Every channel holds the distance in RGB mode; in spectral
//! mode it is a flat spectrum, as in Mitsuba's spectral variants. Alpha is
//! whether the ray hits.
//!
//! ```xml
//! <integrator type="depth"/>
//! ```
//!
//! No parameters. The `aov` integrator's `depth` channel gives the same
//! distance beside a rendered image.

use crate::geometry::Ray;
use crate::scene::Scene;
use crate::spectrum::{Rgb, Spectrum};

#[derive(Clone, Debug, Default)]
pub struct Depth;

impl Depth {
    /// The distance along `ray` to its first hit (0 for none), and the alpha.
    pub fn sample<S: Spectrum>(&self, scene: &Scene, ray: Ray, wl: &S::Wavelengths) -> (S, f32) {
        match scene.accel.intersect(&ray) {
            Some(hit) => (S::from_function(Rgb([hit.t; 3]), |_| hit.t, wl), 1.0),
            None => (S::zero(), 0.0),
        }
    }
}
