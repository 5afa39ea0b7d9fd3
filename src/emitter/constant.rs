//! `constant` — an environment of constant radiance in every direction.
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `radiance` | rgb / spectrum / float | 1 | radiance arriving from every direction |
//!
//! Sampled uniformly over the sphere of directions (pdf 1/4π). A diffuse
//! convex object of albedo ρ inside it renders exactly ρ (the furnace test).
//!
//! ```xml
//! <emitter type="constant"><rgb name="radiance" value="1"/></emitter>
//! ```

use super::EmitterSample;
use crate::math::INV_FOUR_PI;
use crate::math::sampling::square_to_uniform_sphere;
use crate::spectrum::{Emission, Spectrum};
use glam::{Vec2, Vec3};

/// The solid-angle density of every direction.
pub const PDF: f32 = INV_FOUR_PI;

#[derive(Clone, Debug)]
pub struct ConstantLight {
    pub radiance: Emission,
}

impl ConstantLight {
    #[inline]
    pub fn sample_direction<S: Spectrum>(&self, u: Vec2, wl: &S::Wavelengths) -> EmitterSample<S> {
        let d = square_to_uniform_sphere(u);
        EmitterSample { d, dist: f32::INFINITY, p: None, n: Vec3::ZERO, weight: self.radiance.eval::<S>(wl) / PDF, pdf: PDF, delta: false }
    }
}
