//! Scene loading and the loaded scene.
//!
//! Loading runs in three stages, as in Mitsuba: [`xml`] parses the file into
//! nodes with typed, located properties (defaults, `$name` substitution and
//! includes resolved); [`loader`] resolves references and instantiates each
//! plugin through one factory per kind; the result is a [`Scene`] with its
//! acceleration structure built.

pub mod error;
pub mod loader;
pub mod props;
pub mod xml;

pub use error::{Location, SceneError};
pub use loader::{LoadOptions, load_file, load_str};

use crate::bsdf::Bsdf;
use crate::emitter::{Emitter, EmitterSample};
use crate::film::FilmSpec;
use crate::geometry::accel::Accel;
use crate::geometry::ray::offset_origin;
use crate::geometry::{Ray, Shape, SurfaceInteraction};
use crate::integrator::Integrator;
use crate::math::sampling::{square_to_cosine_hemisphere, square_to_uniform_cone, square_to_uniform_sphere, uniform_cone_pdf};
use crate::math::{Frame, PI};
use crate::math::{INV_FOUR_PI, SHADOW_EPSILON};
use crate::sampler::{Sampler, SamplerSpec};
use crate::sensor::Camera;
use crate::spectrum::Spectrum;
use glam::{Vec2, Vec3};

/// Emitter sample of a light at the single point `position` seen from `p`:
/// `intensity` times `falloff(direction of emission)` over the squared distance.
fn point_light_sample<S: Spectrum>(p: Vec3, position: Vec3, falloff: impl Fn(Vec3) -> f32, intensity: S) -> Option<EmitterSample<S>> {
    let v = position - p;
    let dist2 = v.length_squared();
    if dist2 <= 0.0 {
        return None;
    }
    let dist = dist2.sqrt();
    let f = falloff(-v / dist);
    if f <= 0.0 {
        return None;
    }
    Some(EmitterSample { d: v / dist, dist, p: Some(position), n: Vec3::ZERO, weight: intensity * (f / dist2), pdf: 0.0, delta: true })
}

/// The start of a light path.
pub struct EmissionSample<S> {
    pub ray: Ray,
    /// The emitting point and its (shading) normal (zero for point lights).
    pub p: Vec3,
    pub n: Vec3,
    /// Emitted radiance (or intensity) times cosine over the joint density
    /// of point, direction and emitter choice: the light path's throughput.
    pub weight: S,
    /// For area lights: Le / (area density · selection), to connect the
    /// emitting point itself to the camera (emitters seen directly).
    pub position_weight: Option<S>,
}

pub struct Scene {
    pub shapes: Vec<Shape>,
    pub bsdfs: Vec<Bsdf>,
    pub emitters: Vec<Emitter>,
    pub accel: Accel,
    pub camera: Camera,
    pub film: FilmSpec,
    pub sampler: SamplerSpec,
    pub integrator: Integrator,
    /// The scene's integrator is Mitsuba's `stokes`: the polarized modes
    /// write S0–S3 (they do whatever the integrator), the others warn that
    /// they cannot.
    pub stokes_requested: bool,
    /// The environment emitter, if any (seen by rays that leave the scene).
    pub environment: Option<u32>,
    /// Some shape lets rays through ([`Shape::pass_through`]: `mask`,
    /// `null`). When none does, rays take the plain closest-hit and any-hit
    /// paths and no random number is spent on pass-through.
    pub pass_through: bool,
}

/// Most surfaces a ray passes through before it gives up (a guard against
/// a ray stuck on one surface; far more layers than any foliage has).
const MAX_PASSES: u32 = 1024;

impl Scene {
    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<SurfaceInteraction> {
        let hit = self.accel.intersect(ray)?;
        Some(self.shapes[hit.shape as usize].interaction(hit.shape, hit.prim, ray.o, ray.d, hit.t, hit.bary))
    }

    /// The first hit on a shape that does not emit: Mitsuba's
    /// `hide_emitters` lets camera rays pass through emitting shapes.
    pub fn intersect_hiding_emitters(&self, ray: &Ray) -> Option<SurfaceInteraction> {
        let mut ray = *ray;
        for _ in 0..64 {
            let si = self.intersect(&ray)?;
            if self.shapes[si.shape as usize].emitter.is_none() {
                return Some(si);
            }
            let o = si.spawn_origin(ray.d);
            ray = Ray { o, d: ray.d, tmax: ray.tmax - (o - ray.o).length() };
        }
        None
    }

    #[inline]
    pub fn occluded(&self, ray: &Ray) -> bool {
        self.accel.occluded(ray)
    }

    /// The ray continuing straight on past the surface at `si`.
    #[inline]
    fn continue_past(ray: &Ray, si: &SurfaceInteraction) -> Ray {
        let o = si.spawn_origin(ray.d);
        Ray { o, d: ray.d, tmax: ray.tmax - (o - ray.o).length() }
    }

    /// The surface a path ray meets: the closest hit, except that a
    /// pass-through shape (`mask`, `null`) is met only with probability
    /// equal to its opacity α there (one random number per such shape
    /// crossed), else the ray goes straight on — Mitsuba's null lobe,
    /// chosen per ray, without counting a bounce. With `hide_emitters`,
    /// emitting shapes are passed too (camera rays of `hide_emitters`).
    #[inline]
    pub fn intersect_path(&self, ray: &Ray, hide_emitters: bool, sampler: &mut Sampler) -> Option<SurfaceInteraction> {
        if !self.pass_through {
            return if hide_emitters { self.intersect_hiding_emitters(ray) } else { self.intersect(ray) };
        }
        let mut ray = *ray;
        for _ in 0..MAX_PASSES {
            let si = self.intersect(&ray)?;
            let shape = &self.shapes[si.shape as usize];
            let pass = if shape.pass_through {
                let alpha = self.bsdfs[shape.bsdf as usize].opacity(&si);
                alpha < 1.0 && !(alpha > 0.0 && sampler.next_1d() < alpha)
            } else {
                hide_emitters && shape.emitter.is_some()
            };
            if !pass {
                return Some(si);
            }
            ray = Self::continue_past(&ray, &si);
        }
        None
    }

    /// The fraction of light that gets through along the shadow ray `ray`:
    /// 0 if an opaque surface blocks it, else the product of 1 − α over the
    /// pass-through shapes it crosses (Mitsuba's null transmission). Scenes
    /// without pass-through shapes take the any-hit path.
    #[inline]
    pub fn transmittance(&self, ray: &Ray) -> f32 {
        if !self.accel.occluded(ray) {
            return 1.0;
        }
        if !self.pass_through {
            return 0.0;
        }
        let mut ray = *ray;
        let mut tr = 1.0f32;
        for _ in 0..MAX_PASSES {
            let Some(hit) = self.accel.intersect(&ray) else { return tr };
            let shape = &self.shapes[hit.shape as usize];
            if !shape.pass_through {
                return 0.0;
            }
            let si = shape.interaction(hit.shape, hit.prim, ray.o, ray.d, hit.t, hit.bary);
            tr *= 1.0 - self.bsdfs[shape.bsdf as usize].opacity(&si);
            if !(tr > 0.0) {
                return 0.0;
            }
            ray = Self::continue_past(&ray, &si);
            if !(ray.tmax > 0.0) {
                return tr;
            }
        }
        0.0
    }

    /// The BSDF at `si`; on a pass-through shape that of the part that is
    /// there ([`Bsdf::surface`]), the ray having chosen to meet it.
    #[inline]
    pub fn bsdf(&self, si: &SurfaceInteraction) -> &Bsdf {
        let shape = &self.shapes[si.shape as usize];
        let b = &self.bsdfs[shape.bsdf as usize];
        if shape.pass_through { b.surface() } else { b }
    }

    /// Emitted radiance from the surface at `si` back along the ray (zero
    /// from an emitter's back side).
    #[inline]
    pub fn emitted<S: Spectrum>(&self, si: &SurfaceInteraction, wl: &S::Wavelengths) -> Option<S> {
        let e = self.shapes[si.shape as usize].emitter?;
        match &self.emitters[e as usize] {
            Emitter::Area(a) => Some(a.eval(si.frame.n, si.frame.to_world(si.wi)).map_or(S::zero(), |le| le.eval(wl))),
            _ => None,
        }
    }

    /// Radiance arriving from the environment along direction `d` (a ray that escaped).
    #[inline]
    pub fn environment_radiance<S: Spectrum>(&self, wl: &S::Wavelengths) -> Option<S> {
        match &self.emitters[self.environment? as usize] {
            Emitter::Constant(c) => Some(c.radiance.eval(wl)),
            _ => None,
        }
    }

    #[inline]
    fn selection_pmf(&self) -> f32 {
        1.0 / self.emitters.len() as f32
    }

    /// Solid-angle density with which emitter sampling from `p` would pick
    /// the area-light point `hit` (selection included).
    pub fn pdf_emitter_hit(&self, p: Vec3, hit: &SurfaceInteraction) -> f32 {
        let shape = &self.shapes[hit.shape as usize];
        if shape.emitter.is_none() {
            return 0.0;
        }
        shape.pdf_direction(p, hit.p, hit.n) * self.selection_pmf()
    }

    /// Density of sampling the environment in any direction (selection included).
    pub fn pdf_environment(&self) -> f32 {
        if self.environment.is_some() { INV_FOUR_PI * self.selection_pmf() } else { 0.0 }
    }

    /// Picks an emitter uniformly, then a direction towards it, and tests
    /// visibility with a shadow ray. `None` if nothing arrives.
    pub fn sample_emitter<S: Spectrum>(&self, si: &SurfaceInteraction, u: Vec2, wl: &S::Wavelengths) -> Option<EmitterSample<S>> {
        let n = self.emitters.len();
        if n == 0 {
            return None;
        }
        let scaled = u.x * n as f32;
        let index = (scaled as usize).min(n - 1);
        let u = Vec2::new((scaled - index as f32).min(1.0 - f32::EPSILON), u.y);
        let pmf = self.selection_pmf();
        let sample = match &self.emitters[index] {
            Emitter::Area(a) => {
                let ds = self.shapes[a.shape as usize].sample_direction(si.p, u)?;
                // Only the front side emits.
                let radiance = a.eval(ds.sh_n, -ds.d)?;
                if ds.pdf <= 0.0 || !ds.pdf.is_finite() || radiance.is_zero() {
                    return None;
                }
                let pdf = ds.pdf * pmf;
                EmitterSample {
                    d: ds.d,
                    dist: ds.dist,
                    p: Some(ds.p),
                    n: ds.n,
                    weight: radiance.eval::<S>(wl) / pdf,
                    pdf,
                    delta: false,
                }
            }
            Emitter::Point(pl) => point_light_sample(si.p, pl.position, |_| 1.0, pl.intensity.eval::<S>(wl) / pmf)?,
            Emitter::Spot(sl) => point_light_sample(si.p, sl.position, |d| sl.falloff(d), sl.intensity.eval::<S>(wl) / pmf)?,
            Emitter::Directional(dl) => EmitterSample {
                d: -dl.direction,
                dist: f32::INFINITY,
                p: None,
                n: Vec3::ZERO,
                weight: dl.irradiance.eval::<S>(wl) / pmf,
                pdf: 0.0,
                delta: true,
            },
            Emitter::Constant(c) => {
                let d = square_to_uniform_sphere(u);
                let pdf = INV_FOUR_PI * pmf;
                EmitterSample { d, dist: f32::INFINITY, p: None, n: Vec3::ZERO, weight: c.radiance.eval::<S>(wl) / pdf, pdf, delta: false }
            }
        };
        // Shadow ray, stopping just short of the emitter's surface.
        let o = si.spawn_origin(sample.d);
        let ray = match sample.p {
            Some(target) => {
                let target = if sample.n != Vec3::ZERO { offset_origin(target, sample.n, -sample.d) } else { target };
                let v = target - o;
                let dist = v.length();
                if dist <= 0.0 {
                    return None;
                }
                Ray { o, d: v / dist, tmax: dist * (1.0 - SHADOW_EPSILON) }
            }
            None => Ray { o, d: sample.d, tmax: f32::INFINITY },
        };
        let tr = self.transmittance(&ray);
        if !(tr > 0.0) {
            return None;
        }
        let mut sample = sample;
        if tr < 1.0 {
            sample.weight = sample.weight * tr;
        }
        Some(sample)
    }

    /// Starts a light path (particle tracing): picks an emitter uniformly, a
    /// point on it and a direction leaving it. `None` for emitters a light
    /// path cannot start from (the environment and directional lights, which
    /// would need the scene's bounds; the loader refuses them with `ptracer`).
    pub fn sample_emission<S: Spectrum>(&self, u_pick: f32, u_pos: Vec2, u_dir: Vec2, wl: &S::Wavelengths) -> Option<EmissionSample<S>> {
        let n = self.emitters.len();
        if n == 0 {
            return None;
        }
        let index = ((u_pick * n as f32) as usize).min(n - 1);
        let pmf = self.selection_pmf();
        match &self.emitters[index] {
            Emitter::Area(a) => {
                let ps = self.shapes[a.shape as usize].sample_position(u_pos)?;
                if !(ps.pdf_area > 0.0) || a.radiance.is_zero() {
                    return None;
                }
                // Diffuse emission: cosine-weighted about the front side, so
                // Le·cos/pdf = Le·π.
                let local = square_to_cosine_hemisphere(u_dir);
                let d = Frame::from_normal(ps.sh_n).to_world(local);
                let position_weight = a.radiance.eval::<S>(wl) / (ps.pdf_area * pmf);
                Some(EmissionSample {
                    ray: Ray::new(offset_origin(ps.p, ps.n, d), d),
                    p: ps.p,
                    n: ps.sh_n,
                    weight: position_weight * PI,
                    position_weight: Some(position_weight),
                })
            }
            Emitter::Point(pl) => {
                let d = square_to_uniform_sphere(u_dir);
                Some(EmissionSample {
                    ray: Ray::new(pl.position, d),
                    p: pl.position,
                    n: Vec3::ZERO,
                    weight: pl.intensity.eval::<S>(wl) * (4.0 * PI / pmf),
                    position_weight: None,
                })
            }
            Emitter::Spot(sl) => {
                let d = Frame::from_normal(sl.axis).to_world(square_to_uniform_cone(u_dir, sl.cos_cutoff));
                let falloff = sl.falloff(d);
                if falloff <= 0.0 {
                    return None;
                }
                Some(EmissionSample {
                    ray: Ray::new(sl.position, d),
                    p: sl.position,
                    n: Vec3::ZERO,
                    weight: sl.intensity.eval::<S>(wl) * (falloff / (uniform_cone_pdf(sl.cos_cutoff) * pmf)),
                    position_weight: None,
                })
            }
            Emitter::Constant(_) | Emitter::Directional(_) => None,
        }
    }
}
