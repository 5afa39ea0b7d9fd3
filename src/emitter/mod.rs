//! Emitters: where light comes from.
//!
//! Integrators ask the scene for a direction towards an emitter
//! ([`EmitterSample`]) and, when a path hits an emitter on its own, for the
//! density with which that direction would have been sampled, to weight the
//! two strategies by multiple importance sampling. Point and directional
//! emitters are deltas (a single position or direction): they can only be
//! reached by emitter sampling.

pub mod area;
pub mod constant;
pub mod directional;
pub mod point;
pub mod spot;

pub use area::AreaLight;
pub use constant::ConstantLight;
pub use directional::DirectionalLight;
pub use point::PointLight;
pub use spot::SpotLight;

use glam::Vec3;

#[derive(Clone, Debug)]
pub enum Emitter {
    Area(AreaLight),
    Point(PointLight),
    Constant(ConstantLight),
    Directional(DirectionalLight),
    Spot(SpotLight),
}

impl Emitter {
    pub fn is_delta(&self) -> bool {
        matches!(self, Emitter::Point(_) | Emitter::Directional(_) | Emitter::Spot(_))
    }

    /// Emitters at infinity (seen by rays that leave the scene).
    pub fn is_environment(&self) -> bool {
        matches!(self, Emitter::Constant(_))
    }
}

/// A sampled direction towards an emitter, from a reference point.
#[derive(Clone, Copy, Debug)]
pub struct EmitterSample<S> {
    /// Unit direction from the reference point towards the emitter.
    pub d: Vec3,
    /// Distance to the emitter's point (infinite for environment/directional).
    pub dist: f32,
    /// The emitter's point (for the shadow ray), if it is at a finite distance.
    pub p: Option<Vec3>,
    /// Normal at the emitter's point (for offsetting the shadow ray's end).
    pub n: Vec3,
    /// Incident radiance divided by the solid-angle pdf (selection included);
    /// for delta emitters, the incident irradiance-like contribution.
    pub weight: S,
    /// Solid-angle density including the emitter's selection probability;
    /// meaningless (set to 0) for delta emitters.
    pub pdf: f32,
    pub delta: bool,
}
