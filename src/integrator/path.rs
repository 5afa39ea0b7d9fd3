//! `path` — unidirectional path tracing with next-event estimation.
//!
//! At every vertex with a smooth (non-delta) BSDF an emitter is sampled
//! (the direct-lighting estimator of `direct`), and the path continues by
//! BSDF sampling; emitters the path hits on its own are weighted against
//! emitter sampling by the power heuristic, or counted in full after a delta
//! lobe (where emitter sampling cannot reach them). So every light path is
//! counted once and only once. Russian roulette as in Mitsuba: from depth
//! `rr_depth` on, continue with probability min(max(throughput)·η², 0.95).
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `max_depth` | integer | -1 | longest path in segments; -1 = unlimited, 1 = emitters only, 2 = direct light |
//! | `rr_depth` | integer | 5 | depth at which Russian roulette starts |
//! | `hide_emitters` | boolean | false | hide directly visible emitters (camera rays pass through emitting shapes) |
//! | `light_sampling` | string | `bvh` | how emitters are chosen: `uniform` (as Mitsuba), `power`, `bvh` ([`crate::emitter::selection`]) |
//! | `emitter_samples` | integer | 1 | emitter samples at the first vertex ([`crate::integrator::path_split`]) |
//! | `bsdf_samples` | integer | 1 | paths continued from the first vertex ([`crate::integrator::path_split`]) |
//! | `guiding` | boolean | false | path guiding ([`crate::integrator::guiding`], with `guiding_spp`, `bsdf_sampling_fraction`) |
//!
//! ```xml
//! <integrator type="path"><integer name="max_depth" value="8"/></integrator>
//! ```

use crate::bsdf::{Bsdf, Lobe, BsdfContext};
use crate::geometry::{Ray, SurfaceInteraction};
use crate::math::mis_power;
use crate::sampler::Sampler;
use crate::emitter::ShadingPoint;
use crate::scene::Scene;
use glam::Vec3;
use crate::spectrum::Spectrum;

#[derive(Clone, Debug)]
pub struct PathTracer {
    /// `u32::MAX` for unlimited.
    pub max_depth: u32,
    pub rr_depth: u32,
    pub hide_emitters: bool,
    /// Splitting at the first vertex ([`crate::integrator::path_split`]); 1, 1 = none.
    pub emitter_samples: u32,
    pub bsdf_samples: u32,
    /// Path guiding ([`crate::integrator::guiding`]); None = off.
    pub guiding: Option<crate::integrator::guiding::Guiding>,
    /// Path reuse across this many neighbouring pixels
    /// ([`crate::integrator::path_reuse`]); 1 = none.
    pub reuse_pixels: u32,
}

impl PathTracer {
    pub fn li<S: Spectrum>(&self, scene: &Scene, mut ray: Ray, sampler: &mut Sampler, wl: &mut S::Wavelengths) -> S {
        let mut result = S::zero();
        let mut throughput = S::splat(1.0);
        let mut eta = 1.0f32;
        let mut depth = 0u32;
        // The previous vertex, for MIS of emitters hit by BSDF sampling.
        // (p and n kept apart: copied as one struct they were stored and
        // reloaded in pieces of other sizes, a store-forwarding stall.)
        let (mut prev_p, mut prev_n) = (ray.o, Vec3::ZERO);
        let mut prev_pdf = 0.0f32;
        let mut prev_delta = true;
        let mut ctx = BsdfContext::RADIANCE;
        // One interaction slot for all bounces, written in place by the
        // scene (a record returned by value was copied in pieces of another
        // size: a store-forwarding stall).
        let mut slot = SurfaceInteraction::EMPTY;

        loop {
            let hit = scene.intersect_path_into(&ray, self.hide_emitters && depth == 0, sampler, &mut slot);
            let visible = !(self.hide_emitters && depth == 0);
            let si = &slot;
            if !hit {
                if visible {
                    if let Some((env, w)) = escaped::<S>(scene, &ShadingPoint { p: prev_p, n: prev_n }, prev_pdf, prev_delta, ray.d, wl) {
                        result += throughput * env * w;
                    }
                }
                break;
            }
            if visible {
                if let Some(le) = scene.emitted::<S>(si, wl) {
                    result += throughput * le * hit_weight(scene, &ShadingPoint { p: prev_p, n: prev_n }, prev_pdf, prev_delta, si);
                }
            }
            if depth.saturating_add(1) >= self.max_depth {
                break;
            }
            let bsdf = scene.bsdf(si);

            // Past a dispersive interface the direction (and, for a rough
            // one, the value of emitter samples) holds for the hero
            // wavelength only.
            // (Asked only where there are wavelengths: RGB skips the call.)
            if S::hero_wavelength(wl).is_some() && bsdf.disperses() {
                S::terminate_secondary(wl);
            }

            // Next-event estimation.
            if bsdf.lobes().intersects(Lobe::SMOOTH) {
                result += next_event::<S>(scene, si, bsdf, &BsdfContext::RADIANCE, throughput, sampler, wl);
            }

            // Continue the path by sampling the BSDF.
            let Some(bs) = bsdf.sample_inline::<S>(&ctx, si, si.wi, sampler.next_1d(), sampler.next_2d(), wl) else { break };
            ctx = ctx.following(bs.lobe);
            let d = si.to_world(bs.wo);
            throughput *= bs.weight;
            eta *= bs.eta;
            (prev_p, prev_n) = (si.p, si.frame.n);
            prev_pdf = bs.pdf;
            prev_delta = bs.lobe.intersects(Lobe::DELTA);
            ray = Ray::new(si.spawn_origin(d), d);
            depth += 1;

            let Some(scale) = russian_roulette(throughput.max_component(), eta, depth, self.rr_depth, sampler) else { break };
            throughput *= scale;
        }
        result
    }
}

/// Mitsuba's Russian roulette once a path has `depth` bounces: from
/// `rr_depth` on it continues with probability min(t_max·η², 0.95). `None`
/// ends the path (also when its throughput is zero); otherwise the factor
/// its throughput is scaled by (exactly 1 before `rr_depth`).
#[inline(always)]
pub(crate) fn russian_roulette(t_max: f32, eta: f32, depth: u32, rr_depth: u32, sampler: &mut Sampler) -> Option<f32> {
    let mut scale = 1.0;
    if depth >= rr_depth {
        let q = (t_max * eta * eta).min(0.95);
        if !(sampler.next_1d() < q) {
            return None;
        }
        scale = 1.0 / q;
    }
    if !(t_max > 0.0) {
        return None;
    }
    Some(scale)
}

/// The path tracer's next-event estimate at `si` for a path of throughput
/// `beta` (one emitter sample; the caller checks that `bsdf` has a smooth
/// lobe): beta · f · L / p, weighted against
/// BSDF sampling under `ctx` by the power heuristic (in full for a delta
/// emitter). Takes one 2-D sample. Shared with `sppm`'s camera paths.
/// (Always inlined, as is the emitter sample it takes: results returned
/// through memory stalled on store forwarding.)
#[inline(always)]
pub fn next_event<S: Spectrum>(
    scene: &Scene,
    si: &SurfaceInteraction,
    bsdf: &Bsdf,
    ctx: &BsdfContext,
    beta: S,
    sampler: &mut Sampler,
    wl: &S::Wavelengths,
) -> S {
    let Some(es) = scene.sample_emitter::<S>(si, sampler.next_2d(), wl) else { return S::zero() };
    let wo = si.to_local(es.d);
    let (f, pdf): (S, f32) = bsdf.eval_pdf(ctx, si, si.wi, wo, wl);
    if f.is_zero() {
        return S::zero();
    }
    let w = if es.delta { 1.0 } else { mis_power(es.pdf, pdf) };
    beta * f * es.weight * w
}

/// MIS weight of emission met at `si` by a BSDF sample of density
/// `prev_pdf` taken at `prev` (1 after a delta lobe or at the camera).
#[inline]
pub fn hit_weight(scene: &Scene, prev: &ShadingPoint, prev_pdf: f32, prev_delta: bool, si: &SurfaceInteraction) -> f32 {
    if prev_delta { 1.0 } else { mis_power(prev_pdf, scene.pdf_emitter_hit(prev, si)) }
}

/// The environment's radiance along a ray from `prev` that escaped in the
/// unit direction `d`, and its MIS weight as [`escaped_weight`] gives it
/// (radiance and density in one lookup); `None` without an environment.
#[inline]
pub fn escaped<S: Spectrum>(scene: &Scene, prev: &ShadingPoint, prev_pdf: f32, prev_delta: bool, d: glam::Vec3, wl: &S::Wavelengths) -> Option<(S, f32)> {
    let (env, pdf) = scene.environment_radiance_pdf::<S>(prev, d, wl, !prev_delta)?;
    Some((env, if prev_delta { 1.0 } else { mis_power(prev_pdf, pdf) }))
}

/// As [`hit_weight`] for the environment met along the unit direction `d`.
#[inline]
pub fn escaped_weight(scene: &Scene, prev: &ShadingPoint, prev_pdf: f32, prev_delta: bool, d: glam::Vec3) -> f32 {
    if prev_delta { 1.0 } else { mis_power(prev_pdf, scene.pdf_environment(prev, d)) }
}
