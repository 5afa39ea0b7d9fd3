//! `ptracer` — particle tracing: paths start on the emitters and every
//! vertex they reach on a non-delta surface is connected to the camera.
//!
//! The adjoint of `path`: where a camera path must stumble on a small light
//! through glass (a caustic on a diffuse screen, light through a prism), a
//! light path goes there directly and only the last, diffuse, step needs a
//! connection. Each light path leaves an emitter with throughput
//! β₀ = Le·|cos θ₀| / (p_A · p_ω · p_emitter); at a vertex x reached with β
//! it adds, at the film position where x projects,
//!
//! β · f(ω_in, ω_cam) |cos θ_cam| · importance(ω_cam) / ‖x − camera‖²
//!
//! (the geometry term's other cosine is the one the light path already paid
//! for by sampling ω_in by solid angle). BSDFs are sampled in
//! [`TransportMode::Importance`] (no η² on refraction) and with Veach's
//! correction for shading normals. `N = width · height · spp` light paths
//! make an image whose expected value is the `path` integrator's.
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `max_depth` | integer | -1 | longest path in segments, counting the one into the camera; 1 = emitters seen directly |
//! | `rr_depth` | integer | 5 | depth at which Russian roulette starts |
//! | `hide_emitters` | boolean | false | do not show emitters seen directly |
//! | `samples_per_pass` | integer | — | accepted for Mitsuba compatibility (scheduling only) |
//! | `light_sampling` | string | `power` | emitter a light path starts on: `power` (by flux) or `uniform` (as Mitsuba) |
//! | `sphere_connection` | boolean | false | Snell only: also join light paths to the camera through smooth dielectric spheres, in closed form ([`super::sphere_connection`]) |
//!
//! Emitters: all but the projector's own `sample_ray` limits. Emitters at
//! infinity (`constant`, `envmap`, `directional`) start their paths on the
//! disk of the scene's bounding sphere facing the direction they sample
//! ([`crate::emitter::Emitter::sample_ray`]), as Mitsuba 3 does; an
//! environment seen directly is splatted along that same direction from
//! the pinhole (its radiance over the direction's density). Sensor:
//! `perspective` (a pinhole can be connected to; an orthographic camera
//! cannot).
//!
//! ```xml
//! <integrator type="ptracer"><integer name="max_depth" value="8"/></integrator>
//! ```

use crate::bsdf::{BsdfContext, Lobe};
use crate::geometry::{Ray, SurfaceInteraction};
use crate::math::SHADOW_EPSILON;
use crate::sampler::Sampler;
use crate::scene::Scene;
use crate::sensor::Camera;
use crate::spectrum::{Rgb, Spectrum};
use glam::{Vec2, Vec3};

#[derive(Clone, Debug)]
pub struct ParticleTracer {
    /// `u32::MAX` for unlimited.
    pub max_depth: u32,
    pub rr_depth: u32,
    pub hide_emitters: bool,
    /// Join light paths to the camera through smooth dielectric spheres
    /// ([`super::sphere_connection`]).
    pub sphere_connection: bool,
}

impl ParticleTracer {
    /// Traces one light path and hands every contribution to `splat` as
    /// (film position in pixels, RGB value). Values are per light path; the
    /// driver divides by the number of paths.
    pub fn trace<S: Spectrum>(&self, scene: &Scene, sampler: &mut Sampler, wl: &mut S::Wavelengths, splat: &mut impl FnMut(Vec2, Rgb)) {
        let Camera::Perspective(camera) = &scene.camera else { return };
        let (width, height) = (scene.film.width, scene.film.height);
        let size = Vec2::new(width as f32, height as f32);
        let (u_pick, u_pos, u_dir) = (sampler.next_1d(), sampler.next_2d(), sampler.next_2d());
        let Some(em) = scene.sample_emission::<S>(u_pick, u_pos, u_dir, wl) else { return };

        // An environment seen directly: the direction its light path arrives
        // from (the same for every point), seen from the pinhole.
        if em.position_weight.is_none() && !self.hide_emitters && self.max_depth >= 1 {
            if let Some((e, pmf, _)) = scene.lights.select_emission(u_pick).filter(|(e, _, _)| scene.emitters[*e].is_environment()) {
                self.splat_environment::<S>(scene, camera, e, pmf, u_dir, wl, splat);
            }
        }

        // Emitters seen directly: the emitting point itself, one segment.
        if let Some(position_weight) = em.position_weight.filter(|_| !self.hide_emitters && self.max_depth >= 1) {
            if let Some(c) = camera.connect(em.p, width, height) {
                let cos = em.n.dot(c.d);
                let tr = if cos > 0.0 { self.visible(scene, em.p, em.n, camera.origin(), c.d) } else { 0.0 };
                if tr > 0.0 {
                    let value: S = position_weight * (tr * cos * c.importance / (c.dist * c.dist));
                    splat(c.film * size, value.to_rgb(wl));
                }
            }
        }

        let mut beta = em.weight;
        let beta_start = beta.max_component();
        if !(beta_start > 0.0) {
            return;
        }
        let mut ray = em.ray;
        // Where the current segment's direction was sampled from (a point of
        // the emitter or the last scattering vertex): the point source seen
        // by a sphere connection; none for emitters at infinity (a beam).
        let mut source = self.sphere_connection.then(|| scene.lights.select_emission(u_pick)).flatten().map(|(e, _, _)| &scene.emitters[e]).filter(|e| !e.is_environment() && !matches!(e, crate::emitter::Emitter::Directional(_))).map(|_| ray.o);
        // Segments traced so far (emitter → … → current vertex).
        let mut segments = 0u32;
        let mut ctx = BsdfContext::IMPORTANCE;
        loop {
            let Some(si) = scene.intersect_path(&ray, false, sampler) else { break };
            segments += 1;
            // Connecting this vertex to the camera adds one more segment.
            if segments.saturating_add(1) > self.max_depth {
                break;
            }
            let bsdf = scene.bsdf(&si);
            // Through a smooth dielectric sphere to the camera, every
            // wavelength on its own (before the secondaries are dropped).
            if self.sphere_connection {
                if let Some(hit) = super::sphere_connection::sphere_at(scene, &si, bsdf) {
                    let chords = i64::from(self.max_depth) - i64::from(segments) - 1;
                    super::sphere_connection::connect::<S>(scene, camera, &hit, &si, ray.d, source, beta, chords, wl, splat);
                }
            }
            // Past a dispersive interface the direction (and a rough one's
            // connection to the camera) holds for the hero wavelength only.
            if bsdf.disperses() {
                S::terminate_secondary(wl);
            }
            if bsdf.lobes().intersects(Lobe::SMOOTH) {
                if let Some(c) = camera.connect(si.p, width, height) {
                    let wo = si.to_local(c.d);
                    let f: S = bsdf.eval(&BsdfContext::IMPORTANCE, &si, si.wi, wo, wl);
                    let correction = shading_correction(&si, si.wi, wo);
                    let tr = if !f.is_zero() && correction > 0.0 { self.visible(scene, si.p, si.n, camera.origin(), c.d) } else { 0.0 };
                    if tr > 0.0 {
                        let value = beta * f * (tr * correction * c.importance / (c.dist * c.dist));
                        splat(c.film * size, value.to_rgb(wl));
                    }
                }
            }
            if segments.saturating_add(2) > self.max_depth {
                break;
            }
            let Some(bs) = bsdf.sample::<S>(&ctx, &si, si.wi, sampler.next_1d(), sampler.next_2d(), wl) else { break };
            ctx = ctx.following(bs.lobe);
            let correction = shading_correction(&si, si.wi, bs.wo);
            beta *= bs.weight * correction;
            let d = si.to_world(bs.wo);
            ray = Ray::new(si.spawn_origin(d), d);
            // Past a delta vertex the beam's true (virtual) source is unknown:
            // the sphere connection then takes a parallel beam.
            source = (!bs.lobe.intersects(Lobe::DELTA)).then_some(si.p);

            // Russian roulette on the throughput relative to the emitted one.
            let t_max = beta.max_component() / beta_start;
            if !(t_max > 0.0) {
                break;
            }
            if segments >= self.rr_depth {
                let q = t_max.min(0.95);
                if !(sampler.next_1d() < q) {
                    break;
                }
                beta *= 1.0 / q;
            }
        }
    }

    /// Environment emitter `e` (chosen with probability `pmf`) seen from
    /// the pinhole along the direction it samples for `u_dir`: its radiance
    /// over the direction's density, times the camera's importance there.
    #[allow(clippy::too_many_arguments)]
    fn splat_environment<S: Spectrum>(&self, scene: &Scene, camera: &crate::sensor::Perspective, e: usize, pmf: f32, u_dir: Vec2, wl: &S::Wavelengths, splat: &mut impl FnMut(Vec2, Rgb)) {
        let eye = camera.origin();
        let Some(es) = scene.emitters[e].sample_direction::<S>(scene, eye, u_dir, wl) else { return };
        if es.delta || !(es.pdf > 0.0) || es.weight.is_zero() {
            return;
        }
        let dist = 1.0f32.clamp(camera.near_clip, camera.far_clip);
        let Some(c) = camera.connect(eye + es.d * dist, scene.film.width, scene.film.height) else { return };
        let tr = scene.transmittance(&Ray { o: eye, d: es.d, tmax: f32::INFINITY });
        if tr > 0.0 {
            let value: S = es.weight * (tr * c.importance / pmf);
            splat(c.film * Vec2::new(scene.film.width as f32, scene.film.height as f32), value.to_rgb(wl));
        }
    }

    /// The fraction of light that passes the segment from surface point `p`
    /// (normal `n`, zero for a point light) to the pinhole (0 if blocked).
    fn visible(&self, scene: &Scene, p: Vec3, n: Vec3, eye: Vec3, d: Vec3) -> f32 {
        let o = if n != Vec3::ZERO { crate::geometry::ray::offset_origin(p, n, d) } else { p };
        let v = eye - o;
        let len = v.length();
        if !(len > 0.0) {
            return 0.0;
        }
        scene.transmittance(&Ray { o, d: v / len, tmax: len * (1.0 - SHADOW_EPSILON) })
    }
}

/// Veach's correction for shading normals on light paths: the adjoint BSDF
/// of a surface whose shading normal differs from its geometric one is
/// f · |ω_in·n_s| |ω_out·n_g| / (|ω_in·n_g| |ω_out·n_s|) (1 on flat faces).
#[inline]
pub(crate) fn shading_correction(si: &SurfaceInteraction, wi_local: Vec3, wo_local: Vec3) -> f32 {
    let ng = si.to_local(si.n);
    let (in_ng, out_ng) = (wi_local.dot(ng), wo_local.dot(ng));
    let (in_ns, out_ns) = (wi_local.z, wo_local.z);
    let den = in_ng.abs() * out_ns.abs();
    if !(den > 0.0) {
        return 0.0;
    }
    (in_ns.abs() * out_ng.abs()) / den
}
