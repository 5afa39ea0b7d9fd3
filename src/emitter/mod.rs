//! Emitters: where light comes from.
//!
//! Every emitter owns its math behind one interface, dispatched by `match`
//! over [`Emitter`] (as the BSDFs are), so every integrator uses the same
//! four questions:
//!
//! - [`Emitter::sample_direction`]: a direction from a reference point
//!   towards the emitter, with the incident radiance over its solid-angle
//!   density ([`EmitterSample`]); delta emitters (point, spot, directional,
//!   projector) can only be reached this way;
//! - [`Emitter::pdf_direction`]: the density with which that direction
//!   would have been sampled, to weight emitter sampling against BSDF
//!   sampling by multiple importance sampling;
//! - [`Emitter::eval`]: the radiance along a ray that hit an emitting shape
//!   or left the scene ([`Arrival`]);
//! - [`Emitter::sample_ray`]: the start of a light path (a point and a
//!   direction, with their densities), for particle tracing and
//!   bidirectional methods ([`EmissionSample`]).
//!
//! None of these include the probability of choosing the emitter: the scene
//! picks one ([`crate::scene::Scene::select_emitter`], by the strategy of
//! [`selection`]) and divides by it.

pub mod area;
pub mod constant;
pub mod directional;
pub mod envmap;
pub mod point;
pub mod projector;
pub mod selection;
pub mod sphrect;
pub mod spot;

pub use area::AreaLight;
pub use constant::ConstantLight;
pub use directional::DirectionalLight;
pub use envmap::EnvironmentMap;
pub use point::PointLight;
pub use projector::Projector;
pub use selection::{LightSampling, LightSelector, ShadingPoint};
pub use spot::SpotLight;

use crate::geometry::{Ray, SurfaceInteraction};
use crate::scene::Scene;
use crate::spectrum::Spectrum;
use crate::texture::Texture;
use glam::{Vec2, Vec3};

/// A texture of emitted light (radiance, irradiance) at `uv`, uplifted as an
/// illuminant in spectral modes (a listed spectrum used as it is);
/// unpolarized.
#[inline]
pub(crate) fn texture_illuminant<S: Spectrum>(tex: &Texture, uv: Vec2, wl: &S::Wavelengths) -> S {
    match tex {
        Texture::Constant(rgb, cache) => S::from_illuminant_cached(*rgb, cache, wl),
        Texture::Spectral { rgb, spectrum } => S::from_function(*rgb, |l| spectrum.eval(l), wl).depolarize(),
        _ => S::from_illuminant(tex.eval(uv), wl),
    }
}

#[derive(Clone, Debug)]
pub enum Emitter {
    Area(AreaLight),
    Point(PointLight),
    Constant(ConstantLight),
    Directional(DirectionalLight),
    Spot(SpotLight),
    EnvMap(Box<EnvironmentMap>),
    Projector(Box<Projector>),
}

/// Where a ray met an emitter: a point on an emitting shape, or a direction
/// in which it left the scene (an environment emitter).
#[derive(Clone, Copy, Debug)]
pub enum Arrival<'a> {
    /// The ray hit this point of the emitter's shape.
    Surface(&'a SurfaceInteraction),
    /// The ray left the scene travelling in this (unit, world) direction.
    Escaped(Vec3),
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
    /// Incident radiance divided by the solid-angle pdf; for delta emitters,
    /// the incident irradiance-like contribution. From
    /// [`crate::scene::Scene::sample_emitter`], the selection is included.
    pub weight: S,
    /// Solid-angle density (from the scene: selection included);
    /// meaningless (set to 0) for delta emitters.
    pub pdf: f32,
    pub delta: bool,
}

/// The start of a light path.
#[derive(Clone, Copy, Debug)]
pub struct EmissionSample<S> {
    pub ray: Ray,
    /// The emitting point and its (shading) normal (zero for point lights
    /// and for emitters at infinity).
    pub p: Vec3,
    pub n: Vec3,
    /// Emitted radiance (or intensity) times cosine over the joint density
    /// of point and direction (from the scene: and of the emitter's choice):
    /// the light path's throughput.
    pub weight: S,
    /// For area lights: Le / (area density [· selection]), to connect the
    /// emitting point itself to the camera (emitters seen directly).
    pub position_weight: Option<S>,
    /// Density of the position: per unit area (1 for a point light's
    /// single position, a delta).
    pub pdf_pos: f32,
    /// Density of the direction: per unit solid angle (1 for a
    /// directional light's single direction, a delta).
    pub pdf_dir: f32,
}

impl Emitter {
    pub fn is_delta(&self) -> bool {
        matches!(self, Emitter::Point(_) | Emitter::Directional(_) | Emitter::Spot(_) | Emitter::Projector(_))
    }

    /// Emitters at infinity (seen by rays that leave the scene).
    pub fn is_environment(&self) -> bool {
        matches!(self, Emitter::Constant(_) | Emitter::EnvMap(_))
    }

    /// A direction from `p` towards the emitter (visibility not tested; the
    /// emitter's selection not included). `None` if nothing arrives.
    #[inline]
    pub fn sample_direction<S: Spectrum>(&self, scene: &Scene, p: Vec3, u: Vec2, wl: &S::Wavelengths) -> Option<EmitterSample<S>> {
        match self {
            Emitter::Area(a) => a.sample_direction(scene, p, u, wl),
            Emitter::Point(e) => e.sample_direction(p, wl),
            Emitter::Spot(e) => e.sample_direction(p, wl),
            Emitter::Directional(e) => Some(e.sample_direction(wl)),
            Emitter::Constant(e) => Some(e.sample_direction(u, wl)),
            Emitter::EnvMap(e) => e.sample_direction(u, wl),
            Emitter::Projector(e) => e.sample_direction(p, wl),
        }
    }

    /// Solid-angle density with which [`Emitter::sample_direction`] from `p`
    /// picks the direction of `at` (0 for delta emitters).
    #[inline]
    pub fn pdf_direction(&self, scene: &Scene, p: Vec3, at: Arrival) -> f32 {
        match (self, at) {
            (Emitter::Area(a), Arrival::Surface(hit)) => scene.shapes[a.shape as usize].pdf_direction(p, hit.p, hit.n),
            (Emitter::Constant(_), Arrival::Escaped(_)) => constant::PDF,
            (Emitter::EnvMap(e), Arrival::Escaped(d)) => e.pdf_direction(d),
            _ => 0.0,
        }
    }

    /// As [`Emitter::sample_direction`], for direct lighting at a shading
    /// point (`Scene::sample_emitter`): area lights on rectangles sample by
    /// solid angle where that pays ([`sphrect`]). Its density is
    /// [`Emitter::pdf_direct`].
    #[inline]
    pub fn sample_direct<S: Spectrum>(&self, scene: &Scene, p: Vec3, u: Vec2, wl: &S::Wavelengths) -> Option<EmitterSample<S>> {
        match self {
            Emitter::Area(a) => a.sample_direct(scene, p, u, wl),
            _ => self.sample_direction(scene, p, u, wl),
        }
    }

    /// Solid-angle density with which [`Emitter::sample_direct`] from `p`
    /// picks the direction of `at` (0 for delta emitters).
    #[inline]
    pub fn pdf_direct(&self, scene: &Scene, p: Vec3, at: Arrival) -> f32 {
        match (self, at) {
            (Emitter::Area(a), Arrival::Surface(hit)) => a.pdf_direct(scene, p, hit.p, hit.n),
            _ => self.pdf_direction(scene, p, at),
        }
    }

    /// Radiance along a ray that reached the emitter at `at` (zero from an
    /// area light's back side, and for emitters a ray cannot reach).
    #[inline]
    pub fn eval<S: Spectrum>(&self, at: Arrival, wl: &S::Wavelengths) -> S {
        match (self, at) {
            (Emitter::Area(a), Arrival::Surface(si)) => a.eval(si, wl),
            (Emitter::Constant(c), Arrival::Escaped(_)) => c.radiance.eval(wl),
            (Emitter::EnvMap(e), Arrival::Escaped(d)) => e.eval(d, wl),
            _ => S::zero(),
        }
    }

    /// [`Emitter::eval`] and [`Emitter::pdf_direction`] of a ray that
    /// escaped along `d`, in one lookup where the emitter has one.
    #[inline]
    pub fn eval_pdf_escaped<S: Spectrum>(&self, scene: &Scene, p: Vec3, d: Vec3, wl: &S::Wavelengths) -> (S, f32) {
        match self {
            Emitter::EnvMap(e) => e.eval_pdf(d, wl),
            _ => (self.eval(Arrival::Escaped(d), wl), self.pdf_direction(scene, p, Arrival::Escaped(d))),
        }
    }

    /// Starts a light path on this emitter: a point and a direction leaving
    /// it (the emitter's selection not included). `None` if nothing is
    /// emitted there.
    ///
    /// Emitters at infinity (`constant`, `envmap`, `directional`) pick the
    /// direction the light arrives from as [`Emitter::sample_direction`]
    /// does (by `u_dir`; the directional light has one), then a point
    /// uniform (by `u_pos`) on the disk of the scene's bounding sphere
    /// ([`scene_bounding_sphere`]) facing it, one radius before its centre,
    /// as Mitsuba 3 does: `pdf_pos` = 1/(π R²) per unit area of the disk,
    /// `pdf_dir` the direction's solid-angle density (1 for the directional
    /// light), `weight` = L / (pdf_dir · pdf_pos) (E π R² for the
    /// directional light), `n` zero and no `position_weight` (the disk is
    /// not seen). Every ray from the disk crosses the whole scene.
    pub fn sample_ray<S: Spectrum>(&self, scene: &Scene, u_pos: Vec2, u_dir: Vec2, wl: &S::Wavelengths) -> Option<EmissionSample<S>> {
        match self {
            Emitter::Area(a) => a.sample_ray(scene, u_pos, u_dir, wl),
            Emitter::Point(e) => Some(e.sample_ray(u_dir, wl)),
            Emitter::Spot(e) => e.sample_ray(u_dir, wl),
            Emitter::Projector(e) => e.sample_ray(u_dir, wl),
            Emitter::Constant(_) | Emitter::Directional(_) | Emitter::EnvMap(_) => {
                let (center, radius) = scene_bounding_sphere(scene);
                let es = self.sample_direction::<S>(scene, center, u_dir, wl)?;
                let pdf_dir = if es.delta { 1.0 } else { es.pdf };
                if !(pdf_dir > 0.0) || es.weight.is_zero() {
                    return None;
                }
                Some(infinite_emission(center, radius, -es.d, u_pos, es.weight, pdf_dir))
            }
        }
    }
}

/// The sphere around the scene that light paths from emitters at infinity
/// start on (centre, radius): the bounding box's, its radius enlarged a
/// little so that the disk clears every shape.
pub fn scene_bounding_sphere(scene: &Scene) -> (Vec3, f32) {
    let (lo, hi) = scene.accel.bounds(&scene.shapes);
    let r = 0.5 * (hi - lo).length();
    (0.5 * (lo + hi), (r * (1.0 + 1e-3)).max(1e-4))
}

/// A light path from infinity travelling along the unit `d`: from a point
/// uniform on the disk of radius `radius` through `center` perpendicular to
/// `d`, moved back by `radius`; `weight` is the arriving radiance over the
/// direction's density (the irradiance for a delta direction).
fn infinite_emission<S: Spectrum>(center: Vec3, radius: f32, d: Vec3, u_pos: Vec2, weight: S, pdf_dir: f32) -> EmissionSample<S> {
    let disk = crate::math::sampling::square_to_uniform_disk_concentric(u_pos);
    let frame = crate::math::Frame::from_normal(d);
    let o = center + radius * (frame.to_world(Vec3::new(disk.x, disk.y, 0.0)) - d);
    let area = std::f32::consts::PI * radius * radius;
    EmissionSample { ray: Ray::new(o, d), p: o, n: Vec3::ZERO, weight: weight * area, position_weight: None, pdf_pos: 1.0 / area, pdf_dir }
}

/// Emitter sample of a light at the single point `position` seen from `p`:
/// `intensity` times `falloff(direction of emission)` over the squared distance.
#[inline]
pub(crate) fn point_light_sample<S: Spectrum>(
    p: Vec3,
    position: Vec3,
    falloff: impl Fn(Vec3) -> f32,
    intensity: impl FnOnce(Vec3) -> S,
) -> Option<EmitterSample<S>> {
    let v = position - p;
    let dist2 = v.length_squared();
    if dist2 <= 0.0 {
        return None;
    }
    let dist = dist2.sqrt();
    let emitted = -v / dist;
    let f = falloff(emitted);
    if f <= 0.0 {
        return None;
    }
    Some(EmitterSample { d: v / dist, dist, p: Some(position), n: Vec3::ZERO, weight: intensity(emitted) * (f / dist2), pdf: 0.0, delta: true })
}
