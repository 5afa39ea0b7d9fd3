//! Wavefront (batched) execution of the `path` integrator: the paths of a
//! block of camera samples advance together, stage by stage, instead of one
//! path from camera to end at a time.
//!
//! It renders the `path` integrator in the unpolarized modes (`rgb`,
//! `spectral`) on films without alpha or AOV channels: by default in the
//! `rgb` mode (where it measured faster, see below), on request in
//! `spectral`. Everything else — and `path` when it is switched off — takes
//! the scalar path tracer ([`super::path`]); both give the same image.
//!
//! | setting | values | default | meaning |
//! |---|---|---|---|
//! | `SNELL_WAVEFRONT` | `1`/`on`, `0`/`off` | unset: on in `rgb`, off in `spectral` | render `path` in batches |
//! | `RenderOptions::wavefront` | `Option<bool>` | `None` (as the variable) | the same, per render |
//! | `SNELL_WAVEFRONT_BATCH` | 1–65536 | 256 | paths per batch (for measurements; the image does not depend on it) |
//!
//! ```text
//! SNELL_WAVEFRONT=0 snell render scenes/cornell-box.xml -o scalar.exr
//! SNELL_WAVEFRONT=1 snell render scenes/cornell-box.xml --mode spectral -o batched.exr
//! ```
//!
//! # Design
//!
//! A batch is [`BATCH`] (pixel, sample index) pairs of one tile row, in the
//! order the scalar loop takes them (pixels left to right, sample indices
//! within a pixel), so the camera rays of a batch are a few pixels' worth of
//! nearly parallel rays. Its paths live in SoA queues (rays, throughput,
//! radiance, η, the previous vertex's point, normal, pdf and delta flag for
//! MIS, the BSDF context, the sampler and wavelengths of each path) and the
//! list of live paths is compacted after every stage that ends paths. All
//! paths of a batch have the same depth (they start together and each
//! surviving path takes one bounce per round), so depth is one counter.
//! One round:
//!
//! 1. extension rays of all live paths traced as one stream
//!    ([`crate::geometry::accel::Accel::intersect_stream`]); scenes with
//!    pass-through shapes, and camera rays under `hide_emitters`, take the
//!    scalar `Scene::intersect_path_into` per path (those draw random
//!    numbers while tracing);
//! 2. emission met (MIS against emitter sampling) or the environment, and
//!    the end of paths at `max_depth`;
//! 3. next-event estimation in three passes: emitter samples and their
//!    shadow rays for all paths at a smooth BSDF (the emitter chosen per
//!    path, then area lights on meshes sampled by area for all their lanes
//!    at once by a SIMD kernel, [`super::kernels::area_light_directions`]),
//!    the shadow rays traced as one stream in packets of 8
//!    ([`crate::geometry::accel::Accel::occluded_stream`]; pass-through
//!    scenes: `Scene::transmittance` per ray), then BSDF values, MIS
//!    weights and contributions. Kernel samples at a `diffuse` BSDF stay in
//!    their chunks through the shading
//!    ([`super::kernels::diffuse_light_contributions`]: weight, Lambertian
//!    value and pdf, MIS, contribution) before the shadow test, and only
//!    those with a nonzero BSDF value get a shadow ray; their contribution
//!    is added where the ray is not blocked. Samples of a `constant`
//!    environment at a `diffuse` BSDF take the same kernels (their
//!    directions drawn per lane, their rays by
//!    [`super::kernels::environment_light_rays`]), and the scalar route
//!    evaluates the BSDF before its shadow ray too: a sample the BSDF does
//!    not reflect (half of a uniform sphere's) is not traced;
//! 4. BSDF sampling with the paths grouped by BSDF (a counting sort on the
//!    shape's BSDF index), so that each BSDF's code and data stay hot while
//!    its paths are sampled (the directions of all `diffuse` lanes by a SIMD
//!    kernel, [`super::kernels::diffuse_directions`]); Russian roulette as
//!    `path`.
//!
//! The kernels ([`super::kernels`]) run 16 (AVX-512), 8 (AVX2) or 4 lanes
//! per instruction, chosen at run time as the BVH's traversal is, and
//! compute the same IEEE operations as the scalar code they stand for, so
//! the image stays the same bits. The stages are kept out of line
//! (`inline(never)`: one call per stage and round) so that a profile shows
//! each on its own.
//!
//! Each path owns its sampler ([`Sampler::start`] of its pixel and index)
//! and draws from it in the scalar path tracer's order (wavelength, pixel
//! position, camera, then per bounce: pass-through choices, the emitter
//! sample, the BSDF sample, Russian roulette), and each stage evaluates the
//! same expressions in the same order, so the image is bit-identical to the
//! scalar `path` (tests/wavefront.rs checks it). Samples go into the tile's
//! [`Sink`] (exact fixed-point sums), so the image stays the same for any
//! thread count and pass split.
//!
//! Why batches of a tile row and not whole tiles: a few hundred paths keep
//! the queues (≈ 0.4 KB per path, most of it the surface interaction and
//! the sampler) in the L2 cache, and a row is the unit of work a stop
//! request lets finish.

use super::path::PathTracer;
use super::path_reuse::{self, ReuseBuffers, ReuseLane};
use crate::bsdf::{BsdfContext, Lobe};
use super::kernels::{self, lane_vec3, AreaChunk, DiffuseChunk, LANES};
use crate::bsdf::Bsdf;
use crate::emitter::sphrect::Rectangle;
use crate::emitter::{constant, Emitter, EmitterSample, ShadingPoint};
use crate::math::sampling::{sample_cdf_reuse, square_to_uniform_sphere};
use crate::geometry::ShapeGeometry;
use crate::geometry::mesh::Mesh;
use crate::film::Sink;
use crate::geometry::accel::Hit;
use crate::geometry::{Ray, SurfaceInteraction};
use crate::math::mis_power;
use crate::sampler::{PixelSamples, Sampler};
use crate::sensor::Camera;
use crate::sensor::perspective::{RayChunk, LANES as CAMERA_LANES};
use crate::scene::Scene;
use crate::spectrum::{Rgb, Spectrum};
use crate::texture::Texture;
use glam::{Vec2, Vec3};
use std::ops::Range;
use std::sync::OnceLock;

/// Most triangles of an area light whose corners the next-event stage
/// copies into a table of its own (48 bytes a triangle and 4 of its CDF, per
/// worker's tile).
const LIGHT_TABLE_TRIANGLES: usize = 1024;

/// Paths per batch (unless `SNELL_WAVEFRONT_BATCH` says otherwise).
pub const BATCH: usize = 256;

/// Paths per batch: [`BATCH`], or `SNELL_WAVEFRONT_BATCH` (1 to 65536; for
/// measurements: the image does not depend on it). Read once.
pub fn batch_size() -> usize {
    static SIZE: OnceLock<usize> = OnceLock::new();
    *SIZE.get_or_init(|| match std::env::var("SNELL_WAVEFRONT_BATCH") {
        Ok(v) => match v.trim().parse::<usize>() {
            Ok(n) if (1..=65536).contains(&n) => n,
            _ => {
                eprintln!("warning: SNELL_WAVEFRONT_BATCH={v:?} is not a number from 1 to 65536; using {BATCH}");
                BATCH
            }
        },
        Err(_) => BATCH,
    })
}

/// What `SNELL_WAVEFRONT` asks for (read once): `Some(on)`, or `None` when
/// it is not set.
pub fn env_choice() -> Option<bool> {
    static ON: OnceLock<Option<bool>> = OnceLock::new();
    *ON.get_or_init(|| match std::env::var("SNELL_WAVEFRONT") {
        Ok(v) => match v.trim() {
            "1" | "on" | "true" | "yes" => Some(true),
            "0" | "off" | "false" | "no" => Some(false),
            other => {
                eprintln!("warning: SNELL_WAVEFRONT={other:?} is not one of 1, on, 0, off; ignored");
                None
            }
        },
        Err(_) => None,
    })
}

/// Whether `path` renders with the wavefront tracer in the mode of the
/// spectrum type `S` when the render options do not say: as
/// `SNELL_WAVEFRONT` says, else in RGB (the mode without wavelengths) only.
pub fn default_for<S: Spectrum>() -> bool {
    env_choice().unwrap_or_else(|| !S::POLARIZED && S::hero_wavelength(&S::sample_wavelengths(0.5)).is_none())
}

/// Where a camera sample's pixel lies: the crop window's offset in the full
/// film and the film's inverse size (as the scalar loop has them).
#[derive(Clone, Copy, Debug)]
pub struct CameraSetup {
    pub crop_offset: [u32; 2],
    pub inv_size: Vec2,
}

/// The SoA queues of one batch, kept by a worker and reused.
pub struct Queues<S: Spectrum> {
    sampler: Vec<Sampler>,
    wl: Vec<S::Wavelengths>,
    pos: Vec<Vec2>,
    ray: Vec<Ray>,
    throughput: Vec<S>,
    result: Vec<S>,
    eta: Vec<f32>,
    /// The previous vertex, for MIS at the next one: one record per path
    /// (written together, read together).
    prev: Vec<Prev>,
    ctx: Vec<BsdfContext>,
    si: Vec<SurfaceInteraction>,
    hit: Vec<bool>,
    /// Indices of the live paths, and the next list being built.
    live: Vec<u32>,
    next: Vec<u32>,
    /// Stream buffers: rays and hits of the live paths in `live` order.
    rays: Vec<Ray>,
    hits: Vec<Option<Hit>>,
    /// Shadow queue: path, emitter sample, its BSDF value and MIS weight
    /// (known before the ray is traced: samples the BSDF does not reflect
    /// get none), ray, answer.
    shadow_path: Vec<u32>,
    shadow_sample: Vec<EmitterSample<S>>,
    shadow_term: Vec<(S, f32)>,
    shadow_ray: Vec<Ray>,
    shadow_blocked: Vec<bool>,
    /// Per path, its 2-D emitter sample (drawn ahead in `next_event`),
    /// and where an environment map is the only emitter, the cell it
    /// picks; the environment map's lanes and their samples.
    nee_u: Vec<Vec2>,
    nee_cell: Vec<Option<(usize, usize, Vec2)>>,
    env_map_lane: Vec<u32>,
    env_map_u: Vec<Vec2>,
    env_map_cell: Vec<Option<(usize, usize, Vec2)>>,
    /// Area-light samples for the SIMD kernel: chunks of lanes, and per
    /// lane its path, the selection's probability and the emitter.
    area: Vec<AreaChunk>,
    area_meta: Vec<AreaLane>,
    /// The kernel lanes (indices into `area_meta`) shaded by
    /// [`kernels::diffuse_light_contributions`] with a contribution: their
    /// shadow rays follow the others in `shadow_ray`.
    lit_lane: Vec<u32>,
    /// Samples of a `constant` environment at `diffuse` BSDFs, for
    /// [`kernels::environment_light_rays`] and
    /// [`kernels::diffuse_light_contributions`]: chunks, each lane's path,
    /// and the lanes with a contribution (their shadow rays come last in
    /// `shadow_ray`).
    env: Vec<AreaChunk>,
    env_path: Vec<u32>,
    env_lit: Vec<u32>,
    /// Diffuse lanes for the BSDF-sampling kernel, and their paths.
    diffuse: Vec<DiffuseChunk>,
    diffuse_lane: Vec<u32>,
    /// Their BSDF weights (the reflectance), found while the lanes are
    /// gathered: once per run of the sorted lanes where it is the same for
    /// all of them (a constant colour in RGB).
    diffuse_weight: Vec<S>,
    /// Counting sort by BSDF.
    bsdf_of: Vec<u32>,
    counts: Vec<u32>,
    /// Per emitter, what next-event estimation reads of it for every
    /// sample and what does not depend on the shading point
    /// ([`LightEntry`]), made once per scene rather than once per path and
    /// bounce.
    lights: Vec<LightEntry>,
    /// With one emitter, whether `Scene::select_emitter` picks it (it then
    /// does not depend on the point); `None` with several.
    one_emitter: Option<bool>,
    /// Per shape, what next-event estimation does at its BSDF (as
    /// `Scene::bsdf` picks it): nothing, or sample an emitter, and whether
    /// the kernels shade the sample ([`SurfaceNee`]).
    shape_nee: Vec<SurfaceNee>,
    /// The scene these tables were made for (its emitters' and shapes'
    /// addresses and counts): a worker's queues serve one render, this
    /// guards the rule.
    tables_of: [usize; 4],
    /// Path reuse ([`path_reuse`]): per path its record, the paths that
    /// traced a second ray, and the buffers of the combination.
    reuse: Vec<ReuseLane<S>>,
    reached: Vec<u32>,
    reuse_buffers: ReuseBuffers,
}

/// A path's previous vertex: its point, shading normal, the density of the
/// direction sampled there, and whether that sample was a delta lobe.
#[derive(Clone, Copy, Debug)]
struct Prev {
    p: Vec3,
    n: Vec3,
    pdf: f32,
    delta: bool,
}

/// A lane of the area-light kernels: its path, the selection's
/// probability, the emitter, and whether
/// [`kernels::diffuse_light_contributions`] shades it (a `diffuse` BSDF).
#[derive(Clone, Copy, Debug)]
struct AreaLane {
    path: u32,
    pmf: f32,
    emitter: u32,
    shade: bool,
}

/// An emitter as next-event estimation meets it, made once per scene: the
/// checks and values that do not depend on the shading point, side by side
/// (each lane read them through the emitter, its shape, the mesh's lazily
/// built CDF and its index and vertex buffers).
#[derive(Clone, Debug)]
struct LightEntry {
    kind: KernelLight,
    /// A rectangle's shape, for its test of being seen wide.
    rect: Option<Rectangle>,
    /// For a light the kernel samples with at most
    /// [`LIGHT_TABLE_TRIANGLES`] triangles: the mesh's CDF by area and per
    /// triangle its corners and unit normal (else empty: the mesh is read).
    cdf: Vec<f32>,
    triangles: Vec<[Vec3; 4]>,
    /// 1 / the light's area (zero if the kernel does not sample it).
    inv_area: f32,
    /// Its radiance's channels where they are the same for every path (RGB
    /// mode, which has no wavelengths; `None` otherwise).
    radiance: Option<[f32; 4]>,
}

/// What next-event estimation does at a shape's BSDF.
#[derive(Clone, Copy, Debug)]
enum SurfaceNee {
    /// Nothing: the BSDF has no smooth lobe.
    Skip,
    /// Samples an emitter, shaded by the scalar code.
    Smooth,
    /// A `diffuse` BSDF: samples of kernel lights are shaded by the kernels;
    /// with its reflectance's channels where they are the same for every
    /// lane (a constant colour in RGB mode).
    Diffuse(Option<[f32; 4]>),
}

/// Whether an emitter is an area light the SIMD kernel samples exactly as
/// `AreaLight::sample_direct` would (see [`kernel_samples`]).
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum KernelLight {
    /// Not one: sampled by the scalar code.
    No,
    /// Always (a mesh sampled by area).
    Mesh,
    /// A rectangle: by the kernel unless the shading point sees it wide
    /// (then sampled by solid angle, by the scalar code).
    Rect,
}

impl<S: Spectrum> Default for Queues<S> {
    fn default() -> Self {
        Queues {
            sampler: Vec::with_capacity(BATCH),
            wl: Vec::with_capacity(BATCH),
            pos: Vec::with_capacity(BATCH),
            ray: Vec::with_capacity(BATCH),
            throughput: Vec::with_capacity(BATCH),
            result: Vec::with_capacity(BATCH),
            eta: Vec::with_capacity(BATCH),
            prev: Vec::with_capacity(BATCH),
            ctx: Vec::with_capacity(BATCH),
            si: Vec::with_capacity(BATCH),
            hit: Vec::with_capacity(BATCH),
            live: Vec::with_capacity(BATCH),
            next: Vec::with_capacity(BATCH),
            rays: Vec::with_capacity(BATCH),
            hits: Vec::with_capacity(BATCH),
            shadow_path: Vec::with_capacity(BATCH),
            shadow_sample: Vec::with_capacity(BATCH),
            shadow_term: Vec::with_capacity(BATCH),
            shadow_ray: Vec::with_capacity(BATCH),
            shadow_blocked: Vec::with_capacity(BATCH),
            nee_u: Vec::with_capacity(BATCH),
            nee_cell: Vec::with_capacity(BATCH),
            env_map_lane: Vec::with_capacity(BATCH),
            env_map_u: Vec::with_capacity(BATCH),
            env_map_cell: Vec::with_capacity(BATCH),
            area: Vec::new(),
            area_meta: Vec::with_capacity(BATCH),
            lit_lane: Vec::with_capacity(BATCH),
            env: Vec::new(),
            env_path: Vec::with_capacity(BATCH),
            env_lit: Vec::with_capacity(BATCH),
            diffuse: Vec::new(),
            diffuse_lane: Vec::with_capacity(BATCH),
            diffuse_weight: Vec::with_capacity(BATCH),
            bsdf_of: Vec::with_capacity(BATCH),
            counts: vec![],
            lights: vec![],
            one_emitter: None,
            shape_nee: vec![],
            tables_of: [0; 4],
            reuse: vec![],
            reached: vec![],
            reuse_buffers: ReuseBuffers::default(),
        }
    }
}

/// Renders the samples `samples` of the pixels `xs` of row `y` (crop-window
/// coordinates) with `pt` in batches, adding them to `sink`. Returns the
/// number of invalid (NaN or infinite) estimates, replaced by black.
#[allow(clippy::too_many_arguments)]
pub fn render_row<S: Spectrum>(
    scene: &Scene,
    pt: &PathTracer,
    y: u32,
    xs: Range<u32>,
    samples: Range<u32>,
    cam: &CameraSetup,
    q: &mut Queues<S>,
    sink: &mut Sink,
) -> u64 {
    let mut bad = 0;
    let size = batch_size();
    let mut batch = Vec::with_capacity(size);
    if path_reuse::applies::<S>(scene, pt) {
        // Paths in groups (a sample index, consecutive pixels), a batch
        // holding whole groups.
        let n = pt.reuse_pixels;
        let ox = cam.crop_offset[0];
        let mut groups = Vec::new();
        for i in samples {
            path_reuse::for_each_group(xs.start + ox..xs.end + ox, i, n, |first, end| {
                if batch.len() + (end - first) as usize > size.max(n as usize) {
                    bad += render_batch::<S>(scene, pt, y, &batch, &groups, cam, q, sink);
                    batch.clear();
                    groups.clear();
                }
                batch.extend((first - ox..end - ox).map(|x| (x, i)));
                groups.push(end - first);
            });
        }
        if !batch.is_empty() {
            bad += render_batch::<S>(scene, pt, y, &batch, &groups, cam, q, sink);
        }
        return bad;
    }
    for x in xs {
        for i in samples.clone() {
            batch.push((x, i));
            if batch.len() == size {
                bad += render_batch::<S>(scene, pt, y, &batch, &[], cam, q, sink);
                batch.clear();
            }
        }
    }
    if !batch.is_empty() {
        bad += render_batch::<S>(scene, pt, y, &batch, &[], cam, q, sink);
    }
    bad
}

/// One batch: camera rays, rounds of bounces until no path is left, then
/// the samples into the sink. `groups`: the lengths of the consecutive
/// groups of `jobs` that reuse paths ([`path_reuse`]), or empty.
#[allow(clippy::too_many_arguments)]
fn render_batch<S: Spectrum>(scene: &Scene, pt: &PathTracer, y: u32, jobs: &[(u32, u32)], groups: &[u32], cam: &CameraSetup, q: &mut Queues<S>, sink: &mut Sink) -> u64 {
    q.sampler.clear();
    q.wl.clear();
    q.pos.clear();
    q.ray.clear();
    let [ox, oy] = cam.crop_offset;
    let offset = Vec2::new(ox as f32, oy as f32);
    // A pinhole camera draws nothing: its rays are made after the draws,
    // a chunk of lanes at a time.
    let pinhole = match &scene.camera {
        Camera::Perspective(p) => Some(p),
        _ => None,
    };
    let level = scene.accel.simd_level();
    let mut chunk = RayChunk::default();
    let mut lanes = 0;
    // The samples of a pixel come in a row: what their samplers share is made once.
    let mut pixel = PixelSamples::new(&scene.sampler, ox, y + oy);
    for &(x, index) in jobs {
        if pixel.pixel().0 != x + ox {
            pixel = PixelSamples::new(&scene.sampler, x + ox, y + oy);
        }
        // RGB paths carry no wavelengths and cannot use the draw: skip it
        // (the sample's later draws stay the same).
        let (u, jitter) = pixel.start_camera_into(index, S::SPECTRAL, &mut q.sampler);
        let wl = S::sample_wavelengths(u);
        let pos = Vec2::new(x as f32, y as f32) + jitter;
        let film = (pos + offset) * cam.inv_size;
        match pinhole {
            Some(camera) => {
                chunk.film[0][lanes] = film.x;
                chunk.film[1][lanes] = film.y;
                lanes += 1;
                if lanes == CAMERA_LANES {
                    camera.generate_rays(level, &mut chunk);
                    q.ray.extend((0..lanes).map(|k| chunk.ray(k)));
                    lanes = 0;
                }
            }
            None => {
                let k = q.sampler.len() - 1;
                q.ray.push(scene.camera.sample_ray(film, &mut q.sampler[k]));
            }
        }
        q.wl.push(wl);
        q.pos.push(pos);
    }
    if let (Some(camera), true) = (pinhole, lanes > 0) {
        camera.generate_rays(level, &mut chunk);
        q.ray.extend((0..lanes).map(|k| chunk.ray(k)));
    }
    let n = jobs.len();
    q.throughput.clear();
    q.throughput.resize(n, S::splat(1.0));
    q.result.clear();
    q.result.resize(n, S::zero());
    q.eta.clear();
    q.eta.resize(n, 1.0);
    q.prev.clear();
    q.prev.extend(q.ray.iter().map(|r| Prev { p: r.o, n: Vec3::ZERO, pdf: 0.0, delta: true }));
    q.ctx.clear();
    q.ctx.resize(n, BsdfContext::RADIANCE);
    // Written by the trace before it is read: only grown, never cleared.
    if q.si.len() < n {
        q.si.resize(n, SurfaceInteraction::EMPTY);
    }
    q.hit.clear();
    q.hit.resize(n, false);
    q.live.clear();
    q.live.extend(0..n as u32);

    let reuse = !groups.is_empty();
    if reuse {
        q.reuse.clear();
        q.reuse.resize(n, ReuseLane::default());
        q.reached.clear();
    }
    let mut depth = 0u32;
    while !q.live.is_empty() {
        if reuse && depth == 1 {
            q.reached.clear();
            q.reached.extend_from_slice(&q.live);
        }
        trace_extension(scene, pt, depth, q);
        shade_hits(scene, pt, depth, q);
        if reuse && depth == 0 {
            path_reuse::record_first(scene, &q.live, &q.si, &q.throughput, &q.wl, &mut q.reuse);
        }
        if reuse && depth == 1 {
            path_reuse::record_second(scene, &q.reached, &q.hit, &q.si, &q.result, &mut q.reuse);
        }
        if q.live.is_empty() {
            break;
        }
        next_event(scene, q);
        sample_bsdfs(scene, pt, depth, q);
        if reuse && depth == 0 {
            path_reuse::record_bounce(&q.live, &q.throughput, &mut q.reuse);
        }
        depth += 1;
    }
    if reuse {
        path_reuse::combine(scene, groups, &q.reuse, &mut q.result, &mut q.reuse_buffers);
    }

    let mut bad = 0;
    let samples = (0..n).map(|i| {
        let rgb = q.result[i].to_rgb(&q.wl[i]);
        if rgb.is_finite() {
            (q.pos[i], rgb)
        } else {
            bad += 1;
            (q.pos[i], Rgb::BLACK)
        }
    });
    sink.add_samples(&scene.film.filter, samples);
    bad
}

/// How many hits ahead `trace_extension` prefetches a triangle's indices,
/// and its corners.
const PREFETCH_INDICES_AHEAD: usize = 16;
const PREFETCH_CORNERS_AHEAD: usize = 8;

/// Stage 1: the surfaces the live paths' rays meet, into `q.si` / `q.hit`.
#[inline(never)]
fn trace_extension<S: Spectrum>(scene: &Scene, pt: &PathTracer, depth: u32, q: &mut Queues<S>) {
    let hide = pt.hide_emitters && depth == 0;
    if scene.pass_through || hide {
        for &i in &q.live {
            let i = i as usize;
            q.hit[i] = scene.intersect_path_into(&q.ray[i], hide, &mut q.sampler[i], &mut q.si[i]);
        }
        return;
    }
    let m = q.live.len();
    // Every hit is written by the stream: the buffer is only grown.
    if q.hits.len() < m {
        q.hits.resize(m, None);
    }
    if depth == 0 {
        // All paths, in order (`render_batch`): their rays as they are.
        scene.accel.intersect_stream(&q.ray[..m], &mut q.hits[..m]);
    } else {
        q.rays.clear();
        q.rays.extend(q.live.iter().map(|&i| q.ray[i as usize]));
        scene.accel.intersect_stream(&q.rays, &mut q.hits[..m]);
    }
    // On a mesh too big for the cache a hit's record waits on two
    // dependent misses (the triangle's indices, then its corners): both are
    // prefetched a few hits ahead, so that they overlap with the work on
    // the hits before.
    let prefetch = scene.accel.prefetches();
    if prefetch {
        for h in q.hits[..m.min(PREFETCH_INDICES_AHEAD)].iter().flatten() {
            scene.prefetch_hit_indices(h);
        }
    }
    for (k, &i) in q.live.iter().enumerate() {
        if prefetch {
            if let Some(Some(h)) = q.hits[..m].get(k + PREFETCH_INDICES_AHEAD) {
                scene.prefetch_hit_indices(h);
            }
            if let Some(Some(h)) = q.hits[..m].get(k + PREFETCH_CORNERS_AHEAD) {
                scene.prefetch_hit_corners(h);
            }
        }
        let i = i as usize;
        q.hit[i] = match &q.hits[k] {
            Some(h) => {
                scene.interaction_into(h, &q.ray[i], &mut q.si[i]);
                true
            }
            None => false,
        };
    }
}

/// Stage 2: emission met along the rays (weighted by MIS against emitter
/// sampling), the environment for rays that escaped; ends paths that
/// escaped or reached `max_depth`.
#[inline(never)]
fn shade_hits<S: Spectrum>(scene: &Scene, pt: &PathTracer, depth: u32, q: &mut Queues<S>) {
    let visible = !(pt.hide_emitters && depth == 0);
    // Escaped paths meet light only from an environment.
    let sky = visible && scene.environment.is_some();
    let last = depth.saturating_add(1) >= pt.max_depth;
    q.next.clear();
    for &i in &q.live {
        let i = i as usize;
        // The previous vertex is read only where light was met (most
        // paths meet none).
        if !q.hit[i] {
            if sky {
                let pv = q.prev[i];
                let prev = ShadingPoint { p: pv.p, n: pv.n };
                if let Some((env, w)) = super::path::escaped::<S>(scene, &prev, pv.pdf, pv.delta, q.ray[i].d, &q.wl[i]) {
                    q.result[i] += q.throughput[i] * env * w;
                }
            }
            continue;
        }
        if visible {
            let si = &q.si[i];
            if let Some(le) = scene.emitted::<S>(si, &q.wl[i]) {
                let pv = q.prev[i];
                let prev = ShadingPoint { p: pv.p, n: pv.n };
                q.result[i] += q.throughput[i] * le * super::path::hit_weight(scene, &prev, pv.pdf, pv.delta, si);
            }
        }
        if !last {
            q.next.push(i as u32);
        }
    }
    std::mem::swap(&mut q.live, &mut q.next);
}

/// Stage 3: next-event estimation for every live path at a smooth BSDF:
/// emitter samples and shadow rays, the shadow rays traced as a stream,
/// then the contributions. Also cuts the wavelengths down to the hero
/// wavelength at a dispersive BSDF, as `path` does before its emitter sample.
#[inline(never)]
fn next_event<S: Spectrum>(scene: &Scene, q: &mut Queues<S>) {
    q.shadow_path.clear();
    q.shadow_sample.clear();
    q.shadow_term.clear();
    q.shadow_ray.clear();
    q.area_meta.clear();
    q.env_path.clear();
    let key = [scene.emitters.as_ptr() as usize, scene.emitters.len(), scene.shapes.as_ptr() as usize, scene.shapes.len()];
    if q.tables_of != key {
        make_tables(scene, q);
        q.tables_of = key;
    }
    // Whether the kernels shade the samples at `diffuse` BSDFs (not where
    // shadow rays pass through shapes: their transmittance scales the
    // emitter sample's weight, not the contribution).
    let shade_diffuse = !scene.pass_through && S::from_channels4([0.0; 4]).is_some();
    // Pass 1: the emitter's choice per path; area lights on meshes go to
    // the SIMD kernel, `constant` ones at `diffuse` BSDFs to the
    // environment's kernels, the others are sampled here.
    // Kernel lanes the kernels do not shade (pass 2 takes them one by one).
    let mut unshaded = 0usize;
    // The loop over local slices and field borrows of `q`, each cut to the
    // batch's length once: through `q`, every lane reloaded the vectors'
    // pointers and lengths after each push into the chunks.
    let n = q.throughput.len();
    let Queues { live, si, wl, sampler, throughput, area, area_meta, env, env_path, shadow_path, shadow_sample, shadow_term, shadow_ray, lights, shape_nee, one_emitter, nee_u, nee_cell, env_map_lane, env_map_u, env_map_cell, .. } = q;
    let (si, wl, sampler, throughput) = (&si[..n], &mut wl[..n], &mut sampler[..n], &throughput[..n]);
    let (lights, shape_nee, one_emitter) = (&lights[..], &shape_nee[..], *one_emitter);
    let mut env_lanes = EnvLanes { chunks: env, paths: env_path };
    // Pass 0: each path's 2-D emitter sample, drawn ahead (from the path's
    // own sampler: the same draw). Where an environment map is the only
    // emitter, the cells of all its samples are found together
    // (`EnvironmentMap::sample_cells`): one descent of its pyramid at a
    // time waits on each level's load and division in turn, and was a
    // fifth of a render under a map.
    nee_u.resize(n, Vec2::ZERO);
    let env_map = match (one_emitter, scene.emitters.first()) {
        (Some(true), Some(Emitter::EnvMap(e))) => Some(&**e),
        _ => None,
    };
    env_map_lane.clear();
    env_map_u.clear();
    for &i in live.iter() {
        let i = i as usize;
        if matches!(shape_nee.get(si[i].shape as usize), None | Some(SurfaceNee::Skip)) {
            continue;
        }
        let u = sampler[i].next_2d();
        nee_u[i] = u;
        if env_map.is_some() {
            env_map_lane.push(i as u32);
            env_map_u.push(u);
        }
    }
    if let Some(e) = env_map {
        nee_cell.resize(n, None);
        env_map_cell.resize(env_map_u.len(), None);
        e.sample_cells(scene.accel.simd_level(), env_map_u, env_map_cell);
        for (&i, &c) in env_map_lane.iter().zip(env_map_cell.iter()) {
            nee_cell[i as usize] = c;
        }
    }
    for &i in live.iter() {
        let i = i as usize;
        let si = &si[i];
        if S::hero_wavelength(&wl[i]).is_some() && scene.bsdf(si).disperses() {
            S::terminate_secondary(&mut wl[i]);
        }
        let wl = &wl[i];
        // As `scene.bsdf(si).lobes().intersects(Lobe::SMOOTH)`.
        let nee = shape_nee.get(si.shape as usize).copied().unwrap_or(SurfaceNee::Skip);
        if matches!(nee, SurfaceNee::Skip) {
            continue;
        }
        let u = nee_u[i];
        let selected = match one_emitter {
            Some(true) => Some((0, 1.0, u.x)),
            Some(false) => None,
            None => scene.select_emitter(u.x, &ShadingPoint::from(si)),
        };
        let Some((index, pmf, ux)) = selected else { continue };
        let Some(light) = lights.get(index) else { continue };
        // Behind a rectangle light nothing of it is lit (`Rectangle::behind`):
        // whichever way it were sampled, no contribution and no shadow ray.
        if light.rect.is_some_and(|r| r.behind(si.p)) {
            continue;
        }
        if kernel_samples(light, si.p) {
            let (a, b, c, tri_n, ux) = if light.triangles.is_empty() {
                let Some(mesh) = light_mesh(scene, index) else { continue };
                let (tri, ux) = mesh.sample_triangle(ux);
                let [a, b, c] = mesh.vertices(tri);
                (a, b, c, mesh.face_normal_at(tri, b - a, c - a), ux)
            } else {
                let (tri, ux) = sample_cdf_reuse(&light.cdf, ux);
                let [a, b, c, n] = light.triangles[tri];
                (a, b, c, n, ux)
            };
            let k = area_meta.len();
            if k % LANES == 0 && k / LANES == area.len() {
                area.push(AreaChunk::default());
            }
            let (ch, l) = (&mut area[k / LANES], k % LANES);
            for (dst, src) in [(&mut ch.p, si.p), (&mut ch.n, si.n), (&mut ch.a, a), (&mut ch.b, b), (&mut ch.c, c), (&mut ch.tri_n, tri_n)] {
                dst[0][l] = src.x;
                dst[1][l] = src.y;
                dst[2][l] = src.z;
            }
            ch.u[0][l] = ux;
            ch.u[1][l] = u.y;
            ch.inv_area[l] = light.inv_area;
            // At a `diffuse` BSDF the kernels shade the sample too (the
            // reflectance and radiance as the table has them, else
            // evaluated here).
            let mut shade = false;
            if let (true, SurfaceNee::Diffuse(refl)) = (shade_diffuse, nee) {
                let r = refl.or_else(|| match scene.bsdf(si) {
                    Bsdf::Diffuse(b) => b.reflectance.eval_spectrum::<S>(si, wl).depolarize().to_channels4(),
                    _ => None,
                });
                let e = light.radiance.or_else(|| match &scene.emitters[index] {
                    Emitter::Area(light) => light.radiance.eval::<S>(wl).to_channels4(),
                    _ => None,
                });
                if let (Some(t), Some(r), Some(e)) = (throughput[i].to_channels4(), r, e) {
                    for c in 0..4 {
                        ch.throughput[c][l] = t[c];
                        ch.reflectance[c][l] = r[c];
                        ch.radiance[c][l] = e[c];
                    }
                    ch.fn_[0][l] = si.frame.n.x;
                    ch.fn_[1][l] = si.frame.n.y;
                    ch.fn_[2][l] = si.frame.n.z;
                    ch.wi_z[l] = si.wi.z;
                    ch.pmf[l] = pmf;
                    shade = true;
                }
            }
            unshaded += usize::from(!shade);
            area_meta.push(AreaLane { path: i as u32, pmf, emitter: index as u32, shade });
        } else if shade_diffuse && environment_lane(scene, &mut env_lanes, si, wl, throughput[i], i, index, pmf, Vec2::new(ux, u.y)) {
            // In the environment kernels' chunks.
        } else if let Some((es, ray)) = match env_map {
            Some(e) => e.sample_direction_in::<S>(nee_cell[i], wl).and_then(|es| scene.emitter_ray(si, es, pmf)),
            None => scene.sample_emitter_ray_from::<S>(si, index, pmf, ux, u.y, wl),
        } {
            let Some(term) = bsdf_term(scene, si, &es, wl) else { continue };
            shadow_path.push(i as u32);
            shadow_sample.push(es);
            shadow_term.push(term);
            shadow_ray.push(ray);
        }
    }
    // Pass 2: the kernels; for the lanes they did not shade, the radiance
    // and the selection divided in as `AreaLight::sample_direct` and
    // `Scene::sample_emitter_ray` do, and their shadow rays join the scalar
    // route's. The shaded lanes' shadow rays follow, for the lanes with a
    // contribution only.
    q.lit_lane.clear();
    if !q.area_meta.is_empty() {
        let used = q.area_meta.len().div_ceil(LANES);
        let level = scene.accel.simd_level();
        kernels::area_light_directions(level, &mut q.area[..used]);
        if shade_diffuse {
            kernels::diffuse_light_contributions(level, &mut q.area[..used]);
        }
        if unshaded == 0 {
            // Every kernel lane was shaded by the kernels (the usual case):
            // chunk by chunk, the lit ones straight to their shadow rays.
            let lanes = q.area_meta.len();
            for (c, ch) in q.area[..used].iter().enumerate() {
                for l in 0..LANES.min(lanes - c * LANES) {
                    if ch.lit[l] {
                        q.lit_lane.push((c * LANES + l) as u32);
                        q.shadow_ray.push(ch.shadow_ray(l));
                    }
                }
            }
        } else {
            // Lane by lane: the shaded ones to `lit_lane`, the others
            // weighted and shaded here; then the lit lanes' shadow rays.
            for (k, lane) in q.area_meta.iter().enumerate() {
                let (ch, l) = (&q.area[k / LANES], k % LANES);
                if lane.shade {
                    if ch.lit[l] {
                        q.lit_lane.push(k as u32);
                    }
                    continue;
                }
                if !ch.ok[l] {
                    continue;
                }
                let (i, pmf, index) = (lane.path, lane.pmf, lane.emitter);
                let Emitter::Area(light) = &scene.emitters[index as usize] else { continue };
                let v = |a: &[[f32; LANES]; 3]| lane_vec3(a, l);
                let pdf = ch.pdf[l];
                let radiance: S = light.radiance.eval(&q.wl[i as usize]);
                let weight = radiance / pdf;
                let es = EmitterSample { d: v(&ch.d), dist: ch.dist[l], p: Some(v(&ch.target)), n: v(&ch.tri_n), weight: weight / pmf, pdf: pdf * pmf, delta: false };
                let Some(term) = bsdf_term(scene, &q.si[i as usize], &es, &q.wl[i as usize]) else { continue };
                q.shadow_path.push(i);
                q.shadow_sample.push(es);
                q.shadow_term.push(term);
                q.shadow_ray.push(ch.shadow_ray(l));
            }
            for &k in &q.lit_lane {
                q.shadow_ray.push(q.area[k as usize / LANES].shadow_ray(k as usize % LANES));
            }
        }
    }
    // The environment's lanes: their rays, contributions, and the shadow
    // rays of those with one.
    q.env_lit.clear();
    if !q.env_path.is_empty() {
        let used = q.env_path.len().div_ceil(LANES);
        let level = scene.accel.simd_level();
        kernels::environment_light_rays(level, &mut q.env[..used]);
        kernels::diffuse_light_contributions(level, &mut q.env[..used]);
        for k in 0..q.env_path.len() {
            let (ch, l) = (&q.env[k / LANES], k % LANES);
            if ch.lit[l] {
                q.env_lit.push(k as u32);
                q.shadow_ray.push(ch.shadow_ray(l));
            }
        }
    }
    if q.shadow_ray.is_empty() {
        return;
    }
    q.shadow_blocked.clear();
    q.shadow_blocked.resize(q.shadow_ray.len(), false);
    if !scene.pass_through {
        scene.accel.occluded_stream(&q.shadow_ray, &mut q.shadow_blocked);
    }
    // The shaded lanes' contributions where the light is seen.
    let scalar = q.shadow_path.len();
    let area_end = scalar + q.lit_lane.len();
    for (&k, &blocked) in q.lit_lane.iter().zip(&q.shadow_blocked[scalar..area_end]) {
        if blocked {
            continue;
        }
        let (k, l) = (k as usize, k as usize % LANES);
        let ch = &q.area[k / LANES];
        let i = q.area_meta[k].path as usize;
        if let Some(c) = S::from_channels4([ch.contrib[0][l], ch.contrib[1][l], ch.contrib[2][l], ch.contrib[3][l]]) {
            q.result[i] += c;
        }
    }
    for (&k, &blocked) in q.env_lit.iter().zip(&q.shadow_blocked[area_end..]) {
        if blocked {
            continue;
        }
        let (k, l) = (k as usize, k as usize % LANES);
        let ch = &q.env[k / LANES];
        let i = q.env_path[k] as usize;
        if let Some(c) = S::from_channels4([ch.contrib[0][l], ch.contrib[1][l], ch.contrib[2][l], ch.contrib[3][l]]) {
            q.result[i] += c;
        }
    }
    for k in 0..scalar {
        let i = q.shadow_path[k] as usize;
        let mut es = q.shadow_sample[k];
        if scene.pass_through {
            let tr = scene.transmittance(&q.shadow_ray[k]);
            if !(tr > 0.0) {
                continue;
            }
            if tr < 1.0 {
                es.weight = es.weight * tr;
            }
        } else if q.shadow_blocked[k] {
            continue;
        }
        let (f, w) = q.shadow_term[k];
        q.result[i] += q.throughput[i] * f * es.weight * w;
    }
}

/// The BSDF's value at `si` towards the emitter sample `es` and the
/// sample's MIS weight against BSDF sampling (as `path::next_event`);
/// `None` where the BSDF reflects nothing that way (no shadow ray then).
#[inline(always)]
fn bsdf_term<S: Spectrum>(scene: &Scene, si: &SurfaceInteraction, es: &EmitterSample<S>, wl: &S::Wavelengths) -> Option<(S, f32)> {
    let wo = si.to_local(es.d);
    let (f, pdf): (S, f32) = scene.bsdf(si).eval_pdf(&BsdfContext::RADIANCE, si, si.wi, wo, wl);
    if f.is_zero() {
        return None;
    }
    Some((f, if es.delta { 1.0 } else { mis_power(es.pdf, pdf) }))
}

/// The environment kernels' chunks and, per lane, its path.
struct EnvLanes<'a> {
    chunks: &'a mut Vec<AreaChunk>,
    paths: &'a mut Vec<u32>,
}

/// Puts path `i`'s sample of emitter `index` (picked with probability
/// `pmf`; the 2-D sample `u`) at `si` (its wavelengths `wl`, throughput
/// `throughput`) into the environment kernels' chunks if they compute it
/// exactly as `Scene::sample_emitter_ray_from` and the shading after it
/// would: a `constant` emitter at a `diffuse` BSDF. Its direction is drawn
/// here (`ConstantLight::sample_direction`'s `square_to_uniform_sphere`: a
/// libm sine and cosine, lane by lane). Whether it did.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn environment_lane<S: Spectrum>(scene: &Scene, lanes: &mut EnvLanes<'_>, si: &SurfaceInteraction, wl: &S::Wavelengths, throughput: S, i: usize, index: usize, pmf: f32, u: Vec2) -> bool {
    let (Bsdf::Diffuse(b), Emitter::Constant(light)) = (scene.bsdf(si), &scene.emitters[index]) else { return false };
    let refl = b.reflectance.eval_spectrum::<S>(si, wl).depolarize();
    let radiance: S = light.radiance.eval(wl);
    let (Some(t), Some(r), Some(e)) = (throughput.to_channels4(), refl.to_channels4(), radiance.to_channels4()) else { return false };
    let d = square_to_uniform_sphere(u);
    let k = lanes.paths.len();
    if k % LANES == 0 && k / LANES == lanes.chunks.len() {
        lanes.chunks.push(AreaChunk::default());
    }
    let (ch, l) = (&mut lanes.chunks[k / LANES], k % LANES);
    for (dst, src) in [(&mut ch.p, si.p), (&mut ch.n, si.n), (&mut ch.d, d), (&mut ch.fn_, si.frame.n)] {
        dst[0][l] = src.x;
        dst[1][l] = src.y;
        dst[2][l] = src.z;
    }
    for c in 0..4 {
        ch.throughput[c][l] = t[c];
        ch.reflectance[c][l] = r[c];
        ch.radiance[c][l] = e[c];
    }
    ch.pdf[l] = constant::PDF;
    ch.wi_z[l] = si.wi.z;
    ch.pmf[l] = pmf;
    lanes.paths.push(i as u32);
    true
}

/// The per-path columns BSDF sampling reads and writes, each cut to the
/// batch's length once: one bounds check per lane then serves them all.
struct Columns<'a, S: Spectrum> {
    si: &'a [SurfaceInteraction],
    wl: &'a [S::Wavelengths],
    sampler: &'a mut [Sampler],
    ctx: &'a mut [BsdfContext],
    throughput: &'a mut [S],
    eta: &'a mut [f32],
    prev: &'a mut [Prev],
    ray: &'a mut [Ray],
}

/// A path past its BSDF sample (weight, η, density, lobe; the next ray's
/// origin and direction), then Russian roulette from `rr_depth` on, as
/// `path` does: whether the path goes on.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn advance<S: Spectrum>(c: &mut Columns<'_, S>, i: usize, weight: S, eta: f32, pdf: f32, lobe: Lobe, o: Vec3, d: Vec3, rr: bool) -> bool {
    let si = &c.si[i];
    c.ctx[i] = c.ctx[i].following(lobe);
    c.throughput[i] *= weight;
    c.eta[i] *= eta;
    // Field by field: written as one `Prev { .. }` the record was built in
    // a stack temporary by overlapping 8- and 4-byte stores and read back
    // in wider loads, which cannot be forwarded from those stores (the
    // stall was a fifth of this stage's time on the AVX-512 machine).
    let pv = &mut c.prev[i];
    pv.p = si.p;
    pv.n = si.frame.n;
    pv.pdf = pdf;
    pv.delta = lobe.intersects(Lobe::DELTA);
    c.ray[i] = Ray::new(o, d);
    let t_max = c.throughput[i].max_component();
    if rr {
        let eta = c.eta[i];
        let p = (t_max * eta * eta).min(0.95);
        if !(c.sampler[i].next_1d() < p) {
            return false;
        }
        c.throughput[i] *= 1.0 / p;
    }
    t_max > 0.0
}

/// Whether emitter `index` is an area light that
/// [`kernels::area_light_directions`] samples exactly as
/// `AreaLight::sample_direct` would, as far as the shading point does not
/// matter: constant radiance, not black, on a mesh of positive area
/// without vertex normals (a rectangle only where it is not seen wide).
fn kernel_light(scene: &Scene, index: usize) -> KernelLight {
    let Emitter::Area(a) = &scene.emitters[index] else { return KernelLight::No };
    if a.texture.is_some() || a.is_black() {
        return KernelLight::No;
    }
    let ShapeGeometry::Mesh(m) = &scene.shapes[a.shape as usize].geometry else { return KernelLight::No };
    if m.normals.is_some() || m.triangles.is_empty() || !(m.area() > 0.0) {
        return KernelLight::No;
    }
    if a.rect.is_some() { KernelLight::Rect } else { KernelLight::Mesh }
}

/// The per-scene tables of next-event estimation: per emitter its
/// [`LightEntry`], whether a lone emitter is picked, and per shape its
/// [`SurfaceNee`].
fn make_tables<S: Spectrum>(scene: &Scene, q: &mut Queues<S>) {
    let wl = S::sample_wavelengths(0.5);
    q.lights.clear();
    for e in 0..scene.emitters.len() {
        let kind = kernel_light(scene, e);
        let mesh = if kind == KernelLight::No { None } else { light_mesh(scene, e) };
        let area_light = match &scene.emitters[e] {
            Emitter::Area(a) => Some(a),
            _ => None,
        };
        // (Small lights only: the table is made per tile.)
        let small = mesh.filter(|m| m.triangles.len() <= LIGHT_TABLE_TRIANGLES);
        q.lights.push(LightEntry {
            kind,
            rect: area_light.and_then(|a| a.rect),
            cdf: small.map_or_else(Vec::new, |m| m.triangle_cdf().to_vec()),
            triangles: small.map_or_else(Vec::new, |m| {
                (0..m.triangles.len())
                    .map(|t| {
                        let [a, b, c] = m.vertices(t);
                        [a, b, c, m.face_normal_at(t, b - a, c - a)]
                    })
                    .collect()
            }),
            inv_area: mesh.map_or(0.0, |m| 1.0 / m.area()),
            // Without wavelengths the radiance is one colour for all paths.
            radiance: area_light.filter(|_| !S::SPECTRAL).and_then(|a| a.radiance.eval::<S>(&wl).to_channels4()),
        });
    }
    // With one emitter the choice does not depend on the point or the
    // sample (`LightSelector::select`).
    q.one_emitter = (scene.emitters.len() == 1).then(|| scene.select_emitter(0.0, &ShadingPoint::at(Vec3::ZERO)).is_some());
    q.shape_nee.clear();
    q.shape_nee.extend(scene.shapes.iter().map(|sh| {
        let Some(b) = scene.bsdfs.get(sh.bsdf as usize) else { return SurfaceNee::Skip };
        let b = if sh.pass_through { b.surface() } else { b };
        if !b.lobes().intersects(Lobe::SMOOTH) {
            return SurfaceNee::Skip;
        }
        match b {
            // A constant colour is the same for every lane in RGB, where
            // there are no wavelengths for it to depend on.
            Bsdf::Diffuse(d) => SurfaceNee::Diffuse(match d.reflectance {
                Texture::Constant(..) if !S::SPECTRAL => d.reflectance.eval_spectrum::<S>(&SurfaceInteraction::EMPTY, &wl).depolarize().to_channels4(),
                _ => None,
            }),
            _ => SurfaceNee::Smooth,
        }
    }));
}

/// The mesh emitter `index` lies on, if it is an area light on one.
fn light_mesh(scene: &Scene, index: usize) -> Option<&Mesh> {
    let Emitter::Area(a) = &scene.emitters[index] else { return None };
    let ShapeGeometry::Mesh(m) = &scene.shapes.get(a.shape as usize)?.geometry else { return None };
    Some(m)
}

/// Whether [`kernels::area_light_directions`] samples `light` from `p`
/// exactly as `AreaLight::sample_direct` would: an emitter
/// [`kernel_light`] accepts, and a rectangle not seen wide from `p`. One
/// seen wide is sampled by solid angle (or, where its spherical rectangle
/// fails, by area) by the scalar code, which decides between the two
/// itself: deciding here too computed the spherical rectangle twice.
#[inline(always)]
fn kernel_samples(light: &LightEntry, p: Vec3) -> bool {
    match light.kind {
        KernelLight::No => false,
        KernelLight::Mesh => true,
        KernelLight::Rect => light.rect.is_none_or(|r| !r.seen_wide(p)),
    }
}

/// Stage 4: BSDF sampling of the live paths grouped by BSDF, the next
/// rays, and Russian roulette; the survivors become the live list.
#[inline(never)]
fn sample_bsdfs<S: Spectrum>(scene: &Scene, pt: &PathTracer, depth: u32, q: &mut Queues<S>) {
    // Counting sort of the live paths by their shape's BSDF index.
    // (Over local slices: through `q`, every push and count reloaded the
    // vectors' pointers and lengths, ≈ 60 instructions a lane.)
    let kinds = scene.bsdfs.len();
    q.counts.clear();
    q.counts.resize(kinds + 1, 0);
    q.bsdf_of.clear();
    let (si, shapes) = (&q.si[..], &scene.shapes[..]);
    q.bsdf_of.extend(q.live.iter().map(|&i| (shapes[si[i as usize].shape as usize].bsdf as usize).min(kinds) as u32));
    let counts = &mut q.counts[..];
    for &b in &q.bsdf_of {
        counts[b as usize + 1] += 1;
    }
    for k in 1..counts.len() {
        counts[k] += counts[k - 1];
    }
    q.next.clear();
    q.next.resize(q.live.len(), 0);
    let next = &mut q.next[..];
    for (&i, &b) in q.live.iter().zip(&q.bsdf_of) {
        let slot = &mut counts[b as usize];
        next[*slot as usize] = i;
        *slot += 1;
    }
    std::mem::swap(&mut q.live, &mut q.next);

    let rr = depth + 1 >= pt.rr_depth;
    q.next.clear();
    q.diffuse_lane.clear();
    q.diffuse_weight.clear();
    let live = std::mem::take(&mut q.live);
    let n = q.throughput.len();
    let mut c = Columns::<S> {
        si: &q.si[..n],
        wl: &q.wl[..n],
        sampler: &mut q.sampler[..n],
        ctx: &mut q.ctx[..n],
        throughput: &mut q.throughput[..n],
        eta: &mut q.eta[..n],
        prev: &mut q.prev[..n],
        ray: &mut q.ray[..n],
    };
    // The sorted lanes in runs of one BSDF index (`counts[b]` is now the
    // end of run b).
    let mut start = 0;
    for b in 0..q.counts.len() {
        let end = q.counts[b] as usize;
        let run = &live[start..end];
        start = end;
        let Some(&first) = run.first() else { continue };
        // The run's BSDF where no shape passes rays through (else each
        // lane's, `Scene::bsdf` of its shape), and its weight if constant:
        // a constant reflectance is the same for every lane in RGB, where
        // there are no wavelengths for it to depend on.
        let run_bsdf = if scene.pass_through { None } else { scene.bsdfs.get(b) };
        let run_weight: Option<S> = match run_bsdf {
            Some(Bsdf::Diffuse(d)) if !S::SPECTRAL && matches!(d.reflectance, Texture::Constant(..)) => {
                let first = first as usize;
                Some(d.reflectance.eval_spectrum::<S>(&c.si[first], &c.wl[first]).depolarize())
            }
            _ => None,
        };
        for &i in run {
            let i = i as usize;
            let si = &c.si[i];
            let bsdf = match run_bsdf {
                Some(b) => b,
                None => scene.bsdf(si),
            };
            let sampler = &mut c.sampler[i];
            // Diffuse lanes: their directions by the SIMD kernel below.
            // They do not use the 1-D draw (the lobe choice): it is skipped,
            // the 2-D draw after it stays the same.
            if let Bsdf::Diffuse(db) = bsdf {
                if !(si.wi.z <= 0.0) && c.ctx[i].wants(Lobe::DIFFUSE_REFLECTION) {
                    sampler.skip_1d();
                    let u2 = sampler.next_2d();
                    let k = q.diffuse_lane.len();
                    if k % LANES == 0 && k / LANES == q.diffuse.len() {
                        q.diffuse.push(DiffuseChunk::default());
                    }
                    let (ch, l) = (&mut q.diffuse[k / LANES], k % LANES);
                    for (dst, src) in [(&mut ch.s, si.frame.s), (&mut ch.t, si.frame.t), (&mut ch.fn_, si.frame.n), (&mut ch.p, si.p), (&mut ch.n, si.n)] {
                        dst[0][l] = src.x;
                        dst[1][l] = src.y;
                        dst[2][l] = src.z;
                    }
                    ch.u[0][l] = u2.x;
                    ch.u[1][l] = u2.y;
                    q.diffuse_lane.push(i as u32);
                    let weight = match run_weight {
                        Some(w) => w,
                        None => db.reflectance.eval_spectrum::<S>(si, &c.wl[i]).depolarize(),
                    };
                    q.diffuse_weight.push(weight);
                    continue;
                }
            }
            let (u1, u2) = (sampler.next_1d(), sampler.next_2d());
            let Some(bs) = bsdf.sample_inline::<S>(&c.ctx[i], si, si.wi, u1, u2, &c.wl[i]) else { continue };
            let d = si.to_world(bs.wo);
            let o = si.spawn_origin(d);
            if advance(&mut c, i, bs.weight, bs.eta, bs.pdf, bs.lobe, o, d, rr) {
                q.next.push(i as u32);
            }
        }
    }
    if !q.diffuse_lane.is_empty() {
        let used = q.diffuse_lane.len().div_ceil(LANES);
        kernels::diffuse_directions(scene.accel.simd_level(), &mut q.diffuse[..used]);
        for (k, (&i, &weight)) in q.diffuse_lane.iter().zip(&q.diffuse_weight).enumerate() {
            let i = i as usize;
            let (ch, l) = (&q.diffuse[k / LANES], k % LANES);
            if !ch.ok[l] {
                continue;
            }
            let (pdf, o, d) = (ch.pdf[l], lane_vec3(&ch.o, l), lane_vec3(&ch.d, l));
            if advance(&mut c, i, weight, 1.0, pdf, Lobe::DIFFUSE_REFLECTION, o, d, rr) {
                q.next.push(i as u32);
            }
        }
    }
    q.live = live;
    std::mem::swap(&mut q.live, &mut q.next);
}
