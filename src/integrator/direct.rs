//! `direct` — direct illumination only, by multiple importance sampling of
//! emitters and the BSDF.
//!
//! The seed's surface-area form of the reflection equation,
//! L_r(x') = ∫_A f_r L_e G dA(x''), G = V cos θ' cos θ'' / ‖x'' − x'‖²,
//! is estimated by sampling points x'' on the emitters (the area pdf turned
//! into a solid-angle pdf by the Jacobian dω = cos θ'' dA / ‖x'' − x'‖², the
//! visibility V by a shadow ray), combined with BSDF sampling through the
//! power heuristic. Delta emitters (point, directional) are sampled only by
//! emitter sampling; delta BSDF lobes only by BSDF sampling.
//!
//! With `emitter_samples` = n, each of the n emitter samples carries weight
//! 1/n — for delta emitters too. (Mitsuba 3.9 gives delta emitters weight 1
//! per sample, so its point and directional lights come out n times too
//! bright when n > 1; Snell keeps the physically correct estimate, which the
//! point-light closed-form test checks.)
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `emitter_samples` | integer | `shading_samples` | emitter samples per camera ray |
//! | `bsdf_samples` | integer | `shading_samples` | BSDF samples per camera ray |
//! | `shading_samples` | integer | 1 | default for both |
//! | `hide_emitters` | boolean | false | hide directly visible emitters (camera rays pass through emitting shapes) |
//! | `light_sampling` | string | `bvh` | how emitters are chosen: `uniform` (as Mitsuba), `power`, `bvh` ([`crate::emitter::selection`]) |
//!
//! ```xml
//! <integrator type="direct"><integer name="emitter_samples" value="4"/></integrator>
//! ```

use crate::bsdf::{Lobe, BsdfContext};
use crate::geometry::Ray;
use crate::math::mis_power;
use crate::sampler::Sampler;
use crate::emitter::ShadingPoint;
use crate::scene::Scene;
use crate::spectrum::Spectrum;

#[derive(Clone, Debug)]
pub struct Direct {
    pub emitter_samples: u32,
    pub bsdf_samples: u32,
    pub hide_emitters: bool,
}

impl Direct {
    pub fn li<S: Spectrum>(&self, scene: &Scene, ray: Ray, sampler: &mut Sampler, wl: &mut S::Wavelengths) -> S {
        let mut result = S::zero();
        let hit = scene.intersect_path(&ray, self.hide_emitters, sampler);
        let Some(si) = hit else {
            if !self.hide_emitters {
                if let Some(env) = scene.environment_radiance::<S>(ray.d, wl) {
                    result += env;
                }
            }
            return result;
        };
        if !self.hide_emitters {
            if let Some(le) = scene.emitted::<S>(&si, wl) {
                result += le;
            }
        }
        let bsdf = scene.bsdf(&si);
        let (ne, nb) = (self.emitter_samples as f32, self.bsdf_samples as f32);
        let total = ne + nb;

        // A dispersive interface sends each wavelength its own way: past a
        // rough one (emitter samples too) and in BSDF samples, the hero's alone.
        if bsdf.disperses() && (self.bsdf_samples > 0 || bsdf.lobes().intersects(Lobe::SMOOTH)) {
            S::terminate_secondary(wl);
        }
        if bsdf.lobes().intersects(Lobe::SMOOTH) {
            for _ in 0..self.emitter_samples {
                let Some(es) = scene.sample_emitter::<S>(&si, sampler.next_2d(), wl) else { continue };
                let wo = si.to_local(es.d);
                let f: S = bsdf.eval(&BsdfContext::RADIANCE, &si, si.wi, wo, wl);
                if f.is_zero() {
                    continue;
                }
                let w = if es.delta {
                    1.0 / ne
                } else {
                    mis_power(es.pdf * ne / total, bsdf.pdf::<S>(&BsdfContext::RADIANCE, &si, si.wi, wo, wl) * nb / total) / ne
                };
                result += f * es.weight * w;
            }
        }

        for _ in 0..self.bsdf_samples {
            let Some(bs) = bsdf.sample::<S>(&BsdfContext::RADIANCE, &si, si.wi, sampler.next_1d(), sampler.next_2d(), wl) else { continue };
            let d = si.to_world(bs.wo);
            let ray = Ray::new(si.spawn_origin(d), d);
            let delta = bs.lobe.intersects(Lobe::DELTA);
            let (le, em_pdf) = match scene.intersect_path(&ray, false, sampler) {
                Some(hit) => match scene.emitted::<S>(&hit, wl) {
                    Some(le) => (le, if delta { 0.0 } else { scene.pdf_emitter_hit(&ShadingPoint::from(&si), &hit) }),
                    None => continue,
                },
                None => match scene.environment_radiance::<S>(d, wl) {
                    Some(le) => (le, if delta { 0.0 } else { scene.pdf_environment(&ShadingPoint::from(&si), d) }),
                    None => continue,
                },
            };
            let w = if self.emitter_samples == 0 { 1.0 } else { mis_power(bs.pdf * nb / total, em_pdf * ne / total) };
            result += bs.weight * le * (w / nb);
        }
        result
    }
}
