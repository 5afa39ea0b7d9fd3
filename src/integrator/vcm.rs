//! `vcm` — vertex connection and merging (Georgiev, Křivánek, Davidovič and
//! Slusallek 2012; Hachisuka, Pantaleoni and Jensen's "unified path
//! sampling" of the same year): bidirectional path tracing and photon
//! mapping weighed against each other by one multiple importance sampling.
//!
//! Each iteration (one sample index of the sampler: `sample_count`
//! iterations)
//!
//! 1. traces `photon_count` light subpaths from the finite emitters (light
//!    subpath `i` of iteration `k` is a pure function of the seed, `k` and
//!    `i`), keeps their vertices at surfaces with a smooth lobe, connects
//!    each of those to the pinhole (splatted onto the film, as `bdpt`'s
//!    t = 1 strategies) and builds a hash grid over them;
//! 2. traces one camera subpath per pixel; at each of its vertices it adds
//!    the emission met there, and where the BSDF has a smooth lobe it samples
//!    an emitter (next-event estimation), connects the vertex to every
//!    vertex of the light subpath of the same index (pixel index modulo
//!    `photon_count`) and merges it with the light vertices within the
//!    iteration's radius r (a density estimate: photon mapping).
//!
//! Every estimate is weighted by the power heuristic over all the ways of
//! sampling its path — every connection (s, t) and every merge — with the
//! recursive quantities dVCM, dVC, dVM that each subpath carries (Georgiev's
//! technical report, "Implementing vertex connection and merging"); a merge
//! counts as a strategy of density η = photon_count · π r² times the
//! connection's. So the caustics that bidirectional connections sample
//! badly (a small light focused by glass onto a diffuse floor) come from
//! merging, the diffuse light from connections, and paths that no
//! connection can sample — a caustic seen through glass (specular–diffuse–
//! specular) — from merging alone.
//!
//! The radius shrinks as r_k = r₀ · (k + 1)^((α − 1)/2) over the iterations
//! k = 0, 1, … (α = 0.75 by default, the VCM papers' value; `sppm` uses 2/3),
//! so the merges' bias vanishes and the image converges; with `mode = bpt`
//! the image is unbiased (bidirectional path tracing with the light image,
//! all connections of one light subpath to one camera subpath).
//!
//! Emitters: light subpaths start on `area`, `point` and `spot` emitters,
//! chosen by the emission probabilities of [`crate::emitter`]'s selector
//! renormalized over these. Emitters at infinity (`constant`, `envmap`,
//! `directional`) are reached by camera subpaths only: by leaving the scene
//! and by next-event estimation, weighted against each other as `path`
//! weights them. In `mode = ppm` (camera subpaths stop at their first
//! smooth vertex) their light is therefore missing there: a testing mode.
//! The densities in the weights of emitter sampling are those of choosing
//! the emitter by its emission probability and its point uniformly by area
//! (as `bdpt`'s), whatever way `light_sampling` samples it: weights stay a
//! partition of one, the image unbiased.
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `max_depth` | integer | -1 | longest path in segments; -1 = unlimited, 1 = emitters seen directly |
//! | `rr_depth` | integer | 5 | depth at which Russian roulette starts (camera and light subpaths each) |
//! | `mode` | string | `vcm` | `vcm` (connections and merging), `bpt` (connections only: bidirectional path tracing), `ppm` (merging only, at the camera subpath's first smooth vertex: progressive photon mapping) |
//! | `photon_count` | integer | -1 | light subpaths per iteration; -1 = as many as the crop window's pixels |
//! | `initial_radius` | float | 0 | merge radius of the first iteration in world units; 0 = `radius_footprints` pixel footprints at the median distance of the surfaces the camera sees |
//! | `radius_footprints` | float | 1.5 | the automatic initial radius in pixel footprints |
//! | `alpha` | float | 0.75 | radius reduction, in (0, 1): r_k² = r₀² (k + 1)^(α − 1) |
//! | `light_sampling` | string | `bvh` | emitter choice for next-event estimation (`uniform`, `power`, `bvh`: Snell's scene-wide setting); light subpaths start by the emission probabilities (power unless `uniform`) |
//!
//! ```xml
//! <integrator type="vcm">
//!     <integer name="max_depth" value="12"/>
//!     <string name="mode" value="vcm"/>
//! </integrator>
//! ```
//!
//! Modes `rgb` and `spectral`: in spectral mode all subpaths of an
//! iteration carry its wavelengths (a stratified sequence over the
//! iterations, as `sppm`'s), so that a merge or a connection joins
//! subpaths of the same wavelengths; a subpath (camera or light) that
//! passes a dispersive interface keeps its hero wavelength alone
//! ([`Spectrum::terminate_secondary`]), and so does every connection or
//! merge with a light subpath that did. The polarized modes are refused.
//! Limits: a `perspective` sensor; no `projector` emitter; the whole crop
//! window at once (no tiles). Deterministic: the image depends on the
//! scene, the seed and the sample count only — identical for any thread
//! count and pass split, and a render can be resumed (the radius is a
//! function of the iteration index).

use crate::bsdf::{BsdfContext, Lobe};
use crate::emitter::{Emitter, ShadingPoint};
use crate::film::{FilmState, Sink, window_filter_mass};
use crate::geometry::{Ray, SurfaceInteraction};
use crate::integrator::bdpt::{camera_pdf, emission_pdf, other, transmittance};
use crate::integrator::path::escaped_weight;
use crate::integrator::ptracer::shading_correction;
use crate::math::rounding::floor_i32;
use crate::math::rng::mix64;
use crate::render::RenderOptions;
use crate::sampler::{Sampler, SamplerKind, SamplerSpec};
use crate::scene::Scene;
use crate::sensor::Perspective;
use crate::spectrum::{Rgb, Spectrum};
use glam::{Vec2, Vec3};
use indicatif::ProgressBar;
use rayon::prelude::*;
use std::f32::consts::PI;
use std::ops::Range;

/// Which strategies are used.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VcmMode {
    /// Connections and merging.
    Vcm,
    /// Connections only (bidirectional path tracing).
    Bpt,
    /// Merging only, at the camera subpath's first smooth vertex.
    Ppm,
}

impl VcmMode {
    pub const NAMES: [&'static str; 3] = ["vcm", "bpt", "ppm"];

    pub fn from_name(name: &str) -> Option<VcmMode> {
        match name {
            "vcm" => Some(VcmMode::Vcm),
            "bpt" => Some(VcmMode::Bpt),
            "ppm" => Some(VcmMode::Ppm),
            _ => None,
        }
    }
}

#[derive(Clone, Debug)]
pub struct Vcm {
    /// `u32::MAX` for unlimited.
    pub max_depth: u32,
    pub rr_depth: u32,
    pub mode: VcmMode,
    /// Light subpaths per iteration; 0 = as many as the crop window's pixels.
    pub photon_count: u32,
    /// World units; 0 = automatic ([`Vcm::initial_radius`]).
    pub initial_radius: f32,
    pub radius_footprints: f32,
    pub alpha: f32,
}

/// The power heuristic's measure of a density (ratio).
#[inline]
fn mis(x: f32) -> f32 {
    x * x
}

/// A light subpath's vertex at a surface with a smooth lobe.
#[derive(Clone, Copy, Debug)]
struct LightVertex<S> {
    si: SurfaceInteraction,
    ctx: BsdfContext,
    /// Throughput of the subpath up to and including this vertex.
    beta: S,
    /// Segments from the emitter.
    length: u32,
    /// The subpath passed a dispersive interface: it holds for the hero
    /// wavelength only (spectral mode).
    dispersed: bool,
    d_vcm: f32,
    d_vc: f32,
    d_vm: f32,
}

/// The MIS state of a subpath at its last vertex.
#[derive(Clone, Copy, Debug)]
struct Mis {
    d_vcm: f32,
    d_vc: f32,
    d_vm: f32,
}

impl Mis {
    /// Arrived at a surface `dist2` away with cosine `cos` (geometric
    /// normal) to the incoming direction: solid-angle densities become
    /// area densities at this vertex.
    fn arrive(&mut self, dist2: f32, cos: f32) {
        let c = mis(cos);
        self.d_vcm *= mis(dist2) / c;
        self.d_vc /= c;
        self.d_vm /= c;
    }

    /// Scattered into a direction of cosine `cos_out` (geometric normal),
    /// sampled with solid-angle density `pdf` (forward) whose reverse is
    /// `rev`; `delta` for a delta lobe.
    fn scatter(&mut self, it: &Iteration, delta: bool, cos_out: f32, pdf: f32, rev: f32) {
        if delta {
            self.d_vcm = 0.0;
            self.d_vc *= mis(cos_out);
            self.d_vm *= mis(cos_out);
        } else {
            let g = mis(cos_out / pdf);
            self.d_vc = g * (self.d_vc * mis(rev) + self.d_vcm + it.mis_vm);
            self.d_vm = g * (self.d_vm * mis(rev) + self.d_vcm * it.mis_vc + 1.0);
            self.d_vcm = mis(1.0 / pdf);
        }
    }
}

/// Constants of one iteration.
struct Iteration {
    radius: f32,
    /// Light subpaths of the iteration.
    n_light: f32,
    /// Camera subpaths per unit of the film's (full) image area: its pixels.
    n_camera: f32,
    /// 1 / (π r² · n_light): a merge's density-estimation kernel.
    vm_norm: f32,
    /// mis(η), mis(1/η), η = π r² n_light; zero where merging (connection) is off.
    mis_vm: f32,
    mis_vc: f32,
    use_vc: bool,
    use_vm: bool,
}

/// What the subpaths share.
struct Common<'a> {
    scene: &'a Scene,
    camera: &'a Perspective,
    /// Finite emitters light subpaths start on, with their choice probabilities (summing to one).
    lights: Vec<(usize, f32)>,
}

impl Common<'_> {
    /// Choice probability of emitter `e` for a light subpath.
    fn pmf(&self, e: usize) -> f32 {
        self.lights.iter().find(|l| l.0 == e).map_or(0.0, |l| l.1)
    }

    /// Density (per unit area; per position for a point or spot light) of
    /// a light subpath starting at a point of emitter `e`: the density the
    /// weights give emitter sampling too.
    fn origin_pdf(&self, e: usize) -> f32 {
        let pmf = self.pmf(e);
        match &self.scene.emitters[e] {
            Emitter::Area(a) => {
                let area = self.scene.shapes[a.shape as usize].area();
                if area > 0.0 { pmf / area } else { 0.0 }
            }
            _ => pmf,
        }
    }

    fn select(&self, u: f32) -> Option<(usize, f32)> {
        let mut acc = 0.0;
        for &(e, p) in &self.lights {
            acc += p;
            if u < acc {
                return Some((e, p));
            }
        }
        self.lights.last().copied()
    }
}

/// Light vertices of an iteration, with a uniform hash grid over them.
struct Grid {
    cell: f32,
    mask: usize,
    /// Bucket b holds `items[starts[b]..starts[b + 1]]`.
    starts: Vec<u32>,
    items: Vec<u32>,
}

impl Grid {
    fn build<S>(vertices: &[LightVertex<S>], radius: f32) -> Grid {
        let cell = 2.0 * radius;
        let buckets = vertices.len().max(1).next_power_of_two();
        let mut grid = Grid { cell, mask: buckets - 1, starts: vec![0; buckets + 1], items: vec![0; vertices.len()] };
        let keys: Vec<usize> = vertices.iter().map(|v| grid.bucket(grid.cell_of(v.si.p))).collect();
        for &k in &keys {
            grid.starts[k + 1] += 1;
        }
        for b in 0..buckets {
            grid.starts[b + 1] += grid.starts[b];
        }
        let mut fill = grid.starts.clone();
        for (i, &k) in keys.iter().enumerate() {
            grid.items[fill[k] as usize] = i as u32;
            fill[k] += 1;
        }
        grid
    }

    fn cell_of(&self, p: Vec3) -> [i32; 3] {
        let c = p / self.cell;
        [floor_i32(c.x), floor_i32(c.y), floor_i32(c.z)]
    }

    fn bucket(&self, c: [i32; 3]) -> usize {
        let h = (c[0] as u32).wrapping_mul(73_856_093) ^ (c[1] as u32).wrapping_mul(19_349_663) ^ (c[2] as u32).wrapping_mul(83_492_791);
        h as usize & self.mask
    }

    /// The light vertices of the (at most eight, distinct) buckets of the
    /// cells that a ball of the grid's radius around `p` touches.
    fn near(&self, p: Vec3, mut visit: impl FnMut(u32)) {
        let r = 0.5 * self.cell;
        let (lo, hi) = (self.cell_of(p - Vec3::splat(r)), self.cell_of(p + Vec3::splat(r)));
        let mut seen = [usize::MAX; 8];
        let mut n = 0;
        for x in lo[0]..=hi[0].min(lo[0] + 1) {
            for y in lo[1]..=hi[1].min(lo[1] + 1) {
                for z in lo[2]..=hi[2].min(lo[2] + 1) {
                    let b = self.bucket([x, y, z]);
                    if seen[..n].contains(&b) {
                        continue;
                    }
                    seen[n] = b;
                    n += 1;
                    for &i in &self.items[self.starts[b] as usize..self.starts[b + 1] as usize] {
                        visit(i);
                    }
                }
            }
        }
    }
}

impl Vcm {
    /// The merge radius of the first iteration: `initial_radius`, or
    /// `radius_footprints` pixel footprints at the median distance of the
    /// surfaces seen through a 16 × 16 grid of pixels (5 × the scene's
    /// bounding radius over the film's larger side where nothing is seen).
    pub fn initial_radius(&self, scene: &Scene) -> f32 {
        if self.initial_radius > 0.0 {
            return self.initial_radius;
        }
        let (offset, spread) = crate::integrator::Sppm::pixel_footprint(scene);
        let mut dists = vec![];
        for j in 0..16 {
            for i in 0..16 {
                let pos = Vec2::new((i as f32 + 0.5) / 16.0, (j as f32 + 0.5) / 16.0);
                let ray = scene.camera.generate_ray(pos);
                if let Some(si) = scene.intersect(&ray) {
                    dists.push((si.p - ray.o).length());
                }
            }
        }
        dists.sort_by(f32::total_cmp);
        let r = dists.get(dists.len() / 2).map_or(0.0, |&d| self.radius_footprints * (offset + spread * d));
        if r.is_finite() && r > 0.0 {
            return r;
        }
        let sphere = crate::emitter::scene_bounding_sphere(scene).1;
        let r = 5.0 * sphere / scene.film.width.max(scene.film.height).max(1) as f32;
        if r.is_finite() && r > 0.0 { r } else { 1e-3 }
    }

    fn iteration(&self, scene: &Scene, r0: f32, k: u32, n_light: u32) -> Iteration {
        let radius = (r0 * ((k as f64 + 1.0).powf(0.5 * (self.alpha as f64 - 1.0))) as f32).max(1e-7);
        let n = n_light as f32;
        let eta = PI * radius * radius * n;
        let use_vc = self.mode != VcmMode::Ppm;
        let use_vm = self.mode != VcmMode::Bpt;
        Iteration {
            radius,
            n_light: n,
            n_camera: scene.film.width as f32 * scene.film.height as f32,
            vm_norm: 1.0 / eta,
            mis_vm: if use_vm { mis(eta) } else { 0.0 },
            mis_vc: if use_vc { mis(1.0 / eta) } else { 0.0 },
            use_vc,
            use_vm,
        }
    }

    /// Light subpath `index` of iteration `k`: appends its stored vertices
    /// to `out` and its connections to the camera to `splats` (film
    /// position in pixels of the full film, value per light subpath).
    #[allow(clippy::too_many_arguments)]
    fn light_path<S: Spectrum>(
        &self,
        c: &Common,
        it: &Iteration,
        spec: &SamplerSpec,
        index: u32,
        k: u32,
        wl: &S::Wavelengths,
        out: &mut Vec<LightVertex<S>>,
        splats: &mut Vec<(Vec2, Rgb)>,
    ) {
        let scene = c.scene;
        let mut sampler = Sampler::start(spec, index, k, 0);
        let (mut wl, mut dispersed) = (*wl, false);
        let wl = &mut wl;
        let Some((e, pmf)) = c.select(sampler.next_1d()) else { return };
        let (u_pos, u_dir) = (sampler.next_2d(), sampler.next_2d());
        let emitter = &scene.emitters[e];
        let Some(em) = emitter.sample_ray::<S>(scene, u_pos, u_dir, wl) else { return };
        let p_dir = emission_pdf(scene, e, em.n, em.ray.d);
        if !(p_dir > 0.0 && pmf > 0.0) {
            return;
        }
        let mut beta = em.weight * (1.0 / pmf);
        let p_area = c.origin_pdf(e);
        let cos_light = if matches!(emitter, Emitter::Area(_)) { em.n.dot(em.ray.d).abs() } else { 1.0 };
        let d_vc = if emitter.is_delta() { 0.0 } else { mis(cos_light / (p_area * p_dir)) };
        let mut m = Mis { d_vcm: mis(1.0 / p_dir), d_vc, d_vm: d_vc * it.mis_vc };
        let mut ray = em.ray;
        let mut prev = em.p;
        let mut ctx = BsdfContext::IMPORTANCE;
        let start = beta.max_component();
        let mut length = 0u32;
        loop {
            let Some(si) = scene.intersect_path(&ray, false, &mut sampler) else { return };
            length += 1;
            let cos_in = si.n.dot(ray.d).abs();
            if !(cos_in > 0.0) {
                return;
            }
            m.arrive((si.p - prev).length_squared(), cos_in);
            let bsdf = scene.bsdf(&si);
            // Past a dispersive interface the subpath holds for the hero wavelength only.
            if bsdf.disperses() {
                S::terminate_secondary(wl);
                // (RGB mode has no secondary wavelengths: nothing to keep apart.)
                dispersed = S::hero_wavelength(wl).is_some();
            }
            if bsdf.lobes().intersects(Lobe::SMOOTH) && length < self.max_depth {
                let v = LightVertex { si, ctx, beta, length, dispersed, d_vcm: m.d_vcm, d_vc: m.d_vc, d_vm: m.d_vm };
                if it.use_vc {
                    if let Some(s) = self.connect_camera(c, it, &v, wl) {
                        splats.push(s);
                    }
                }
                out.push(v);
            }
            if length.saturating_add(2) > self.max_depth {
                return;
            }
            let Some(bs) = bsdf.sample::<S>(&ctx, &si, si.wi, sampler.next_1d(), sampler.next_2d(), wl) else { return };
            let delta = bs.lobe.intersects(Lobe::DELTA);
            let wo = si.to_world(bs.wo);
            let rev = if delta { 0.0 } else { bsdf.pdf::<S>(&BsdfContext { mode: other(ctx.mode), ..ctx }, &si, bs.wo, si.wi, wl) };
            m.scatter(it, delta, si.n.dot(wo).abs(), bs.pdf, rev);
            beta *= bs.weight * shading_correction(&si, si.wi, bs.wo);
            ctx = ctx.following(bs.lobe);
            prev = si.p;
            ray = Ray::new(si.spawn_origin(wo), wo);
            let t_max = beta.max_component() / start;
            if !(t_max > 0.0) {
                return;
            }
            if length >= self.rr_depth {
                let q = t_max.min(0.95);
                if !(sampler.next_1d() < q) {
                    return;
                }
                beta *= 1.0 / q;
            }
        }
    }

    /// A light vertex seen by the pinhole: its film position (pixels of
    /// the full film) and weighted value per light subpath.
    fn connect_camera<S: Spectrum>(&self, c: &Common, it: &Iteration, v: &LightVertex<S>, wl: &S::Wavelengths) -> Option<(Vec2, Rgb)> {
        let scene = c.scene;
        let film = &scene.film;
        let conn = c.camera.connect(v.si.p, film.width, film.height)?;
        let si = &v.si;
        let wo = si.to_local(conn.d);
        let bsdf = scene.bsdf(si);
        let f: S = bsdf.eval(&v.ctx, si, si.wi, wo, wl);
        let correction = shading_correction(si, si.wi, wo);
        if f.is_zero() || !(correction > 0.0) {
            return None;
        }
        let tr = transmittance(scene, si.p, si.n, c.camera.origin(), Vec3::ZERO);
        if !(tr > 0.0) {
            return None;
        }
        let value = v.beta * f * (tr * correction * conn.importance / (conn.dist * conn.dist));
        let cam_pdf_a = camera_pdf(c.camera, -conn.d) * it.n_camera * si.n.dot(conn.d).abs() / (conn.dist * conn.dist);
        let rev = bsdf.pdf::<S>(&BsdfContext { mode: other(v.ctx.mode), ..v.ctx }, si, wo, si.wi, wl);
        let w_light = mis(cam_pdf_a / it.n_light) * (it.mis_vm + v.d_vcm + v.d_vc * mis(rev));
        let w = 1.0 / (w_light + 1.0);
        // The film divides splats by the crop window's pixels per iteration.
        let scale = w * (film.crop[2] as f32 * film.crop[3] as f32) / it.n_light;
        let rgb = value.to_rgb(wl) * scale;
        (w > 0.0).then(|| (conn.film * Vec2::new(film.width as f32, film.height as f32), rgb))
    }

    /// The camera subpath through `ray`: the pixel's estimate and alpha.
    /// In spectral mode the estimate is made of two parts: the light that
    /// holds for all of the path's wavelengths, and the light of
    /// connections and merges with light subpaths that passed a dispersive
    /// interface (for the hero wavelength only), converted to RGB apart.
    #[allow(clippy::too_many_arguments)]
    fn camera_path<S: Spectrum>(
        &self,
        c: &Common,
        it: &Iteration,
        ray: Ray,
        sampler: &mut Sampler,
        wl: &S::Wavelengths,
        light: &[LightVertex<S>],
        all: &[LightVertex<S>],
        grid: Option<&Grid>,
    ) -> (Rgb, f32) {
        let scene = c.scene;
        let mut result = S::zero();
        // Light of connections and merges with dispersed light subpaths.
        let mut hero = S::zero();
        let mut wl = *wl;
        let pc = camera_pdf(c.camera, ray.d) * it.n_camera;
        if !(pc > 0.0) {
            return (Rgb::zero(), 0.0);
        }
        let mut m = Mis { d_vcm: mis(it.n_light / pc), d_vc: 0.0, d_vm: 0.0 };
        let mut ray = ray;
        let mut prev = c.camera.origin();
        let mut beta = S::splat(1.0);
        let mut ctx = BsdfContext::RADIANCE;
        let mut length = 0u32;
        let mut specular = true;
        let mut prev_sp = ShadingPoint::at(prev);
        let (mut prev_pdf, mut prev_delta) = (0.0f32, true);
        let mut eta = 1.0f32;
        let mut alpha = 0.0;
        loop {
            let Some(si) = scene.intersect_path(&ray, false, sampler) else {
                if let Some(le) = scene.environment_radiance::<S>(ray.d, &wl) {
                    let w = if length == 0 || (!it.use_vc && specular) {
                        1.0
                    } else if it.use_vc {
                        escaped_weight(scene, &prev_sp, prev_pdf, prev_delta, ray.d)
                    } else {
                        0.0
                    };
                    if length == 0 {
                        alpha = 1.0;
                    }
                    result += beta * le * w;
                }
                break;
            };
            length += 1;
            if length == 1 {
                alpha = 1.0;
            }
            let cos_in = si.n.dot(ray.d).abs();
            if !(cos_in > 0.0) {
                break;
            }
            m.arrive((si.p - prev).length_squared(), cos_in);
            if let Some(le) = scene.emitted::<S>(&si, &wl) {
                if !le.is_zero() {
                    let w = if length == 1 || (!it.use_vc && specular) {
                        1.0
                    } else if it.use_vc {
                        let e = scene.shapes[si.shape as usize].emitter.map_or(0, |e| e as usize);
                        let p_area = c.origin_pdf(e);
                        let p_emit = p_area * emission_pdf(scene, e, si.frame.n, si.to_world(si.wi));
                        1.0 / (1.0 + mis(p_area) * m.d_vcm + mis(p_emit) * m.d_vc)
                    } else {
                        0.0
                    };
                    result += beta * le * w;
                }
            }
            if length >= self.max_depth {
                break;
            }
            let bsdf = scene.bsdf(&si);
            // Past a dispersive interface the subpath holds for the hero wavelength only.
            if bsdf.disperses() {
                S::terminate_secondary(&mut wl);
            }
            let wl = &wl;
            if bsdf.lobes().intersects(Lobe::SMOOTH) {
                if it.use_vc {
                    result += self.next_event(c, it, &si, &ctx, beta, &m, sampler, wl);
                    for v in light {
                        if v.length + 1 + length <= self.max_depth {
                            let x = self.connect(c, it, &si, &ctx, beta, &m, v, wl);
                            if v.dispersed {
                                hero += x;
                            } else {
                                result += x;
                            }
                        }
                    }
                }
                if let (true, Some(grid)) = (it.use_vm, grid) {
                    let (x, h) = self.merge(c, it, &si, &ctx, beta, &m, length, all, grid, wl);
                    result += x;
                    hero += h;
                }
            }
            let Some(bs) = bsdf.sample::<S>(&ctx, &si, si.wi, sampler.next_1d(), sampler.next_2d(), wl) else { break };
            let delta = bs.lobe.intersects(Lobe::DELTA);
            // Photon mapping alone: the smooth lobes' light is the merge's.
            if !it.use_vc && !delta {
                break;
            }
            let wo = si.to_world(bs.wo);
            let rev = if delta { 0.0 } else { bsdf.pdf::<S>(&BsdfContext { mode: other(ctx.mode), ..ctx }, &si, bs.wo, si.wi, wl) };
            m.scatter(it, delta, si.n.dot(wo).abs(), bs.pdf, rev);
            beta *= bs.weight;
            specular &= delta;
            ctx = ctx.following(bs.lobe);
            eta *= bs.eta;
            prev_sp = ShadingPoint::from(&si);
            prev_pdf = bs.pdf;
            prev_delta = delta;
            prev = si.p;
            ray = Ray::new(si.spawn_origin(wo), wo);
            let t_max = beta.max_component();
            if !(t_max > 0.0) {
                break;
            }
            if length >= self.rr_depth {
                let q = (t_max * eta * eta).min(0.95);
                if !(sampler.next_1d() < q) {
                    break;
                }
                beta *= 1.0 / q;
            }
        }
        let mut rgb = result.to_rgb(&wl);
        if !hero.is_zero() {
            S::terminate_secondary(&mut wl);
            rgb += hero.to_rgb(&wl);
        }
        (rgb, alpha)
    }

    /// Next-event estimation at camera vertex `si`.
    #[allow(clippy::too_many_arguments)]
    fn next_event<S: Spectrum>(&self, c: &Common, it: &Iteration, si: &SurfaceInteraction, ctx: &BsdfContext, beta: S, m: &Mis, sampler: &mut Sampler, wl: &S::Wavelengths) -> S {
        let scene = c.scene;
        let u = sampler.next_2d();
        let Some((e, pmf, ux)) = scene.select_emitter(u.x, &ShadingPoint::from(si)) else { return S::zero() };
        let emitter = &scene.emitters[e];
        let Some(es) = emitter.sample_direct::<S>(scene, si.p, Vec2::new(ux, u.y), wl) else { return S::zero() };
        let bsdf = scene.bsdf(si);
        let wo = si.to_local(es.d);
        let (f, pdf): (S, f32) = bsdf.eval_pdf(ctx, si, si.wi, wo, wl);
        if f.is_zero() || es.weight.is_zero() || !(pmf > 0.0) {
            return S::zero();
        }
        let tr = match es.p {
            Some(p) => transmittance(scene, si.p, si.n, p, es.n),
            None => scene.transmittance(&Ray { o: si.spawn_origin(es.d), d: es.d, tmax: f32::INFINITY }),
        };
        if !(tr > 0.0) {
            return S::zero();
        }
        let value = beta * f * es.weight * (tr / pmf);
        let w = match es.p {
            // At infinity: against BSDF sampling only, as `path` weighs them.
            None => {
                if es.delta {
                    1.0
                } else {
                    let p_light = pmf * es.pdf;
                    mis(p_light) / (mis(p_light) + mis(pdf))
                }
            }
            Some(_) => {
                let p_area = c.origin_pdf(e);
                let dist2 = es.dist * es.dist;
                let cos_light = es.n.dot(es.d).abs();
                let w_light = if emitter.is_delta() || !(p_area > 0.0 && cos_light > 0.0) { 0.0 } else { mis(pdf * cos_light / (p_area * dist2)) };
                let rev = bsdf.pdf::<S>(&BsdfContext { mode: other(ctx.mode), ..*ctx }, si, wo, si.wi, wl);
                let p_emit = emission_pdf(scene, e, es.n, -es.d);
                let w_cam = mis(p_emit * si.n.dot(es.d).abs() / dist2) * (it.mis_vm + m.d_vcm + m.d_vc * mis(rev));
                1.0 / (w_light + 1.0 + w_cam)
            }
        };
        value * w
    }

    /// Camera vertex `si` joined to light vertex `v` by a shadow ray.
    #[allow(clippy::too_many_arguments)]
    fn connect<S: Spectrum>(&self, c: &Common, it: &Iteration, si: &SurfaceInteraction, ctx: &BsdfContext, beta: S, m: &Mis, v: &LightVertex<S>, wl: &S::Wavelengths) -> S {
        let scene = c.scene;
        let d = v.si.p - si.p;
        let d2 = d.length_squared();
        if !(d2 > 0.0) {
            return S::zero();
        }
        let w = d / d2.sqrt();
        let bsdf = scene.bsdf(si);
        let wo_c = si.to_local(w);
        let (f_cam, pdf_cam): (S, f32) = bsdf.eval_pdf(ctx, si, si.wi, wo_c, wl);
        if f_cam.is_zero() {
            return S::zero();
        }
        let sl = &v.si;
        let bsdf_l = scene.bsdf(sl);
        let wo_l = sl.to_local(-w);
        let (f_light, pdf_light): (S, f32) = bsdf_l.eval_pdf(&v.ctx, sl, sl.wi, wo_l, wl);
        let correction = shading_correction(sl, sl.wi, wo_l);
        if f_light.is_zero() || !(correction > 0.0) {
            return S::zero();
        }
        let tr = transmittance(scene, si.p, si.n, sl.p, sl.n);
        if !(tr > 0.0) {
            return S::zero();
        }
        let rev_cam = bsdf.pdf::<S>(&BsdfContext { mode: other(ctx.mode), ..*ctx }, si, wo_c, si.wi, wl);
        let rev_light = bsdf_l.pdf::<S>(&BsdfContext { mode: other(v.ctx.mode), ..v.ctx }, sl, wo_l, sl.wi, wl);
        let (cos_c, cos_l) = (si.n.dot(w).abs(), sl.n.dot(w).abs());
        let w_light = mis(pdf_cam * cos_l / d2) * (it.mis_vm + v.d_vcm + v.d_vc * mis(rev_light));
        let w_cam = mis(pdf_light * cos_c / d2) * (it.mis_vm + m.d_vcm + m.d_vc * mis(rev_cam));
        let weight = 1.0 / (w_light + 1.0 + w_cam);
        beta * f_cam * f_light * v.beta * (tr * correction * weight / d2)
    }

    /// Camera vertex `si` (`length` segments from the pinhole) merged with
    /// the light vertices within the radius: the light of the subpaths that
    /// hold for all wavelengths, and of those that passed a dispersive
    /// interface (hero wavelength only).
    #[allow(clippy::too_many_arguments)]
    fn merge<S: Spectrum>(
        &self,
        c: &Common,
        it: &Iteration,
        si: &SurfaceInteraction,
        ctx: &BsdfContext,
        beta: S,
        m: &Mis,
        length: u32,
        all: &[LightVertex<S>],
        grid: &Grid,
        wl: &S::Wavelengths,
    ) -> (S, S) {
        let scene = c.scene;
        let bsdf = scene.bsdf(si);
        let r2 = it.radius * it.radius;
        let (mut sum, mut hero) = (S::zero(), S::zero());
        grid.near(si.p, |i| {
            let v = &all[i as usize];
            if (v.si.p - si.p).length_squared() >= r2 || v.length + length > self.max_depth {
                return;
            }
            // Not across a corner or onto the other side of a thin wall.
            if v.si.n.dot(si.n).abs() < 0.1 {
                return;
            }
            let wo = si.to_local(v.si.to_world(v.si.wi));
            let cos = wo.z.abs();
            if !(cos > 1e-6) {
                return;
            }
            let (f, pdf): (S, f32) = bsdf.eval_pdf(ctx, si, si.wi, wo, wl);
            if f.is_zero() {
                return;
            }
            let w = if it.use_vc {
                let rev = bsdf.pdf::<S>(&BsdfContext { mode: other(ctx.mode), ..*ctx }, si, wo, si.wi, wl);
                let w_light = v.d_vcm * it.mis_vc + v.d_vm * mis(pdf);
                let w_cam = m.d_vcm * it.mis_vc + m.d_vm * mis(rev);
                1.0 / (w_light + 1.0 + w_cam)
            } else {
                1.0
            };
            let x = f * v.beta * (w / cos);
            if v.dispersed {
                hero += x;
            } else {
                sum += x;
            }
        });
        (beta * sum * it.vm_norm, beta * hero * it.vm_norm)
    }
}

/// Renders iterations `samples` of the whole crop window into `state`
/// (the render loop's pass): per iteration the light subpaths (in parallel,
/// collected in index order), their splats, the grid, then the camera
/// subpaths through [`crate::render::render_splatting`]. Returns the camera
/// samples taken and the invalid values.
#[allow(clippy::too_many_arguments)]
pub(crate) fn render_range<S: Spectrum>(
    scene: &Scene,
    vcm: &Vcm,
    options: &RenderOptions,
    pool: &rayon::ThreadPool,
    samples: &Range<u32>,
    rect: [u32; 4],
    state: &mut FilmState,
    bar: &ProgressBar,
) -> anyhow::Result<(u64, u64)> {
    if S::POLARIZED {
        anyhow::bail!("the vcm integrator renders in the rgb and spectral modes only, not in a polarized mode; use path for polarization");
    }
    let crate::sensor::Camera::Perspective(camera) = &scene.camera else {
        anyhow::bail!("vcm needs a perspective sensor");
    };
    let [ox, oy, w, h] = scene.film.crop;
    if rect != [0, 0, w, h] {
        anyhow::bail!("vcm renders the whole crop window at once (its light subpaths serve every pixel); it cannot render tiles");
    }
    let finite: Vec<(usize, f32)> = (0..scene.emitters.len())
        .filter(|&e| matches!(scene.emitters[e], Emitter::Area(_) | Emitter::Point(_) | Emitter::Spot(_)))
        .map(|e| (e, scene.lights.pmf_emission(e)))
        .filter(|&(_, p)| p > 0.0 && p.is_finite())
        .collect();
    let total: f32 = finite.iter().map(|l| l.1).sum();
    let c = Common { scene, camera, lights: finite.into_iter().map(|(e, p)| (e, p / total)).collect() };
    let n_light = if vcm.photon_count > 0 { vcm.photon_count } else { (w as u64 * h as u64).clamp(1, 1 << 24) as u32 };
    let r0 = vcm.initial_radius(scene);
    let spec = SamplerSpec { kind: SamplerKind::Independent, seed: scene.sampler.seed ^ 0x7663_6d6c_6967_6874, ..scene.sampler };
    let offset = Vec2::new(ox as f32, oy as f32);
    let inv_size = Vec2::new(1.0 / scene.film.width as f32, 1.0 / scene.film.height as f32);
    let n_extra = state.header.layout.extra.len();
    let has_alpha = scene.film.pixel_format.has_alpha();
    let mass = (window_filter_mass(&scene.film.filter, w), window_filter_mass(&scene.film.filter, h));
    let border = (scene.film.filter.radius() + 0.5).ceil() as i32;
    let (mut taken, mut invalid) = (0u64, 0u64);
    const CHUNK: u32 = 256;
    for k in samples.clone() {
        if options.stopped() {
            break;
        }
        // The iteration's wavelengths, shared by its light and camera
        // subpaths (a merge needs both at the same ones): a stratified
        // sequence over the iterations, a function of the seed and k only.
        let u = ((k as f64 * 0.618_033_988_749_894_9 + (mix64(scene.sampler.seed ^ 0x7663_6d77) >> 11) as f64 / (1u64 << 53) as f64) % 1.0) as f32;
        let wl = S::sample_wavelengths(u.min(1.0 - f32::EPSILON));
        let it = vcm.iteration(scene, r0, k, n_light);
        // Light subpaths, in chunks collected in index order.
        type Chunk<S> = (Vec<LightVertex<S>>, Vec<u32>, Vec<(Vec2, Rgb)>);
        let chunks: Vec<Chunk<S>> = pool.install(|| {
            (0..n_light.div_ceil(CHUNK))
                .into_par_iter()
                .map(|ch| {
                    let (mut verts, mut ends, mut splats) = (vec![], vec![], vec![]);
                    for i in ch * CHUNK..((ch + 1) * CHUNK).min(n_light) {
                        vcm.light_path::<S>(&c, &it, &spec, i, k, &wl, &mut verts, &mut splats);
                        ends.push(verts.len() as u32);
                    }
                    (verts, ends, splats)
                })
                .collect()
        });
        let mut all = Vec::with_capacity(chunks.iter().map(|ch| ch.0.len()).sum());
        let mut splats = Vec::with_capacity(chunks.iter().map(|ch| ch.2.len()).sum());
        let mut starts = vec![0u32];
        for (verts, ends, s) in chunks {
            let base = all.len() as u32;
            starts.extend(ends.iter().map(|e| base + e));
            all.extend(verts);
            splats.extend(s);
        }
        let grid = it.use_vm.then(|| Grid::build(&all, it.radius));
        let (all, starts, grid, it, c) = (&all, &starts, grid.as_ref(), &it, &c);
        // The light subpaths' camera connections: each worker splats an
        // equal share into its own sink (fixed-point sums: the image does
        // not depend on the split).
        let layout = &state.header.layout;
        let sinks: Vec<(Sink, u64)> = pool.broadcast(|b| {
            let (n, m) = (splats.len(), b.num_threads());
            let mut sink = Sink::new(layout, -border, -border, (w as i32 + 2 * border) as usize, (h as i32 + 2 * border) as usize);
            let mut bad = 0u64;
            for &(p, value) in &splats[n * b.index() / m..n * (b.index() + 1) / m] {
                if value.is_finite() {
                    sink.splat_in_window(&scene.film.filter, p - offset, value, &mass.0, &mass.1);
                } else {
                    bad += 1;
                }
            }
            (sink, bad)
        });
        for (sink, bad) in &sinks {
            state.add_sink(sink);
            invalid += bad;
        }
        let init = || vec![0.0f32; n_extra];
        let (t, bad) = crate::render::render_splatting(scene, options, pool, &(k..k + 1), rect, state, bar, init, |extra, x, y, index, sink, bad| {
            let mut sampler = Sampler::start(&scene.sampler, x, y, index);
            let _ = sampler.next_1d();
            let pos = Vec2::new((x - ox) as f32, (y - oy) as f32) + sampler.next_2d();
            let ray = scene.camera.sample_ray((pos + offset) * inv_size, &mut sampler);
            let i = ((y as u64 * scene.film.width as u64 + x as u64) % n_light as u64) as usize;
            let light = &all[starts[i] as usize..starts[i + 1] as usize];
            let (mut rgb, a) = vcm.camera_path::<S>(c, it, ray, &mut sampler, &wl, light, all, grid);
            if !rgb.is_finite() {
                *bad += 1;
                rgb = Rgb::BLACK;
            }
            if has_alpha && n_extra > 0 {
                extra[0] = a;
            }
            sink.add_sample(&scene.film.filter, pos, rgb, None, extra);
        });
        taken += t;
        invalid += bad;
    }
    Ok((taken, invalid))
}
