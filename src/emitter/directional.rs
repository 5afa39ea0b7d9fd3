//! `directional` — a distant light arriving from one direction.
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `irradiance` | rgb / spectrum / float | — | irradiance on a surface facing the light (W/m²) |
//! | `direction` | vector | — | direction the light travels in (or +z of `to_world`) |
//! | `to_world` | transform | identity | orientation, if `direction` is not given |
//!
//! A delta light: a surface whose normal makes angle θ with the direction
//! towards the light receives irradiance E cos θ.
//!
//! ```xml
//! <emitter type="directional">
//!     <vector name="direction" x="0" y="-1" z="-1"/>
//!     <rgb name="irradiance" value="2"/>
//! </emitter>
//! ```

use super::EmitterSample;
use crate::spectrum::{Emission, Spectrum};
use glam::Vec3;

#[derive(Clone, Debug)]
pub struct DirectionalLight {
    /// Unit direction the light travels in.
    pub direction: Vec3,
    pub irradiance: Emission,
}

impl DirectionalLight {
    #[inline]
    pub fn sample_direction<S: Spectrum>(&self, wl: &S::Wavelengths) -> EmitterSample<S> {
        EmitterSample {
            d: -self.direction,
            dist: f32::INFINITY,
            p: None,
            n: Vec3::ZERO,
            weight: self.irradiance.eval::<S>(wl),
            pdf: 0.0,
            delta: true,
        }
    }
}
