//! Sensors: cameras that turn a film position into a primary ray.
//!
//! Film positions are in [0,1]², x to the right and y downwards. As in
//! Mitsuba, the camera looks along +z of its `to_world`, with +x of camera
//! space at the image's left and +y at its top.

pub mod orthographic;
pub mod perspective;
pub mod radiancemeter;
pub mod thinlens;

pub use orthographic::Orthographic;
pub use perspective::{CameraConnection, Perspective};
pub use radiancemeter::RadianceMeter;
pub use thinlens::ThinLens;

use crate::geometry::Ray;
use crate::sampler::Sampler;
use glam::{Vec2, Vec3};

#[derive(Clone, Debug)]
pub enum Camera {
    Perspective(Perspective),
    Orthographic(Orthographic),
    ThinLens(ThinLens),
    /// One ray for every film position.
    RadianceMeter(RadianceMeter),
}

impl Camera {
    #[inline]
    pub fn generate_ray(&self, film: Vec2) -> Ray {
        match self {
            Camera::Perspective(c) => c.generate_ray(film),
            Camera::Orthographic(c) => c.generate_ray(film),
            Camera::ThinLens(c) => c.generate_ray(film, Vec2::splat(0.5)),
            Camera::RadianceMeter(c) => c.generate_ray(),
        }
    }

    /// The ray through film position `film`, drawing the aperture sample a
    /// thin lens needs from `sampler` (pinhole cameras draw nothing).
    #[inline]
    pub fn sample_ray(&self, film: Vec2, sampler: &mut Sampler) -> Ray {
        match self {
            Camera::ThinLens(c) => c.generate_ray(film, sampler.next_2d()),
            _ => self.generate_ray(film),
        }
    }

    /// The camera's up direction in the world (+y of camera space), from
    /// which polarized renders measure Stokes vectors, as Mitsuba does.
    pub fn up(&self) -> Vec3 {
        let to_world = match self {
            Camera::Perspective(c) => &c.to_world,
            Camera::Orthographic(c) => &c.to_world,
            Camera::ThinLens(c) => &c.to_world,
            Camera::RadianceMeter(c) => return c.up,
        };
        to_world.vector(Vec3::Y).normalize_or_zero()
    }
}
