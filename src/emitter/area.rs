//! `area` — a diffuse area light: the shape it is nested in emits constant
//! radiance from its front side (the side its normal points to).
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `radiance` | rgb / spectrum / float | — | emitted radiance L_e |
//!
//! Direct lighting samples a point x'' on the shape and weights by the
//! geometry term of the surface-area form of the reflection equation,
//! G = V cos θ' cos θ'' / ‖x'' − x'‖²: the shape's area pdf is turned into a
//! solid-angle pdf by ‖x'' − x'‖² / cos θ'' (spheres are sampled by solid
//! angle directly).
//!
//! ```xml
//! <shape type="rectangle">
//!     <emitter type="area"><rgb name="radiance" value="10"/></emitter>
//! </shape>
//! ```

use crate::spectrum::Emission;
use glam::Vec3;

#[derive(Clone, Debug)]
pub struct AreaLight {
    pub shape: u32,
    pub radiance: Emission,
}

impl AreaLight {
    /// Radiance leaving the surface with shading normal `sh_n` in direction
    /// `w`: `None` from the back, which does not emit.
    #[inline]
    pub fn eval(&self, sh_n: Vec3, w: Vec3) -> Option<&Emission> {
        (sh_n.dot(w) > 0.0).then_some(&self.radiance)
    }
}
