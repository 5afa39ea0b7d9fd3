//! The render loop: one loop for every integrator. A render is a set of
//! sample ranges of every pixel of the crop window; a range is rendered on a
//! pool of threads into [`Sink`]s (tiles of camera samples, or whole-window
//! splat buffers for light tracing) whose exact fixed-point sums add into a
//! [`FilmState`] (see [`crate::film::accumulator`]). So the image depends
//! only on the scene, the seed and the samples rendered — not on the thread
//! count, the order of the work, the split of the samples into passes, or
//! the machines that rendered them ([`render_samples`] + [`FilmState::merge`]).
//! [`render_passes`] renders in progressive passes with a callback, and
//! [`render_progressive`] also resumes from a saved state.

use crate::film::{FilmState, Image, Layout, PixelFormat, Sink, StateHeader, window_filter_mass};
use crate::integrator::{Bdpt, BdptScratch, Integrator, ParticleTracer};
use crate::spectrum::Rgb;
use crate::sampler::Sampler;
use crate::scene::Scene;
use crate::spectrum::Spectrum;
use crate::spectrum::mueller::{rotate_stokes_basis, stokes_basis};
use glam::{Vec2, Vec3};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use rayon::prelude::*;
use serde::Serialize;
use std::ops::Range;
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
    /// (tile rows; rows of light paths) not yet started are skipped, the
    /// pass under way is abandoned and the image is that of the last
    /// complete pass, or the partial first pass ([`RenderStats::interrupted`]).
    pub stop: Option<Arc<AtomicBool>>,
    /// Render in this many passes of growing sample counts (0 or 1: one
    /// pass), calling the `on_pass` callback of [`render_passes`] after each.
    pub passes: u32,
    /// Render `path` with the batched (wavefront) path tracer where it
    /// applies ([`crate::integrator::wavefront`]); `None`: as the
    /// environment variable `SNELL_WAVEFRONT` says, else in RGB only.
    pub wavefront: Option<bool>,
    /// Adaptive sampling: more samples where the image is noisier, up to
    /// the sampler's sample count (`None`: every pixel gets them all).
    pub adaptive: Option<Adaptive>,
    /// Join the passes still to come into one once they are expected (at
    /// the rate of the passes so far) to take at most this many seconds.
    /// Passes are for previews, checkpoints and interruptions, which a
    /// render about to end does not need, and each costs a film state, a
    /// merge and a developed image (≈ 10 % of a half-second render in five
    /// passes). The image is the same, bit for bit. `None`: every planned
    /// pass (a preview or a caller's callback sees each one).
    pub join_passes_under: Option<f64>,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions { threads: 0, progress: false, stop: None, passes: 1, wavefront: None, adaptive: None, join_passes_under: None }
    }
}

/// Adaptive sampling: every pixel first gets `min_spp` samples; then, in
/// rounds that double the samples per pixel up to the sampler's sample
/// count, only pixels whose estimated relative standard error (from their
/// own samples and their neighbours': [`crate::film::adaptive`]) is above
/// `threshold` get more. Pixel `p` holds samples `[0, n_p)`, its count
/// `n_p` a function of the film sums alone, so the image is the same for
/// any thread count. Camera-path integrators only (light tracing splats a
/// path anywhere on the film: a pixel's samples are not its own). Stopping
/// on the samples' own estimate biases a pixel slightly (one that happened
/// to look converged stops); see the README's "Adaptive sampling".
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Adaptive {
    /// The relative standard error at which a pixel stops: its error over
    /// √(value² + 0.01), per channel (so below 0.1 the absolute error).
    pub threshold: f64,
    /// Samples of every pixel before the first decision; 0: the default,
    /// [`Adaptive::default_min_spp`].
    pub min_spp: u32,
}

impl Adaptive {
    /// The samples every pixel gets at least, of a render of `spp` samples
    /// per pixel: an eighth, at least 16 (at most `spp`).
    pub fn default_min_spp(spp: u32) -> u32 {
        (spp / 8).max(16).min(spp)
    }

    /// The minimum of a render of `spp` samples per pixel, or an error for
    /// options that make no sense.
    pub fn min_spp_of(&self, spp: u32) -> anyhow::Result<u32> {
        if !(self.threshold.is_finite() && self.threshold > 0.0) {
            anyhow::bail!("the noise threshold must be a positive number (a relative standard error such as 0.02), not {}", self.threshold);
        }
        let min = if self.min_spp == 0 { Adaptive::default_min_spp(spp) } else { self.min_spp };
        if min > spp {
            anyhow::bail!("the adaptive minimum of {min} samples per pixel is above the render's {spp}: lower --min-spp or raise --spp");
        }
        Ok(min)
    }
}

impl RenderOptions {
    pub(crate) fn stopped(&self) -> bool {
        self.stop.as_ref().is_some_and(|s| s.load(Ordering::Relaxed))
    }
}

/// Bytes the render of `scene` holds at its peak: the workers' sinks (tiles
/// with their filter borders, or whole-window splat buffers for light
/// tracing), the film's fixed-point sums (twice when rendering in passes:
/// the passes so far and the pass under way), the developed image and an
/// encoded copy for output; `polarized` adds the Stokes sums and layers.
pub fn estimate_memory(scene: &Scene, polarized: bool) -> u64 {
    estimate(scene, polarized, true)
}

fn estimate(scene: &Scene, polarized: bool, passes: bool) -> u64 {
    let (w, h) = (scene.film.crop[2] as u64, scene.film.crop[3] as u64);
    let pixels = w * h;
    let border = (scene.film.filter.radius() + 0.5).ceil() as u64;
    let threads = rayon::current_num_threads() as u64;
    let copies = if passes { 2 } else { 1 };
    if let Integrator::Sppm(sppm) = &scene.integrator {
        let points = sppm.photons.points_per_pixel();
        let history = if sppm.camera_paths > 1 { crate::integrator::sppm::HISTORY_PER_PIXEL } else { 0 };
        let filter = crate::integrator::sppm::filter_bytes_per_pixel(&scene.film.filter);
        return pixels * (points * crate::integrator::sppm::MEMORY_PER_PIXEL + 2 * 4 * 16 + 2 * 12 + history + filter);
    }
    if let Integrator::Particle(_) = &scene.integrator {
        return copies * pixels * 3 * 16 + pixels * (12 + 12) + threads * (w + 2 * border) * (h + 2 * border) * 3 * 16;
    }
    if let Integrator::Bdpt(_) = &scene.integrator {
        // Camera sums (RGB, weight, alpha) and splats, whole-window sinks per worker.
        let stride = 4 + 3 + 1;
        return copies * pixels * stride * 16 + pixels * (16 + 12) + threads * (w + 2 * border) * (h + 2 * border) * stride * 16;
    }
    let extra = scene.integrator.channel_names().len() as u64 + 1;
    let stride = 4 + extra + if polarized { 9 } else { 0 };
    let tile = threads * (TILE as u64 + 2 * border).pow(2) * stride * 16;
    let image = if polarized { 12 * 4 } else { 12 } + 4 * extra;
    tile + pixels * (copies * stride * 16 + 2 * image)
}

/// Refuses a film whose estimated memory is above the budget
/// ([`crate::limits::max_film_bytes`]), before anything is allocated.
fn check_memory(scene: &Scene, polarized: bool, passes: bool) -> anyhow::Result<()> {
    let need = estimate(scene, polarized, passes);
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
pub(crate) fn thread_pool(threads: usize) -> anyhow::Result<rayon::ThreadPool> {
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
    /// The process's CPU seconds (user + system, all threads) over the same
    /// span as `render_seconds`: the figure to set against another
    /// renderer's render-call CPU time, startup and loading excluded.
    pub render_cpu_seconds: f64,
    pub samples_per_second: f64,
    /// Samples whose estimate was NaN or infinite, replaced by zero.
    pub invalid_samples: u64,
    /// Whether the render was stopped early ([`RenderOptions::stop`]).
    pub interrupted: bool,
    /// Samples (camera samples, or light paths) actually taken, and the
    /// number a full render takes.
    pub samples_taken: u64,
    pub samples_planned: u64,
    /// Samples per pixel in the image when every pixel has the same (the
    /// last complete pass; the full count for a finished render), 0 when the
    /// image is a partial first pass.
    pub spp_done: u32,
    /// How an adaptive render spent its samples.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub adaptive: Option<AdaptiveStats>,
}

/// What [`RenderStats`] says of an adaptive render ([`Adaptive`]).
#[derive(Clone, Debug, Serialize)]
pub struct AdaptiveStats {
    pub threshold: f64,
    pub min_spp: u32,
    /// Samples per pixel, on average over the pixels, and the fewest and
    /// most any pixel got.
    pub mean_spp: f64,
    pub least_spp: u32,
    pub most_spp: u32,
    pub rounds: Vec<AdaptiveRound>,
}

/// One round of an adaptive render.
#[derive(Clone, Debug, Serialize)]
pub struct AdaptiveRound {
    /// The samples per pixel of the pixels sampled, at the round's end.
    pub spp: u32,
    /// The fraction of the pixels sampled in the round, and its samples.
    pub active_fraction: f64,
    pub samples: u64,
}

impl RenderStats {
    /// A render of `scene` at `spp` samples per pixel that took `rendered`
    /// samples (camera samples, or light paths) in `seconds`, its image being
    /// that of `result`.
    fn new(scene: &Scene, spp: u32, threads: usize, seconds: f64, cpu_seconds: f64, rendered: u64, result: &FilmState) -> RenderStats {
        let planned = scene.film.crop[2] as u64 * scene.film.crop[3] as u64 * spp as u64;
        let taken = result.header.samples_taken;
        RenderStats {
            interrupted: taken < planned,
            samples_taken: taken,
            samples_planned: planned,
            spp_done: if result.header.complete { result.spp() } else { 0 },
            width: scene.film.crop[2],
            height: scene.film.crop[3],
            spp,
            threads,
            render_seconds: seconds,
            render_cpu_seconds: cpu_seconds,
            samples_per_second: if seconds > 0.0 { rendered as f64 / seconds } else { 0.0 },
            invalid_samples: result.header.invalid_samples,
            adaptive: None,
        }
    }
}

/// CPU seconds (user + system) the process has used so far, all threads
/// together (`getrusage`); 0 where that is not available.
pub(crate) fn process_cpu_seconds() -> f64 {
    #[cfg(unix)]
    {
        // SAFETY: getrusage only writes the struct it is given.
        let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
        if unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut usage) } == 0 {
            let seconds = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 * 1e-6;
            return seconds(usage.ru_utime) + seconds(usage.ru_stime);
        }
    }
    0.0
}

pub(crate) fn thread_count(options: &RenderOptions) -> usize {
    if options.threads == 0 { std::thread::available_parallelism().map_or(1, |n| n.get()) } else { options.threads }
}

pub(crate) fn progress_bar(options: &RenderOptions, len: u64) -> ProgressBar {
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
    /// The exact sums behind `image` (samples `[0, spp_done)`, or the ranges of a resumed distributed render): what a
    /// checkpoint saves ([`FilmState::to_bytes`]).
    pub state: &'a FilmState,
    /// The fraction of the pixels that got samples in this pass: 1, but
    /// for the later rounds of an adaptive render ([`Adaptive`]), where
    /// `spp_done` is the count of those pixels.
    pub active_fraction: f64,
}

/// The cumulative samples per pixel after each of `passes` passes of an
/// `spp`-sample render: growing passes (doubling) whose last ends at `spp`.
pub fn pass_schedule(spp: u32, passes: u32) -> Vec<u32> {
    let passes = passes.clamp(1, spp.max(1));
    // checked_shr: a shift of 64 or more (thousands of passes) is 0, not wrapped.
    let mut ends: Vec<u32> = (1..=passes).map(|k| (spp as u64).checked_shr(passes - k).unwrap_or(0) as u32).collect();
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

/// Renders in [`RenderOptions::passes`] passes (see [`pass_schedule`]):
/// pass k renders only the samples `[end_{k−1}, end_k)` of every pixel and
/// adds them, exactly, to the previous passes'. `on_pass` gets the image so
/// far after each pass. A stop request ([`RenderOptions::stop`]) abandons
/// the pass under way and returns the last complete pass (every pixel with
/// the same samples), or, if none completed, what the first pass rendered.
pub fn render_passes<S: Spectrum>(
    scene: &Scene,
    options: &RenderOptions,
    on_pass: &mut dyn FnMut(&PassReport),
) -> anyhow::Result<(Image, RenderStats)> {
    let (image, stats, _) = render_progressive::<S>(scene, options, None, on_pass)?;
    Ok((image, stats))
}

/// [`render_passes`], continuing from `resume` (a state of this scene and
/// mode holding samples `[0, k)`, e.g. from a checkpoint, or any complete
/// sample ranges, e.g. from a distributed render) if given, and also
/// returning the final [`FilmState`] (for checkpoints and merging). The
/// passes are those of [`pass_schedule`] that miss samples, each rendering
/// the samples it misses; the result is bit-identical to an uninterrupted
/// render.
pub fn render_progressive<S: Spectrum>(
    scene: &Scene,
    options: &RenderOptions,
    resume: Option<FilmState>,
    on_pass: &mut dyn FnMut(&PassReport),
) -> anyhow::Result<(Image, RenderStats, FilmState)> {
    if let Integrator::Sppm(sppm) = &scene.integrator {
        if resume.is_some() {
            anyhow::bail!("cannot resume: sppm's progressive state (per-pixel radii, photon counts and flux) is not saved in a film state; render from the start");
        }
        check_memory(scene, S::POLARIZED, true)?;
        let cpu = process_cpu_seconds();
        let (image, mut stats, state) = crate::integrator::sppm::render::<S>(scene, sppm, options, on_pass)?;
        stats.render_cpu_seconds = process_cpu_seconds() - cpu;
        return Ok((image, stats, state));
    }
    if let Some(adaptive) = &options.adaptive {
        if resume.is_some() {
            anyhow::bail!(
                "cannot resume an adaptive render: its pixels hold different sample counts, which a film state does not record; render it again"
            );
        }
        return render_adaptive::<S>(scene, options, adaptive, on_pass);
    }
    let spp = scene.sampler.sample_count;
    let threads = thread_count(options);
    // Before anything is allocated.
    check_memory(scene, S::POLARIZED, options.passes > 1 || resume.is_some())?;
    let mut state = match resume {
        Some(s) => {
            let fresh = FilmState::empty(state_header::<S>(scene));
            fresh.check_compatible(&s).map_err(|e| anyhow::anyhow!("cannot resume: {}", e.to_string().trim_start_matches("cannot merge film states: ")))?;
            if !s.header.complete {
                anyhow::bail!("cannot resume: the saved state is of a render stopped part-way through a pass (not every pixel has its samples)");
            }
            s
        }
        None => FilmState::empty(state_header::<S>(scene)),
    };
    // Each pass of the schedule renders the samples it misses (all of them
    // without a resume; those after k for a resume of [0, k)).
    let mut schedule: Vec<(u32, Vec<Range<u32>>)> = vec![];
    let mut begin = 0;
    for end in pass_schedule(spp, options.passes) {
        let holes = missing(state.ranges(), begin..end);
        if !holes.is_empty() {
            schedule.push((end, holes));
        }
        begin = end;
    }
    let pixels = scene.film.crop[2] as u64 * scene.film.crop[3] as u64;
    let bar = progress_bar(options, pixels * (spp - state.spp().min(spp)) as u64);
    let start = Instant::now();
    let cpu_start = process_cpu_seconds();
    let mut rendered = 0u64;
    let mut partial = None;
    let mut k = 0;
    while k < schedule.len() {
        let holes = &schedule[k].1;
        let mut pass = render_range::<S>(scene, options, threads, holes[0].clone(), &bar)?;
        for hole in &holes[1..] {
            if !pass.header.complete {
                break;
            }
            pass.merge(&render_range::<S>(scene, options, threads, hole.clone(), &bar)?)?;
        }
        rendered += pass.header.samples_taken;
        if !pass.header.complete {
            // Abandoned: keep the complete passes, or this one if there is none.
            if state.header.samples_taken == 0 {
                partial = Some(pass);
            }
            break;
        }
        if state.header.samples_taken == 0 && state.ranges().is_empty() {
            state = pass;
        } else {
            state.merge(&pass)?;
        }
        let image = state.develop();
        on_pass(&PassReport {
            pass: k as u32 + 1,
            passes: schedule.len() as u32,
            spp_done: state.spp(),
            spp_total: spp,
            elapsed_seconds: start.elapsed().as_secs_f64(),
            image: &image,
            state: &state,
            active_fraction: 1.0,
        });
        if options.stopped() {
            break;
        }
        k += 1;
        if let Some(limit) = options.join_passes_under {
            join_short_rest(&mut schedule, k, start.elapsed().as_secs_f64(), limit);
        }
    }
    let seconds = start.elapsed().as_secs_f64();
    let cpu_seconds = process_cpu_seconds() - cpu_start;
    bar.finish_and_clear();
    let result = partial.unwrap_or(state);
    let stats = RenderStats::new(scene, spp, threads, seconds, cpu_seconds, rendered, &result);
    Ok((result.develop(), stats, result))
}

/// An adaptive render ([`Adaptive`]): a round of `min_spp` samples of
/// every pixel, then rounds that double the samples per pixel (up to the
/// sampler's count) of the pixels still active. Each round renders the
/// first half of its samples into the `half` film and the second into
/// another; both go into the `all` film, and the two images give each
/// pixel's error estimate ([`crate::film::adaptive`]). `on_pass` is called
/// after each round. A stop request abandons the round under way (keeping
/// the first one's partial image if it is the first).
fn render_adaptive<S: Spectrum>(
    scene: &Scene,
    options: &RenderOptions,
    adaptive: &Adaptive,
    on_pass: &mut dyn FnMut(&PassReport),
) -> anyhow::Result<(Image, RenderStats, FilmState)> {
    use crate::film::adaptive::{smoothed_errors, squared_errors, still_active};
    if let Some(name) = scene.integrator.light_path_name() {
        anyhow::bail!(
            "adaptive sampling needs a camera-path integrator (path, direct, volpath, AOVs): {name} adds light paths anywhere on the film, so a pixel's samples are not its own to count"
        );
    }
    if options.passes > 1 {
        anyhow::bail!("adaptive sampling renders in its own rounds (the minimum, then doubling sample counts); it does not take a number of passes");
    }
    let spp = scene.sampler.sample_count;
    let min_spp = adaptive.min_spp_of(spp)?;
    let threads = thread_count(options);
    // The budget of a render in passes (two films); this one holds four at
    // its peak (all samples, the first halves, the round's two halves).
    check_memory(scene, S::POLARIZED, true)?;
    let [_, _, w, h] = scene.film.crop;
    let (w, h) = (w as usize, h as usize);
    let header = state_header::<S>(scene);
    let mut all = FilmState::empty(header.clone());
    let mut half = FilmState::empty(header);
    let mut active = vec![true; w * h];
    let mut counts = vec![0u32; w * h];
    let mut rounds: Vec<AdaptiveRound> = vec![];
    let mut final_image = None;
    let bar = progress_bar(options, (w * h) as u64 * spp as u64);
    let start = Instant::now();
    let cpu_start = process_cpu_seconds();
    let mut partial = None;
    let mut interrupted = false;
    // The rounds' ends in samples per pixel: the minimum, doubling, the count.
    let mut ends = vec![min_spp];
    while let Some(&last) = ends.last().filter(|&&e| e < spp) {
        ends.push(last.saturating_mul(2).min(spp));
    }
    let (mut begin, mut end) = (0, min_spp);
    loop {
        let sampled = active.iter().filter(|&&on| on).count();
        let mid = begin + (end - begin) / 2;
        let first = render_into::<S>(scene, options, threads, begin..mid, &bar, FilmState::empty(all.header.clone()), Some(&active))?;
        let second = if first.header.complete {
            render_into::<S>(scene, options, threads, mid..end, &bar, FilmState::empty(all.header.clone()), Some(&active))?
        } else {
            FilmState::empty(all.header.clone())
        };
        if !(first.header.complete && second.header.complete) {
            interrupted = true;
            if rounds.is_empty() {
                let mut p = first;
                p.merge(&second)?;
                p.header.complete = false;
                partial = Some(p);
            }
            break;
        }
        half.merge(&first)?;
        all.merge(&first)?;
        all.merge(&second)?;
        for (n, &on) in counts.iter_mut().zip(&active) {
            if on {
                *n = end;
            }
        }
        rounds.push(AdaptiveRound {
            spp: end,
            active_fraction: sampled as f64 / (w * h).max(1) as f64,
            samples: first.header.samples_taken + second.header.samples_taken,
        });
        let mut image = all.develop();
        image.channels.push(sample_counts(&counts));
        on_pass(&adaptive_report(&rounds, &ends, start, &image, &all));
        let last = end == spp || options.stopped();
        if !last {
            let errors = smoothed_errors(&squared_errors(&image, &half.develop()), w, h);
            active = still_active(&errors, &active, w, h, adaptive.threshold as f32);
        }
        final_image = Some(image);
        if last {
            interrupted = end < spp;
            break;
        }
        if !active.contains(&true) {
            break;
        }
        (begin, end) = (end, end.saturating_mul(2).min(spp));
    }
    let seconds = start.elapsed().as_secs_f64();
    let cpu_seconds = process_cpu_seconds() - cpu_start;
    bar.finish_and_clear();
    let mut result = partial.unwrap_or(all);
    let taken = result.header.samples_taken;
    // Every pixel holds samples [0, min_spp) at least, some more: no range
    // says which, so the state is marked incomplete, which keeps it from
    // being resumed or merged as if it held the same samples everywhere.
    result.header.ranges = if rounds.is_empty() { vec![] } else { vec![0..min_spp] };
    result.header.complete = false;
    let mut stats = RenderStats::new(scene, spp, threads, seconds, cpu_seconds, taken, &result);
    stats.interrupted = interrupted;
    stats.spp_done = if rounds.is_empty() { 0 } else { min_spp };
    let pixels = (w * h).max(1) as f64;
    stats.adaptive = Some(AdaptiveStats {
        threshold: adaptive.threshold,
        min_spp,
        mean_spp: counts.iter().map(|&n| n as f64).sum::<f64>() / pixels,
        least_spp: counts.iter().copied().min().unwrap_or(0),
        most_spp: counts.iter().copied().max().unwrap_or(0),
        rounds,
    });
    // The last round's image (`all` is merged only with complete rounds),
    // unless the render stopped inside the first round.
    let image = match final_image {
        Some(image) => image,
        None => {
            let mut image = result.develop();
            image.channels.push(sample_counts(&counts));
            image
        }
    };
    Ok((image, stats, result))
}

/// The per-pixel sample counts of an adaptive render, as the image's
/// channel `spp`.
fn sample_counts(counts: &[u32]) -> crate::film::Channel {
    crate::film::Channel { name: "spp".into(), values: counts.iter().map(|&n| n as f32).collect() }
}

/// The [`PassReport`] of an adaptive render after `rounds`.
/// `ends`: the rounds' ends planned.
fn adaptive_report<'a>(rounds: &[AdaptiveRound], ends: &[u32], start: Instant, image: &'a Image, state: &'a FilmState) -> PassReport<'a> {
    let last = rounds.last().map_or((0, 1.0), |r| (r.spp, r.active_fraction));
    PassReport {
        pass: rounds.len() as u32,
        passes: ends.len() as u32,
        spp_done: last.0,
        spp_total: ends.last().copied().unwrap_or(0),
        elapsed_seconds: start.elapsed().as_secs_f64(),
        image,
        state,
        active_fraction: last.1,
    }
}

/// Joins passes `done..` of `schedule` into one (their sample ranges, with
/// adjacent ones made one range) when the passes before `done`, which took
/// `elapsed` seconds, say they would take at most `limit` seconds.
fn join_short_rest(schedule: &mut Vec<(u32, Vec<Range<u32>>)>, done: usize, elapsed: f64, limit: f64) {
    if schedule.len() < done + 2 {
        return;
    }
    let samples = |passes: &[(u32, Vec<Range<u32>>)]| passes.iter().flat_map(|(_, h)| h).map(|r| r.len() as f64).sum::<f64>();
    let (rendered, rest) = (samples(&schedule[..done]), samples(&schedule[done..]));
    if rendered <= 0.0 || rest * elapsed / rendered > limit {
        return;
    }
    let end = schedule[schedule.len() - 1].0;
    let mut joined: Vec<Range<u32>> = vec![];
    for r in schedule.drain(done..).flat_map(|(_, h)| h) {
        match joined.last_mut() {
            Some(last) if last.end == r.start => last.end = r.end,
            _ => joined.push(r),
        }
    }
    schedule.push((end, joined));
}

/// The parts of `range` that none of `held` (sorted, disjoint) covers.
fn missing(held: &[Range<u32>], range: Range<u32>) -> Vec<Range<u32>> {
    let mut out = vec![];
    let mut at = range.start;
    for h in held {
        if h.end <= at || h.start >= range.end {
            continue;
        }
        if h.start > at {
            out.push(at..h.start);
        }
        at = at.max(h.end);
    }
    if at < range.end {
        out.push(at..range.end);
    }
    out
}

/// Renders samples `samples` (a range of sample indices) of every pixel of
/// the crop window and returns their accumulated sums. The states of
/// disjoint ranges [`FilmState::merge`] exactly into the state of their
/// union: rendering `[0, k)` here and `[k, n)` on another machine and
/// merging gives, bit for bit, the image of `[0, n)`. A stop request makes
/// the state incomplete (`header.complete == false`).
pub fn render_samples<S: Spectrum>(scene: &Scene, options: &RenderOptions, samples: Range<u32>) -> anyhow::Result<FilmState> {
    if samples.start > samples.end || samples.end > scene.sampler.sample_count {
        anyhow::bail!(
            "sample range {}..{} is outside the render's {} samples per pixel",
            samples.start,
            samples.end,
            scene.sampler.sample_count
        );
    }
    if let Integrator::Sppm(_) = &scene.integrator {
        anyhow::bail!("sppm's progressive state cannot be split into sample ranges or merged: render it in one piece");
    }
    check_memory(scene, S::POLARIZED, false)?;
    let pixels = scene.film.crop[2] as u64 * scene.film.crop[3] as u64;
    let bar = progress_bar(options, pixels * samples.len() as u64);
    let state = render_range::<S>(scene, options, thread_count(options), samples, &bar)?;
    bar.finish_and_clear();
    Ok(state)
}

/// Renders samples `samples` of the pixels of the tile `pixels` (x, y,
/// width, height in crop-window coordinates) and returns their sums, with
/// those the filter spreads beyond the tile ([`FilmState::empty_tile`]).
/// The states of tiles covering the window add up
/// ([`FilmState::merge_tiles`]) to exactly the state [`render_samples`]
/// returns: every sample is seeded by its pixel's place in the full film and
/// lands at the same film position, whatever the tile. For light tracing,
/// a tile is the light paths of its pixels; their splats land anywhere, so
/// its state keeps the whole window.
pub fn render_tile_samples<S: Spectrum>(scene: &Scene, options: &RenderOptions, samples: Range<u32>, pixels: [u32; 4]) -> anyhow::Result<FilmState> {
    if samples.start > samples.end || samples.end > scene.sampler.sample_count {
        anyhow::bail!(
            "sample range {}..{} is outside the render's {} samples per pixel",
            samples.start,
            samples.end,
            scene.sampler.sample_count
        );
    }
    let header = state_header::<S>(scene);
    let particle = matches!(scene.integrator, Integrator::Particle(_));
    let reach = if particle { u32::MAX } else { (scene.film.filter.radius() + 0.5).ceil() as u32 };
    // The budget holds for the tile's window (a tile exists to render a film
    // too large for one machine's memory).
    let [_, _, cw, ch] = scene.film.crop;
    let window = |n: u32, size: u32| (n as u64 + 2 * reach.min(size) as u64).min(size as u64);
    let need = window(pixels[2], cw) * window(pixels[3], ch) * header.layout.stride() as u64 * 16 * 2;
    if need > crate::limits::max_film_bytes() {
        anyhow::bail!(
            "the tile of {} × {} pixels needs about {} MB while rendering, above the budget of {} MB (use smaller tiles, or raise the budget with SNELL_MAX_FILM_BYTES)",
            pixels[2],
            pixels[3],
            need.div_ceil(1 << 20),
            crate::limits::max_film_bytes().div_ceil(1 << 20)
        );
    }
    let state = FilmState::empty_tile(header, pixels, reach)?;
    let bar = progress_bar(options, pixels[2] as u64 * pixels[3] as u64 * samples.len() as u64);
    let state = render_into::<S>(scene, options, thread_count(options), samples, &bar, state, None)?;
    bar.finish_and_clear();
    Ok(state)
}

/// A digest of what the image depends on besides the sample range: the
/// film, sampler, camera, integrator, the scene's contents (counts of
/// shapes, BSDFs, emitters) and the mode `S`.
pub fn scene_fingerprint<S: Spectrum>(scene: &Scene) -> u64 {
    let text = format!(
        "{:?}|{:?}|{:?}|{:?}|{}|{}|{}|{}",
        scene.film, scene.sampler, scene.camera, scene.integrator,
        scene.shapes.len(), scene.bsdfs.len(), scene.emitters.len(),
        std::any::type_name::<S>()
    );
    // FNV-1a, then mixed: stable across runs and machines.
    let h = text.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| (h ^ b as u64).wrapping_mul(0x0100_0000_01b3));
    crate::math::rng::mix64(h)
}

/// The header of an empty state of `scene` rendered in mode `S`.
pub(crate) fn state_header<S: Spectrum>(scene: &Scene) -> StateHeader {
    let particle = matches!(scene.integrator, Integrator::Particle(_));
    let alpha = scene.film.pixel_format.has_alpha();
    let extra = if particle { vec![] } else { alpha.then(|| "A".to_string()).into_iter().chain(scene.integrator.channel_names()).collect() };
    let format = scene.film.pixel_format;
    let format_name = PixelFormat::NAMES
        .iter()
        .find(|n| PixelFormat::from_name(n) == Some(format))
        .map_or("rgb".to_string(), |n| n.to_string());
    StateHeader {
        film_size: [scene.film.width, scene.film.height],
        crop: scene.film.crop,
        seed: scene.sampler.seed,
        sample_count: scene.sampler.sample_count,
        fingerprint: scene_fingerprint::<S>(scene),
        pixel_format: format_name,
        layout: Layout { camera: !particle, splats: particle || matches!(scene.integrator, Integrator::Bdpt(_) | Integrator::Vcm(_)), stokes: S::POLARIZED && !particle, extra },
        ranges: vec![],
        complete: true,
        samples_taken: 0,
        invalid_samples: 0,
        radiance_scale: scene.camera.radiance_scale(),
    }
}

/// One pass: samples `samples` of every pixel, by whichever loop the
/// integrator needs.
fn render_range<S: Spectrum>(scene: &Scene, options: &RenderOptions, threads: usize, samples: Range<u32>, bar: &ProgressBar) -> anyhow::Result<FilmState> {
    let state = FilmState::empty(state_header::<S>(scene));
    render_into::<S>(scene, options, threads, samples, bar, state, None)
}

/// Renders samples `samples` of the pixels of `state` (the whole crop
/// window, or a tile: [`FilmState::pixels`]) into it; with `active` (a
/// flag per pixel of the crop window, camera-path integrators only) only
/// those of the pixels flagged. The state's ranges then say which samples
/// the flagged pixels got.
fn render_into<S: Spectrum>(
    scene: &Scene,
    options: &RenderOptions,
    threads: usize,
    samples: Range<u32>,
    bar: &ProgressBar,
    mut state: FilmState,
    active: Option<&[bool]>,
) -> anyhow::Result<FilmState> {
    let pool = thread_pool(threads)?;
    if samples.is_empty() {
        return Ok(state);
    }
    let rect = state.pixels();
    if let Integrator::Path(pt) = &scene.integrator {
        if let Some(g) = &pt.guiding {
            crate::integrator::guiding::train::ensure_trained::<S>(scene, pt, g, &pool);
        }
    }
    if active.is_some() && scene.integrator.light_path_name().is_some() {
        anyhow::bail!("adaptive sampling needs a camera-path integrator");
    }
    let (taken, invalid) = if let Integrator::Particle(tracer) = &scene.integrator {
        render_particles::<S>(scene, tracer, options, &pool, &samples, rect, &mut state, bar)
    } else if let Integrator::Bdpt(bdpt) = &scene.integrator {
        if S::POLARIZED {
            anyhow::bail!("the bdpt integrator renders in the rgb and spectral modes only, not in a polarized mode; use path for polarization");
        }
        render_bdpt::<S>(scene, bdpt, options, &pool, &samples, rect, &mut state, bar)?
    } else if let Integrator::Vcm(vcm) = &scene.integrator {
        crate::integrator::vcm::render_range::<S>(scene, vcm, options, &pool, &samples, rect, &mut state, bar)?
    } else {
        render_camera::<S>(scene, options, &pool, &samples, rect, &mut state, bar, active)
    };
    let pixels = match active {
        Some(a) => a.iter().filter(|&&on| on).count() as u64,
        None => rect[2] as u64 * rect[3] as u64,
    };
    let planned = pixels * samples.len() as u64;
    state.header.samples_taken = taken;
    state.header.invalid_samples = invalid;
    state.header.complete = taken == planned;
    state.add_range(samples);
    Ok(state)
}

/// Camera paths: tiles of the crop window rendered in parallel, each into
/// its own [`Sink`] that is then added to the state (exact integer sums, so
/// the order tiles finish in does not matter). Returns the samples taken
/// and the invalid ones. With `active` (a flag per pixel of the crop
/// window), only the flagged pixels are sampled.
#[allow(clippy::too_many_arguments)]
fn render_camera<S: Spectrum>(
    scene: &Scene,
    options: &RenderOptions,
    pool: &rayon::ThreadPool,
    samples: &Range<u32>,
    rect: [u32; 4],
    state: &mut FilmState,
    bar: &ProgressBar,
    active: Option<&[bool]>,
) -> (u64, u64) {
    // The crop window (the whole film unless the scene crops): pixels are
    // numbered within it, the camera sees the full film. `rect` is the part
    // rendered (the whole window, or a tile of a distributed render).
    let [ox, oy, cw, _] = scene.film.crop;
    let [rx, ry, rw, rh] = rect;
    let taken = AtomicU64::new(0);
    let border = (scene.film.filter.radius() + 0.5).ceil() as i32;
    let up = scene.camera.up();
    // Further per-sample channels: alpha if the film has it, then the
    // integrator's (AOVs, moments). None for a plain RGB render.
    let alpha = scene.film.pixel_format.has_alpha();
    let layout = state.header.layout.clone();
    let n_extra = layout.extra.len();

    // The runs of consecutive pixels to sample in row y, columns xs.
    let runs = |y: u32, xs: Range<u32>| -> Vec<Range<u32>> {
        let Some(active) = active else { return vec![xs] };
        let on = |x: u32| active[(y * cw + x) as usize];
        let mut out: Vec<Range<u32>> = vec![];
        for x in xs.filter(|&x| on(x)) {
            match out.last_mut() {
                Some(r) if r.end == x => r.end = x + 1,
                _ => out.push(x..x + 1),
            }
        }
        out
    };
    // Path reuse groups pixels within a tile's row: wider tiles, so that
    // few groups are cut short by a tile's edge.
    let tile_w = match &scene.integrator {
        Integrator::Path(pt) if crate::integrator::path_reuse::applies::<S>(scene, pt) => TILE * 4,
        _ => TILE,
    };
    let mut tiles = vec![];
    for ty in (ry..ry + rh).step_by(TILE as usize) {
        for tx in (rx..rx + rw).step_by(tile_w as usize) {
            let (tw, th) = (tile_w.min(rx + rw - tx), TILE.min(ry + rh - ty));
            if (ty..ty + th).any(|y| !runs(y, tx..tx + tw).is_empty()) {
                tiles.push((tx, ty, tw, th));
            }
        }
    }
    let invalid = AtomicU64::new(0);
    let inv_size = Vec2::new(1.0 / scene.film.width as f32, 1.0 / scene.film.height as f32);
    let offset = Vec2::new(ox as f32, oy as f32);
    let shared = std::sync::Mutex::new(state);
    // The batched path tracer, where selected and where it applies.
    let wavefront = match &scene.integrator {
        Integrator::Path(pt) if !pt.splits() && !pt.guides() && !S::POLARIZED && n_extra == 0 && options.wavefront.unwrap_or_else(crate::integrator::wavefront::default_for::<S>) => Some(pt),
        _ => None,
    };
    let setup = crate::integrator::wavefront::CameraSetup { crop_offset: [ox, oy], inv_size };

    pool.install(|| {
        tiles.par_iter().for_each(|&(tx, ty, tw, th)| {
            let mut sink = Sink::new(&layout, tx as i32 - border, ty as i32 - border, (tw as i32 + 2 * border) as usize, (th as i32 + 2 * border) as usize);
            let mut extra = vec![0.0f32; n_extra];
            let mut bad = 0u64;
            let mut queues = wavefront.map(|_| crate::integrator::wavefront::Queues::<S>::default());
            for y in ty..ty + th {
                // A tile row is the unit of work that a stop request lets finish.
                if options.stopped() {
                    break;
                }
                let runs = runs(y, tx..tx + tw);
                let work = runs.iter().map(|r| r.len() as u64).sum::<u64>() * samples.len() as u64;
                taken.fetch_add(work, Ordering::Relaxed);
                if let (Some(pt), Some(q)) = (wavefront, queues.as_mut()) {
                    for xs in runs {
                        bad += crate::integrator::wavefront::render_row::<S>(scene, pt, y, xs, samples.clone(), &setup, q, &mut sink);
                    }
                    bar.inc(work);
                    continue;
                }
                for x in runs.into_iter().flatten() {
                    // Seeded by the pixel's place in the full film: a crop
                    // renders the same samples as the full render there.
                    for index in samples.clone() {
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
                            l
                        };
                        let mut rgb = l.to_rgb(&wl);
                        // S1–S3 only in the polarized modes (a constant: no cost otherwise).
                        let mut s123 = if S::POLARIZED { camera_stokes(&l, ray.d, up, &wl) } else { [Rgb::BLACK; 3] };
                        if !rgb.is_finite() || !s123.iter().all(Rgb::is_finite) {
                            bad += 1;
                            (rgb, s123) = (Rgb::BLACK, [Rgb::BLACK; 3]);
                        }
                        sink.add_sample(&scene.film.filter, pos, rgb, S::POLARIZED.then_some(&s123), &extra);
                    }
                }
                bar.inc(work);
            }
            if bad > 0 {
                invalid.fetch_add(bad, Ordering::Relaxed);
            }
            // Integer sums: the order in which tiles are added does not matter.
            if let Ok(mut state) = shared.lock() {
                state.add_sink(&sink);
            }
        })
    });
    (taken.into_inner(), invalid.into_inner())
}

/// The loop of the integrators that splat (`ptracer`, `bdpt`): every
/// (pixel, sample index) of `rect` is handed to `sample` (pixel x, y in the
/// full film, the sample index, the worker's [`Sink`] over the whole crop
/// window, its count of invalid values). Each worker keeps one sink (splats
/// land anywhere) and takes rows of pixels from a shared counter; the sinks'
/// integer sums are added at the end, so the image is the same for any
/// thread count and pass split. `init` makes a worker's own scratch memory.
/// Returns the samples taken and the invalid ones.
#[allow(clippy::too_many_arguments)]
pub(crate) fn render_splatting<T>(
    scene: &Scene,
    options: &RenderOptions,
    pool: &rayon::ThreadPool,
    samples: &Range<u32>,
    rect: [u32; 4],
    state: &mut FilmState,
    bar: &ProgressBar,
    init: impl Fn() -> T + Sync,
    sample: impl Fn(&mut T, u32, u32, u32, &mut Sink, &mut u64) + Sync,
) -> (u64, u64) {
    // `rect`: the pixels whose samples are taken (the window, or a tile);
    // splats land anywhere on the full film, only the crop window is kept.
    let [ox, oy, w, h] = scene.film.crop;
    let [rx, ry, rw, rh] = rect;
    let border = (scene.film.filter.radius() + 0.5).ceil() as i32;
    let layout = state.header.layout.clone();
    let next_row = AtomicU64::new(0);
    let taken = AtomicU64::new(0);
    let invalid = AtomicU64::new(0);
    let sinks: Vec<Sink> = pool.broadcast(|_| {
        let mut sink = Sink::new(&layout, -border, -border, (w as i32 + 2 * border) as usize, (h as i32 + 2 * border) as usize);
        let mut scratch = init();
        let mut bad = 0u64;
        loop {
            let y = next_row.fetch_add(1, Ordering::Relaxed);
            // A row of pixels is the unit of work that a stop request lets finish.
            if y >= rh as u64 || options.stopped() {
                break;
            }
            let y = ry + y as u32;
            taken.fetch_add(rw as u64 * samples.len() as u64, Ordering::Relaxed);
            for x in rx..rx + rw {
                for index in samples.clone() {
                    sample(&mut scratch, x + ox, y + oy, index, &mut sink, &mut bad);
                }
            }
            bar.inc(rw as u64 * samples.len() as u64);
        }
        if bad > 0 {
            invalid.fetch_add(bad, Ordering::Relaxed);
        }
        sink
    });
    for sink in &sinks {
        state.add_sink(sink);
    }
    (taken.into_inner(), invalid.into_inner())
}

/// Particle tracing: one light path per (pixel, sample index) of the crop
/// window — `width · height · spp` paths in all — each splatting its
/// camera connections through the reconstruction filter into a worker's
/// [`Sink`] over the whole window; the image divides the splat sums by the
/// number of paths. Rows of pixels are the units of work.
fn render_particles<S: Spectrum>(
    scene: &Scene,
    tracer: &ParticleTracer,
    options: &RenderOptions,
    pool: &rayon::ThreadPool,
    samples: &Range<u32>,
    rect: [u32; 4],
    state: &mut FilmState,
    bar: &ProgressBar,
) -> (u64, u64) {
    let [ox, oy, _, _] = scene.film.crop;
    let offset = Vec2::new(ox as f32, oy as f32);
    // Light paths get their own random numbers, apart from camera samples.
    let light = crate::sampler::SamplerSpec { seed: scene.sampler.seed ^ 0x7061_7274_6963_6c65, ..scene.sampler };
    render_splatting(scene, options, pool, samples, rect, state, bar, || (), |_, x, y, index, sink, bad| {
        let mut sampler = Sampler::start(&light, x, y, index);
        let mut wl = S::sample_wavelengths(sampler.next_1d());
        tracer.trace::<S>(scene, &mut sampler, &mut wl, &mut |pos, rgb| {
            if rgb.is_finite() {
                sink.splat(&scene.film.filter, pos - offset, rgb);
            } else {
                *bad += 1;
            }
        });
    })
}

/// Bidirectional path tracing: every (pixel, sample index) of the crop
/// window traces a camera subpath (from `Sampler::start` of the scene's
/// sampler) and a light subpath (from a sampler of its own seed, as
/// [`render_particles`]); the pixel estimate goes through the filter as a
/// camera sample, the light-image connections are splatted. The loop is
/// [`render_splatting`]'s (a sink over the whole window per worker, rows of
/// pixels as units of work), so the image is the same for any thread count
/// and pass split. The image divides splat sums by the number of light
/// subpaths, width · height · spp.
fn render_bdpt<S: Spectrum>(
    scene: &Scene,
    bdpt: &Bdpt,
    options: &RenderOptions,
    pool: &rayon::ThreadPool,
    samples: &Range<u32>,
    rect: [u32; 4],
    state: &mut FilmState,
    bar: &ProgressBar,
) -> anyhow::Result<(u64, u64)> {
    let crate::sensor::Camera::Perspective(camera) = &scene.camera else {
        anyhow::bail!("bdpt needs a perspective sensor");
    };
    let [ox, oy, w, h] = scene.film.crop;
    let offset = Vec2::new(ox as f32, oy as f32);
    let inv_size = Vec2::new(1.0 / scene.film.width as f32, 1.0 / scene.film.height as f32);
    let n_extra = state.header.layout.extra.len();
    let alpha = scene.film.pixel_format.has_alpha();
    let light = crate::sampler::SamplerSpec { seed: scene.sampler.seed ^ 0x6264_7074_6c69_6768, ..scene.sampler };
    // Splats weighed as the camera samples they are combined with by MIS
    // (normalized by the filter's mass inside the window, which matters at
    // its border); without MIS as `ptracer`'s.
    let mass = bdpt.mis.then(|| (window_filter_mass(&scene.film.filter, w), window_filter_mass(&scene.film.filter, h)));
    let init = || (BdptScratch::<S>::default(), vec![0.0f32; n_extra]);
    Ok(render_splatting(scene, options, pool, samples, rect, state, bar, init, |(scratch, extra), x, y, index, sink, bad| {
        let mut sampler = Sampler::start(&scene.sampler, x, y, index);
        let mut wl = S::sample_wavelengths(sampler.next_1d());
        // Crop-window coordinates, as the sink's.
        let pos = Vec2::new((x - ox) as f32, (y - oy) as f32) + sampler.next_2d();
        let ray = scene.camera.sample_ray((pos + offset) * inv_size, &mut sampler);
        let mut light_sampler = Sampler::start(&light, x, y, index);
        let (l, a) = bdpt.sample::<S>(scene, camera, ray, &mut sampler, &mut light_sampler, &mut wl, scratch, &mut |p, rgb| {
            if !rgb.is_finite() {
                *bad += 1;
            } else if let Some((mx, my)) = &mass {
                sink.splat_in_window(&scene.film.filter, p - offset, rgb, mx, my);
            } else {
                sink.splat(&scene.film.filter, p - offset, rgb);
            }
        });
        let mut rgb = l.to_rgb(&wl);
        if !rgb.is_finite() {
            *bad += 1;
            rgb = Rgb::BLACK;
        }
        if alpha && n_extra > 0 {
            extra[0] = a;
        }
        sink.add_sample(&scene.film.filter, pos, rgb, None, extra);
    }))
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

#[cfg(test)]
mod tests {
    use super::{missing, pass_schedule};

    #[test]
    fn missing_ranges_are_the_complement() {
        assert_eq!(missing(&[], 0..8), vec![0..8]);
        assert_eq!(missing(&[0..4], 0..8), vec![4..8]);
        assert_eq!(missing(&[2..3, 5..6], 0..8), vec![0..2, 3..5, 6..8]);
        assert_eq!(missing(&[0..2, 4..9], 1..8), vec![2..4]);
        assert!(missing(&[0..8], 2..6).is_empty());
    }

    #[test]
    fn pass_schedule_grows_and_ends_at_the_sample_count() {
        assert_eq!(pass_schedule(256, 1), vec![256]);
        assert_eq!(pass_schedule(256, 0), vec![256]);
        assert_eq!(pass_schedule(256, 4), vec![32, 64, 128, 256]);
        for spp in (1..40).chain([2000, 16000, 1 << 24]) {
            for passes in (0..12).chain([63, 64, 65, 100, 2000, 5000]) {
                let s = pass_schedule(spp, passes);
                assert_eq!(*s.last().unwrap(), spp);
                assert!(s.windows(2).all(|w| w[0] < w[1]), "{spp} {passes}: {s:?}");
                assert!(s[0] >= 1);
            }
        }
    }
}
