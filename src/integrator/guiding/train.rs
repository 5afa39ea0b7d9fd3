//! The training pre-phase: iterations of doubling sample counts, each
//! fitting a new [`SdTree`] to the records of paths guided by the previous
//! one (see the module doc of [`super`] for why the result does not depend
//! on the thread count).

use super::Guiding;
use super::sdtree::{Record, SdTree};
use super::trace::{Recorder, li};
use crate::integrator::path::PathTracer;
use crate::sampler::{Sampler, SamplerKind, SamplerSpec};
use crate::scene::Scene;
use crate::spectrum::Spectrum;
use glam::{Vec2, Vec3};
use rayon::prelude::*;
use std::sync::Arc;

/// Whether the guide learns direct light too. Off: next-event estimation
/// already samples it (and the guide's density enters its MIS weight), so
/// the guide learns what comes after another bounce or through a delta
/// chain (caustics). Measured on the Cornell box at 64², 64 spp: relMSE
/// 1.38e-3 without direct light, 1.54e-3 with it.
const LEARN_DIRECT: bool = false;

/// Mixed into the scene's seed for the training sampler.
const TRAINING_SEED: u64 = 0x6775_6964_696e_6721;

/// Samples per pixel of each training iteration: 1, 2, 4, …, the last
/// taking the rest of `total` (at least as many as the one before).
pub fn schedule(total: u32) -> Vec<u32> {
    let mut out = vec![];
    let (mut left, mut size) = (total, 1u32);
    while left > 0 {
        if left < size.saturating_mul(3) {
            out.push(left);
            break;
        }
        out.push(size);
        left -= size;
        size = size.saturating_mul(2);
    }
    out
}

/// Trains the guide of `guiding` for the spectrum type `S` on `scene` if
/// that has not been done yet (a no-op in the polarized modes).
pub fn ensure_trained<S: Spectrum>(scene: &Scene, pt: &PathTracer, guiding: &Guiding, pool: &rayon::ThreadPool) {
    let Some(slot) = Guiding::slot::<S>() else { return };
    guiding.trained[slot].get_or_init(|| Arc::new(train::<S>(scene, pt, guiding, pool)));
}

/// Runs the training iterations and returns the last guide.
pub fn train<S: Spectrum>(scene: &Scene, pt: &PathTracer, guiding: &Guiding, pool: &rayon::ThreadPool) -> SdTree {
    let (lo, hi) = scene.accel.bounds(&scene.shapes);
    // A little margin: points on the box's faces fall inside.
    let margin = (hi - lo).max(Vec3::splat(1e-3)) * 1e-3;
    let (lo, hi) = (lo - margin, hi + margin);
    let spec = SamplerSpec { sample_count: guiding.guiding_spp.max(1), seed: scene.sampler.seed ^ TRAINING_SEED, kind: SamplerKind::Independent };
    let [ox, oy, cw, ch] = scene.film.crop;
    let inv_size = Vec2::new(1.0 / scene.film.width as f32, 1.0 / scene.film.height as f32);
    let offset = Vec2::new(ox as f32, oy as f32);
    let mut guide: Option<SdTree> = None;
    let mut first = 0u32;
    for spp in schedule(guiding.guiding_spp) {
        let samples = first..first + spp;
        first += spp;
        let current = guide.as_ref();
        // One record list per row, concatenated in row order.
        let rows: Vec<Vec<Record>> = pool.install(|| {
            (0..ch)
                .into_par_iter()
                .map(|y| {
                    let mut rec = Recorder::<S>::new(LEARN_DIRECT);
                    for x in 0..cw {
                        for index in samples.clone() {
                            let mut sampler = Sampler::start(&spec, x + ox, y + oy, index);
                            let mut wl = S::sample_wavelengths(sampler.next_1d());
                            let pos = Vec2::new(x as f32, y as f32) + sampler.next_2d();
                            let ray = scene.camera.sample_ray((pos + offset) * inv_size, &mut sampler);
                            li::<S>(pt, guiding, current, scene, ray, &mut sampler, &mut wl, Some(&mut rec));
                        }
                    }
                    rec.records
                })
                .collect()
        });
        let mut records: Vec<Record> = rows.concat();
        drop(rows);
        guide = Some(SdTree::build(&mut records, lo, hi, spp, true));
    }
    guide.unwrap_or_default()
}
