//! `volpath` — path tracing through participating media ([`crate::medium`]).
//!
//! The path tracer of `path`, plus: a path knows the medium it travels in
//! (the camera's is empty; crossing a shape that names an `interior` or
//! `exterior` medium moves the path into the one on the side it goes to,
//! as Mitsuba's `target_medium`), and along each segment inside a medium it
//! samples where it scatters ([`Medium::sample_scattering`]). At a
//! scattering point it estimates direct light by sampling an emitter (if the
//! medium's `sample_emitters`) and continues in a direction drawn from the
//! phase function, the two weighted by the power heuristic as at surfaces.
//! Shadow rays pass through `null` (and the open part of `mask`) surfaces,
//! through `thindielectric` ones (keeping 1 − the slab's reflectance, as
//! Mitsuba's `volpath` does) and through media, attenuated by their
//! transmittance; any other surface blocks them. Crossing a `null` boundary is not a bounce; a scattering in
//! a medium is one (`max_depth` counts both kinds, as Mitsuba's does).
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `max_depth` | integer | -1 | longest path in scattering events; -1 = unlimited |
//! | `rr_depth` | integer | 5 | depth at which Russian roulette starts |
//! | `hide_emitters` | boolean | false | hide directly visible emitters |
//! | `light_sampling` | string | `bvh` | as for `path` |
//!
//! Mitsuba's `volpathmis` (the same image with spectral MIS over
//! wavelengths) and `prbvolpath` (its differentiable variant) are read as
//! `volpath`: their images converge to the same values, and Snell's
//! distance sampling already weighs all channels (see [`crate::medium`]).
//! Modes: `rgb` and `spectral` (the polarized modes are refused).
//!
//! ```xml
//! <integrator type="volpath"><integer name="max_depth" value="16"/></integrator>
//! ```

use crate::bsdf::{Bsdf, BsdfContext, Lobe};
use crate::emitter::ShadingPoint;
use crate::geometry::{Ray, Shape, SurfaceInteraction};
use crate::integrator::path::{escaped, hit_weight, russian_roulette};
use crate::math::mis_power;
use crate::sampler::Sampler;
use crate::scene::Scene;
use crate::spectrum::Spectrum;
use glam::Vec3;

/// Most surfaces a path or shadow ray crosses without scattering.
const MAX_CROSSINGS: u32 = 4096;

#[derive(Clone, Debug)]
pub struct VolPath {
    /// `u32::MAX` for unlimited.
    pub max_depth: u32,
    pub rr_depth: u32,
    pub hide_emitters: bool,
}

/// The medium a path is in after leaving the surface `si` of `shape` in
/// direction `d`, having been in `current`: a shape that names a medium on
/// either side decides (its exterior if `d` leaves on the side of the
/// geometric normal, its interior otherwise); other shapes change nothing.
#[inline]
pub fn medium_after(shape: &Shape, si: &SurfaceInteraction, d: Vec3, current: Option<u32>) -> Option<u32> {
    if shape.interior.is_none() && shape.exterior.is_none() {
        return current;
    }
    if d.dot(si.n) > 0.0 { shape.exterior } else { shape.interior }
}

impl VolPath {
    pub fn li<S: Spectrum>(&self, scene: &Scene, mut ray: Ray, sampler: &mut Sampler, wl: &mut S::Wavelengths) -> S {
        let mut result = S::zero();
        let mut beta = S::splat(1.0);
        let mut eta = 1.0f32;
        let mut depth = 0u32;
        let mut medium = scene.camera_medium;
        let mut prev = ShadingPoint::at(ray.o);
        let mut prev_pdf = 0.0f32;
        let mut prev_delta = true;
        let mut ctx = BsdfContext::RADIANCE;
        let mut si = SurfaceInteraction::EMPTY;
        let mut crossings = 0u32;

        loop {
            let hit = scene.intersect_into(&ray, &mut si);
            let t_surface = if hit { si.t } else { f32::INFINITY };

            // A scattering in the medium before the surface?
            if let Some(m) = medium {
                let med = &scene.media[m as usize];
                let scattered = med.sample_scattering::<S>(ray.o, ray.d, t_surface, &mut beta, sampler, wl);
                if beta.is_zero() {
                    break;
                }
                if let Some(t) = scattered {
                    if depth.saturating_add(1) >= self.max_depth {
                        break;
                    }
                    let p = ray.at(t);
                    let wi = -ray.d;
                    let at = ShadingPoint::at(p);
                    if med.sample_emitters {
                        // A medium point: no normal, so no offset and no side.
                        let mut point = SurfaceInteraction::EMPTY;
                        point.p = p;
                        if let Some((d, weight, pdf, delta)) = sample_light::<S>(scene, &point, None, Some(m), sampler, wl) {
                            let f = med.phase.eval(p, wi, d);
                            let w = if delta { 1.0 } else { mis_power(pdf, f) };
                            result += beta * weight * (f * w);
                        }
                    }
                    let (wo, pdf) = med.phase.sample(p, wi, sampler.next_2d());
                    prev = at;
                    prev_pdf = pdf;
                    // Without emitter sampling here, emitters met next count in full.
                    prev_delta = !med.sample_emitters;
                    ray = Ray::new(p, wo);
                    depth += 1;
                    let Some(scale) = russian_roulette(beta.max_component(), eta, depth, self.rr_depth, sampler) else { break };
                    beta *= scale;
                    continue;
                }
            }

            let visible = !(self.hide_emitters && depth == 0);
            if !hit {
                if visible {
                    if let Some((env, w)) = escaped::<S>(scene, &prev, prev_pdf, prev_delta, ray.d, wl) {
                        result += beta * env * w;
                    }
                }
                break;
            }
            let shape = &scene.shapes[si.shape as usize];
            // Surfaces a path passes without a bounce: hidden emitters seen
            // by the camera, `null` and the open part of `mask`.
            let pass = if shape.pass_through {
                let alpha = scene.bsdfs[shape.bsdf as usize].opacity(&si);
                alpha < 1.0 && !(alpha > 0.0 && sampler.next_1d() < alpha)
            } else {
                !visible && shape.emitter.is_some()
            };
            if pass {
                crossings += 1;
                if crossings > MAX_CROSSINGS {
                    break;
                }
                medium = medium_after(shape, &si, ray.d, medium);
                let o = si.spawn_origin(ray.d);
                ray = Ray::new(o, ray.d);
                continue;
            }
            if visible {
                if let Some(le) = scene.emitted::<S>(&si, wl) {
                    result += beta * le * hit_weight(scene, &prev, prev_pdf, prev_delta, &si);
                }
            }
            if depth.saturating_add(1) >= self.max_depth {
                break;
            }
            let bsdf = scene.bsdf(&si);
            if S::hero_wavelength(wl).is_some() && bsdf.disperses() {
                S::terminate_secondary(wl);
            }
            if bsdf.lobes().intersects(Lobe::SMOOTH) {
                if let Some((d, weight, pdf, delta)) = sample_light::<S>(scene, &si, Some(shape), medium, sampler, wl) {
                    let wo = si.to_local(d);
                    let (f, bsdf_pdf): (S, f32) = bsdf.eval_pdf(&BsdfContext::RADIANCE, &si, si.wi, wo, wl);
                    if !f.is_zero() {
                        let w = if delta { 1.0 } else { mis_power(pdf, bsdf_pdf) };
                        result += beta * f * weight * w;
                    }
                }
            }
            let Some(bs) = bsdf.sample_inline::<S>(&ctx, &si, si.wi, sampler.next_1d(), sampler.next_2d(), wl) else { break };
            let d = si.to_world(bs.wo);
            beta *= bs.weight;
            eta *= bs.eta;
            medium = medium_after(shape, &si, d, medium);
            ray = Ray::new(si.spawn_origin(d), d);
            // Straight through a thin dielectric is a null crossing, as in
            // Mitsuba (whose thindielectric flags it Null): no bounce, and
            // the last scattering vertex stays the one emitters hit next are
            // weighed from (shadow rays cross such slabs, see above).
            if matches!(bsdf, Bsdf::ThinDielectric(_)) && bs.lobe == Lobe::DELTA_TRANSMISSION {
                crossings += 1;
                if crossings > MAX_CROSSINGS {
                    break;
                }
                continue;
            }
            ctx = ctx.following(bs.lobe);
            prev = ShadingPoint::from(&si);
            prev_pdf = bs.pdf;
            prev_delta = bs.lobe.intersects(Lobe::DELTA);
            depth += 1;
            let Some(scale) = russian_roulette(beta.max_component(), eta, depth, self.rr_depth, sampler) else { break };
            beta *= scale;
        }
        result
    }
}

/// An emitter sample for the point `si` (a surface point, or a point in a
/// medium with a zero normal), attenuated along the way: (direction,
/// L·T/pdf, pdf, delta). `boundary` is the shape `si` lies on, if any: the
/// shadow ray then starts in the medium on the side it leaves to.
fn sample_light<S: Spectrum>(
    scene: &Scene,
    si: &SurfaceInteraction,
    boundary: Option<&Shape>,
    medium: Option<u32>,
    sampler: &mut Sampler,
    wl: &S::Wavelengths,
) -> Option<(Vec3, S, f32, bool)> {
    let u = sampler.next_2d();
    let (index, pmf, ux) = scene.select_emitter(u.x, &ShadingPoint::from(si))?;
    let (sample, ray) = scene.sample_emitter_ray_from::<S>(si, index, pmf, ux, u.y, wl)?;
    let medium = boundary.map_or(medium, |shape| medium_after(shape, si, ray.d, medium));
    let tr = transmittance::<S>(scene, ray, medium, sampler, wl);
    if tr.is_zero() {
        return None;
    }
    Some((sample.d, sample.weight * tr, sample.pdf, sample.delta))
}

/// The fraction of light that arrives along the shadow ray `ray` starting in
/// `medium`: zero if a surface other than a pass-through or thin dielectric
/// one blocks it, else the product of the media's transmittances, (1 − α)
/// of the pass-through surfaces and the thin slabs' straight transmission,
/// switching media at their boundaries.
pub fn transmittance<S: Spectrum>(scene: &Scene, mut ray: Ray, mut medium: Option<u32>, sampler: &mut Sampler, wl: &S::Wavelengths) -> S {
    let mut tr = S::splat(1.0);
    let mut si = SurfaceInteraction::EMPTY;
    for _ in 0..MAX_CROSSINGS {
        let hit = scene.accel.intersect(&ray);
        let segment = hit.as_ref().map_or(ray.tmax, |h| h.t);
        if let Some(m) = medium {
            tr *= scene.media[m as usize].transmittance::<S>(ray.o, ray.d, segment, sampler, wl);
            if tr.is_zero() {
                return tr;
            }
        }
        let Some(hit) = hit else { return tr };
        let shape = &scene.shapes[hit.shape as usize];
        let bsdf = &scene.bsdfs[shape.bsdf as usize];
        if !shape.pass_through && !matches!(bsdf, Bsdf::ThinDielectric(_)) {
            return S::zero();
        }
        scene.interaction_into(&hit, &ray, &mut si);
        if let Bsdf::ThinDielectric(thin) = bsdf {
            tr *= thin.straight_transmission::<S>(&si, si.frame.n.dot(ray.d).abs(), wl);
        } else {
            tr *= 1.0 - bsdf.opacity(&si);
        }
        if tr.is_zero() {
            return tr;
        }
        medium = medium_after(shape, &si, ray.d, medium);
        let o = si.spawn_origin(ray.d);
        ray = Ray { o, d: ray.d, tmax: ray.tmax - (o - ray.o).length() };
        if !(ray.tmax > 0.0) {
            return tr;
        }
    }
    S::zero()
}
