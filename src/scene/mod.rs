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
pub mod search;
pub mod unsupported;
pub mod xml;

pub use error::{Location, SceneError};
pub use loader::{LoadOptions, load_file, load_str};

use crate::bsdf::Bsdf;
use crate::emitter::{Arrival, EmitterSample};
use crate::film::FilmSpec;
use crate::geometry::accel::Accel;
use crate::geometry::ray::offset_origin;
use crate::geometry::{Ray, Shape, SurfaceInteraction};
use crate::integrator::Integrator;
use crate::emitter::Emitter;
use crate::emitter::{LightSampling, LightSelector, ShadingPoint};
use crate::math::SHADOW_EPSILON;
use crate::sampler::{Sampler, SamplerSpec};
use crate::sensor::Camera;
use crate::spectrum::Spectrum;
use glam::{Vec2, Vec3};

pub use crate::emitter::EmissionSample;

pub struct Scene {
    pub shapes: Vec<Shape>,
    pub bsdfs: Vec<Bsdf>,
    pub emitters: Vec<Emitter>,
    /// Participating media ([`crate::medium`]), named by shapes' `interior`
    /// and `exterior`; only `volpath` renders them.
    pub media: Vec<crate::medium::Medium>,
    /// The medium the camera is in (none: Snell's sensors take no medium).
    pub camera_medium: Option<u32>,
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
    /// Warnings from loading (each a line "warning: …", naming the
    /// parameter and its location), for the caller to show.
    pub warnings: Vec<String>,
    /// Some shape lets rays through ([`Shape::pass_through`]: `mask`,
    /// `null`). When none does, rays take the plain closest-hit and any-hit
    /// paths and no random number is spent on pass-through.
    pub pass_through: bool,
    /// How emitters are chosen for next-event estimation and light paths.
    pub lights: LightSelector,
    /// The files the scene was read from besides its top-level XML:
    /// included XML files, then meshes and images in the order read (what
    /// a checkpoint's digest covers besides the scene text).
    pub files: Vec<std::path::PathBuf>,
    /// The folder of the top-level XML file: checkpoints name [`Scene::files`]
    /// relative to it, so that a scene folder can move.
    pub folder: std::path::PathBuf,
}

/// Most surfaces a ray passes through before it gives up (a guard against
/// a ray stuck on one surface; far more layers than any foliage has).
const MAX_PASSES: u32 = 1024;

impl Scene {
    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<SurfaceInteraction> {
        let mut si = SurfaceInteraction::EMPTY;
        self.intersect_into(ray, &mut si).then_some(si)
    }

    /// As [`Scene::intersect`], the interaction written straight into the
    /// caller's slot `out` (left as it was on a miss); whether the ray hit.
    /// For hot loops: a path reuses one slot across its bounces.
    #[inline]
    pub fn intersect_into(&self, ray: &Ray, out: &mut SurfaceInteraction) -> bool {
        let Some(hit) = self.accel.intersect(ray) else { return false };
        self.interaction_into(&hit, ray, out);
        true
    }

    /// The full interaction at a hit the accelerator found along `ray`
    /// (moved to world space for a shape placed by an instance), into `out`.
    #[inline(always)]
    pub(crate) fn interaction_into(&self, hit: &crate::geometry::accel::Hit, ray: &Ray, out: &mut SurfaceInteraction) {
        let shape = &self.shapes[hit.shape as usize];
        if hit.instance != crate::geometry::accel::NO_INSTANCE {
            let to_world = &self.accel.instance(hit.instance).to_world;
            return shape.interaction_instanced_into(to_world, hit.shape, hit.prim, ray.o, ray.d, hit.t, hit.bary, out);
        }
        shape.interaction_into(hit.shape, hit.prim, ray.o, ray.d, hit.t, hit.bary, out)
    }

    /// Prefetches the corner indices of the triangle `hit` is on (if on a
    /// mesh), the first of [`Scene::interaction_into`]'s two dependent reads.
    #[inline(always)]
    pub(crate) fn prefetch_hit_indices(&self, hit: &crate::geometry::accel::Hit) {
        if let Some(mesh) = self.hit_mesh(hit) {
            mesh.prefetch_indices(hit.prim as usize);
        }
    }

    /// Prefetches the corners of the triangle `hit` is on (if on a mesh);
    /// its indices should be in cache by then.
    #[inline(always)]
    pub(crate) fn prefetch_hit_corners(&self, hit: &crate::geometry::accel::Hit) {
        if let Some(mesh) = self.hit_mesh(hit) {
            mesh.prefetch_corners(hit.prim as usize);
        }
    }

    #[inline(always)]
    fn hit_mesh(&self, hit: &crate::geometry::accel::Hit) -> Option<&crate::geometry::mesh::Mesh> {
        match self.shapes.get(hit.shape as usize).map(|s| &s.geometry) {
            Some(crate::geometry::ShapeGeometry::Mesh(m)) => Some(m),
            _ => None,
        }
    }

    /// The first hit on a shape that does not emit: Mitsuba's
    /// `hide_emitters` lets camera rays pass through emitting shapes.
    pub fn intersect_hiding_emitters(&self, ray: &Ray) -> Option<SurfaceInteraction> {
        let mut si = SurfaceInteraction::EMPTY;
        self.intersect_hiding_emitters_into(ray, &mut si).then_some(si)
    }

    /// As [`Scene::intersect_hiding_emitters`], into the caller's slot `out`.
    pub fn intersect_hiding_emitters_into(&self, ray: &Ray, out: &mut SurfaceInteraction) -> bool {
        let mut ray = *ray;
        for _ in 0..64 {
            if !self.intersect_into(&ray, out) {
                return false;
            }
            if self.shapes[out.shape as usize].emitter.is_none() {
                return true;
            }
            let o = out.spawn_origin(ray.d);
            ray = Ray { o, d: ray.d, tmax: ray.tmax - (o - ray.o).length() };
        }
        false
    }

    #[inline]
    pub fn occluded(&self, ray: &Ray) -> bool {
        self.accel.occluded(ray)
    }

    /// The ray continuing straight on past the surface at `si`.
    #[inline]
    pub(crate) fn continue_past(ray: &Ray, si: &SurfaceInteraction) -> Ray {
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
        let mut si = SurfaceInteraction::EMPTY;
        self.intersect_path_into(ray, hide_emitters, sampler, &mut si).then_some(si)
    }

    /// As [`Scene::intersect_path`], the interaction written straight into
    /// the caller's slot `out`; whether a surface was met.
    #[inline]
    pub fn intersect_path_into(&self, ray: &Ray, hide_emitters: bool, sampler: &mut Sampler, out: &mut SurfaceInteraction) -> bool {
        if !self.pass_through {
            return if hide_emitters { self.intersect_hiding_emitters_into(ray, out) } else { self.intersect_into(ray, out) };
        }
        let mut ray = *ray;
        for _ in 0..MAX_PASSES {
            if !self.intersect_into(&ray, out) {
                return false;
            }
            let si = &*out;
            let shape = &self.shapes[si.shape as usize];
            let pass = if shape.pass_through {
                let alpha = self.bsdfs[shape.bsdf as usize].opacity(si);
                alpha < 1.0 && !(alpha > 0.0 && sampler.next_1d() < alpha)
            } else {
                hide_emitters && shape.emitter.is_some()
            };
            if !pass {
                return true;
            }
            ray = Self::continue_past(&ray, si);
        }
        false
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
        let mut si = SurfaceInteraction::EMPTY;
        for _ in 0..MAX_PASSES {
            let Some(hit) = self.accel.intersect(&ray) else { return tr };
            let shape = &self.shapes[hit.shape as usize];
            if !shape.pass_through {
                return 0.0;
            }
            self.interaction_into(&hit, &ray, &mut si);
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
    /// from an emitter's back side); `None` if the shape does not emit.
    #[inline]
    pub fn emitted<S: Spectrum>(&self, si: &SurfaceInteraction, wl: &S::Wavelengths) -> Option<S> {
        let e = self.shapes[si.shape as usize].emitter?;
        Some(self.emitters[e as usize].eval(Arrival::Surface(si), wl))
    }

    /// Radiance arriving from the environment along a ray that escaped
    /// travelling in the unit direction `d`; `None` without an environment.
    #[inline]
    pub fn environment_radiance<S: Spectrum>(&self, d: Vec3, wl: &S::Wavelengths) -> Option<S> {
        Some(self.emitters[self.environment? as usize].eval(Arrival::Escaped(d), wl))
    }

    /// Radiance arriving from the environment along a ray from `from` that
    /// escaped in the unit direction `d`, and the density with which
    /// emitter sampling at `from` picks `d` (selection included; as
    /// [`Scene::pdf_environment`], computed only `with_pdf`, else 0);
    /// `None` without an environment.
    #[inline]
    pub fn environment_radiance_pdf<S: Spectrum>(&self, from: &ShadingPoint, d: Vec3, wl: &S::Wavelengths, with_pdf: bool) -> Option<(S, f32)> {
        let e = self.environment?;
        let emitter = &self.emitters[e as usize];
        let pmf = if with_pdf { self.emitter_pmf(e as usize, from) } else { 0.0 };
        if !(pmf > 0.0) {
            return Some((emitter.eval(Arrival::Escaped(d), wl), 0.0));
        }
        let (radiance, pdf) = emitter.eval_pdf_escaped(self, from.p, d, wl);
        Some((radiance, pdf * pmf))
    }

    /// Picks an emitter for `u` in [0, 1) to light the shading point `at`
    /// (by the scene's [`LightSampling`] strategy): its index, the
    /// probability of that choice, and `u` re-scaled to [0, 1) within it.
    #[inline]
    pub fn select_emitter(&self, u: f32, at: &ShadingPoint) -> Option<(usize, f32, f32)> {
        self.lights.select(u, at)
    }

    /// The probability with which [`Scene::select_emitter`] picks emitter
    /// `index` for the shading point `at`.
    #[inline]
    pub fn emitter_pmf(&self, index: usize, at: &ShadingPoint) -> f32 {
        self.lights.pmf(index, at)
    }

    /// Chooses how emitters are selected from now on (rebuilding the
    /// selector; the loader sets it from the integrator's `light_sampling`).
    pub fn set_light_sampling(&mut self, strategy: LightSampling) {
        self.lights = LightSelector::new(strategy, &self.emitters, &self.shapes);
    }

    /// Solid-angle density with which emitter sampling from the shading
    /// point `from` would pick the area-light point `hit` (selection
    /// included, with the probability it has at `from`).
    pub fn pdf_emitter_hit(&self, from: &ShadingPoint, hit: &SurfaceInteraction) -> f32 {
        let Some(e) = self.shapes[hit.shape as usize].emitter else { return 0.0 };
        let pmf = self.emitter_pmf(e as usize, from);
        if !(pmf > 0.0) {
            return 0.0;
        }
        self.emitters[e as usize].pdf_direct(self, from.p, Arrival::Surface(hit)) * pmf
    }

    /// Density with which emitter sampling from the shading point `from`
    /// would pick the environment in the unit direction `d` (selection included).
    pub fn pdf_environment(&self, from: &ShadingPoint, d: Vec3) -> f32 {
        let Some(e) = self.environment else { return 0.0 };
        let pmf = self.emitter_pmf(e as usize, from);
        if !(pmf > 0.0) {
            return 0.0;
        }
        self.emitters[e as usize].pdf_direction(self, from.p, Arrival::Escaped(d)) * pmf
    }

    /// Picks an emitter, then a direction towards it, and tests visibility
    /// with a shadow ray. `None` if nothing arrives. Weight and pdf include
    /// the selection. (Always inlined: returned through memory, the sample
    /// was written in pieces and read back whole, a store-forwarding stall.)
    #[inline(always)]
    pub fn sample_emitter<S: Spectrum>(&self, si: &SurfaceInteraction, u: Vec2, wl: &S::Wavelengths) -> Option<EmitterSample<S>> {
        let (sample, ray) = self.sample_emitter_ray::<S>(si, u, wl)?;
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

    /// [`Scene::sample_emitter`]'s sample before visibility: the emitter
    /// sample (selection included) and the shadow ray that tests it,
    /// stopping just short of the emitter's surface. The batched path
    /// tracer traces these rays together.
    #[inline(always)]
    pub fn sample_emitter_ray<S: Spectrum>(&self, si: &SurfaceInteraction, u: Vec2, wl: &S::Wavelengths) -> Option<(EmitterSample<S>, Ray)> {
        let (index, pmf, ux) = self.select_emitter(u.x, &ShadingPoint::from(si))?;
        self.sample_emitter_ray_from::<S>(si, index, pmf, ux, u.y, wl)
    }

    /// [`Scene::sample_emitter_ray`] after the selection: emitter `index`
    /// picked with probability `pmf`, the 2-D sample (`ux` re-scaled by
    /// the selection, `uy`). The batched path tracer selects first, then
    /// sends some lights to its own kernels and the others here.
    #[inline(always)]
    pub fn sample_emitter_ray_from<S: Spectrum>(&self, si: &SurfaceInteraction, index: usize, pmf: f32, ux: f32, uy: f32, wl: &S::Wavelengths) -> Option<(EmitterSample<S>, Ray)> {
        let u = Vec2::new(ux, uy);
        // Area lights (the common case) inline, the others by call.
        let sample = match &self.emitters[index] {
            Emitter::Area(a) => a.sample_direct::<S>(self, si.p, u, wl),
            e => e.sample_direct::<S>(self, si.p, u, wl),
        }?;
        self.emitter_ray(si, sample, pmf)
    }

    /// The rest of [`Scene::sample_emitter_ray_from`] for an emitter
    /// `sample` taken at `si`, picked with probability `pmf`: the selection
    /// divided in, and the shadow ray.
    #[inline(always)]
    pub fn emitter_ray<S: Spectrum>(&self, si: &SurfaceInteraction, mut sample: EmitterSample<S>, pmf: f32) -> Option<(EmitterSample<S>, Ray)> {
        sample.weight = sample.weight / pmf;
        sample.pdf *= pmf;
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
        Some((sample, ray))
    }

    /// Starts a light path (particle tracing): picks an emitter (uniformly
    /// for `uniform` light sampling, else by power: there is no shading
    /// point yet), a point on it and a direction leaving it
    /// ([`Emitter::sample_ray`]); weights include the selection. `None` for emitters a light path cannot start from.
    pub fn sample_emission<S: Spectrum>(&self, u_pick: f32, u_pos: Vec2, u_dir: Vec2, wl: &S::Wavelengths) -> Option<EmissionSample<S>> {
        let (index, pmf, _) = self.lights.select_emission(u_pick)?;
        let mut em = self.emitters[index].sample_ray::<S>(self, u_pos, u_dir, wl)?;
        em.weight = em.weight / pmf;
        em.position_weight = em.position_weight.map(|w| w / pmf);
        Some(em)
    }
}
