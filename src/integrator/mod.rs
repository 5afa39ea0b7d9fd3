//! Integrators: estimate the radiance arriving along a camera ray.
//!
//! Both are generic over the path's [`Spectrum`] type and follow Mitsuba 3's
//! definitions, so the same XML gives the same expected image.

pub mod direct;
pub mod path;
pub mod ptracer;

pub use direct::Direct;
pub use path::PathTracer;
pub use ptracer::ParticleTracer;

use crate::geometry::Ray;
use crate::sampler::Sampler;
use crate::scene::Scene;
use crate::spectrum::Spectrum;

#[derive(Clone, Debug)]
pub enum Integrator {
    Direct(Direct),
    Path(PathTracer),
    /// Light paths splatted onto the film; rendered by its own driver
    /// ([`crate::render`]), never through [`Integrator::li`].
    Particle(ParticleTracer),
}

impl Integrator {
    #[inline]
    /// Radiance along `ray`. A dispersive interface on the path may cut `wl`
    /// down to its hero wavelength; the film must weight with the final `wl`.
    pub fn li<S: Spectrum>(&self, scene: &Scene, ray: Ray, sampler: &mut Sampler, wl: &mut S::Wavelengths) -> S {
        match self {
            Integrator::Direct(d) => d.li(scene, ray, sampler, wl),
            Integrator::Path(p) => p.li(scene, ray, sampler, wl),
            Integrator::Particle(_) => S::zero(),
        }
    }
}
