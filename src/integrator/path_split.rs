//! Splitting at the first vertex for `path`: several emitter samples and
//! several BSDF continuations per camera ray.
//!
//! Where the camera ray meets a surface, `path` with `emitter_samples` = m
//! and `bsdf_samples` = n takes m next-event estimates (each weighted 1/m)
//! and continues n independent paths from there (each weighted 1/n), every
//! one of them an ordinary `path` from its second vertex on. The camera ray,
//! its intersection, the first vertex's shading and the film update are paid
//! once for all of them: worth it where most of the noise comes after the
//! first vertex (indirect light) or from the emitter sample there.
//! Emission met by the first BSDF continuations is weighed against the
//! first vertex's emitter samples by the power heuristic with the sample
//! counts (as `direct`), so m = 0 leaves that to the continuations alone.
//! m = n = 1 is the plain estimator (and takes its code path).
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `emitter_samples` | integer | 1 | emitter samples at the first vertex (≥ 0) |
//! | `bsdf_samples` | integer | 1 | BSDF continuations (whole paths) from the first vertex (≥ 1) |
//!
//! ```xml
//! <integrator type="path">
//!     <integer name="max_depth" value="8"/>
//!     <integer name="bsdf_samples" value="2"/>
//! </integrator>
//! ```
//!
//! Sampler dimensions: continuation j draws from dimension
//! `SPLIT_DIM + j·SPLIT_STRIDE` on ([`Sampler::set_dimension`]), so each
//! continuation's draws line up across a pixel's samples and keep the
//! sampler's stratification however long the continuations before it ran.
//! Every draw stays a function of (seed, pixel, sample index, dimension):
//! images are the same for any thread count and pass split.

use crate::bsdf::{Bsdf, BsdfContext, Lobe};
use crate::emitter::ShadingPoint;
use crate::geometry::{Ray, SurfaceInteraction};
use crate::integrator::path::{PathTracer, escaped, hit_weight};
use crate::math::mis_power;
use crate::sampler::Sampler;
use crate::scene::Scene;
use crate::spectrum::Spectrum;

/// First sampler dimension of the first continuation.
pub const SPLIT_DIM: u32 = 1 << 12;
/// Dimensions reserved per continuation (a path draws about four per bounce).
pub const SPLIT_STRIDE: u32 = 1 << 12;

impl PathTracer {
    /// Whether this path tracer splits at the first vertex.
    #[inline]
    pub fn splits(&self) -> bool {
        self.emitter_samples != 1 || self.bsdf_samples != 1
    }

    /// [`PathTracer::li`] with `emitter_samples` and `bsdf_samples` at the
    /// first vertex.
    pub fn li_split<S: Spectrum>(&self, scene: &Scene, ray: Ray, sampler: &mut Sampler, wl: &mut S::Wavelengths) -> S {
        let mut result = S::zero();
        let mut slot = SurfaceInteraction::EMPTY;
        let visible = !self.hide_emitters;
        if !scene.intersect_path_into(&ray, self.hide_emitters, sampler, &mut slot) {
            if visible {
                if let Some(env) = scene.environment_radiance::<S>(ray.d, wl) {
                    result += env;
                }
            }
            return result;
        }
        if visible {
            if let Some(le) = scene.emitted::<S>(&slot, wl) {
                result += le;
            }
        }
        if self.max_depth <= 1 {
            return result;
        }
        let si = slot;
        let bsdf = scene.bsdf(&si);
        if S::hero_wavelength(wl).is_some() && bsdf.disperses() {
            S::terminate_secondary(wl);
        }
        let (m, n) = (self.emitter_samples, self.bsdf_samples.max(1));
        // BSDF pdfs scaled by n/m make the power heuristic count samples.
        let ratio = n as f32 / m.max(1) as f32;
        if m > 0 && bsdf.lobes().intersects(Lobe::SMOOTH) {
            let mut direct = S::zero();
            for _ in 0..m {
                direct += next_event_counted::<S>(scene, &si, bsdf, ratio, sampler, wl);
            }
            result += direct * (1.0 / m as f32);
        }
        let mut indirect = S::zero();
        for j in 0..n {
            sampler.set_dimension(SPLIT_DIM + j * SPLIT_STRIDE);
            indirect += self.continuation::<S>(scene, &si, bsdf, ratio, m == 0, sampler, wl, &mut slot);
        }
        result + indirect * (1.0 / n as f32)
    }

    /// One path continued from the first vertex `si` by sampling its BSDF:
    /// `path`'s loop from the second vertex on. Emission met right after the
    /// first vertex takes the counted MIS weight (`ratio` = n/m; in full if
    /// the first vertex took no emitter samples).
    #[allow(clippy::too_many_arguments)]
    fn continuation<S: Spectrum>(
        &self,
        scene: &Scene,
        si: &SurfaceInteraction,
        bsdf: &Bsdf,
        ratio: f32,
        no_emitter_samples: bool,
        sampler: &mut Sampler,
        wl: &mut S::Wavelengths,
        slot: &mut SurfaceInteraction,
    ) -> S {
        let mut result = S::zero();
        let Some(bs) = bsdf.sample_inline::<S>(&BsdfContext::RADIANCE, si, si.wi, sampler.next_1d(), sampler.next_2d(), wl) else {
            return result;
        };
        let mut ctx = BsdfContext::RADIANCE.following(bs.lobe);
        let d = si.to_world(bs.wo);
        let mut throughput = bs.weight;
        let mut eta = bs.eta;
        let mut prev = ShadingPoint { p: si.p, n: si.frame.n };
        let mut prev_pdf = bs.pdf * ratio;
        let mut prev_delta = bs.lobe.intersects(Lobe::DELTA) || no_emitter_samples;
        let mut ray = Ray::new(si.spawn_origin(d), d);
        let mut depth = 1u32;
        if !(throughput.max_component() > 0.0) {
            return result;
        }
        loop {
            let hit = scene.intersect_path_into(&ray, false, sampler, slot);
            let si = &*slot;
            if !hit {
                if let Some((env, w)) = escaped::<S>(scene, &prev, prev_pdf, prev_delta, ray.d, wl) {
                    result += throughput * env * w;
                }
                break;
            }
            if let Some(le) = scene.emitted::<S>(si, wl) {
                result += throughput * le * hit_weight(scene, &prev, prev_pdf, prev_delta, si);
            }
            if depth.saturating_add(1) >= self.max_depth {
                break;
            }
            let bsdf = scene.bsdf(si);
            if S::hero_wavelength(wl).is_some() && bsdf.disperses() {
                S::terminate_secondary(wl);
            }
            if bsdf.lobes().intersects(Lobe::SMOOTH) {
                result += crate::integrator::path::next_event::<S>(scene, si, bsdf, &BsdfContext::RADIANCE, throughput, sampler, wl);
            }
            let Some(bs) = bsdf.sample_inline::<S>(&ctx, si, si.wi, sampler.next_1d(), sampler.next_2d(), wl) else { break };
            ctx = ctx.following(bs.lobe);
            let d = si.to_world(bs.wo);
            throughput *= bs.weight;
            eta *= bs.eta;
            prev = ShadingPoint { p: si.p, n: si.frame.n };
            prev_pdf = bs.pdf;
            prev_delta = bs.lobe.intersects(Lobe::DELTA);
            ray = Ray::new(si.spawn_origin(d), d);
            depth += 1;

            let Some(scale) = crate::integrator::path::russian_roulette(throughput.max_component(), eta, depth, self.rr_depth, sampler) else { break };
            throughput *= scale;
        }
        result
    }
}

/// [`crate::integrator::path::next_event`] at the first vertex (path
/// throughput 1) with the power heuristic counting samples: the BSDF pdf
/// scaled by `ratio` = BSDF samples / emitter samples.
#[inline]
fn next_event_counted<S: Spectrum>(scene: &Scene, si: &SurfaceInteraction, bsdf: &Bsdf, ratio: f32, sampler: &mut Sampler, wl: &S::Wavelengths) -> S {
    let Some(es) = scene.sample_emitter::<S>(si, sampler.next_2d(), wl) else { return S::zero() };
    let wo = si.to_local(es.d);
    let (f, pdf): (S, f32) = bsdf.eval_pdf(&BsdfContext::RADIANCE, si, si.wi, wo, wl);
    if f.is_zero() {
        return S::zero();
    }
    let w = if es.delta { 1.0 } else { mis_power(es.pdf, pdf * ratio) };
    f * es.weight * w
}
