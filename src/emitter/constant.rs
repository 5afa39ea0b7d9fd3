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

use crate::spectrum::Emission;

#[derive(Clone, Debug)]
pub struct ConstantLight {
    pub radiance: Emission,
}
