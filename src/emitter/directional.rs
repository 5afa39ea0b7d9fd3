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

use crate::spectrum::Emission;
use glam::Vec3;

#[derive(Clone, Debug)]
pub struct DirectionalLight {
    /// Unit direction the light travels in.
    pub direction: Vec3,
    pub irradiance: Emission,
}
