//! Integrators: estimate the radiance arriving along a camera ray.
//!
//! Both are generic over the path's [`Spectrum`] type and follow Mitsuba 3's
//! definitions, so the same XML gives the same expected image.

pub mod aov;
pub mod bdpt;
pub mod depth;
pub mod direct;
pub mod guiding;
pub mod kernels;
pub mod path;
pub mod path_reuse;
pub mod path_split;
pub mod ptracer;
pub mod sphere_connection;
pub mod sppm;
pub mod vcm;
pub mod volpath;
pub mod wavefront;

pub use aov::{Aov, AovKind, Moment};
pub use bdpt::{Bdpt, BdptScratch};
pub use depth::Depth;
pub use direct::Direct;
pub use path::PathTracer;
pub use ptracer::ParticleTracer;
pub use sppm::Sppm;
pub use vcm::{Vcm, VcmMode};
pub use volpath::VolPath;

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
    /// Arbitrary output variables beside nested integrators' images.
    Aov(Aov),
    /// First and second moments of nested integrators' samples.
    Moment(Moment),
    /// Bidirectional path tracing: camera samples and light-image splats,
    /// rendered by its own driver ([`crate::render`]), never through
    /// [`Integrator::li`].
    Bdpt(Bdpt),
    /// Stochastic progressive photon mapping; rendered by its own driver
    /// ([`sppm::render`]), never through [`Integrator::li`].
    Sppm(Sppm),
    /// Vertex connection and merging; rendered by its own driver
    /// ([`vcm::render_range`]), never through [`Integrator::li`].
    Vcm(Vcm),
    /// Path tracing through participating media.
    VolPath(VolPath),
    /// The distance to the first hit along each camera ray.
    Depth(Depth),
}

impl Integrator {
    /// The plugin name of an integrator that adds light paths anywhere on
    /// the film (so that a pixel's samples are not only its own camera
    /// paths); `None` for the camera-path integrators.
    pub fn light_path_name(&self) -> Option<&'static str> {
        match self {
            Integrator::Particle(_) => Some("ptracer"),
            Integrator::Bdpt(_) => Some("bdpt"),
            Integrator::Vcm(_) => Some("vcm"),
            Integrator::Sppm(_) => Some("sppm"),
            Integrator::Direct(_) | Integrator::Path(_) | Integrator::VolPath(_) | Integrator::Depth(_) | Integrator::Aov(_) | Integrator::Moment(_) => None,
        }
    }

    #[inline]
    /// Radiance along `ray`. A dispersive interface on the path may cut `wl`
    /// down to its hero wavelength; the film must weight with the final `wl`.
    pub fn li<S: Spectrum>(&self, scene: &Scene, ray: Ray, sampler: &mut Sampler, wl: &mut S::Wavelengths) -> S {
        match self {
            Integrator::Direct(d) => d.li(scene, ray, sampler, wl),
            Integrator::Path(p) => p.li_any(scene, ray, sampler, wl),
            Integrator::VolPath(v) => v.li(scene, ray, sampler, wl),
            Integrator::Depth(d) => d.sample(scene, ray, wl).0,
            Integrator::Particle(_) | Integrator::Bdpt(_) | Integrator::Sppm(_) | Integrator::Vcm(_) => S::zero(),
            Integrator::Aov(a) => a.integrators.first().map_or(S::zero(), |(_, i)| i.li(scene, ray, sampler, wl)),
            Integrator::Moment(m) => m.integrators.first().map_or(S::zero(), |(_, i)| i.li(scene, ray, sampler, wl)),
        }
    }

    /// Whether this integrator (or one nested in it) renders participating media.
    pub fn renders_media(&self) -> bool {
        match self {
            Integrator::VolPath(_) => true,
            Integrator::Aov(a) => a.integrators.iter().any(|(_, i)| i.renders_media()),
            Integrator::Moment(m) => m.integrators.iter().any(|(_, i)| i.renders_media()),
            _ => false,
        }
    }

    /// Names of the further channels this integrator writes (AOVs, moments),
    /// as Mitsuba names them; empty for the plain integrators.
    pub fn channel_names(&self) -> Vec<String> {
        match self {
            Integrator::Aov(a) => a.channel_names(),
            Integrator::Moment(m) => m.channel_names(),
            _ => vec![],
        }
    }

    pub fn channel_count(&self) -> usize {
        match self {
            Integrator::Direct(_) | Integrator::Path(_) | Integrator::VolPath(_) | Integrator::Depth(_) | Integrator::Particle(_) | Integrator::Bdpt(_) | Integrator::Sppm(_) | Integrator::Vcm(_) => 0,
            _ => self.channel_names().len(),
        }
    }

    /// Radiance along `ray` as [`Integrator::li`], with the further channels
    /// written to `channels` (as many as [`Integrator::channel_names`]), and
    /// the sample's alpha as Mitsuba's integrators report it: for `path`, 1
    /// if the environment is visible (an environment emitter and no
    /// `hide_emitters`), else whether the camera ray hits a surface it
    /// shows; for `direct`, whether it hits one. Costs one more ray cast
    /// than `li` for `direct` and `path` (only asked for when the film has
    /// alpha or an AOV integrator nests them).
    pub fn sample<S: Spectrum>(&self, scene: &Scene, ray: Ray, sampler: &mut Sampler, wl: &mut S::Wavelengths, channels: &mut [f32]) -> (S, f32) {
        let hits = |hide: bool| {
            let hit = if hide { scene.intersect_hiding_emitters(&ray) } else { scene.intersect(&ray) };
            if hit.is_some() { 1.0 } else { 0.0 }
        };
        match self {
            Integrator::Direct(d) => (d.li(scene, ray, sampler, wl), hits(d.hide_emitters)),
            Integrator::Path(p) => {
                let alpha = if scene.environment.is_some() && !p.hide_emitters { 1.0 } else { hits(p.hide_emitters) };
                (p.li_any(scene, ray, sampler, wl), alpha)
            }
            Integrator::VolPath(v) => {
                let alpha = if scene.environment.is_some() && !v.hide_emitters { 1.0 } else { hits(v.hide_emitters) };
                (v.li(scene, ray, sampler, wl), alpha)
            }
            Integrator::Depth(d) => d.sample(scene, ray, wl),
            Integrator::Particle(_) | Integrator::Bdpt(_) | Integrator::Sppm(_) | Integrator::Vcm(_) => (S::zero(), 0.0),
            Integrator::Aov(a) => a.sample(scene, ray, sampler, wl, channels),
            Integrator::Moment(m) => m.sample(scene, ray, sampler, wl, channels),
        }
    }
}
