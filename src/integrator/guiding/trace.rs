//! The guided path tracer: `path`'s loop ([`crate::integrator::path`]) with
//! one-sample MIS of the BSDF and the guide at guided vertices, and, while
//! training, the records of the radiance each vertex received.
//!
//! A vertex is guided where its BSDF has only smooth reflection lobes
//! (diffuse, glossy) and the guide has a distribution for its region. There
//! the direction comes from the BSDF with probability α
//! (`bsdf_sampling_fraction`), else from the guide, and is weighted by
//! f / (α·p_bsdf + (1−α)·p_guide). That combined density is the BSDF
//! strategy's density in the power heuristic against next-event
//! estimation, both for the emitter sample taken there and for emission
//! the path meets next. Delta, transmissive and null lobes are sampled as
//! in `path`. Both branches take the same draws (one 1-D, one 2-D), so the
//! sampler's dimensions line up as in `path`.
//!
//! Records (training only): each emitter sample gives one (radiance ×
//! MIS weight / its density) in its direction; each sampled direction of a
//! smooth vertex gives the MIS-weighted radiance the rest of the path
//! brought back through it, over the density it was sampled with. Their
//! sum is an unbiased estimate of the incident radiance's integral over any
//! set of directions, the quantity the quadtrees are fitted to.

use super::Guiding;
use super::sdtree::{Record, SdTree, normal_bin};
use crate::bsdf::{BsdfContext, Lobe};
use crate::emitter::ShadingPoint;
use crate::geometry::{Ray, SurfaceInteraction};
use crate::integrator::path::{PathTracer, escaped, hit_weight};
use crate::math::mis_power;
use crate::sampler::Sampler;
use crate::scene::Scene;
use crate::spectrum::Spectrum;
use glam::Vec3;

/// Lobes of a BSDF the guide may sample.
const GUIDED: Lobe = Lobe::DIFFUSE_REFLECTION.union(Lobe::GLOSSY_REFLECTION);

/// A vertex whose incident radiance is being gathered.
#[derive(Clone, Copy)]
pub struct Open<S> {
    p: Vec3,
    bin: u8,
    d: Vec3,
    pdf: f32,
    /// Throughput from this vertex's incoming ray on.
    t: S,
    /// Radiance gathered so far.
    l: S,
}

/// Training state of one worker: open vertices of the current path and the
/// records made.
pub struct Recorder<S> {
    open: Vec<Open<S>>,
    pub records: Vec<Record>,
    /// Whether the vertex before the current one pushed the last open record.
    last_is_prev: bool,
    /// Whether to learn direct light too (emitter samples and emission met
    /// right after a smooth vertex); else only what next-event estimation
    /// cannot reach from there.
    pub learn_direct: bool,
}

impl<S: Spectrum> Recorder<S> {
    pub fn new(learn_direct: bool) -> Self {
        Recorder { open: Vec::with_capacity(16), records: vec![], last_is_prev: false, learn_direct }
    }
}

/// Most vertices of one path whose incident radiance is recorded.
const MAX_OPEN: usize = 32;

impl<S: Spectrum> Recorder<S> {
    #[inline]
    fn add(&mut self, x: S) {
        for o in self.open.iter_mut() {
            o.l += o.t * x;
        }
    }
    /// Emission met by the sample of the previous vertex: direct light of
    /// that vertex if it was smooth (`nee_reachable`).
    #[inline]
    fn add_emission(&mut self, x: S, nee_reachable: bool) {
        let n = self.open.len();
        let skip = !self.learn_direct && nee_reachable && self.last_is_prev;
        for o in self.open[..if skip { n - 1 } else { n }].iter_mut() {
            o.l += o.t * x;
        }
    }
    #[inline]
    fn scale(&mut self, w: S) {
        for o in self.open.iter_mut() {
            o.t *= w;
        }
    }
    #[inline]
    fn scale_f(&mut self, w: f32) {
        for o in self.open.iter_mut() {
            o.t *= w;
        }
    }
    fn record(&mut self, p: Vec3, n: Vec3, d: Vec3, value: f32) {
        if self.learn_direct && value.is_finite() && value >= 0.0 {
            self.records.push(Record { p, bin: normal_bin(n), d, value });
        }
    }
    fn flush(&mut self) {
        for o in std::mem::take(&mut self.open) {
            let v = o.l.channel_mean().max(0.0) / o.pdf;
            if v.is_finite() {
                self.records.push(Record { p: o.p, bin: o.bin, d: o.d, value: v });
            }
        }
        self.open.clear();
    }
}

/// Radiance along `ray` by the guided path tracer; `guide` None samples as
/// `path` does (the first training iteration); `rec` gathers records.
#[allow(clippy::too_many_arguments)]
pub fn li<S: Spectrum>(
    pt: &PathTracer,
    params: &Guiding,
    guide: Option<&SdTree>,
    scene: &Scene,
    mut ray: Ray,
    sampler: &mut Sampler,
    wl: &mut S::Wavelengths,
    mut rec: Option<&mut Recorder<S>>,
) -> S {
    let alpha = params.bsdf_sampling_fraction;
    let mut result = S::zero();
    let mut throughput = S::splat(1.0);
    let mut eta = 1.0f32;
    let mut depth = 0u32;
    let (mut prev_p, mut prev_n) = (ray.o, Vec3::ZERO);
    let mut prev_pdf = 0.0f32;
    let mut prev_delta = true;
    let mut ctx = BsdfContext::RADIANCE;
    let mut slot = SurfaceInteraction::EMPTY;
    if let Some(r) = rec.as_deref_mut() {
        r.open.clear();
        r.last_is_prev = false;
    }

    loop {
        let hit = scene.intersect_path_into(&ray, pt.hide_emitters && depth == 0, sampler, &mut slot);
        let visible = !(pt.hide_emitters && depth == 0);
        let si = &slot;
        if !hit {
            if visible {
                if let Some((env, w)) = escaped::<S>(scene, &ShadingPoint { p: prev_p, n: prev_n }, prev_pdf, prev_delta, ray.d, wl) {
                    let x = env * w;
                    result += throughput * x;
                    if let Some(r) = rec.as_deref_mut() {
                        r.add_emission(x, !prev_delta);
                    }
                }
            }
            break;
        }
        if visible {
            if let Some(le) = scene.emitted::<S>(si, wl) {
                let x = le * hit_weight(scene, &ShadingPoint { p: prev_p, n: prev_n }, prev_pdf, prev_delta, si);
                result += throughput * x;
                if let Some(r) = rec.as_deref_mut() {
                    r.add_emission(x, !prev_delta);
                }
            }
        }
        if depth.saturating_add(1) >= pt.max_depth {
            break;
        }
        let bsdf = scene.bsdf(si);
        if S::hero_wavelength(wl).is_some() && bsdf.disperses() {
            S::terminate_secondary(wl);
        }
        let lobes = bsdf.lobes();
        let guidable = !lobes.is_empty() && GUIDED.contains(lobes);
        // The normal on the path's side: the two sides of a surface see
        // different light.
        let side_n = if si.wi.z < 0.0 { -si.frame.n } else { si.frame.n };
        let dirs = if guidable { guide.and_then(|g| g.lookup(si.p, side_n)) } else { None };

        // Next-event estimation, the BSDF strategy's density combined.
        if lobes.intersects(Lobe::SMOOTH) {
            if let Some(es) = scene.sample_emitter::<S>(si, sampler.next_2d(), wl) {
                let wo = si.to_local(es.d);
                let (f, pdf): (S, f32) = bsdf.eval_pdf(&BsdfContext::RADIANCE, si, si.wi, wo, wl);
                let pdf = match dirs {
                    Some(t) => alpha * pdf + (1.0 - alpha) * t.pdf(es.d),
                    None => pdf,
                };
                let w = if es.delta { 1.0 } else { mis_power(es.pdf, pdf) };
                if !f.is_zero() {
                    let x = f * es.weight * w;
                    result += throughput * x;
                    if let Some(r) = rec.as_deref_mut() {
                        r.add(x);
                    }
                }
                if guidable {
                    if let Some(r) = rec.as_deref_mut() {
                        r.record(si.p, side_n, es.d, (es.weight * w).channel_mean());
                    }
                }
            }
        }

        // Continue the path.
        let u1 = sampler.next_1d();
        let u2 = sampler.next_2d();
        let (weight, pdf, d, lobe, bs_eta) = match dirs {
            None => {
                let Some(bs) = bsdf.sample_inline::<S>(&ctx, si, si.wi, u1, u2, wl) else { break };
                (bs.weight, bs.pdf, si.to_world(bs.wo), bs.lobe, bs.eta)
            }
            Some(t) => {
                let (wo, lobe) = if u1 < alpha {
                    let Some(bs) = bsdf.sample_inline::<S>(&ctx, si, si.wi, (u1 / alpha).min(1.0 - f32::EPSILON), u2, wl) else { break };
                    (bs.wo, bs.lobe)
                } else {
                    (si.to_local(t.sample(u2)), Lobe::empty())
                };
                let d = si.to_world(wo);
                let (f, p_bsdf): (S, f32) = bsdf.eval_pdf(&ctx, si, si.wi, wo, wl);
                let pdf = alpha * p_bsdf + (1.0 - alpha) * t.pdf(d);
                if !(pdf > 0.0) || f.is_zero() {
                    break;
                }
                (f * (1.0 / pdf), pdf, d, lobe, 1.0)
            }
        };
        ctx = ctx.following(lobe);
        throughput *= weight;
        eta *= bs_eta;
        let delta = lobe.intersects(Lobe::DELTA);
        if let Some(r) = rec.as_deref_mut() {
            r.scale(weight);
            r.last_is_prev = guidable && !delta && r.open.len() < MAX_OPEN;
            if r.last_is_prev {
                r.open.push(Open { p: si.p, bin: normal_bin(side_n), d, pdf, t: S::splat(1.0), l: S::zero() });
            }
        }
        (prev_p, prev_n) = (si.p, si.frame.n);
        prev_pdf = pdf;
        prev_delta = delta;
        ray = Ray::new(si.spawn_origin(d), d);
        depth += 1;

        let Some(scale) = crate::integrator::path::russian_roulette(throughput.max_component(), eta, depth, pt.rr_depth, sampler) else { break };
        throughput *= scale;
        if let Some(r) = rec.as_deref_mut() {
            r.scale_f(scale);
        }
    }
    if let Some(r) = rec {
        r.flush();
    }
    result
}
