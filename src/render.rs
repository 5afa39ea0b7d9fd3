//! The render driver: splits the film into tiles, renders them on a pool of
//! threads, merges them in a fixed order (so the image depends only on the
//! scene and the seed, not on the thread count or timing) and reports progress.

use crate::film::{Film, Image, TileBuffer};
use crate::sampler::Sampler;
use crate::scene::Scene;
use crate::spectrum::Spectrum;
use glam::Vec2;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use rayon::prelude::*;
use serde::Serialize;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

const TILE: u32 = 16;

#[derive(Clone, Debug)]
pub struct RenderOptions {
    /// Worker threads (0 = all cores).
    pub threads: usize,
    /// Show a progress bar on stderr (only drawn when stderr is a terminal).
    pub progress: bool,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions { threads: 0, progress: false }
    }
}

#[derive(Clone, Debug, Serialize)]
pub struct RenderStats {
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub threads: usize,
    /// Rendering only: excludes loading the scene and building the BVH.
    pub render_seconds: f64,
    pub samples_per_second: f64,
    /// Samples whose estimate was NaN or infinite, replaced by zero.
    pub invalid_samples: u64,
}

pub fn render<S: Spectrum>(scene: &Scene, options: &RenderOptions) -> anyhow::Result<(Image, RenderStats)> {
    let threads = if options.threads == 0 { std::thread::available_parallelism().map_or(1, |n| n.get()) } else { options.threads };
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build()?;
    let (w, h) = (scene.film.width, scene.film.height);
    let spp = scene.sampler.sample_count;
    let border = (scene.film.filter.radius() + 0.5).ceil() as i32;

    let mut tiles = vec![];
    for ty in (0..h).step_by(TILE as usize) {
        for tx in (0..w).step_by(TILE as usize) {
            tiles.push((tx, ty, TILE.min(w - tx), TILE.min(h - ty)));
        }
    }
    let bar = if options.progress {
        let bar = ProgressBar::with_draw_target(Some(tiles.len() as u64), ProgressDrawTarget::stderr());
        bar.set_style(
            ProgressStyle::with_template("{spinner} rendering [{bar:40}] {percent:>3}% {elapsed_precise} (ETA {eta})")
                .unwrap_or_else(|_| ProgressStyle::default_bar())
                .progress_chars("=> "),
        );
        bar
    } else {
        ProgressBar::hidden()
    };
    let invalid = AtomicU64::new(0);
    let inv_size = Vec2::new(1.0 / w as f32, 1.0 / h as f32);

    let start = Instant::now();
    let buffers: Vec<TileBuffer> = pool.install(|| {
        tiles
            .par_iter()
            .map(|&(tx, ty, tw, th)| {
                let mut buf = TileBuffer::new(
                    tx as i32 - border,
                    ty as i32 - border,
                    (tw as i32 + 2 * border) as usize,
                    (th as i32 + 2 * border) as usize,
                );
                let mut bad = 0u64;
                for y in ty..ty + th {
                    for x in tx..tx + tw {
                        let mut sampler = Sampler::for_pixel(scene.sampler.seed, x, y);
                        for _ in 0..spp {
                            let mut wl = S::sample_wavelengths(sampler.next_1d());
                            let pos = Vec2::new(x as f32, y as f32) + sampler.next_2d();
                            let ray = scene.camera.generate_ray(pos * inv_size);
                            let l: S = scene.integrator.li(scene, ray, &mut sampler, &mut wl);
                            let mut rgb = l.to_rgb(&wl);
                            if !rgb.is_finite() {
                                bad += 1;
                                rgb = crate::spectrum::Rgb::BLACK;
                            }
                            buf.splat(&scene.film.filter, (pos.x, pos.y), rgb);
                        }
                    }
                }
                if bad > 0 {
                    invalid.fetch_add(bad, Ordering::Relaxed);
                }
                bar.inc(1);
                buf
            })
            .collect()
    });
    let seconds = start.elapsed().as_secs_f64();
    bar.finish_and_clear();

    let mut film = Film::new(w, h);
    for b in &buffers {
        film.merge(b);
    }
    let samples = w as f64 * h as f64 * spp as f64;
    let stats = RenderStats {
        width: w,
        height: h,
        spp,
        threads,
        render_seconds: seconds,
        samples_per_second: if seconds > 0.0 { samples / seconds } else { 0.0 },
        invalid_samples: invalid.into_inner(),
    };
    Ok((film.develop(), stats))
}
