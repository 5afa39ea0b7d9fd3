//! `sppm` — stochastic progressive photon mapping (Hachisuka & Jensen 2009).
//!
//! Renders the light that a path tracer cannot find: specular–diffuse–
//! specular paths such as a caustic seen through glass or the floor of a
//! pool seen through its surface, where a camera path would have to hit a
//! small light after a chain of delta (mirror, refraction) bounces.
//!
//! The light is split in two by the path's vertex just before the visible
//! point (the camera path's first non-delta surface): light reaching the
//! visible point straight from a delta bounce (a mirror, a refraction: a
//! caustic) is gathered from photons; all other light is path traced from
//! the visible point. Jensen's caustic photon map, made progressive: photons
//! go only where a path tracer cannot, and the smooth indirect light keeps
//! a path tracer's noise without a photon map's blur. With
//! `photons = indirect` the split is classic SPPM's instead: photons carry
//! all light that bounced at least once before the visible point, and only
//! the direct light there is sampled. With `photons = all_caustics` the
//! caustic photons are gathered at every smooth vertex of the camera path,
//! not only at the visible point: the light a path tracer finds worst
//! after the first bounce too (a small light met through glass from a
//! diffuse wall lit by a caustic) comes from photons, and the camera path
//! stops wherever a delta bounce follows a smooth one. The later vertices
//! are not tracked from one iteration to the next, so they take a radius
//! shared by all (`vertex_radius_scale` × the visible points' mean initial
//! radius in the first iteration), shrunk as VCM shrinks its radius:
//! r_k² = r_1² · k^(α − 1); each iteration's estimate there is added to
//! the pixel's path-traced light. With `photons = final_gather` (Jensen's
//! final gather) the visible point gathers the caustic photons as with
//! `caustics`, and the camera path's one smooth bounce from it finds a
//! gather point x2 (if x2 has a smooth lobe; light leaving x2 by a delta
//! lobe is a caustic at the visible point): there the emitted light and
//! the direct light (emitter sampling and one BSDF sample of the smooth
//! lobes, weighted by MIS) are path traced, and all photons that bounced
//! at least once before x2 (caustics included) are gathered with the
//! later vertices' radius of `all_caustics`; the path ends one vertex
//! after x2. The photon map's blur is then seen only through a diffuse
//! bounce, and the camera path's cost ends at two vertices.
//!
//! Each iteration (one per sample of the sampler: `sample_count` iterations)
//!
//! 1. traces one camera path per pixel through delta bounces (mirrors,
//!    smooth dielectrics, dispersive glass with its hero wavelength) to its
//!    first non-delta surface, the pixel's *visible point*, adding the
//!    emission met on the way and the direct light there (one emitter
//!    sample). On a BSDF with both delta and smooth lobes (smooth plastic)
//!    the path stops there or follows the delta lobes with probability ½
//!    each (weighted by 2). From the visible point it goes on as `path` does
//!    (the same vertex shading: emitter sampling and BSDF sampling weighted
//!    by MIS; only the smooth lobes at the visible point) and stops where
//!    the vertex after the visible point scatters by a delta lobe: that
//!    light is the photons' (`photons = indirect`: it stops at the vertex
//!    after the visible point, having counted the emission met there);
//! 2. traces `photon_count` light paths from the emitters (started by
//!    [`crate::scene::Scene::sample_emission`], as `ptracer` and `bdpt` start
//!    theirs; importance transport,
//!    Veach's shading-normal correction as `ptracer`); at every non-delta
//!    surface reached straight from a delta bounce (`photons = indirect`:
//!    after any bounce) each photon adds
//!    β_cam · f · Φ to the statistics of the visible points within their
//!    pixel's radius R (a uniform hash grid of the visible points; no photon
//!    is stored);
//! 3. updates every pixel that received M > 0 photons (α = `alpha`):
//!    N ← N + αM, R ← R·√((N + αM)/(N + M)), τ ← (τ + Φ)·R'²/R².
//!
//! After k iterations a pixel shows D/k + τ / (k · `photon_count` · π R²),
//! D the sum of the camera passes' path-traced light. The radius shrinks so
//! that bias and variance both vanish: the error against the true image
//! falls as the iterations grow (the bias like R², the variance like
//! 1/(k R²)). A pixel's initial radius is `radius_footprints` (1.5) × its footprint at its first
//! visible point (the camera's pixel spread times the camera path's length),
//! as small as the pixel grid can resolve: Mitsuba 0.6's scene-wide guess
//! (5 × bounding radius / film size) blurred the caustics of large scenes
//! over tens of pixels.
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `photon_count` | integer | -1 | photons traced per iteration; -1 = as many as the film has pixels (Mitsuba 0.6: 250000; photons only carry caustics here, so fewer do) |
//! | `initial_radius` | float | 0 | initial gather radius in world units; 0 = 1.5 pixel footprints at each pixel's first visible point (5 × bounding-sphere radius / larger film side where the camera gives no footprint) |
//! | `alpha` | float | 2/3 | fraction of new photons kept per iteration, in (0, 1); Mitsuba 0.6 defaults to 0.7, the issue asks for 2/3 |
//! | `max_depth` | integer | -1 | longest path in segments (camera segments plus photon segments); -1 = unlimited, 1 = emitters seen directly, 2 = direct light |
//! | `rr_depth` | integer | 5 | depth at which Russian roulette starts (camera and light paths each) |
//! | `granularity` | integer | 0 | photons per unit of parallel work; 0 = automatic. No effect on the image |
//! | `max_passes` | integer | -1 | iterations; -1 = the sampler's `sample_count` (a command-line sample count wins over both) |
//! | `photons` | string | `caustics` | the light photons carry: `caustics` (arriving at the visible point straight from a delta bounce; the rest is path traced), `all_caustics` (arriving straight from a delta bounce at any smooth vertex of the camera path from the visible point on), `indirect` (everything that bounced before the visible point: classic SPPM, only direct light sampled there), `final_gather` (caustics at the visible point; everything that bounced before the vertex after it gathered there: Jensen's final gather), `none` (no photons: the image without caustics, for measuring the split; not a complete image) |
//! | `vertex_radius_scale` | float | 4 (`final_gather`: 2) | `photons = all_caustics` or `final_gather`: the radius at the camera path's later vertices in the first iteration, in units of the visible points' mean initial radius |
//! | `radius_footprints` | float | 1.5 | the automatic initial radius (`initial_radius` 0) in pixel footprints at each pixel's first visible point |
//! | `camera_paths` | integer | 1 | camera paths per pixel and iteration, 1–64, where the light before the visible point varies: each counts the light it meets up to its visible point (emitters seen straight, in mirrors, through glass), and the first goes on from its visible point as the only one does (see below) |
//!
//! ```xml
//! <integrator type="sppm">
//!     <integer name="photon_count" value="100000"/>
//!     <float name="initial_radius" value="0.01"/>
//!     <integer name="max_depth" value="8"/>
//! </integrator>
//! ```
//!
//! `camera_paths` = n > 1: the light a camera path meets before its
//! visible point (a small emitter seen through a gem's facets, its image a
//! few pixels or less) is the part of the image that wants many samples a
//! pixel, and the cheap one: such paths stop at their visible points. In
//! a pixel where that light varied in the earlier iterations and made at
//! least half of its main paths' variance (and in the first two
//! iterations everywhere), n − 1 more paths estimate it, averaged with the
//! main path's; the main path alone goes on (direct light, final gather,
//! photons). Unbiased: each path's part before its visible point has the
//! same expectation, and whether a pixel takes more paths depends on
//! earlier iterations only. The other paths draw from the scene's sampler
//! kind with a seed of their own, at consecutive indices per pixel, so the
//! main paths are those of one path and n = 1 gives the same image as
//! before. Measured (docs/performance.md): on the diamond 3× the
//! efficiency at 8–16 paths; level on the glass of water and the caustic
//! box, whose noise is elsewhere. Rare paths to an emitter in a pixel
//! that never showed them stay single samples (no earlier variation calls
//! for more paths there).
//!
//! Limits and behaviour:
//! - Modes `rgb` and `spectral` (all camera and light paths of one
//!   iteration share its wavelengths, as pbrt-v4 does, so a photon and a
//!   visible point see the same ones); the polarized modes are refused.
//! - Photons start on every kind of emitter ([`crate::emitter::Emitter::sample_ray`]):
//!   finite ones sample their own rays; emitters at infinity (`constant`,
//!   `envmap`, `directional`) send photons from a disk of the scene's
//!   bounding sphere (most of which land where no camera looks in a large
//!   scene: such scenes need more photons).
//! - The film's `rfilter` counts as for `path`: each camera path starts
//!   uniformly in its pixel, and its light reaches the pixels around by
//!   the filter's weight, as a splatting film adds a sample (`Splat`).
//!   The photons' flux found at a pixel's visible point is kept per pixel
//!   it reaches (τ per slot, shrunk with that pixel's radius), so a pixel
//!   is Σ w·L over the paths that reach it over the filter's mass inside
//!   the crop window, what `path`'s Σ w·L / Σ w converges to (negative
//!   lobes included). A wide filter smooths the noise as it does for
//!   `path` (the caustic box with the scene's Gaussian: 5.5× `path`'s
//!   efficiency, docs/performance.md); τ takes (2⌈r − ½⌉ + 1)² slots a
//!   pixel (a box: 1, Mitsuba's Gaussian: 25).
//! - The per-pixel state (R, N, τ) is not a sum of samples: a render cannot
//!   be split into sample ranges, merged ([`crate::film::FilmState::merge`])
//!   or resumed from a checkpoint; those refuse. The film state of a pass
//!   holds the image so far (for writing it out).
//! - Deterministic: the image depends on the scene, the seed and the
//!   iteration count only — identical for any thread count and pass split
//!   (photon flux is summed in fixed point with dithered rounding, so the
//!   order of the sums does not matter).
//! - Memory: per pixel one visible point, its statistics and at most eight
//!   grid entries ([`MEMORY_PER_PIXEL`] bytes in all); photons are not
//!   stored, so memory does not grow with `photon_count`. With
//!   `photons = all_caustics` or `final_gather` each later vertex of an
//!   iteration's camera paths takes as much again (`final_gather`: at
//!   most one a pixel). The film's filter adds 24 bytes a pixel per slot
//!   of τ ([`filter_bytes_per_pixel`]: 608 for Mitsuba's Gaussian, 32
//!   for a box).

use crate::bsdf::{Bsdf, BsdfContext, Lobe};
use crate::film::{window_filter_mass, FilmState, Filter, FilterKind, Image, Sink};
use crate::geometry::{Ray, SurfaceInteraction};
use crate::emitter::ShadingPoint;
use crate::integrator::path::{escaped, hit_weight, next_event};
use crate::math::rounding::{floor_i32, floor_i64};
use crate::integrator::ptracer::shading_correction;
use crate::math::rng::mix64;
use crate::math::INV_PI;
use crate::render::{PassReport, RenderOptions, RenderStats};
use crate::sampler::{Sampler, SamplerKind, SamplerSpec};
use crate::scene::Scene;
use crate::spectrum::{Rgb, Sampled, Spectrum};
use glam::{Vec2, Vec3};
use rayon::prelude::*;
use std::sync::atomic::{AtomicI64, AtomicU32, Ordering};
use std::time::Instant;

#[derive(Clone, Debug)]
pub struct Sppm {
    /// Photons per iteration; 0 = automatic (as many as the film's pixels).
    pub photon_count: u32,
    /// World units; 0 = automatic ([`Sppm::radius`]).
    pub initial_radius: f32,
    pub alpha: f32,
    /// `u32::MAX` for unlimited.
    pub max_depth: u32,
    pub rr_depth: u32,
    /// Photons per unit of parallel work (0 = automatic).
    pub granularity: u32,
    /// Iterations asked for by `max_passes` (0: the sampler's sample count);
    /// the loader sets the sample count from it.
    pub max_passes: u32,
    /// Which light the photons carry (the camera paths trace the rest).
    pub photons: Photons,
    /// The automatic initial radius in pixel footprints at the visible point.
    pub radius_footprints: f32,
    /// `photons = all_caustics` or `final_gather`: the first iteration's gather radius at the
    /// camera path's later vertices, in units of the visible points' mean
    /// initial radius.
    pub vertex_radius_scale: f32,
    /// Camera paths a pixel and iteration (`camera_paths`): one goes on
    /// from its visible point; all of them count the light they meet up to
    /// theirs.
    pub camera_paths: u32,
}

/// The split of the light between photons and camera paths (`photons`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Photons {
    /// Photons arriving straight from a delta bounce (Jensen's caustic map).
    Caustics,
    /// The same photons gathered at every non-delta vertex of the camera
    /// path, not only at the visible point.
    AllCaustics,
    /// Photons after any bounce: all indirect light (classic SPPM).
    Indirect,
    /// Jensen's final gather: caustic photons at the visible point, and
    /// all photons that bounced at least once at the vertex after it,
    /// where the camera path ends after one more direct-light estimate.
    FinalGather,
    /// No photons: the image without the caustics (a diagnostic).
    None,
}

impl Photons {
    pub const NAMES: [&'static str; 5] = ["caustics", "all_caustics", "indirect", "final_gather", "none"];

    pub fn from_name(name: &str) -> Option<Photons> {
        match name {
            "caustics" => Some(Photons::Caustics),
            "all_caustics" => Some(Photons::AllCaustics),
            "indirect" => Some(Photons::Indirect),
            "final_gather" => Some(Photons::FinalGather),
            "none" => Some(Photons::None),
            _ => None,
        }
    }

    /// Whether photons are gathered at camera-path vertices after the
    /// visible point too (with the shared, scheduled radius).
    pub fn gathers_later(self) -> bool {
        matches!(self, Photons::AllCaustics | Photons::FinalGather)
    }

    /// The default `vertex_radius_scale`: the final gather's point sees the
    /// photons through one more diffuse bounce, where a smaller radius pays
    /// (caustic box 64²: error 9.3e-4 at 2 against 9.7e-4 at 4 for 0.7× the
    /// CPU).
    pub fn default_vertex_radius_scale(self) -> f32 {
        if self == Photons::FinalGather { 2.0 } else { 4.0 }
    }

    /// Gather points a pixel, for the memory estimate: `all_caustics`
    /// gathers at every later smooth vertex (counted as three a pixel;
    /// measured at max_depth 8: Cornell box 2.2, caustic box 1.6, glass of
    /// water 0.4), `final_gather` at one at most.
    pub fn points_per_pixel(self) -> u64 {
        match self {
            Photons::AllCaustics => 4,
            Photons::FinalGather => 2,
            _ => 1,
        }
    }
}

/// A pixel's visible point in one iteration: where its camera path met its
/// first non-delta surface, the path's throughput and wavelengths there, and
/// the camera segments it took.
struct VisiblePoint<S: Spectrum> {
    si: SurfaceInteraction,
    beta: S,
    wl: S::Wavelengths,
    depth: u32,
    /// Length of the camera path to the point (sum of its segments).
    distance: f32,
}

/// What a camera path found: its light (RGB), the part of it met up to and
/// including its visible point (emitters seen straight or through delta
/// bounces; all of it if it reached none), and the visible point.
struct CameraPath<S: Spectrum> {
    light: Rgb,
    before_vp: Rgb,
    vp: Option<VisiblePoint<S>>,
    /// Where on the film the path started (film pixels).
    pos: Vec2,
}

/// `camera_paths`: what a pixel's camera paths found in the earlier
/// iterations, as running sums of luminance (R + G + B): their light up to
/// their visible points (all paths), and the main paths' whole light.
#[derive(Clone, Copy, Default)]
struct PathHistory {
    before: [f64; 3],
    main: [f64; 3],
}

impl PathHistory {
    /// Whether iteration `iteration` traces the other paths: in the first
    /// two everywhere, then where the light before the visible point has
    /// varied and made at least half of the main paths' variance.
    fn wants_more(&self, iteration: u32) -> bool {
        let variance = |[n, sum, sq]: [f64; 3]| (sq - sum * sum / n.max(1.0)) / n.max(1.0);
        let before = variance(self.before);
        iteration < 2 || (before > 1e-9 * self.before[2] / self.before[0].max(1.0) && before > 0.5 * variance(self.main))
    }

    fn add_before(&mut self, light: Rgb) {
        Self::add(&mut self.before, light);
    }

    fn add_main(&mut self, light: Rgb) {
        Self::add(&mut self.main, light);
    }

    fn add(sums: &mut [f64; 3], light: Rgb) {
        let l = (light[0] + light[1] + light[2]) as f64;
        *sums = [sums[0] + 1.0, sums[1] + l, sums[2] + l * l];
    }
}

/// A pixel's progressive statistics.
#[derive(Clone, Copy)]
struct PixelStats {
    radius: f64,
    n: f64,
    /// Sum over iterations of the camera passes' emitted and direct light.
    direct: [f64; 3],
}

/// Bytes a render holds per pixel besides the film: visible point, grid
/// entries (at most eight, and the points gathered while building),
/// statistics, the photon sums of an iteration and its packed targets.
pub const MEMORY_PER_PIXEL: u64 = (std::mem::size_of::<Option<VisiblePoint<Sampled>>>()
    + 8 * std::mem::size_of::<GridEntry>()
    + std::mem::size_of::<(GridEntry, f32)>()
    + 4
    + std::mem::size_of::<PixelStats>()
    + std::mem::size_of::<PointSums>()
    + std::mem::size_of::<Option<Target<Sampled>>>()) as u64;

/// Bytes a pixel's `camera_paths` history takes (only with `camera_paths` > 1).
pub const HISTORY_PER_PIXEL: u64 = std::mem::size_of::<PathHistory>() as u64;

/// Photon flux is summed per pixel in fixed point: units of 2^−16, each
/// term (a photon's β_cam·f·Φ) clamped to ±2^24 (far beyond any pixel's
/// light), so 2^23 such terms fit an `i64`.
const FIXED_SCALE: f64 = 65536.0;
const FIXED_MAX: f64 = (1u64 << 40) as f64;

/// Visible points of one iteration in a uniform grid of cells of twice the
/// largest radius (a point's sphere overlaps at most 2 × 2 × 2 cells),
/// hashed into as many buckets as there are points. Rebuilt in place each
/// iteration: its buffers keep their capacity (allocating them anew cost
/// page faults every iteration).
#[derive(Default)]
struct Grid {
    origin: Vec3,
    inv_cell: f32,
    /// Bucket b holds `items[starts[b]..starts[b + 1]]`.
    starts: Vec<u32>,
    items: Vec<GridEntry>,
    /// The points to build from, each with its radius (filled by the caller
    /// or [`Grid::build`]).
    entries: Vec<(GridEntry, f32)>,
    /// Scratch of the build: each entry's buckets, and the buckets' fill.
    point_buckets: Vec<[u32; 8]>,
    fill: Vec<u32>,
}

/// A visible point in a bucket: its position and squared radius beside its
/// pixel, so that the distance test (which most candidates fail) reads one
/// contiguous array instead of the pixels' visible points and statistics.
#[derive(Clone, Copy)]
struct GridEntry {
    p: Vec3,
    r2: f32,
    pixel: u32,
}

impl Grid {
    /// Rebuilds the grid from the valid visible points with their pixels'
    /// radii; false if there is none.
    fn build<S: Spectrum>(&mut self, points: &[Option<VisiblePoint<S>>], stats: &[PixelStats]) -> bool {
        self.entries.clear();
        self.entries.extend(points.iter().zip(stats).enumerate().filter_map(|(i, (vp, st))| {
            let r = st.radius as f32;
            vp.as_ref().map(|vp| (GridEntry { p: vp.si.p, r2: r * r, pixel: i as u32 }, r))
        }));
        self.rebuild()
    }

    /// Rebuilds the grid from `entries`, each a visible point (`pixel`: its
    /// index among the points looked up) with its radius; false if the
    /// grid is empty (no point, or no positive radius).
    fn rebuild(&mut self) -> bool {
        let (mut lo, mut hi, mut max_r) =
            (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY), 0.0f32);
        for (e, r) in &self.entries {
            lo = lo.min(e.p);
            hi = hi.max(e.p);
            max_r = max_r.max(*r);
        }
        let count = self.entries.len();
        if count == 0 || !(max_r > 0.0) || !lo.is_finite() || !hi.is_finite() {
            return false;
        }
        self.origin = lo - Vec3::splat(max_r);
        self.inv_cell = 1.0 / (2.0 * max_r);
        // A point goes once into each bucket its cells hash to: two of its
        // cells may share a bucket, and a photon there must count it once.
        // The hashing in parallel (each point's buckets, at most 8); the
        // buckets filled in the points' order.
        const NONE: u32 = u32::MAX;
        let mut point_buckets = std::mem::take(&mut self.point_buckets);
        self.entries
            .par_iter()
            .map(|(e, r)| {
                let mut out = [NONE; 8];
                let mut n = 0;
                let r = Vec3::splat(*r);
                let (a, b) = (self.cell(e.p - r), self.cell(e.p + r));
                for z in a[2]..=b[2] {
                    for y in a[1]..=b[1] {
                        for x in a[0]..=b[0] {
                            let bucket = hash_cell([x, y, z], count) as u32;
                            if n < 8 && !out[..n].contains(&bucket) {
                                out[n] = bucket;
                                n += 1;
                            }
                        }
                    }
                }
                out
            })
            .collect_into_vec(&mut point_buckets);
        let counts = &mut self.starts;
        counts.clear();
        counts.resize(count + 1, 0);
        for bs in &point_buckets {
            for &b in bs.iter().take_while(|&&b| b != NONE) {
                counts[b as usize + 1] += 1;
            }
        }
        for b in 0..count {
            counts[b + 1] += counts[b];
        }
        self.fill.clear();
        self.fill.extend_from_slice(counts);
        let empty = GridEntry { p: Vec3::ZERO, r2: 0.0, pixel: 0 };
        self.items.clear();
        self.items.resize(counts[count] as usize, empty);
        for ((e, _), bs) in self.entries.iter().zip(&point_buckets) {
            for &b in bs.iter().take_while(|&&b| b != NONE) {
                self.items[self.fill[b as usize] as usize] = *e;
                self.fill[b as usize] += 1;
            }
        }
        self.point_buckets = point_buckets;
        true
    }

    #[inline]
    fn cell(&self, p: Vec3) -> [i32; 3] {
        let c = (p - self.origin) * self.inv_cell;
        // `as` saturates: far-away points share the border cells.
        [floor_i32(c.x), floor_i32(c.y), floor_i32(c.z)]
    }

    /// The visible points that may lie within their radius of `p`.
    #[inline]
    fn near(&self, p: Vec3) -> &[GridEntry] {
        let b = hash_cell(self.cell(p), self.starts.len() - 1);
        &self.items[self.starts[b] as usize..self.starts[b + 1] as usize]
    }
}

#[inline]
fn hash_cell(c: [i32; 3], buckets: usize) -> usize {
    let h = (c[0] as u32).wrapping_mul(73_856_093)
        ^ (c[1] as u32).wrapping_mul(19_349_663)
        ^ (c[2] as u32).wrapping_mul(83_492_791);
    h as usize % buckets
}

impl Sppm {
    /// The initial radius when none is given and the camera gives no
    /// pixel footprint: 5 × the scene's bounding-sphere radius over the
    /// film's larger side in pixels (Mitsuba 0.6's guess).
    pub fn radius(&self, scene: &Scene) -> f32 {
        if self.initial_radius > 0.0 {
            return self.initial_radius;
        }
        let sphere = bounding_sphere(scene).1;
        let r = 5.0 * sphere / scene.film.width.max(scene.film.height).max(1) as f32;
        if r.is_finite() && r > 0.0 { r } else { 1e-3 }
    }

    /// A pixel's footprint as a function of the distance along its ray:
    /// `(offset, spread)`, the footprint at distance t being
    /// offset + spread · t (the distance between the rays through the
    /// centres of the film's middle pixel and its right neighbour; offset
    /// is the orthographic camera's pixel size, spread the perspective
    /// camera's angle per pixel).
    pub fn pixel_footprint(scene: &Scene) -> (f32, f32) {
        let size = Vec2::new(scene.film.width as f32, scene.film.height as f32);
        let c = (size * 0.5).floor() + Vec2::splat(0.5);
        let a = scene.camera.generate_ray(c / size);
        let b = scene.camera.generate_ray((c + Vec2::X) / size);
        let offset = (b.o - a.o).length();
        let spread = (b.d.normalize_or_zero() - a.d.normalize_or_zero()).length();
        if offset.is_finite() && spread.is_finite() { (offset, spread) } else { (0.0, 0.0) }
    }

    /// The camera path of pixel (`x`, `y`) of the full film in iteration
    /// `iteration`: the light it found (RGB) and its visible point, if it
    /// reached one. A path tracer's path (`PathTracer::li`'s vertex
    /// shading: emitter sampling and BSDF sampling weighted by MIS, the
    /// same [`next_event`], [`hit_weight`]) with three differences: the
    /// first non-delta vertex is the visible point (on a BSDF with both
    /// delta and smooth lobes, with probability ½: then only its smooth
    /// lobes are sampled there, else only its delta lobes, each weighted by
    /// 2); with `photons = caustics` the path stops where the vertex after
    /// the visible point scatters by a delta lobe (the photons carry that
    /// light), and with `photons = indirect` it stops at the vertex after
    /// the visible point (only direct light is sampled there). With
    /// `photons = all_caustics` every non-delta vertex after the visible
    /// point is a gather point too, pushed onto `later`, and the path stops
    /// wherever a delta bounce follows a smooth one after the visible point.
    /// With `photons = final_gather` the vertex after the visible point is
    /// the gather point (pushed onto `later`) if it has a smooth lobe, else
    /// the path stops there; it samples its smooth lobes only, and the path
    /// stops at the vertex after it.
    fn camera_path<S: Spectrum>(
        &self,
        scene: &Scene,
        x: u32,
        y: u32,
        (spec, index): (&SamplerSpec, u32),
        wl: S::Wavelengths,
        later: &mut Vec<VisiblePoint<S>>,
        to_visible_point: bool,
    ) -> CameraPath<S> {
        let mut sampler = Sampler::start(spec, x, y, index);
        let inv_size = Vec2::new(
            1.0 / scene.film.width as f32,
            1.0 / scene.film.height as f32,
        );
        let pos = Vec2::new(x as f32, y as f32) + sampler.next_2d();
        let mut ray = scene.camera.sample_ray(pos * inv_size, &mut sampler);
        let mut wl = wl;
        let mut l = S::zero();
        let mut beta = S::splat(1.0);
        let mut eta = 1.0f32;
        // Segments so far (a vertex found by the ray makes it depth + 1).
        let mut depth = 0u32;
        let mut distance = 0.0f32;
        let mut ctx = BsdfContext::RADIANCE;
        let mut prev = ShadingPoint::at(ray.o);
        let mut prev_pdf = 0.0f32;
        let mut prev_delta = true;
        let mut vp: Option<VisiblePoint<S>> = None;
        // The light met up to and including the visible point.
        let mut before_vp: Option<S> = None;
        // Vertices since the visible point (0: at it or before it).
        let mut after = 0u32;
        loop {
            let Some(si) = scene.intersect_path(&ray, false, &mut sampler) else {
                if let Some((env, w)) = escaped::<S>(scene, &prev, prev_pdf, prev_delta, ray.d, &wl) {
                    l += beta * env * w;
                }
                break;
            };
            depth += 1;
            if vp.is_none() {
                distance += si.t * ray.d.length();
            } else {
                after += 1;
            }
            if let Some(le) = scene.emitted::<S>(&si, &wl) {
                l += beta * le * hit_weight(scene, &prev, prev_pdf, prev_delta, &si);
            }
            // Emitter sampling and photons each add at least one segment.
            if depth >= self.max_depth
                || (after >= 1 && self.photons == Photons::Indirect)
                || (after >= 2 && self.photons == Photons::FinalGather)
            {
                break;
            }
            let bsdf = scene.bsdf(&si);
            if bsdf.disperses() {
                S::terminate_secondary(&mut wl);
            }
            let lobes = bsdf.lobes();
            let (smooth, delta) = (
                lobes.intersects(Lobe::SMOOTH),
                lobes.intersects(Lobe::DELTA),
            );
            let mut sample_ctx = ctx;
            if after >= 1 && self.photons == Photons::AllCaustics && smooth {
                // Light arriving here straight from a delta bounce is the
                // photons' (a photon adds at least one segment).
                later.push(VisiblePoint { si: si.clone(), beta, wl, depth, distance });
            }
            if after == 1 && self.photons == Photons::FinalGather {
                // The final gather's point: light that bounced before it
                // is the photons', light straight from its delta lobes the
                // visible point's caustic photons; its smooth lobes' direct
                // light is sampled here, and the path ends one vertex on.
                if !smooth {
                    break;
                }
                later.push(VisiblePoint { si: si.clone(), beta, wl, depth, distance });
                sample_ctx = ctx.with_lobes(Lobe::SMOOTH);
            }
            if vp.is_none() {
                if !smooth && !delta {
                    break;
                }
                // Both kinds of lobes: stop or go on with probability ½ each.
                let (stop, scale) = match (smooth, delta) {
                    (true, true) => (sampler.next_1d() < 0.5, 2.0),
                    (s, _) => (s, 1.0),
                };
                beta *= scale;
                if stop {
                    before_vp = Some(l);
                    if to_visible_point {
                        break;
                    }
                    sample_ctx = ctx.with_lobes(Lobe::SMOOTH);
                    vp = Some(VisiblePoint {
                        si: si.clone(),
                        beta,
                        wl,
                        depth,
                        distance,
                    });
                } else if smooth {
                    sample_ctx = ctx.with_lobes(Lobe::DELTA);
                }
            }
            if vp.is_some() && lobes.intersects(Lobe::SMOOTH) && sample_ctx.lobes.intersects(Lobe::SMOOTH) {
                l += next_event::<S>(scene, &si, bsdf, &sample_ctx, beta, &mut sampler, &wl);
            }
            let Some(bs) = bsdf.sample::<S>(
                &sample_ctx,
                &si,
                si.wi,
                sampler.next_1d(),
                sampler.next_2d(),
                &wl,
            ) else {
                break;
            };
            let delta_bounce = bs.lobe.intersects(Lobe::DELTA);
            let caustic = match self.photons {
                // Onto the visible point (whose bounce is always smooth).
                Photons::Caustics | Photons::None | Photons::FinalGather => after == 1,
                // Onto any smooth vertex from the visible point on.
                Photons::AllCaustics => after >= 1 && !prev_delta,
                Photons::Indirect => false,
            };
            if delta_bounce && caustic {
                // A caustic onto the previous vertex: the photons' part.
                break;
            }
            ctx = ctx.following(bs.lobe);
            beta *= bs.weight;
            eta *= bs.eta;
            prev = ShadingPoint::from(&si);
            prev_pdf = bs.pdf;
            prev_delta = delta_bounce;
            let d = si.to_world(bs.wo);
            ray = Ray::new(si.spawn_origin(d), d);
            let Some(scale) = crate::integrator::path::russian_roulette(beta.max_component(), eta, depth, self.rr_depth, &mut sampler) else { break };
            beta *= scale;
        }
        let finite = |l: S| Some(l.to_rgb(&wl)).filter(|rgb| rgb.is_finite()).unwrap_or(Rgb::zero());
        CameraPath { light: finite(l), before_vp: finite(before_vp.unwrap_or(l)), vp, pos }
    }

    /// Traces photon `index` of iteration `iteration` and adds it to the
    /// visible points near its non-delta hits.
    #[allow(clippy::too_many_arguments)]
    fn photon<S: Spectrum>(
        &self,
        scene: &Scene,
        spec: &SamplerSpec,
        index: u32,
        iteration: u32,
        wl: S::Wavelengths,
        visible_map: &PhotonMap<S>,
        later: Option<&PhotonMap<S>>,
    ) {
        let mut sampler = Sampler::start(spec, index, iteration, 0);
        let mut wl = wl;
        let mut dispersed = false;
        // One light-path start shared with `ptracer` and `bdpt`.
        let (u_pick, u_pos, u_dir) = (sampler.next_1d(), sampler.next_2d(), sampler.next_2d());
        let Some(em) = scene.sample_emission::<S>(u_pick, u_pos, u_dir, &wl) else {
            return;
        };
        let (mut ray, mut beta) = (em.ray, em.weight);
        let beta_start = beta.max_component();
        if !(beta_start > 0.0) {
            return;
        }
        let mut segments = 0u32;
        let mut ctx = BsdfContext::IMPORTANCE;
        // Whether the photon's last bounce was by a delta lobe: only such
        // photons (caustics) are deposited; the camera paths trace the rest.
        let mut after_delta = false;
        loop {
            let Some(si) = scene.intersect_path(&ray, false, &mut sampler) else {
                break;
            };
            segments += 1;
            // A visible point is at least one camera segment away.
            if segments.saturating_add(1) > self.max_depth {
                break;
            }
            let bsdf = scene.bsdf(&si);
            if bsdf.disperses() {
                S::terminate_secondary(&mut wl);
                dispersed = true;
            }
            // Whether the photon counts at the visible points and at the
            // later gather points.
            let (visible, at_later) = match self.photons {
                Photons::Caustics | Photons::AllCaustics => (after_delta, after_delta),
                Photons::Indirect => (segments >= 2, segments >= 2),
                Photons::FinalGather => (after_delta, segments >= 2),
                Photons::None => (false, false),
            };
            if (visible || at_later) && bsdf.lobes().intersects(Lobe::SMOOTH) {
                let seed =
                    mix64(((iteration as u64) << 32 | index as u64) ^ ((segments as u64) << 58));
                if visible {
                    self.deposit(scene, &si, ray.d, segments, beta, dispersed, seed, visible_map);
                }
                if let (true, Some(map)) = (at_later, later) {
                    self.deposit(scene, &si, ray.d, segments, beta, dispersed, !seed, map);
                }
            }
            if segments.saturating_add(2) > self.max_depth {
                break;
            }
            let Some(bs) =
                bsdf.sample::<S>(&ctx, &si, si.wi, sampler.next_1d(), sampler.next_2d(), &wl)
            else {
                break;
            };
            ctx = ctx.following(bs.lobe);
            after_delta = bs.lobe.intersects(Lobe::DELTA);
            beta *= bs.weight * shading_correction(&si, si.wi, bs.wo);
            let d = si.to_world(bs.wo);
            ray = Ray::new(si.spawn_origin(d), d);
            let t_max = beta.max_component() / beta_start;
            if !(t_max > 0.0) {
                break;
            }
            if segments >= self.rr_depth {
                let q = t_max.min(0.95);
                if !(sampler.next_1d() < q) {
                    break;
                }
                beta *= 1.0 / q;
            }
        }
    }

    /// Adds a photon with throughput `beta` that reached `si` along `d`
    /// after `segments` segments to every visible point within its radius.
    #[allow(clippy::too_many_arguments)]
    fn deposit<S: Spectrum>(
        &self,
        scene: &Scene,
        si: &SurfaceInteraction,
        d: Vec3,
        segments: u32,
        beta: S,
        dispersed: bool,
        seed: u64,
        map: &PhotonMap<S>,
    ) {
        for (k, e) in map.grid.near(si.p).iter().enumerate() {
            if (e.p - si.p).length_squared() >= e.r2 {
                continue;
            }
            let i = e.pixel as usize;
            let Some(t) = &map.targets[i] else { continue };
            if t.depth.saturating_add(segments) > self.max_depth {
                continue;
            }
            // Not across a corner or onto the other side of a thin wall.
            if t.n.dot(si.n).abs() < 0.1 {
                continue;
            }
            let sums = &map.sums.points[i];
            if map.sums.counted {
                sums.count.fetch_add(1, Ordering::Relaxed);
            }
            let Some(value) = t.reflected(&map.points[i], d, beta, |si| scene.bsdf(si)) else { continue };
            let mut wl = t.wl;
            if dispersed {
                S::terminate_secondary(&mut wl);
            }
            let rgb = value.to_rgb(&wl);
            if !rgb.is_finite() {
                continue;
            }
            let h = mix64(seed ^ (k as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15));
            for c in 0..3 {
                // Dithered rounding: unbiased, and the same whatever the order.
                let u = ((h >> (20 * c)) & 0xfffff) as f64 / (1u64 << 20) as f64;
                let v = (rgb[c] as f64 * FIXED_SCALE).clamp(-FIXED_MAX, FIXED_MAX);
                let q = floor_i64(v + u);
                if q != 0 {
                    sums.phi[c].fetch_add(q, Ordering::Relaxed);
                }
            }
        }
    }
}

/// The scene's bounding sphere (centre, radius).
fn bounding_sphere(scene: &Scene) -> (Vec3, f32) {
    let (lo, hi) = scene.accel.bounds(&scene.shapes);
    (0.5 * (lo + hi), 0.5 * (hi - lo).length())
}

#[cfg(test)]
mod tests {
    use super::{Grid, PixelStats, Splat, Target, VisiblePoint};
    use crate::bsdf::{Bsdf, Diffuse};
    use crate::geometry::SurfaceInteraction;
    use crate::math::{Frame, Pcg32};
    use crate::spectrum::{Rgb, Sampled, Spectrum};
    use crate::texture::Texture;
    use glam::Vec3;

    /// The splat's bands of rows: within a phase the rows they reach do
    /// not meet, and each band's slice holds every row its paths reach, so
    /// the two phases add every path's light once, in parallel.
    #[test]
    fn splat_bands_cover_their_reach_without_meeting() {
        for (w, h, reach) in [(5usize, 1usize, 0i32), (3, 17, 2), (4, 64, 2), (2, 9, 8), (7, 40, 3)] {
            let splat = Splat {
                filter: crate::film::Filter::new(crate::film::FilterKind::Box),
                reach,
                size: [w as i32, h as i32],
                inv_mass: [vec![1.0; w], vec![1.0; h]],
            };
            let rows = splat.band_rows();
            let mut stats = vec![PixelStats { radius: 0.0, n: 0.0, direct: [0.0; 3] }; w * h];
            let mut sources = vec![0u32; h];
            for phase in 0..2 {
                let mut last_end = 0;
                for (band, first, slice) in splat.bands(&mut stats, phase) {
                    assert_eq!(band % 2, phase);
                    assert_eq!(slice.len() % w, 0);
                    let end = first + slice.len() / w;
                    assert!(first >= last_end || band == phase, "{w}×{h}, reach {reach}: bands of one phase meet");
                    last_end = end;
                    for y in band * rows..((band + 1) * rows).min(h) {
                        sources[y] += 1;
                        let (lo, hi) = (y.saturating_sub(reach as usize), (y + reach as usize).min(h - 1));
                        assert!(first <= lo && hi < end, "{w}×{h}, reach {reach}: row {y} reaches {lo}..={hi} outside {first}..{end}");
                    }
                }
            }
            assert!(sources.iter().all(|&n| n == 1), "{w}×{h}, reach {reach}: each row a source once");
        }
    }

    /// A deposit at a `diffuse` point takes ρ/π from its target instead of
    /// evaluating the BSDF: the same value (to rounding) for every photon
    /// and path direction, and nothing wherever the evaluation gives
    /// nothing (a photon from below, a path that arrived from below).
    #[test]
    fn diffuse_targets_reflect_what_the_bsdf_evaluates() {
        fn check<S: Spectrum>() {
            let bsdf = Bsdf::Diffuse(Diffuse { reflectance: Texture::constant(Rgb::new(0.2, 0.5, 0.8)) });
            let mut rng = Pcg32::new(11, 3);
            let unit = |rng: &mut Pcg32| loop {
                let v = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - Vec3::ONE;
                if v.length_squared() > 0.01 && v.length_squared() <= 1.0 {
                    return v.normalize();
                }
            };
            let (mut lit, mut dark) = (0, 0);
            for _ in 0..4000 {
                let n = unit(&mut rng);
                let frame = Frame::from_normal(n);
                let si = SurfaceInteraction { n, frame, wi: frame.to_local(unit(&mut rng)), ..SurfaceInteraction::EMPTY };
                let vp = VisiblePoint { si, beta: S::splat(0.7), wl: S::sample_wavelengths(rng.next_f32()), depth: 1, distance: 1.0 };
                let target = Target::of(&bsdf, &vp);
                assert!(target.lambert.is_some(), "a diffuse point takes the shortcut");
                let evaluated = Target { lambert: None, ..target };
                let (d, beta, wl) = (unit(&mut rng), S::splat(1.3), vp.wl);
                let vp = Some(vp);
                let got = target.reflected(&vp, d, beta, |_| &bsdf);
                let want = evaluated.reflected(&vp, d, beta, |_| &bsdf);
                match (got, want) {
                    (Some(g), Some(w)) => {
                        lit += 1;
                        let (g, w) = (g.to_rgb(&wl), w.to_rgb(&wl));
                        for c in 0..3 {
                            assert!((g[c] - w[c]).abs() <= 1e-5 * w[c].abs().max(1e-3), "{g:?} against {w:?}");
                        }
                    }
                    (None, None) => dark += 1,
                    (g, w) => panic!("shortcut {:?}, evaluated {:?}", g.map(|_| ()), w.map(|_| ())),
                }
            }
            // About a quarter of the pairs have both directions above.
            assert!(lit > 600 && dark > 2000, "lit {lit}, dark {dark}");
        }
        check::<Rgb>();
        check::<Sampled>();
    }

    /// Every visible point within its radius of a query is found, and no
    /// other, and each once, on points of many radii (the cells are sized by
    /// the largest; two cells of a point may hash to one bucket, which must
    /// still list it once or a photon there counts it twice).
    #[test]
    fn grid_finds_every_point_in_reach() {
        let mut rng = Pcg32::new(7, 1);
        let n = 500;
        let points: Vec<Option<VisiblePoint<Rgb>>> = (0..n)
            .map(|i| {
                (i % 7 != 3).then(|| VisiblePoint {
                    si: SurfaceInteraction {
                        p: Vec3::new(rng.next_f32(), rng.next_f32(), 0.2 * rng.next_f32()),
                        ..SurfaceInteraction::EMPTY
                    },
                    beta: Rgb::splat(1.0),
                    wl: Rgb::sample_wavelengths(0.5),
                    depth: 1,
                    distance: 1.0,
                })
            })
            .collect();
        let stats: Vec<PixelStats> = (0..n)
            .map(|_| PixelStats {
                radius: 0.01 + 0.09 * rng.next_f32() as f64,
                n: 0.0,
                direct: [0.0; 3],
            })
            .collect();
        let mut grid = Grid::default();
        assert!(grid.build(&points, &stats), "points");
        let mut found = 0;
        for _ in 0..2000 {
            let q = Vec3::new(1.2 * rng.next_f32() - 0.1, 1.2 * rng.next_f32() - 0.1, 0.2 * rng.next_f32());
            let mut got: Vec<u32> = grid
                .near(q)
                .iter()
                .filter(|e| (e.p - q).length_squared() < e.r2)
                .map(|e| e.pixel)
                .collect();
            got.sort_unstable();
            let listed = got.len();
            got.dedup();
            assert_eq!(listed, got.len(), "a point listed twice in the bucket of {q}");
            let want: Vec<u32> = (0..n as u32)
                .filter(|&i| {
                    let r = stats[i as usize].radius as f32;
                    points[i as usize].as_ref().is_some_and(|vp| (vp.si.p - q).length_squared() < r * r)
                })
                .collect();
            assert_eq!(got, want, "query {q}");
            found += want.len();
        }
        assert!(found > 2000, "the queries reach points ({found})");
    }

}

/// A visible point's photon sums of one iteration in one aligned 32-byte
/// block, so that a deposit's four adds write one cache line.
#[derive(Default)]
#[repr(align(32))]
struct PointSums {
    phi: [AtomicI64; 3],
    /// Photons counted, for the point's radius (not kept at the later
    /// vertices, whose radius follows a fixed schedule).
    count: AtomicU32,
}

/// One iteration's photon sums per visible point.
#[derive(Default)]
struct Sums {
    points: Vec<PointSums>,
    /// Whether deposits count their photons.
    counted: bool,
}

impl Sums {
    /// Zero sums for `points` points (counted or not), in the buffer of
    /// the last iteration.
    fn reset(&mut self, points: usize, counted: bool) {
        self.points.clear();
        self.points.resize_with(points, Default::default);
        self.counted = counted;
    }

    fn phi(&self, i: usize, c: usize) -> i64 {
        self.points[i].phi[c].load(Ordering::Relaxed)
    }
}

/// What a deposit reads of a visible point, packed and built once an
/// iteration: the visible points themselves are 150 bytes apart, and at a
/// `diffuse` point no BSDF (nor its texture) is evaluated per photon
/// (measured: 2–5 % of the caustic box's time, docs/performance.md).
#[derive(Clone, Copy)]
struct Target<S: Spectrum> {
    /// Geometric normal (for the test against photons across a corner).
    n: Vec3,
    /// The shading frame's normal.
    shading_n: Vec3,
    depth: u32,
    /// At a `diffuse` BSDF: the path's throughput times ρ/π (zero where the
    /// path arrived from below), the same for every photon from above, so
    /// the BSDF is not evaluated per photon; `None`: evaluated.
    lambert: Option<S>,
    wl: S::Wavelengths,
}

impl<S: Spectrum> Target<S> {
    /// The target of `vp`, whose BSDF is `bsdf`.
    fn of(bsdf: &Bsdf, vp: &VisiblePoint<S>) -> Target<S> {
        let lambert = match bsdf {
            // `Diffuse::eval`: zero unless both directions are above.
            Bsdf::Diffuse(_) if vp.si.wi.z <= 0.0 => Some(S::zero()),
            Bsdf::Diffuse(b) => {
                Some(vp.beta * b.reflectance.eval_spectrum::<S>(&vp.si, &vp.wl).depolarize() * INV_PI)
            }
            _ => None,
        };
        Target { n: vp.si.n, shading_n: vp.si.frame.n, depth: vp.depth, lambert, wl: vp.wl }
    }

    /// What a photon of throughput `beta` arriving along `d` adds at the
    /// point (`vp`: the point itself, and `bsdf_at` its BSDF, read only
    /// where it is not `diffuse`): throughput · f · beta / |cos|, or `None`
    /// where the BSDF reflects none of it.
    #[inline]
    fn reflected<'b>(&self, vp: &Option<VisiblePoint<S>>, d: Vec3, beta: S, bsdf_at: impl FnOnce(&SurfaceInteraction) -> &'b Bsdf) -> Option<S> {
        match self.lambert {
            // f / cos = ρ/π for a photon from above (`Diffuse::eval`).
            Some(w) => (self.shading_n.dot(-d) > 1e-6 && !w.is_zero()).then(|| w * beta),
            None => {
                let vp = vp.as_ref()?;
                let wi = vp.si.to_local(-d);
                let cos = wi.z.abs();
                if !(cos > 1e-6) {
                    return None;
                }
                let f: S = bsdf_at(&vp.si).eval(&BsdfContext::RADIANCE, &vp.si, vp.si.wi, wi, &vp.wl);
                (!f.is_zero()).then(|| vp.beta * f * beta * (1.0 / cos))
            }
        }
    }
}

/// The visible points (or later vertices) photons are deposited at: their
/// grid, the points, their packed targets and the sums of the iteration.
struct PhotonMap<'a, S: Spectrum> {
    grid: &'a Grid,
    points: &'a [Option<VisiblePoint<S>>],
    targets: &'a [Option<Target<S>>],
    sums: &'a Sums,
}


/// Each point's target, in parallel, into `out`'s buffer.
fn build_targets<S: Spectrum>(scene: &Scene, points: &[Option<VisiblePoint<S>>], out: &mut Vec<Option<Target<S>>>) {
    points.par_iter().map(|vp| vp.as_ref().map(|vp| Target::of(scene.bsdf(&vp.si), vp))).collect_into_vec(out);
}

/// The farthest a camera path's light may reach, in pixels each way.
const MAX_REACH: i32 = 8;
/// Weights along one axis: 2 · `MAX_REACH` + 1 pixels.
type AxisWeights = [f32; (2 * MAX_REACH + 1) as usize];

/// How a camera path's light reaches the pixels: through the film's
/// reconstruction filter, as a splatting film adds a sample, from where
/// the path started in its pixel (uniformly). The path-traced light of an
/// iteration is added at once; the photons' flux found at a pixel's
/// visible points is kept apart for each pixel its paths reach (τ per
/// slot: SPPM's radius belongs to the pixel whose points gathered it).
/// A pixel is then Σ w·L over the paths that reach it, over the filter's
/// mass inside the crop window: what `path`'s Σ w·L / Σ w converges to.
/// A `box` keeps each path's light in its own pixel (one slot).
struct Splat {
    filter: Filter,
    /// Pixels each way a path's light reaches ([`reach`]).
    reach: i32,
    /// The crop window's width and height.
    size: [i32; 2],
    /// 1 / the filter's mass inside the window, per column and per row.
    inv_mass: [Vec<f64>; 2],
}

impl Splat {
    fn new(scene: &Scene) -> anyhow::Result<Splat> {
        let filter = scene.film.filter.clone();
        let is_box = matches!(filter.kind, FilterKind::Box);
        let reach = reach(&filter);
        if reach > MAX_REACH {
            anyhow::bail!(
                "sppm: the film's rfilter (radius {}) reaches {reach} pixels each way; sppm takes at most {MAX_REACH}",
                filter.radius()
            );
        }
        let [_, _, w, h] = scene.film.crop;
        let inv_mass = |n: u32| -> Vec<f64> {
            if is_box {
                return vec![1.0; n as usize];
            }
            window_filter_mass(&filter, n).iter().map(|&m| if m > 0.0 { 1.0 / m as f64 } else { 0.0 }).collect()
        };
        let inv_mass = [inv_mass(w), inv_mass(h)];
        Ok(Splat { filter, reach, size: [w as i32, h as i32], inv_mass })
    }

    /// Slots a pixel keeps: one per pixel its paths may reach.
    fn slots(&self) -> usize {
        let n = (2 * self.reach + 1) as usize;
        n * n
    }

    /// The filter's weights at the 2 · reach + 1 pixels around pixel `j`
    /// of a row (or column) of `n`, for a start at `p` (window pixels); 0
    /// outside the window.
    fn axis(&self, j: i32, p: f32, n: i32, out: &mut AxisWeights) {
        // A box keeps the path in its own pixel, whatever the start's
        // rounding at the pixel's edge.
        if let FilterKind::Box = self.filter.kind {
            out[0] = 1.0;
            return;
        }
        // `eval_span`: the film's own lookups (`Filter::eval`'s bits), a few
        // at a time.
        let count = (2 * self.reach + 1) as usize;
        let first = j - self.reach;
        self.filter.eval_span(first, p, &mut out[..count]);
        for (t, w) in out[..count].iter_mut().enumerate() {
            let i = first + t as i32;
            if i < 0 || i >= n {
                *w = 0.0;
            }
        }
    }

    /// Pixel `i`'s column and row, and the filter's weights along each axis
    /// for its path that started at `pos` ([`Splat::axis`]).
    #[inline]
    fn axis_weights(&self, i: usize, pos: Vec2) -> ([i32; 2], AxisWeights, AxisWeights) {
        let [w, h] = self.size;
        let (jx, jy) = ((i % w as usize) as i32, (i / w as usize) as i32);
        let (mut wx, mut wy) = ([0.0; (2 * MAX_REACH + 1) as usize], [0.0; (2 * MAX_REACH + 1) as usize]);
        self.axis(jx, pos.x, w, &mut wx);
        self.axis(jy, pos.y, h, &mut wy);
        ([jx, jy], wx, wy)
    }

    /// Calls `f(slot, pixel, weight)` for every slot of pixel `i` whose
    /// path started at `pos`: the pixel it stands for (`None` outside the
    /// window) and the filter's weight there (possibly 0 or negative).
    #[inline]
    fn for_each_weight(&self, i: usize, pos: Vec2, mut f: impl FnMut(usize, Option<usize>, f64)) {
        let [w, h] = self.size;
        let ([jx, jy], wx, wy) = self.axis_weights(i, pos);
        let n = 2 * self.reach + 1;
        for ty in 0..n {
            for tx in 0..n {
                let (cx, cy) = (jx - self.reach + tx, jy - self.reach + ty);
                let inside = cx >= 0 && cy >= 0 && cx < w && cy < h;
                f((ty * n + tx) as usize, inside.then(|| (cy * w + cx) as usize), wx[tx as usize] as f64 * wy[ty as usize] as f64);
            }
        }
    }

    /// Adds the light `value` of a path of pixel `i` that started at `pos`
    /// to the path-traced sums of the pixels it reaches; `stats` holds the
    /// window's rows from `first_row` on (a band, [`Splat::bands`]).
    fn add_direct(&self, stats: &mut [PixelStats], first_row: usize, i: usize, pos: Vec2, value: [f64; 3]) {
        // `for_each_weight`'s weights, by rows, skipping the zero ones
        // (`axis` gives 0 outside the window): a Gaussian's 25 slots hold
        // at most 16 pixels a path reaches.
        let w = self.size[0] as usize;
        let ([jx, jy], wx, wy) = self.axis_weights(i, pos);
        let n = (2 * self.reach + 1) as usize;
        for (ty, &row_weight) in wy[..n].iter().enumerate() {
            if row_weight == 0.0 {
                continue;
            }
            let row = (jy - self.reach + ty as i32) as usize - first_row;
            for (tx, &column_weight) in wx[..n].iter().enumerate() {
                if column_weight == 0.0 {
                    continue;
                }
                let weight = column_weight as f64 * row_weight as f64;
                let c = row * w + (jx - self.reach + tx as i32) as usize;
                for (sum, v) in stats[c].direct.iter_mut().zip(value) {
                    *sum += weight * v;
                }
            }
        }
    }

    /// Rows of the window in one band of paths splatted by one worker: more
    /// than twice the reach, so that the rows two bands apart write to do
    /// not meet.
    fn band_rows(&self) -> usize {
        (2 * self.reach as usize + 1).max(4)
    }

    /// `stats` cut into the bands of one `phase` (0: the even bands, 1: the
    /// odd): for each, its band index and the rows its paths reach (the
    /// band and `reach` rows each side, inside the window), as the first
    /// row and those rows' stats. The bands of a phase reach disjoint rows.
    fn bands<'a>(&self, stats: &'a mut [PixelStats], phase: usize) -> Vec<(usize, usize, &'a mut [PixelStats])> {
        let (w, h) = (self.size[0] as usize, self.size[1] as usize);
        let (rows, reach) = (self.band_rows(), self.reach as usize);
        let mut out = Vec::new();
        let (mut rest, mut rest_row) = (stats, 0usize);
        for band in (phase..h.div_ceil(rows)).step_by(2) {
            let first = (band * rows).saturating_sub(reach);
            let end = ((band + 1) * rows + reach).min(h);
            let (_, tail) = std::mem::take(&mut rest).split_at_mut((first - rest_row) * w);
            let (mine, tail) = tail.split_at_mut((end - first) * w);
            out.push((band, first, mine));
            (rest, rest_row) = (tail, end);
        }
        out
    }

    /// Pixel `c`'s photon light: over the pixels whose paths reach it, τ of
    /// their slot for `c` over (photons · π R²).
    fn gathered(&self, c: usize, stats: &[PixelStats], tau: &[[f64; 3]], photons: f64) -> [f64; 3] {
        let [w, h] = self.size;
        let (cx, cy) = ((c % w as usize) as i32, (c / w as usize) as i32);
        let n = 2 * self.reach + 1;
        let slots = self.slots();
        let mut out = [0.0f64; 3];
        for ty in 0..n {
            for tx in 0..n {
                // The pixel j whose slot (tx, ty) stands for c.
                let (jx, jy) = (cx + self.reach - tx, cy + self.reach - ty);
                if jx < 0 || jy < 0 || jx >= w || jy >= h {
                    continue;
                }
                let j = (jy * w + jx) as usize;
                let area = std::f64::consts::PI * stats[j].radius * stats[j].radius;
                if area > 0.0 {
                    let t = &tau[j * slots + (ty * n + tx) as usize];
                    for k in 0..3 {
                        out[k] += t[k] / (photons * area);
                    }
                }
            }
        }
        out
    }

    /// 1 / the filter's mass inside the window at pixel `c`.
    fn inv_mass(&self, c: usize) -> f64 {
        let w = self.size[0] as usize;
        self.inv_mass[0][c % w] * self.inv_mass[1][c / w]
    }
}

/// Pixels each way the light of a path that starts in a pixel reaches
/// through `filter`: ⌈radius − ½⌉ (a box: 0).
fn reach(filter: &Filter) -> i32 {
    if let FilterKind::Box = filter.kind { 0 } else { (filter.radius() - 0.5).ceil().max(0.0) as i32 }
}

/// Bytes `sppm` keeps per pixel for the film's filter `filter`: the
/// photons' flux per pixel a path reaches (`Splat`) and the path's start.
pub fn filter_bytes_per_pixel(filter: &Filter) -> u64 {
    (2 * reach(filter) as u64 + 1).pow(2) * 24 + 8
}

/// Pixels a unit of parallel work in the camera pass.
const CAMERA_CHUNK: usize = 64;

/// Renders `scene` (whose integrator is `sppm`) progressively: the film's
/// sample count is the number of iterations, split into the passes of
/// [`crate::render::pass_schedule`]; `on_pass` gets the image after each.
pub fn render<S: Spectrum>(
    scene: &Scene,
    sppm: &Sppm,
    options: &RenderOptions,
    on_pass: &mut dyn FnMut(&PassReport),
) -> anyhow::Result<(Image, RenderStats, FilmState)> {
    if S::POLARIZED {
        anyhow::bail!("sppm does not carry polarization; render it with --mode rgb or spectral");
    }
    // Without a delta lobe in the scene no photon is a caustic: the later
    // vertices would wait for photons that never come (the same image).
    let no_caustics = !scene.bsdfs.iter().any(|b| b.lobes().intersects(Lobe::DELTA));
    let visible_only;
    let sppm = if sppm.photons == Photons::AllCaustics && no_caustics {
        visible_only = Sppm { photons: Photons::Caustics, ..sppm.clone() };
        &visible_only
    } else {
        sppm
    };
    let iterations = scene.sampler.sample_count;
    let threads = crate::render::thread_count(options);
    let pool = crate::render::thread_pool(threads)?;
    let [ox, oy, w, h] = scene.film.crop;
    let pixels = w as usize * h as usize;
    let photon_count = if sppm.photon_count > 0 {
        sppm.photon_count
    } else {
        pixels.clamp(1, 1 << 24) as u32
    };
    let bar = crate::render::progress_bar(options, pixels as u64 * iterations as u64);
    // The initial radius: the given one for every pixel, or each pixel's
    // footprint at its first visible point times `radius_footprints` (0 = not
    // yet set), or Mitsuba 0.6's guess where the camera gives no footprint.
    let (r0, footprint) = if sppm.initial_radius > 0.0 {
        (sppm.initial_radius as f64, None)
    } else {
        (0.0, Some(Sppm::pixel_footprint(scene)))
    };
    let r_fallback = sppm.radius(scene) as f64;
    // `photons = all_caustics`: the later vertices' first radius (set in
    // the first iteration, from its visible points' radii).
    let mut vertex_radius = if sppm.initial_radius > 0.0 {
        sppm.vertex_radius_scale as f64 * sppm.initial_radius as f64
    } else {
        0.0
    };
    let mut stats = vec![
        PixelStats {
            radius: r0,
            n: 0.0,
            direct: [0.0; 3]
        };
        pixels
    ];
    // How each camera path's light reaches the pixels (the film's
    // filter), and each pixel's photon flux τ per pixel its path reaches.
    let splat = Splat::new(scene)?;
    let mut tau = vec![[0.0f64; 3]; pixels * splat.slots()];
    let mut positions = vec![Vec2::ZERO; pixels];
    // Photons get their own independent random numbers.
    let photon_spec = SamplerSpec {
        kind: SamplerKind::Independent,
        seed: scene.sampler.seed ^ 0x7370_706d_7068_6f74,
        ..scene.sampler
    };
    let schedule = crate::render::pass_schedule(iterations, options.passes);
    let start = Instant::now();
    let mut done = 0u32;
    let header = crate::render::state_header::<S>(scene);
    let mut state = FilmState::empty(header.clone());
    // The buffers of an iteration, kept across iterations.
    let mut direct = vec![Rgb::zero(); pixels];
    let mut points: Vec<Option<VisiblePoint<S>>> = (0..pixels).map(|_| None).collect();
    // (and, with `camera_paths` > 1, its pixels' `PathHistory`)
    // (and the other camera paths' light where they were traced: pixel,
    // film position and light, splatted after the iteration)
    #[allow(clippy::type_complexity)]
    let mut chunk_later: Vec<(Vec<VisiblePoint<S>>, Vec<u32>, Vec<PathHistory>, Vec<(u32, Vec2, Rgb)>)> =
        (0..pixels.div_ceil(CAMERA_CHUNK)).map(|_| Default::default()).collect();
    // `camera_paths`: the main paths draw from the scene's sampler as with
    // one path; the others from one of their own (another seed), each
    // pixel's taking consecutive indices, so that all iterations' together
    // are one sequence of the sampler's.
    let paths = sppm.camera_paths.max(1);
    let mut extra_spec = SamplerSpec { seed: scene.sampler.seed ^ 0x6361_6d65_7261, ..scene.sampler };
    extra_spec.set_sample_count(iterations.saturating_mul(paths - 1).max(1));
    let mut later: Vec<Option<VisiblePoint<S>>> = Vec::new();
    let mut later_pixel: Vec<u32> = Vec::new();
    let mut later_light: Vec<[f64; 3]> = Vec::new();
    let (mut sums, mut later_sums) = (Sums::default(), Sums::default());
    let (mut targets, mut later_targets) = (Vec::new(), Vec::new());
    let (mut grid, mut later_grid) = (Grid::default(), Grid::default());
    let min_len = if sppm.granularity > 0 {
        sppm.granularity as usize
    } else {
        1024
    };
    'passes: for (k, &end) in schedule.iter().enumerate() {
        while done < end {
            if options.stopped() {
                break 'passes;
            }
            let iteration = done;
            // Shared wavelengths of the iteration: a stratified sequence.
            let u = ((iteration as f64 * 0.618_033_988_749_894_9
                + (mix64(scene.sampler.seed) >> 11) as f64 / (1u64 << 53) as f64)
                % 1.0) as f32;
            let wl = S::sample_wavelengths(u.min(1.0 - f32::EPSILON));
            // One camera path per pixel, in chunks whose later gather
            // points are appended in pixel order.
            pool.install(|| {
                direct
                    .par_chunks_mut(CAMERA_CHUNK)
                    .zip(points.par_chunks_mut(CAMERA_CHUNK))
                    .zip(positions.par_chunks_mut(CAMERA_CHUNK))
                    .zip(chunk_later.par_iter_mut())
                    .enumerate()
                    .for_each(|(c, (((direct, points), positions), (later, later_pixel, history, others)))| {
                        later.clear();
                        later_pixel.clear();
                        others.clear();
                        if paths > 1 && history.len() != direct.len() {
                            history.resize(direct.len(), PathHistory::default());
                        }
                        for (j, ((d, vp), pos)) in direct.iter_mut().zip(points.iter_mut()).zip(positions.iter_mut()).enumerate() {
                            let i = c * CAMERA_CHUNK + j;
                            let (px, py) = (ox + (i % w as usize) as u32, oy + (i / w as usize) as u32);
                            let main = sppm.camera_path::<S>(scene, px, py, (&scene.sampler, iteration), wl, later, false);
                            (*d, *vp, *pos) = (main.light, main.vp, main.pos - Vec2::new(ox as f32, oy as f32));
                            if paths > 1 {
                                // The other paths where they pay (decided on
                                // earlier paths only, so the average stays
                                // unbiased): their light up to their
                                // visible points, averaged with the main
                                // path's.
                                let h = &mut history[j];
                                if h.wants_more(iteration) {
                                    // Each path's light counts where it
                                    // started on the film (the filter).
                                    let share = 1.0 / paths as f32;
                                    for p in 0..paths - 1 {
                                        let index = iteration * (paths - 1) + p;
                                        let other = sppm.camera_path::<S>(scene, px, py, (&extra_spec, index), wl, later, true);
                                        h.add_before(other.before_vp);
                                        let at = other.pos - Vec2::new(ox as f32, oy as f32);
                                        others.push((i as u32, at, other.before_vp * share));
                                    }
                                    *d += main.before_vp * share - main.before_vp;
                                }
                                h.add_before(main.before_vp);
                                h.add_main(main.light);
                            }
                            later_pixel.resize(later.len(), i as u32);
                        }
                    })
            });
            later.clear();
            later_pixel.clear();
            for (vps, pix, _, _) in &mut chunk_later {
                later.extend(vps.drain(..).map(Some));
                later_pixel.append(pix);
            }
            if let Some((offset, spread)) = footprint {
                for (st, vp) in stats.iter_mut().zip(&points) {
                    if let (0.0, Some(vp)) = (st.radius, vp) {
                        let r = sppm.radius_footprints as f64 * (offset + spread * vp.distance) as f64;
                        st.radius = if r.is_finite() && r > 0.0 { r } else { r_fallback };
                    }
                }
            }
            sums.reset(pixels, true);
            if vertex_radius == 0.0 && sppm.photons.gathers_later() {
                let (sum, n) = stats.iter().filter(|st| st.radius > 0.0).fold((0.0, 0usize), |(s, n), st| (s + st.radius, n + 1));
                let mean = sum / n.max(1) as f64;
                vertex_radius = sppm.vertex_radius_scale as f64 * if mean > 0.0 { mean } else { r_fallback };
            }
            // The later vertices' radius: VCM's schedule, r² ∝ k^(α − 1) in
            // the k-th iteration, so that bias and variance both vanish.
            let later_r = vertex_radius * ((iteration + 1) as f64).powf((sppm.alpha as f64 - 1.0) / 2.0);
            later_sums.reset(later.len(), false);
            later_grid.entries.clear();
            later_grid.entries.extend(later.iter().enumerate().filter_map(|(j, vp)| {
                let r = later_r as f32;
                vp.as_ref().map(|vp| (GridEntry { p: vp.si.p, r2: r * r, pixel: j as u32 }, r))
            }));
            let later_ok = pool.install(|| later_grid.rebuild());
            if sppm.photons != Photons::None && pool.install(|| grid.build(&points, &stats)) {
                pool.install(|| {
                    build_targets(scene, &points, &mut targets);
                    if later_ok {
                        build_targets(scene, &later, &mut later_targets);
                    }
                });
                let visible = PhotonMap { grid: &grid, points: &points, targets: &targets, sums: &sums };
                let later = later_ok.then_some(PhotonMap {
                    grid: &later_grid,
                    points: &later,
                    targets: &later_targets,
                    sums: &later_sums,
                });
                pool.install(|| {
                    (0..photon_count).into_par_iter().with_min_len(min_len).for_each(|p| {
                        sppm.photon::<S>(scene, &photon_spec, p, iteration, wl, &visible, later.as_ref());
                    })
                });
            }
            // The later vertices' photons: each iteration's own density
            // estimate, added to its pixel's path-traced light.
            let later_scale = 1.0 / (FIXED_SCALE * photon_count.max(1) as f64 * std::f64::consts::PI * later_r * later_r);
            later_light.clear();
            later_light.resize(if later_pixel.is_empty() { 0 } else { pixels }, [0.0f64; 3]);
            if later_scale.is_finite() {
                for (j, &i) in later_pixel.iter().enumerate() {
                    for c in 0..3 {
                        later_light[i as usize][c] += later_sums.phi(j, c) as f64 * later_scale;
                    }
                }
            }
            // The iteration's path-traced light (each camera path's, and the
            // final gathers' photons at its main path's start) through the
            // film's filter into the pixels it reaches: bands of rows in
            // parallel, the even bands and then the odd (whose rows reached
            // do not meet), so each pixel's sums take the same order
            // whatever the threads.
            let band_pixels = splat.band_rows() * w as usize;
            for phase in 0..2 {
                let bands = splat.bands(&mut stats, phase);
                pool.install(|| {
                    bands.into_par_iter().for_each(|(band, first_row, stats)| {
                        let sources = band * band_pixels..((band + 1) * band_pixels).min(pixels);
                        for i in sources.clone() {
                            let d = direct[i];
                            let mut value = if d.is_finite() { [d[0] as f64, d[1] as f64, d[2] as f64] } else { [0.0; 3] };
                            if let Some(light) = later_light.get(i) {
                                for c in 0..3 {
                                    value[c] += light[c];
                                }
                            }
                            splat.add_direct(stats, first_row, i, positions[i], value);
                        }
                        // The other paths, kept by chunks of pixels.
                        let chunks = sources.start / CAMERA_CHUNK..sources.end.div_ceil(CAMERA_CHUNK);
                        for (_, _, _, others) in &chunk_later[chunks] {
                            for &(i, pos, light) in others {
                                if sources.contains(&(i as usize)) && light.is_finite() {
                                    splat.add_direct(stats, first_row, i as usize, pos, [light[0] as f64, light[1] as f64, light[2] as f64]);
                                }
                            }
                        }
                    })
                });
            }
            let alpha = sppm.alpha as f64;
            let slots = splat.slots();
            pool.install(|| {
                stats
                    .par_iter_mut()
                    .zip(tau.par_chunks_mut(slots))
                    .zip(&positions)
                    .enumerate()
                    .for_each(|(i, ((st, tau), pos))| {
                        let m = sums.points[i].count.load(Ordering::Relaxed) as f64;
                        if m > 0.0 {
                            let n_new = st.n + alpha * m;
                            let ratio = n_new / (st.n + m);
                            let phi = [0, 1, 2].map(|c| sums.phi(i, c) as f64 / FIXED_SCALE);
                            // The flux counts for each pixel the path's
                            // start reaches, by the filter's weight there.
                            // (Every slot takes the ratio: the radius
                            // shrinks for all the pixel's flux.)
                            splat.for_each_weight(i, *pos, |slot, _, weight| {
                                for c in 0..3 {
                                    tau[slot][c] = (tau[slot][c] + phi[c] * weight) * ratio;
                                }
                            });
                            st.n = n_new;
                            st.radius *= ratio.sqrt();
                        }
                    })
            });
            done += 1;
            bar.inc(pixels as u64);
        }
        state = pool.install(|| develop(photon_count, &header, &stats, &tau, &splat, done));
        let image = state.develop();
        on_pass(&PassReport {
            pass: k as u32 + 1,
            passes: schedule.len() as u32,
            spp_done: done,
            spp_total: iterations,
            elapsed_seconds: start.elapsed().as_secs_f64(),
            image: &image,
            state: &state,
            active_fraction: 1.0,
        });
    }
    if state.spp() != done {
        // Stopped between passes' ends: the iterations that did finish.
        state = pool.install(|| develop(photon_count, &header, &stats, &tau, &splat, done));
    }
    bar.finish_and_clear();
    let seconds = start.elapsed().as_secs_f64();
    let taken = state.header.samples_taken;
    let stats = RenderStats {
        width: w,
        height: h,
        spp: iterations,
        threads,
        render_seconds: seconds,
        render_cpu_seconds: 0.0, // measured by the caller, render::render_progressive
        samples_per_second: if seconds > 0.0 {
            taken as f64 / seconds
        } else {
            0.0
        },
        invalid_samples: 0,
        interrupted: done < iterations,
        samples_taken: taken,
        samples_planned: pixels as u64 * iterations as u64,
        spp_done: done,
        adaptive: None,
    };
    Ok((state.develop(), stats, state))
}

/// The film state of the image after `iterations` iterations: each pixel's
/// radiance (already filtered, [`Splat`]) as one sample of weight 1 at its
/// centre (a box).
fn develop(
    photon_count: u32,
    header: &crate::film::StateHeader,
    stats: &[PixelStats],
    tau: &[[f64; 3]],
    splat: &Splat,
    iterations: u32,
) -> FilmState {
    let mut state = FilmState::empty(header.clone());
    let [w, h] = splat.size.map(|n| n as u32);
    if iterations == 0 {
        return state;
    }
    let mut sink = Sink::new(&header.layout, 0, 0, w as usize, h as usize);
    let extra = vec![1.0f32; header.layout.extra.len()];
    let filter = Filter::new(crate::film::FilterKind::Box);
    let k = iterations as f64;
    let photons = k * photon_count.max(1) as f64;
    // Each pixel's value in parallel (the slots of the pixels around it),
    // then into the film in order.
    let values: Vec<Rgb> = stats
        .par_iter()
        .enumerate()
        .map(|(i, st)| {
            let gathered = splat.gathered(i, stats, tau, photons);
            let inv_mass = splat.inv_mass(i);
            let v = |c: usize| {
                let x = (st.direct[c] / k + gathered[c]) * inv_mass;
                if x.is_finite() { x as f32 } else { 0.0 }
            };
            Rgb::new(v(0), v(1), v(2))
        })
        .collect();
    for (i, value) in values.into_iter().enumerate() {
        let pos = Vec2::new((i % w as usize) as f32 + 0.5, (i / w as usize) as f32 + 0.5);
        sink.add_sample(&filter, pos, value, None, &extra);
    }
    state.add_sink(&sink);
    state.header.samples_taken = w as u64 * h as u64 * iterations as u64;
    state.add_range(0..iterations);
    state
}
