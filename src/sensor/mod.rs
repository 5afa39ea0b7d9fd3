//! Sensors: cameras that turn a film position into a primary ray.
//!
//! Film positions are in [0,1]², x to the right and y downwards. As in
//! Mitsuba, the camera looks along +z of its `to_world`, with +x of camera
//! space at the image's left and +y at its top.

pub mod distant;
pub mod irradiancemeter;
pub mod orthographic;
pub mod perspective;
pub mod radiancemeter;
pub mod thinlens;

pub use distant::{Distant, DistantTarget};
pub use irradiancemeter::IrradianceMeter;
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
    /// Rays from a shape's surface, each weighted by π.
    IrradianceMeter(IrradianceMeter),
    /// Parallel rays from outside the scene onto a target.
    Distant(Distant),
}

impl Camera {
    #[inline]
    pub fn generate_ray(&self, film: Vec2) -> Ray {
        match self {
            Camera::Perspective(c) => c.generate_ray(film),
            Camera::Orthographic(c) => c.generate_ray(film),
            Camera::ThinLens(c) => c.generate_ray(film, Vec2::splat(0.5)),
            Camera::RadianceMeter(c) => c.generate_ray(),
            // The film position places the point; the direction is the normal.
            Camera::IrradianceMeter(c) => c.sample_ray(film, Vec2::splat(0.5)),
            // The film position places the target point.
            Camera::Distant(c) => c.sample_ray(film),
        }
    }

    /// The ray through film position `film`, drawing the aperture sample a
    /// thin lens needs from `sampler` (pinhole cameras draw nothing).
    #[inline]
    pub fn sample_ray(&self, film: Vec2, sampler: &mut Sampler) -> Ray {
        match self {
            Camera::ThinLens(c) => c.generate_ray(film, sampler.next_2d()),
            Camera::IrradianceMeter(c) => {
                let u_pos = sampler.next_2d();
                c.sample_ray(u_pos, sampler.next_2d())
            }
            Camera::Distant(c) => c.sample_ray(sampler.next_2d()),
            _ => self.generate_ray(film),
        }
    }

    /// What the radiance of each camera sample is multiplied by: π for an
    /// irradiance meter (applied when the film is developed), else 1.
    pub fn radiance_scale(&self) -> f32 {
        match self {
            Camera::IrradianceMeter(_) => IrradianceMeter::WEIGHT,
            _ => 1.0,
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
            Camera::IrradianceMeter(c) => return c.up(),
            Camera::Distant(c) => return c.up(),
        };
        to_world.vector(Vec3::Y).normalize_or_zero()
    }
}
