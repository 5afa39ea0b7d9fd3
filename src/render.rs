//! The render driver: splits the film into tiles, renders them on a pool of
//! threads, merges them in a fixed order (so the image depends only on the
//! scene and the seed, not on the thread count or timing) and reports progress.

use crate::film::{Film, Filter, Image, TileBuffer};
use crate::integrator::{Integrator, ParticleTracer};
use crate::spectrum::Rgb;
use crate::sampler::Sampler;
use crate::scene::Scene;
use crate::spectrum::Spectrum;
use crate::spectrum::mueller::{rotate_stokes_basis, stokes_basis};
use glam::{Vec2, Vec3};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use rayon::prelude::*;
use serde::Serialize;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::Instant;

const TILE: u32 = 16;

#[derive(Clone, Debug)]
pub struct RenderOptions {
    /// Worker threads (0 = all cores).
    pub threads: usize,
    /// Show a progress bar on stderr (only drawn when stderr is a terminal).
    pub progress: bool,
    /// Set (e.g. by a Ctrl-C / SIGTERM handler) to stop early: work units
    /// (tile rows; batches of light paths) not yet started are skipped, and
    /// the image develops from the samples taken ([`RenderStats::interrupted`]).
    pub stop: Option<Arc<AtomicBool>>,
    /// Render in this many passes of growing sample counts (0 or 1: one
    /// pass), calling the `on_pass` callback of [`render_passes`] after each.
    pub passes: u32,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions { threads: 0, progress: false, stop: None, passes: 1 }
    }
}

impl RenderOptions {
    fn stopped(&self) -> bool {
        self.stop.as_ref().is_some_and(|s| s.load(Ordering::Relaxed))
    }
}

/// Bytes the render of `scene` holds at its peak (tile buffers with their
/// filter borders, the film's f64 sums, the developed image and an encoded
/// copy for output), `polarized` adding the Stokes layers.
pub fn estimate_memory(scene: &Scene, polarized: bool) -> u64 {
    let (w, h) = (scene.film.width as u64, scene.film.height as u64);
    let pixels = w * h;
    let border = (scene.film.filter.radius() + 0.5).ceil() as u64;
    if let Integrator::Particle(_) = &scene.integrator {
        let threads = rayon::current_num_threads() as u64;
        return pixels * (24 + 12 + 12) + threads * (w + 2 * border) * (h + 2 * border) * 12;
    }
    let tiles_x = w.div_ceil(TILE as u64);
    let tiles_y = h.div_ceil(TILE as u64);
    let tile_pixels = tiles_x * tiles_y * (TILE as u64 + 2 * border).pow(2);
    let (tile, film, image) = if polarized { (16 + 36, 32 + 72, 12 * 4) } else { (16, 32, 12) };
    tile_pixels * tile + pixels * (film + image + image)
}

/// Refuses a film whose estimated memory is above the budget
/// ([`crate::limits::max_film_bytes`]), before anything is allocated.
fn check_memory(scene: &Scene, polarized: bool) -> anyhow::Result<()> {
    let need = estimate_memory(scene, polarized);
    let max = crate::limits::max_film_bytes();
    if need > max {
        let mb = |b: u64| b.div_ceil(1 << 20);
        anyhow::bail!(
            "the film of {} × {} pixels needs about {} MB while rendering, above the budget of {} MB \
             (raise it with --max-film-mb or the environment variable SNELL_MAX_FILM_BYTES)",
            scene.film.width,
            scene.film.height,
            mb(need),
            mb(max)
        );
    }
    Ok(())
}

/// A pool of `threads` workers, with an error that names the thread count
/// when the system refuses them.
fn thread_pool(threads: usize) -> anyhow::Result<rayon::ThreadPool> {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| anyhow::anyhow!("cannot start {threads} worker threads (--threads {threads}): {e}"))
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
    /// Whether the render was stopped early ([`RenderOptions::stop`]).
    pub interrupted: bool,
    /// Samples (camera samples, or light paths) actually taken, and the
    /// number a full render takes.
    pub samples_taken: u64,
    pub samples_planned: u64,
}

impl RenderStats {
    /// `samples` (camera samples, or light paths) rendered in `seconds`.
    fn new(scene: &Scene, spp: u32, threads: usize, seconds: f64, samples: f64, invalid_samples: u64) -> RenderStats {
        let planned = scene.film.crop[2] as u64 * scene.film.crop[3] as u64 * spp as u64;
        RenderStats {
            interrupted: (samples as u64) < planned,
            samples_taken: samples as u64,
            samples_planned: planned,
            width: scene.film.crop[2],
            height: scene.film.crop[3],
            spp,
            threads,
            render_seconds: seconds,
            samples_per_second: if seconds > 0.0 { samples / seconds } else { 0.0 },
            invalid_samples,
        }
    }
}

fn thread_count(options: &RenderOptions) -> usize {
    if options.threads == 0 { std::thread::available_parallelism().map_or(1, |n| n.get()) } else { options.threads }
}

fn progress_bar(options: &RenderOptions, len: u64) -> ProgressBar {
    if options.progress {
        let bar = ProgressBar::with_draw_target(Some(len), ProgressDrawTarget::stderr());
        bar.set_style(
            ProgressStyle::with_template("{spinner} rendering [{bar:40}] {percent:>3}% {elapsed_precise} (ETA {eta})")
                .unwrap_or_else(|_| ProgressStyle::default_bar())
                .progress_chars("=> "),
        );
        bar
    } else {
        ProgressBar::hidden()
    }
}

/// What [`render_passes`] reports after each pass: the image of every
/// sample taken so far, and how far the render is.
pub struct PassReport<'a> {
    /// 1-based number of the pass just finished, and the number planned.
    pub pass: u32,
    pub passes: u32,
    /// Samples per pixel in `image`, and in the finished render.
    pub spp_done: u32,
    pub spp_total: u32,
    /// Seconds since the first pass began.
    pub elapsed_seconds: f64,
    pub image: &'a Image,
}

/// The cumulative samples per pixel after each of `passes` passes of an
/// `spp`-sample render: growing passes (doubling) whose last ends at `spp`.
pub fn pass_schedule(spp: u32, passes: u32) -> Vec<u32> {
    let passes = passes.clamp(1, spp.max(1));
    let mut ends: Vec<u32> = (1..=passes).map(|k| ((spp as u64) >> (passes - k)) as u32).collect();
    // Small renders: make each pass take at least one sample.
    for k in 0..ends.len() {
        let least = k as u32 + 1;
        if ends[k] < least {
            ends[k] = least;
        }
    }
    ends
}

/// Renders `scene` to an image (one pass, or [`RenderOptions::passes`]).
pub fn render<S: Spectrum>(scene: &Scene, options: &RenderOptions) -> anyhow::Result<(Image, RenderStats)> {
    render_passes::<S>(scene, options, &mut |_| {})
}

/// Renders in [`RenderOptions::passes`] passes (see [`pass_schedule`]),
/// calling `on_pass` with the image so far after each; a stop request ends
/// the render after the pass under way.
pub fn render_passes<S: Spectrum>(
    scene: &Scene,
    options: &RenderOptions,
    on_pass: &mut dyn FnMut(&PassReport),
) -> anyhow::Result<(Image, RenderStats)> {
    let schedule = pass_schedule(scene.sampler.sample_count, options.passes);
    let start = Instant::now();
    let mut last = None;
    for (k, &spp) in schedule.iter().enumerate() {
        // Placeholder until the render loop takes sample ranges: a pass
        // re-renders samples [0, spp) (addressable samples: the same image).
        let (image, stats) = if let Integrator::Particle(tracer) = &scene.integrator {
            render_particles::<S>(scene, tracer, options, spp)?
        } else {
            render_camera::<S>(scene, options, spp)?
        };
        on_pass(&PassReport {
            pass: k as u32 + 1,
            passes: schedule.len() as u32,
            spp_done: spp,
            spp_total: scene.sampler.sample_count,
            elapsed_seconds: start.elapsed().as_secs_f64(),
            image: &image,
        });
        let stop = stats.interrupted || options.stopped();
        last = Some((image, stats));
        if stop {
            break;
        }
    }
    last.ok_or_else(|| anyhow::anyhow!("no pass was rendered"))
}

fn render_camera<S: Spectrum>(scene: &Scene, options: &RenderOptions, spp: u32) -> anyhow::Result<(Image, RenderStats)> {
    check_memory(scene, S::POLARIZED)?;
    let threads = thread_count(options);
    let pool = thread_pool(threads)?;
    // The crop window (the whole film unless the scene crops): pixels are
    // numbered within it, the camera sees the full film.
    let [ox, oy, w, h] = scene.film.crop;
    let taken = AtomicU64::new(0);
    let border = (scene.film.filter.radius() + 0.5).ceil() as i32;
    let up = scene.camera.up();
    // Further per-sample channels: alpha if the film has it, then the
    // integrator's (AOVs, moments). None for a plain RGB render.
    let alpha = scene.film.pixel_format.has_alpha();
    let channel_names: Vec<String> = alpha.then(|| "A".to_string()).into_iter().chain(scene.integrator.channel_names()).collect();
    let n_extra = channel_names.len();

    let mut tiles = vec![];
    for ty in (0..h).step_by(TILE as usize) {
        for tx in (0..w).step_by(TILE as usize) {
            tiles.push((tx, ty, TILE.min(w - tx), TILE.min(h - ty)));
        }
    }
    let bar = progress_bar(options, tiles.len() as u64);
    let invalid = AtomicU64::new(0);
    let inv_size = Vec2::new(1.0 / scene.film.width as f32, 1.0 / scene.film.height as f32);
    let offset = Vec2::new(ox as f32, oy as f32);

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
                if S::POLARIZED {
                    buf = buf.with_stokes();
                }
                if n_extra > 0 {
                    buf = buf.with_extra(n_extra);
                }
                let mut extra = vec![0.0f32; n_extra];
                let mut bad = 0u64;
                for y in ty..ty + th {
                    // A tile row is the unit of work that a stop request lets finish.
                    if options.stopped() {
                        break;
                    }
                    taken.fetch_add(tw as u64 * spp as u64, Ordering::Relaxed);
                    for x in tx..tx + tw {
                        // Seeded by the pixel's place in the full film: a crop
                        // renders the same samples as the full render there.
                        for index in 0..spp {
                            let mut sampler = Sampler::start(&scene.sampler, x + ox, y + oy, index);
                            let mut wl = S::sample_wavelengths(sampler.next_1d());
                            let pos = Vec2::new(x as f32, y as f32) + sampler.next_2d();
                            let ray = scene.camera.sample_ray((pos + offset) * inv_size, &mut sampler);
                            let l: S = if n_extra == 0 {
                                scene.integrator.li(scene, ray, &mut sampler, &mut wl)
                            } else {
                                let first = alpha as usize;
                                let (l, a) = scene.integrator.sample(scene, ray, &mut sampler, &mut wl, &mut extra[first..]);
                                if alpha {
                                    extra[0] = a;
                                }
                                if !extra.iter().all(|v| v.is_finite()) {
                                    extra.fill(0.0);
                                }
                                buf.splat_extra(&scene.film.filter, (pos.x, pos.y), &extra);
                                l
                            };
                            let mut rgb = l.to_rgb(&wl);
                            // S1–S3 only in the polarized modes (a constant: no cost otherwise).
                            let mut s123 = if S::POLARIZED { camera_stokes(&l, ray.d, up, &wl) } else { [Rgb::BLACK; 3] };
                            if !rgb.is_finite() || !s123.iter().all(Rgb::is_finite) {
                                bad += 1;
                                (rgb, s123) = (Rgb::BLACK, [Rgb::BLACK; 3]);
                            }
                            if S::POLARIZED {
                                buf.splat_stokes(&scene.film.filter, (pos.x, pos.y), rgb, s123);
                            } else {
                                buf.splat(&scene.film.filter, (pos.x, pos.y), rgb);
                            }
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

    let mut film = Film::new(w, h).with_channels(scene.film.pixel_format, channel_names);
    if S::POLARIZED {
        film = film.with_stokes();
    }
    for b in &buffers {
        film.merge(b);
    }
    let samples = taken.into_inner() as f64;
    let stats = RenderStats::new(scene, spp, threads, seconds, samples, invalid.into_inner());
    Ok((film.develop(), stats))
}

/// S1, S2, S3 (as film RGB) of the light a camera ray along `d` brings back,
/// measured in the camera's frame as Mitsuba's `stokes` integrator does:
/// the reference direction is d × up (the image's right, for a camera not
/// rolled), so S1 > 0 is light polarized horizontally in the image, S2 > 0
/// along the diagonal from bottom left to top right, S3 > 0 right-circular.
fn camera_stokes<S: Spectrum>(l: &S, d: Vec3, up: Vec3, wl: &S::Wavelengths) -> [Rgb; 3] {
    let [_, s1, s2, s3] = l.stokes();
    // The light travels along −d; integrators give its Stokes vector in the
    // canonical frame of −d.
    let forward = -d;
    let target = d.cross(up);
    let r = if target.length_squared() > 1e-12 { rotate_stokes_basis(forward, stokes_basis(forward), target) } else { glam::Mat4::IDENTITY };
    // Rotating the frame mixes S1 and S2 only (glam matrices are column-major).
    let s1r = s1 * r.y_axis.y + s2 * r.z_axis.y;
    let s2r = s1 * r.y_axis.z + s2 * r.z_axis.z;
    [s1r.to_rgb(wl), s2r.to_rgb(wl), s3.to_rgb(wl)]
}

/// Light paths are split into this many batches whatever the thread count,
/// and the batches' images summed in order: the image depends on the seed only.
const PARTICLE_CHUNKS: u64 = 256;

/// Particle tracing: `width · height · spp` light paths, each splatting its
/// camera connections through the reconstruction filter (weights normalised
/// per splat, so a splat deposits exactly its value), divided by the number
/// of paths.
fn render_particles<S: Spectrum>(scene: &Scene, tracer: &ParticleTracer, options: &RenderOptions, spp: u32) -> anyhow::Result<(Image, RenderStats)> {
    check_memory(scene, S::POLARIZED)?;
    let threads = thread_count(options);
    let pool = thread_pool(threads)?;
    // Paths land anywhere on the full film; only the crop window is kept.
    let [ox, oy, w, h] = scene.film.crop;
    let offset = Vec2::new(ox as f32, oy as f32);
    let mut traced = 0u64;
    let total = w as u64 * h as u64 * spp as u64;
    let chunks = PARTICLE_CHUNKS.min(total.max(1));
    let border = (scene.film.filter.radius() + 0.5).ceil() as usize;
    let (bw, bh) = (w as usize + 2 * border, h as usize + 2 * border);
    let bar = progress_bar(options, chunks);
    let invalid = AtomicU64::new(0);
    let mut sums = vec![[0.0f64; 3]; w as usize * h as usize];

    let start = Instant::now();
    let chunk_ids: Vec<u64> = (0..chunks).collect();
    for batch in chunk_ids.chunks(threads.max(1)) {
        // A batch of chunks is the unit of work that a stop request lets finish.
        if options.stopped() {
            break;
        }
        traced += batch.iter().map(|&c| total * (c + 1) / chunks - total * c / chunks).sum::<u64>();
        let images: Vec<Vec<[f32; 3]>> = pool.install(|| {
            batch
                .par_iter()
                .map(|&c| {
                    let mut buf = vec![[0.0f32; 3]; bw * bh];
                    let mut bad = 0u64;
                    let (first, last) = (total * c / chunks, total * (c + 1) / chunks);
                    for i in first..last {
                        // Light path i is addressed as a sample of a pixel of its own numbering.
                        let light = crate::sampler::SamplerSpec { seed: scene.sampler.seed ^ 0x7061_7274_6963_6c65, ..scene.sampler };
                        let mut sampler = Sampler::start(&light, i as u32, (i >> 32) as u32 | 0x8000_0000, 0);
                        let mut wl = S::sample_wavelengths(sampler.next_1d());
                        tracer.trace::<S>(scene, &mut sampler, &mut wl, &mut |pos, rgb| {
                            if rgb.is_finite() {
                                splat_normalized(&mut buf, bw, border, &scene.film.filter, pos - offset, rgb);
                            } else {
                                bad += 1;
                            }
                        });
                    }
                    if bad > 0 {
                        invalid.fetch_add(bad, Ordering::Relaxed);
                    }
                    bar.inc(1);
                    buf
                })
                .collect()
        });
        for image in &images {
            for y in 0..h as usize {
                let row = &image[(y + border) * bw + border..(y + border) * bw + border + w as usize];
                for (dst, src) in sums[y * w as usize..(y + 1) * w as usize].iter_mut().zip(row) {
                    for k in 0..3 {
                        dst[k] += src[k] as f64;
                    }
                }
            }
        }
    }
    let seconds = start.elapsed().as_secs_f64();
    bar.finish_and_clear();
    // Divided by the paths actually traced (all of them unless stopped early).
    let scale = 1.0 / traced.max(1) as f64;
    let pixels = sums
        .iter()
        .map(|s| {
            let v = Rgb::new((s[0] * scale) as f32, (s[1] * scale) as f32, (s[2] * scale) as f32);
            if v.is_finite() { v } else { Rgb::BLACK }
        })
        .collect();
    let stats = RenderStats::new(scene, spp, threads, seconds, traced as f64, invalid.into_inner());
    let mut image = Image::new(w, h, pixels);
    image.pixel_format = scene.film.pixel_format;
    if scene.film.pixel_format.has_alpha() {
        // Light paths have no camera ray to cover a pixel: opaque everywhere.
        image.channels.push(crate::film::Channel { name: "A".into(), values: vec![1.0; (w * h) as usize] });
    }
    Ok((image, stats))
}

/// Adds `value` at film position `pos` (pixels) to a full-film buffer with a
/// `border`-pixel margin, spread over the filter's footprint with weights
/// that sum to one.
fn splat_normalized(buf: &mut [[f32; 3]], stride: usize, border: usize, filter: &Filter, pos: Vec2, value: Rgb) {
    const MAX: usize = 9;
    let r = filter.radius();
    let x0 = (pos.x - 0.5 - r).ceil() as i32;
    let y0 = (pos.y - 0.5 - r).ceil() as i32;
    let nx = (((pos.x - 0.5 + r).floor() as i32 - x0 + 1).max(0) as usize).min(MAX);
    let ny = (((pos.y - 0.5 + r).floor() as i32 - y0 + 1).max(0) as usize).min(MAX);
    let (mut wx, mut wy) = ([0.0f32; MAX], [0.0f32; MAX]);
    for i in 0..nx {
        wx[i] = filter.eval((x0 + i as i32) as f32 + 0.5 - pos.x);
    }
    for j in 0..ny {
        wy[j] = filter.eval((y0 + j as i32) as f32 + 0.5 - pos.y);
    }
    let norm = wx[..nx].iter().sum::<f32>() * wy[..ny].iter().sum::<f32>();
    if !(norm > 0.0) {
        return;
    }
    let b = border as i32;
    let height = (buf.len() / stride) as i32;
    for j in 0..ny {
        let y = y0 + j as i32 + b;
        if y < 0 || y >= height || wy[j] == 0.0 {
            continue;
        }
        for i in 0..nx {
            let x = x0 + i as i32 + b;
            if x < 0 || x >= stride as i32 {
                continue;
            }
            let wgt = wx[i] * wy[j] / norm;
            let px = &mut buf[y as usize * stride + x as usize];
            for k in 0..3 {
                px[k] += value.0[k] * wgt;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::pass_schedule;

    #[test]
    fn pass_schedule_grows_and_ends_at_the_sample_count() {
        assert_eq!(pass_schedule(256, 1), vec![256]);
        assert_eq!(pass_schedule(256, 0), vec![256]);
        assert_eq!(pass_schedule(256, 4), vec![32, 64, 128, 256]);
        for spp in 1..40 {
            for passes in 0..12 {
                let s = pass_schedule(spp, passes);
                assert_eq!(*s.last().unwrap(), spp);
                assert!(s.windows(2).all(|w| w[0] < w[1]), "{spp} {passes}: {s:?}");
                assert!(s[0] >= 1);
            }
        }
    }
}
