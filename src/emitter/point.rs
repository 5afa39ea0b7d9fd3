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

use crate::spectrum::Emission;
use glam::Vec3;

#[derive(Clone, Debug)]
pub struct PointLight {
    pub position: Vec3,
    pub intensity: Emission,
}
