//! Sensors: cameras that turn a film position into a primary ray.
//!
//! Film positions are in [0,1]², x to the right and y downwards. As in
//! Mitsuba, the camera looks along +z of its `to_world`, with +x of camera
//! space at the image's left and +y at its top.

pub mod orthographic;
pub mod perspective;

pub use orthographic::Orthographic;
pub use perspective::{CameraConnection, Perspective};

use crate::geometry::Ray;
use glam::{Vec2, Vec3};

#[derive(Clone, Debug)]
pub enum Camera {
    Perspective(Perspective),
    Orthographic(Orthographic),
}

impl Camera {
    #[inline]
    pub fn generate_ray(&self, film: Vec2) -> Ray {
        match self {
            Camera::Perspective(c) => c.generate_ray(film),
            Camera::Orthographic(c) => c.generate_ray(film),
        }
    }

    /// The camera's up direction in the world (+y of camera space), from
    /// which polarized renders measure Stokes vectors, as Mitsuba does.
    pub fn up(&self) -> Vec3 {
        let to_world = match self {
            Camera::Perspective(c) => &c.to_world,
            Camera::Orthographic(c) => &c.to_world,
        };
        to_world.vector(Vec3::Y).normalize_or_zero()
    }
}
