//! `bdpt` — bidirectional path tracing (Veach 1997, ch. 10) with multiple
//! importance sampling over every connection strategy.
//!
//! Each camera sample traces a camera subpath z₀ (the pinhole) z₁ … and a
//! light subpath y₀ (a point on an emitter) y₁ …, and joins them in every
//! way: the strategy (s, t) uses the first s light vertices and the first t
//! camera vertices, one path of s + t − 1 segments.
//!
//! - s = 0: the camera subpath hits an emitter (or leaves the scene into an
//!   environment emitter);
//! - s = 1: next-event estimation — a point on an emitter is sampled from
//!   z_{t−1} (as `path` does) and connected to it;
//! - t = 1: a light vertex y_{s−1} is connected to the pinhole and splatted
//!   onto the film where it projects (as `ptracer` does);
//! - s, t ≥ 2: y_{s−1} and z_{t−1} are joined by a shadow ray.
//!
//! Every strategy's estimate is weighted by the power heuristic
//!
//! w_{s,t} = p_{s,t}² / Σ_{i} p_{i,s+t−i}²,
//!
//! p_{i,j} being the density (area measure) with which strategy (i, j)
//! samples the same path. The ratios p_{i+1}/p_i need only each vertex's
//! forward and reverse densities, so the sum costs one pass over the two
//! subpaths (pbrt-v4's formulation). Strategies that cannot sample a path
//! are left out of its sum: connections at a vertex scattered by a delta
//! lobe (ideal mirror or glass), s = 0 for a point or spot light, and the
//! strategies switched off by `light_image` / `sample_direct`; so the
//! weights of the remaining strategies still sum to one and the image is
//! unbiased. Pixel estimates (t ≥ 2) go through the reconstruction filter;
//! splats (t = 1) are divided by the number of light subpaths, width ·
//! height · spp, as `ptracer`'s are, and weighed per pixel by the filter's
//! mass inside the window (`Sink::splat_in_window`), as the film normalizes
//! the camera samples it is combined with: else the strategies' estimates
//! differ at the window's border (up to 12 % there with `sample_direct` off).
//! With `mis` = false the splats are `ptracer`'s own.
//!
//! Light subpaths are sampled in importance transport with Veach's
//! correction for shading normals, and both subpaths end by Russian
//! roulette from depth `rr_depth` on. A dispersive BSDF met on either
//! subpath cuts the sample down to its hero wavelength.
//!
//! Emitters: light subpaths start on `area`, `point`, `spot` emitters and
//! on those at infinity (`constant`, `envmap`, `directional`): these send
//! their subpaths from the disk of the scene's bounding sphere facing the
//! direction they sample ([`Emitter::sample_ray`]), as pbrt-v4 does. Their
//! vertex is a direction: its densities are per unit solid angle (the
//! emitter's choice times its direction density from the light's side,
//! the BSDF's from the camera's), and the next vertex's density from the
//! light's side is the disk's 1/(π R²) times the cosine there; the
//! strategies s = 0 (a camera subpath leaving the scene), s = 1 and s ≥ 2
//! are weighted against each other with these. A `projector` is refused.
//! Sensor: `perspective`. Modes: `rgb` and `spectral` (the polarized modes
//! are refused).
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `max_depth` | integer | -1 | longest path in segments; -1 = unlimited, 1 = emitters seen directly |
//! | `rr_depth` | integer | 5 | depth at which Russian roulette starts |
//! | `light_image` | boolean | true | use the t = 1 strategies (light vertices connected to the camera) |
//! | `sample_direct` | boolean | true | use the s = 1 strategies (emitter sampling) |
//! | `hide_emitters` | boolean | false | emitters seen directly are black (they still block what is behind them) |
//! | `light_sampling` | string | `uniform` | emitter choice for s = 1 (`uniform`, `power`, `bvh`); light subpaths start by power unless `uniform` |
//! | `strategy_s`, `strategy_t` | integer | -1 | debugging: keep only the contributions of strategies with this s (t); -1 = all |
//! | `mis` | boolean | true | debugging: `false` weights every strategy kept by 1 (with `strategy_t` = 1: pure light tracing) |
//!
//! Mitsuba 0.6's names (`maxDepth`, `rrDepth`, `lightImage`, `sampleDirect`)
//! are read as these.
//!
//! ```xml
//! <integrator type="bdpt">
//!     <integer name="max_depth" value="8"/>
//!     <boolean name="light_image" value="true"/>
//! </integrator>
//! ```

use crate::bsdf::{BsdfContext, Lobe, TransportMode};
use crate::emitter::{Emitter, ShadingPoint};
use crate::geometry::ray::offset_origin;
use crate::geometry::{Ray, SurfaceInteraction};
use crate::integrator::ptracer::shading_correction;
use crate::math::sampling::uniform_cone_pdf;
use crate::math::SHADOW_EPSILON;
use crate::sampler::Sampler;
use crate::scene::Scene;
use crate::sensor::Perspective;
use crate::spectrum::{Rgb, Spectrum};
use glam::{Vec2, Vec3};
use std::f32::consts::PI;

#[derive(Clone, Debug)]
pub struct Bdpt {
    /// `u32::MAX` for unlimited.
    pub max_depth: u32,
    pub rr_depth: u32,
    pub light_image: bool,
    pub sample_direct: bool,
    pub hide_emitters: bool,
    /// Keep only the strategies with this s / t (debugging; weights unchanged).
    pub strategy_s: Option<u32>,
    pub strategy_t: Option<u32>,
    /// Weight strategies by MIS (else by 1: only meaningful with one strategy kept).
    pub mis: bool,
}

#[derive(Clone, Copy, Debug)]
enum Kind {
    /// The pinhole.
    Camera,
    /// A point on emitter `index` (the first vertex of a light subpath).
    Light(usize),
    /// Emitter `index` at infinity (`constant`, `envmap`, `directional`):
    /// `ns` is the direction its light travels in; `p` is a point of no
    /// meaning (the start of a light subpath on the scene's disk). Its
    /// densities are per unit solid angle (of `ns`), and the vertex after
    /// it has the disk's density 1/(π R²) projected on its surface.
    Infinite(usize),
    /// A point on a surface.
    Surface,
}

#[derive(Clone, Copy, Debug)]
struct Vertex<S> {
    kind: Kind,
    p: Vec3,
    /// Geometric normal, zero where there is none (pinhole, point light):
    /// converts solid-angle densities into area densities at this vertex.
    ng: Vec3,
    /// Normal that emission is measured from (area lights).
    ns: Vec3,
    si: Option<SurfaceInteraction>,
    ctx: BsdfContext,
    /// Throughput of the subpath up to and including this vertex.
    beta: S,
    /// Scattered by a delta lobe: cannot be connected.
    delta: bool,
    /// Area density of this vertex sampled by its own subpath, and by the other one.
    pdf_fwd: f32,
    pdf_rev: f32,
}

/// How a camera subpath left the scene.
#[derive(Clone, Copy, Debug)]
struct Escape<S> {
    d: Vec3,
    beta: S,
    /// Solid-angle density of the direction (BSDF sample); `delta` if not MIS-able.
    pdf: f32,
    delta: bool,
}

/// The subpaths of one sample, kept between samples to reuse their memory.
pub struct BdptScratch<S> {
    camera: Vec<Vertex<S>>,
    light: Vec<Vertex<S>>,
}

impl<S> Default for BdptScratch<S> {
    fn default() -> Self {
        BdptScratch { camera: Vec::new(), light: Vec::new() }
    }
}

/// What the estimators need besides the vertices.
struct Ctx<'a, S: Spectrum> {
    scene: &'a Scene,
    camera: &'a Perspective,
    wl: &'a S::Wavelengths,
}

pub(crate) fn other(mode: TransportMode) -> TransportMode {
    match mode {
        TransportMode::Radiance => TransportMode::Importance,
        TransportMode::Importance => TransportMode::Radiance,
    }
}

/// Solid-angle density with which the pinhole emits a camera ray along the
/// unit direction `d` (the film position uniform over the image): 1/(A cos³θ),
/// A the film's area at unit depth; 0 outside the image.
pub(crate) fn camera_pdf(camera: &Perspective, d: Vec3) -> f32 {
    let l = camera.to_world.inverse_vector(d);
    let len = l.length();
    if !(l.z > 0.0 && len > 0.0) {
        return 0.0;
    }
    let tan_y = camera.tan_half_x / camera.aspect;
    let (sx, sy) = (l.x / (l.z * camera.tan_half_x), l.y / (l.z * tan_y));
    let film = Vec2::new(0.5 * (1.0 - sx), 0.5 * (1.0 - sy)) - camera.principal_offset;
    if !((0.0..=1.0).contains(&film.x) && (0.0..=1.0).contains(&film.y)) {
        return 0.0;
    }
    let cos = l.z / len;
    1.0 / (4.0 * camera.tan_half_x * tan_y * cos * cos * cos)
}

/// Solid-angle density with which emitter `e` emits a light path along `d`
/// from a point with emission normal `ns` ([`Emitter::sample_ray`]).
pub(crate) fn emission_pdf(scene: &Scene, e: usize, ns: Vec3, d: Vec3) -> f32 {
    match &scene.emitters[e] {
        Emitter::Area(_) => ns.dot(d).max(0.0) / PI,
        Emitter::Point(_) => 1.0 / (4.0 * PI),
        Emitter::Spot(s) if s.axis.dot(d) > s.cos_cutoff => uniform_cone_pdf(s.cos_cutoff),
        _ => 0.0,
    }
}

/// Density with which a light subpath starts from emitter `e` at infinity
/// with its light travelling along `-towards`: its choice times the
/// solid-angle density of the direction (1 for a directional light's).
fn infinite_origin_pdf(scene: &Scene, e: usize, towards: Vec3) -> f32 {
    let pmf = scene.lights.pmf_emission(e);
    let emitter = &scene.emitters[e];
    if emitter.is_delta() { pmf } else { pmf * emitter.pdf_direction(scene, Vec3::ZERO, crate::emitter::Arrival::Escaped(towards)) }
}

/// Density per unit area with which a light subpath from infinity (along
/// `d`) reaches `v`: the disk's 1/(π R²), projected on `v`'s surface.
fn infinite_area_pdf<S>(scene: &Scene, d: Vec3, v: &Vertex<S>) -> f32 {
    let r = crate::emitter::scene_bounding_sphere(scene).1;
    let p = 1.0 / (PI * r * r);
    if v.ng != Vec3::ZERO { p * v.ng.dot(d).abs() } else { p }
}

/// Density with which a light subpath starts at a point of emitter `e`:
/// its choice times the area density (area lights sample uniformly by area).
fn origin_pdf(scene: &Scene, e: usize) -> f32 {
    let pmf = scene.lights.pmf_emission(e);
    match &scene.emitters[e] {
        Emitter::Area(a) => {
            let area = scene.shapes[a.shape as usize].area();
            if area > 0.0 { pmf / area } else { 0.0 }
        }
        _ => pmf,
    }
}

/// `pdf` (per unit solid angle at `from`) as a density per unit area at `to`
/// (as it is, per unit solid angle, for a vertex at infinity).
fn to_area<S>(pdf: f32, from: Vec3, to: &Vertex<S>) -> f32 {
    if matches!(to.kind, Kind::Infinite(_)) {
        return pdf;
    }
    let v = to.p - from;
    let d2 = v.length_squared();
    if !(d2 > 0.0) {
        return 0.0;
    }
    let mut p = pdf / d2;
    if to.ng != Vec3::ZERO {
        p *= to.ng.dot(v).abs() / d2.sqrt();
    }
    p
}

/// The fraction of light passing between points `a` and `b` (geometric
/// normals `na`, `nb`; zero for a point).
pub(crate) fn transmittance(scene: &Scene, a: Vec3, na: Vec3, b: Vec3, nb: Vec3) -> f32 {
    let d = b - a;
    let o = if na != Vec3::ZERO { offset_origin(a, na, d) } else { a };
    let target = if nb != Vec3::ZERO { offset_origin(b, nb, -d) } else { b };
    let v = target - o;
    let len = v.length();
    if !(len > 0.0) {
        return 0.0;
    }
    scene.transmittance(&Ray { o, d: v / len, tmax: len * (1.0 - SHADOW_EPSILON) })
}

impl<S: Spectrum> Vertex<S> {
    /// The camera subpath's first vertex: the pinhole at `origin`.
    fn pinhole(origin: Vec3) -> Vertex<S> {
        Vertex { kind: Kind::Camera, p: origin, ng: Vec3::ZERO, ns: Vec3::ZERO, si: None, ctx: BsdfContext::RADIANCE, beta: S::splat(1.0), delta: false, pdf_fwd: 1.0, pdf_rev: 0.0 }
    }

    fn surface(si: SurfaceInteraction, ctx: BsdfContext, beta: S) -> Self {
        Vertex { kind: Kind::Surface, p: si.p, ng: si.n, ns: si.frame.n, si: Some(si), ctx, beta, delta: false, pdf_fwd: 0.0, pdf_rev: 0.0 }
    }

    /// Whether a shadow ray may end here (a BSDF with a smooth lobe).
    fn connectible(&self, scene: &Scene) -> bool {
        match (&self.kind, &self.si) {
            (Kind::Surface, Some(si)) => scene.bsdf(si).lobes().intersects(Lobe::SMOOTH),
            _ => true,
        }
    }

    fn is_delta_light(&self, scene: &Scene) -> bool {
        matches!(self.kind, Kind::Light(e) | Kind::Infinite(e) if scene.emitters[e].is_delta())
    }

    /// Unit direction from this vertex towards `to` (towards the emitter
    /// for a vertex at infinity).
    fn direction_to(&self, to: &Vertex<S>) -> Vec3 {
        match (self.kind, to.kind) {
            (_, Kind::Infinite(_)) => -to.ns,
            (Kind::Infinite(_), _) => self.ns,
            _ => (to.p - self.p).normalize_or_zero(),
        }
    }

    /// Area density at `next` with which this vertex, reached from `prev`,
    /// samples `next` in transport `mode`.
    fn pdf(&self, c: &Ctx<S>, prev: Option<&Vertex<S>>, next: &Vertex<S>, mode: TransportMode) -> f32 {
        if matches!(self.kind, Kind::Infinite(_)) {
            return infinite_area_pdf(c.scene, self.ns, next);
        }
        let w = self.direction_to(next);
        if w == Vec3::ZERO {
            return 0.0;
        }
        let solid = match self.kind {
            Kind::Camera => camera_pdf(c.camera, w),
            Kind::Light(e) => emission_pdf(c.scene, e, self.ns, w),
            Kind::Infinite(_) => 0.0,
            Kind::Surface => {
                let (Some(si), Some(prev)) = (&self.si, prev) else { return 0.0 };
                let wp = self.direction_to(prev);
                let ctx = BsdfContext { mode, ..self.ctx };
                c.scene.bsdf(si).pdf::<S>(&ctx, si, si.to_local(wp), si.to_local(w), c.wl)
            }
        };
        to_area(solid, self.p, next)
    }

    /// The emitter at this surface vertex, if its shape emits.
    fn emitter(&self, scene: &Scene) -> Option<usize> {
        let si = self.si.as_ref()?;
        scene.shapes[si.shape as usize].emitter.map(|e| e as usize)
    }
}

impl Bdpt {
    /// Whether strategy (s, t) is used at all.
    fn allowed(&self, s: usize, t: usize) -> bool {
        t >= 1 && s + t >= 2 && !(s == 1 && t == 1) && (t != 1 || self.light_image) && (s != 1 || self.sample_direct)
    }

    /// Whether strategy (s, t)'s contributions are kept (debugging filters).
    fn kept(&self, s: usize, t: usize) -> bool {
        self.strategy_s.is_none_or(|v| v as usize == s) && self.strategy_t.is_none_or(|v| v as usize == t)
    }

    /// One camera sample through `ray`: returns the pixel estimate (strategies
    /// t ≥ 2) and its alpha, and hands the t = 1 contributions to `splat` as
    /// (film position in pixels of the full film, RGB value per light subpath).
    /// `sampler` drives the camera subpath, `light_sampler` the light subpath.
    #[allow(clippy::too_many_arguments)]
    pub fn sample<S: Spectrum>(
        &self,
        scene: &Scene,
        camera: &Perspective,
        ray: Ray,
        sampler: &mut Sampler,
        light_sampler: &mut Sampler,
        wl: &mut S::Wavelengths,
        scratch: &mut BdptScratch<S>,
        splat: &mut impl FnMut(Vec2, Rgb),
    ) -> (S, f32) {
        let BdptScratch { camera: cam, light } = scratch;
        cam.clear();
        light.clear();

        // Camera subpath: the pinhole, then up to max_depth surface vertices.
        cam.push(Vertex::pinhole(camera.origin()));
        let max_camera = (self.max_depth as usize).saturating_add(1);
        let escape = self.walk(scene, camera, ray, S::splat(1.0), camera_pdf(camera, ray.d), sampler, wl, TransportMode::Radiance, max_camera, cam);
        let alpha = if cam.len() > 1 || (escape.is_some() && scene.environment.is_some() && !self.hide_emitters) { 1.0 } else { 0.0 };

        // Light subpath: a point on an emitter, then up to max_depth − 1 surface vertices.
        let max_light = self.max_depth as usize;
        // (A lone emitter point would only serve s = 1, t = 1, which is not used.)
        if max_light >= 2 {
            if let Some((e, pmf, _)) = scene.lights.select_emission(light_sampler.next_1d()) {
                let (u_pos, u_dir) = (light_sampler.next_2d(), light_sampler.next_2d());
                if let Some(em) = scene.emitters[e].sample_ray::<S>(scene, u_pos, u_dir, wl) {
                    let infinite = em.position_weight.is_none() && matches!(scene.emitters[e], Emitter::Constant(_) | Emitter::EnvMap(_) | Emitter::Directional(_));
                    light.push(Vertex {
                        kind: if infinite { Kind::Infinite(e) } else { Kind::Light(e) },
                        p: em.p,
                        ng: em.n,
                        ns: if infinite { em.ray.d } else { em.n },
                        si: None,
                        ctx: BsdfContext::IMPORTANCE,
                        beta: S::zero(),
                        delta: false,
                        pdf_fwd: if infinite { infinite_origin_pdf(scene, e, -em.ray.d) } else { origin_pdf(scene, e) },
                        pdf_rev: 0.0,
                    });
                    let beta = em.weight / pmf;
                    if beta.max_component() > 0.0 {
                        self.walk(scene, camera, em.ray, beta, em.pdf_dir, light_sampler, wl, TransportMode::Importance, max_light, light);
                    }
                }
            }
        }

        // All connections, with the wavelengths as the subpaths left them.
        let wl: &S::Wavelengths = wl;
        let c = Ctx::<S> { scene, camera, wl };
        let size = Vec2::new(scene.film.width as f32, scene.film.height as f32);
        let mut result = S::zero();
        let (nc, nl) = (cam.len(), light.len());
        for t in 1..=nc {
            // One emitter sample per camera vertex, drawn whether used or not.
            let u_direct = if t >= 2 { sampler.next_2d() } else { Vec2::ZERO };
            for s in 0..=nl.max(1) {
                if !self.allowed(s, t) || !self.kept(s, t) || (s + t - 1) as u64 > self.max_depth as u64 {
                    continue;
                }
                if s >= 2 && s > nl {
                    continue;
                }
                if t == 1 {
                    if let Some((film, value)) = self.connect_camera(&c, cam, light, s) {
                        splat(film * size, value.to_rgb(wl));
                    }
                } else {
                    result += self.connect(&c, cam, light, s, t, u_direct);
                }
            }
        }
        if let Some(esc) = escape {
            result += self.escaped(&c, cam, &esc);
        }
        (result, alpha)
    }

    /// Extends `path` (whose last vertex is where `ray` starts) by random
    /// walk; `pdf` is the solid-angle density of `ray`'s direction (0 for a
    /// delta lobe). Returns how a camera walk left the scene.
    ///
    /// The densities kept on the vertices are those [`Vertex::pdf`] gives
    /// for the vertices' positions, not the sampled directions' own: a ray
    /// leaves a surface from a point pushed off it, so the direction to the
    /// point it hits is not quite the one sampled (some per cent apart for
    /// near points seen at grazing angles, in the corners of a room), and
    /// the strategies' weights, which meet each density once as stored here
    /// and once recomputed at a connection, would not sum to one.
    #[allow(clippy::too_many_arguments)]
    fn walk<S: Spectrum>(
        &self,
        scene: &Scene,
        camera: &Perspective,
        mut ray: Ray,
        mut beta: S,
        mut pdf: f32,
        sampler: &mut Sampler,
        wl: &mut S::Wavelengths,
        mode: TransportMode,
        max_vertices: usize,
        path: &mut Vec<Vertex<S>>,
    ) -> Option<Escape<S>> {
        let mut ctx = BsdfContext::new(mode);
        let start = beta.max_component();
        let mut eta = 1.0f32;
        let mut delta = true;
        while path.len() < max_vertices {
            let Some(si) = scene.intersect_path(&ray, false, sampler) else {
                return (mode == TransportMode::Radiance).then_some(Escape { d: ray.d, beta, pdf, delta });
            };
            let mut v = Vertex::surface(si, ctx, beta);
            let n = path.len();
            {
                let c = Ctx::<S> { scene, camera, wl: &*wl };
                let last = &path[n - 1];
                if pdf > 0.0 {
                    v.pdf_fwd = last.pdf(&c, n.checked_sub(2).map(|i| &path[i]), &v, mode);
                }
                // The vertex before `last` as reached from `v`, now that `last`'s both neighbours are known.
                if n >= 2 && !last.delta {
                    let rev = last.pdf(&c, Some(&v), &path[n - 2], other(mode));
                    path[n - 2].pdf_rev = rev;
                }
            }
            path.push(v);
            if path.len() >= max_vertices {
                break;
            }
            let bsdf = scene.bsdf(&si);
            // Past a dispersive interface the path holds for the hero wavelength only.
            if bsdf.disperses() {
                S::terminate_secondary(wl);
            }
            let Some(bs) = bsdf.sample::<S>(&ctx, &si, si.wi, sampler.next_1d(), sampler.next_2d(), wl) else { break };
            delta = bs.lobe.intersects(Lobe::DELTA);
            let mut weight = bs.weight;
            if mode == TransportMode::Importance {
                weight = weight * shading_correction(&si, si.wi, bs.wo);
            }
            beta *= weight;
            pdf = if delta { 0.0 } else { bs.pdf };
            let n = path.len();
            path[n - 1].delta = delta;
            ctx = ctx.following(bs.lobe);
            eta *= bs.eta;
            let d = si.to_world(bs.wo);
            ray = Ray::new(si.spawn_origin(d), d);

            let t_max = beta.max_component() / start;
            if !(t_max > 0.0) {
                break;
            }
            // Segments before the one just sampled: n − 1 (as `path` and `ptracer` count).
            if (n - 1) as u32 >= self.rr_depth {
                let q = if mode == TransportMode::Radiance { t_max * eta * eta } else { t_max }.min(0.95);
                if !(sampler.next_1d() < q) {
                    break;
                }
                beta *= 1.0 / q;
            }
        }
        None
    }

    /// Strategy (s, 1): light vertex y_{s−1} seen by the pinhole; its film
    /// position ([0,1]²) and value per light subpath.
    fn connect_camera<S: Spectrum>(&self, c: &Ctx<S>, cam: &[Vertex<S>], light: &[Vertex<S>], s: usize) -> Option<(Vec2, S)> {
        let qs = light.get(s.checked_sub(1)?)?;
        let si = qs.si.as_ref()?;
        if !qs.connectible(c.scene) {
            return None;
        }
        let conn = c.camera.connect(qs.p, c.scene.film.width, c.scene.film.height)?;
        let wo = si.to_local(conn.d);
        let f: S = c.scene.bsdf(si).eval(&qs.ctx, si, si.wi, wo, c.wl);
        let correction = shading_correction(si, si.wi, wo);
        if f.is_zero() || !(correction > 0.0) {
            return None;
        }
        let tr = transmittance(c.scene, qs.p, qs.ng, cam[0].p, Vec3::ZERO);
        if !(tr > 0.0) {
            return None;
        }
        let value = qs.beta * f * (tr * correction * conn.importance / (conn.dist * conn.dist));
        let w = self.mis_weight(c, cam, light, Some(&cam[0]), s, 1);
        // (A zero-weight splat would add nothing.)
        (w > 0.0).then(|| (conn.film, value * w))
    }

    /// Strategy (s, t), t ≥ 2: the pixel estimate's share.
    fn connect<S: Spectrum>(&self, c: &Ctx<S>, cam: &[Vertex<S>], light: &[Vertex<S>], s: usize, t: usize, u_direct: Vec2) -> S {
        let scene = c.scene;
        let pt = &cam[t - 1];
        let Some(si) = pt.si.as_ref() else { return S::zero() };
        if s == 0 {
            if t == 2 && self.hide_emitters {
                return S::zero();
            }
            let Some(le) = scene.emitted::<S>(si, c.wl) else { return S::zero() };
            let value = pt.beta * le;
            if value.is_zero() {
                return S::zero();
            }
            return value * self.mis_weight(c, cam, light, None, 0, t);
        }
        if !pt.connectible(scene) {
            return S::zero();
        }
        let bsdf = scene.bsdf(si);
        if s == 1 {
            // Next-event estimation from z_{t−1}.
            let Some((e, pmf, ux)) = scene.select_emitter(u_direct.x, &ShadingPoint::from(si)) else { return S::zero() };
            let Some(es) = scene.emitters[e].sample_direction::<S>(scene, si.p, Vec2::new(ux, u_direct.y), c.wl) else { return S::zero() };
            let wo = si.to_local(es.d);
            let f: S = bsdf.eval(&pt.ctx, si, si.wi, wo, c.wl);
            if f.is_zero() || es.weight.is_zero() {
                return S::zero();
            }
            let tr = match es.p {
                Some(p) => transmittance(scene, si.p, si.n, p, es.n),
                None => {
                    let o = si.spawn_origin(es.d);
                    scene.transmittance(&Ray { o, d: es.d, tmax: f32::INFINITY })
                }
            };
            if !(tr > 0.0) {
                return S::zero();
            }
            let value = pt.beta * f * es.weight * (tr / pmf);
            let w = match es.p {
                // Emitters at infinity: a vertex along the direction.
                None => {
                    let sampled = Vertex {
                        kind: Kind::Infinite(e),
                        p: si.p + es.d,
                        ng: Vec3::ZERO,
                        ns: -es.d,
                        si: None,
                        ctx: BsdfContext::IMPORTANCE,
                        beta: S::zero(),
                        delta: false,
                        pdf_fwd: infinite_origin_pdf(scene, e, es.d),
                        pdf_rev: 0.0,
                    };
                    self.mis_weight(c, cam, light, Some(&sampled), 1, t)
                }
                Some(p) => {
                    let sampled = Vertex {
                        kind: Kind::Light(e),
                        p,
                        ng: es.n,
                        ns: es.n,
                        si: None,
                        ctx: BsdfContext::IMPORTANCE,
                        beta: S::zero(),
                        delta: false,
                        pdf_fwd: origin_pdf(scene, e),
                        pdf_rev: 0.0,
                    };
                    self.mis_weight(c, cam, light, Some(&sampled), 1, t)
                }
            };
            return value * w;
        }
        // s, t ≥ 2: a shadow ray between y_{s−1} and z_{t−1}.
        let qs = &light[s - 1];
        let Some(sl) = qs.si.as_ref() else { return S::zero() };
        if !qs.connectible(scene) {
            return S::zero();
        }
        let v = qs.p - pt.p;
        let d2 = v.length_squared();
        if !(d2 > 0.0) {
            return S::zero();
        }
        let w = v / d2.sqrt();
        let f_cam: S = bsdf.eval(&pt.ctx, si, si.wi, si.to_local(w), c.wl);
        if f_cam.is_zero() {
            return S::zero();
        }
        let wo_l = sl.to_local(-w);
        let f_light: S = scene.bsdf(sl).eval(&qs.ctx, sl, sl.wi, wo_l, c.wl);
        let correction = shading_correction(sl, sl.wi, wo_l);
        if f_light.is_zero() || !(correction > 0.0) {
            return S::zero();
        }
        let tr = transmittance(scene, pt.p, pt.ng, qs.p, qs.ng);
        if !(tr > 0.0) {
            return S::zero();
        }
        let value = pt.beta * f_cam * f_light * qs.beta * (tr * correction / d2);
        value * self.mis_weight(c, cam, light, None, s, t)
    }

    /// The camera subpath left the scene: an environment emitter's light
    /// (strategy s = 0), weighted against every other strategy (emitter
    /// sampling at its last vertex, light subpaths from the environment).
    /// Appends the vertex at infinity to `cam`.
    fn escaped<S: Spectrum>(&self, c: &Ctx<S>, cam: &mut Vec<Vertex<S>>, esc: &Escape<S>) -> S {
        let t = cam.len() + 1;
        if (t == 2 && self.hide_emitters) || !self.kept(0, t) {
            return S::zero();
        }
        let (Some(env), Some(le)) = (c.scene.environment, c.scene.environment_radiance::<S>(esc.d, c.wl)) else { return S::zero() };
        let last = &cam[cam.len() - 1];
        let v = Vertex {
            kind: Kind::Infinite(env as usize),
            p: last.p + esc.d,
            ng: Vec3::ZERO,
            ns: -esc.d,
            si: None,
            ctx: BsdfContext::RADIANCE,
            beta: esc.beta,
            delta: false,
            pdf_fwd: if esc.delta { 0.0 } else { esc.pdf },
            pdf_rev: 0.0,
        };
        // The vertex before the last one as reached from the escape (as `walk` keeps it).
        let n = cam.len();
        if n >= 2 && !last.delta {
            let rev = last.pdf(c, Some(&v), &cam[n - 2], TransportMode::Importance);
            cam[n - 2].pdf_rev = rev;
        }
        cam.push(v);
        esc.beta * le * self.mis_weight(c, cam, &[], None, 0, t)
    }

    /// The power-heuristic weight of strategy (s, t) for the path it made;
    /// `sampled` is the vertex the strategy sampled anew (the emitter point
    /// for s = 1, the pinhole for t = 1).
    fn mis_weight<S: Spectrum>(&self, c: &Ctx<S>, cam: &[Vertex<S>], light: &[Vertex<S>], sampled: Option<&Vertex<S>>, s: usize, t: usize) -> f32 {
        if !self.mis || s + t == 2 {
            return 1.0;
        }
        let scene = c.scene;
        let qs: Option<&Vertex<S>> = match s {
            0 => None,
            1 => sampled,
            _ => light.get(s - 1),
        };
        let pt: &Vertex<S> = if t == 1 { sampled.unwrap_or(&cam[0]) } else { &cam[t - 1] };
        let qs_minus = if s >= 2 { light.get(s - 2) } else { None };
        let pt_minus = if t >= 2 { cam.get(t - 2) } else { None };

        // The connection's ends scatter smoothly (their delta flags are
        // dropped); the reverse densities of the two vertices at each end
        // are those of this path.
        let emitter_at_pt = if s == 0 { pt.emitter(scene) } else { None };
        let pt_rev = match (qs, pt.kind) {
            (Some(q), _) => q.pdf(c, qs_minus, pt, TransportMode::Importance),
            (None, Kind::Infinite(e)) => infinite_origin_pdf(scene, e, -pt.ns),
            (None, _) => emitter_at_pt.map_or(0.0, |e| origin_pdf(scene, e)),
        };
        let pt_minus_rev = pt_minus.map_or(0.0, |pm| match (qs, pt.kind) {
            (Some(q), _) => pt.pdf(c, Some(q), pm, TransportMode::Importance),
            (None, Kind::Infinite(_)) => pt.pdf(c, None, pm, TransportMode::Importance),
            (None, _) => emitter_at_pt.map_or(0.0, |e| to_area(emission_pdf(scene, e, pt.ns, (pm.p - pt.p).normalize_or_zero()), pt.p, pm)),
        });
        let qs_rev = qs.map_or(0.0, |q| pt.pdf(c, pt_minus, q, TransportMode::Radiance));
        let qs_minus_rev = match (qs, qs_minus) {
            (Some(q), Some(qm)) => q.pdf(c, Some(pt), qm, TransportMode::Radiance),
            _ => 0.0,
        };
        // (forward density, reverse density, delta) of the strategy's i-th camera and light vertex.
        let cam_at = |i: usize| {
            let v = &cam[i];
            if i + 1 == t {
                (v.pdf_fwd, pt_rev, false)
            } else if i + 2 == t {
                (v.pdf_fwd, pt_minus_rev, v.delta)
            } else {
                (v.pdf_fwd, v.pdf_rev, v.delta)
            }
        };
        let light_vertex = |i: usize| if s == 1 { sampled } else { light.get(i) };
        let light_at = |i: usize| {
            let Some(v) = light_vertex(i) else { return (0.0, 0.0, false) };
            if i + 1 == s {
                (v.pdf_fwd, qs_rev, false)
            } else if i + 2 == s {
                (v.pdf_fwd, qs_minus_rev, v.delta)
            } else {
                (v.pdf_fwd, v.pdf_rev, v.delta)
            }
        };

        let remap = |f: f32| if f != 0.0 { f } else { 1.0 };
        let mut sum = 0.0f32;
        let mut ri = 1.0f32;
        // Strategies that sample more of the path from the light's side.
        let mut next = cam_at(t - 1);
        for i in (1..t).rev() {
            let (cur, prev) = (next, cam_at(i - 1));
            ri *= remap(cur.1) / remap(cur.0);
            if !cur.2 && !prev.2 && self.allowed(s + t - i, i) {
                sum += ri * ri;
            }
            next = prev;
        }
        // Strategies that sample more of it from the camera's side.
        ri = 1.0;
        for i in (0..s).rev() {
            let cur = light_at(i);
            ri *= remap(cur.1) / remap(cur.0);
            let delta_light = if i > 0 { light_at(i - 1).2 } else { light_vertex(0).is_some_and(|v| v.is_delta_light(scene)) };
            if !cur.2 && !delta_light && self.allowed(i, s + t - i) {
                sum += ri * ri;
            }
        }
        let w = 1.0 / (1.0 + sum);
        if w.is_finite() { w } else { 0.0 }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spectrum::Rgb;
    use crate::{LoadOptions, load_file};
    use std::collections::HashMap;
    use std::path::Path;

    /// The path `x` (x₀ the pinhole … x_k on emitter `e`, found by a camera
    /// walk) as the camera subpath of its first t vertices and the light
    /// subpath of its last s = k + 1 − t (y₀ = x_k), each vertex's forward
    /// and reverse densities as the walks give them (those at the
    /// connection are [`Bdpt::mis_weight`]'s own).
    fn split(c: &Ctx<Rgb>, x: &[Vertex<Rgb>], e: usize, t: usize) -> (Vec<Vertex<Rgb>>, Vec<Vertex<Rgb>>) {
        let k = x.len() - 1;
        let mut cam: Vec<Vertex<Rgb>> = x[..t].to_vec();
        for i in 1..t {
            cam[i].pdf_fwd = x[i - 1].pdf(c, i.checked_sub(2).map(|j| &x[j]), &x[i], TransportMode::Radiance);
        }
        for i in 0..t.saturating_sub(2) {
            cam[i].pdf_rev = x[i + 1].pdf(c, Some(&x[i + 2]), &x[i], TransportMode::Importance);
        }
        let mut light: Vec<Vertex<Rgb>> = (0..k + 1 - t).map(|j| x[k - j]).collect();
        if let Some(y0) = light.first_mut() {
            let (kind, pdf_fwd) = match y0.kind {
                Kind::Infinite(e) => (Kind::Infinite(e), infinite_origin_pdf(c.scene, e, -y0.ns)),
                _ => (Kind::Light(e), origin_pdf(c.scene, e)),
            };
            *y0 = Vertex { kind, si: None, delta: false, pdf_fwd, pdf_rev: 0.0, ..*y0 };
        }
        let s = light.len();
        for j in 1..s {
            light[j].ctx = BsdfContext::IMPORTANCE;
            light[j].pdf_fwd = light[j - 1].pdf(c, j.checked_sub(2).map(|i| &light[i]), &light[j], TransportMode::Importance);
        }
        for j in 0..s.saturating_sub(2) {
            light[j].pdf_rev = x[k - j - 1].pdf(c, Some(&x[k - j - 2]), &x[k - j], TransportMode::Radiance);
        }
        (cam, light)
    }

    /// For paths that camera walks bring to an emitter, the weights of the
    /// strategies that are taken — by every option setting — sum to one:
    /// each strategy switched off by `light_image` / `sample_direct` (or
    /// unable to sample the path: a connection at a delta vertex) is left
    /// out of every other strategy's weight, and no strategy taken is.
    #[test]
    fn weights_of_the_strategies_taken_sum_to_one() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/scenes/cornell-glass-gold.xml");
        let params = HashMap::from([("res".to_string(), "16".to_string())]);
        let scene = load_file(&path, &LoadOptions { params, ..Default::default() }).expect("scene");
        let crate::sensor::Camera::Perspective(camera) = &scene.camera else { panic!("perspective") };
        let c = Ctx::<Rgb> { scene: &scene, camera, wl: &() };
        let mut tested = [0usize; 4];
        for (n, (light_image, sample_direct)) in [(true, true), (false, true), (true, false), (false, false)].into_iter().enumerate() {
            let bdpt = Bdpt { max_depth: 7, rr_depth: 100, light_image, sample_direct, hide_emitters: false, strategy_s: None, strategy_t: None, mis: true };
            for index in 0..20000 {
                let (x, y) = (index % 16, index / 16 % 16);
                let mut sampler = Sampler::start(&scene.sampler, x, y, index);
                let pos = (Vec2::new(x as f32, y as f32) + sampler.next_2d()) / 16.0;
                let ray = scene.camera.sample_ray(pos, &mut sampler);
                let mut path = vec![Vertex::pinhole(camera.origin())];
                bdpt.walk(&scene, camera, ray, Rgb::splat(1.0), camera_pdf(camera, ray.d), &mut sampler, &mut (), TransportMode::Radiance, 8, &mut path);
                // The densities the walk keeps are its vertices' own (see `walk`).
                let close = |a: f32, b: f32| (a - b).abs() <= 1e-4 * a.abs().max(b.abs()) + 1e-12;
                for i in 1..path.len() {
                    let fwd = if path[i - 1].delta { 0.0 } else { path[i - 1].pdf(&c, i.checked_sub(2).map(|j| &path[j]), &path[i], TransportMode::Radiance) };
                    assert!(close(path[i].pdf_fwd, fwd), "vertex {i}: forward density {} kept, {fwd} recomputed", path[i].pdf_fwd);
                    if i + 1 < path.len() && !path[i].delta {
                        let rev = path[i].pdf(&c, Some(&path[i + 1]), &path[i - 1], TransportMode::Importance);
                        assert!(close(path[i - 1].pdf_rev, rev), "vertex {}: reverse density {} kept, {rev} recomputed", i - 1, path[i - 1].pdf_rev);
                    }
                }
                // Every prefix of the walk ending on the lit side of an emitter is a path.
                for k in 2..path.len() {
                    let Some(e) = path[k].emitter(&scene) else { continue };
                    let si = path[k].si.expect("surface");
                    if scene.emitted::<Rgb>(&si, &()).is_none_or(|le| le.is_zero()) {
                        continue;
                    }
                    let x = &path[..=k];
                    let mut sum = 0.0f64;
                    let mut weights = vec![];
                    for t in 1..=k + 1 {
                        let s = k + 1 - t;
                        let (cam, light) = split(&c, x, e, t);
                        let taken = bdpt.allowed(s, t) && !cam[t - 1].delta && (s < 2 || !light[s - 1].delta);
                        if !taken {
                            continue;
                        }
                        let w = match (s, t) {
                            (1, _) => bdpt.mis_weight(&c, &cam, &[], Some(&light[0]), 1, t),
                            (_, 1) => bdpt.mis_weight(&c, &cam, &light, Some(&cam[0]), s, 1),
                            _ => bdpt.mis_weight(&c, &cam, &light, None, s, t),
                        };
                        weights.push(((s, t), w));
                        sum += w as f64;
                    }
                    if weights.len() > 1 {
                        tested[n] += 1;
                    }
                    assert!((sum - 1.0).abs() < 1e-3, "light_image {light_image}, sample_direct {sample_direct}: weights {weights:?} sum to {sum}");
                }
            }
        }
        eprintln!("paths with two strategies or more: {tested:?}");
        assert!(tested.iter().all(|&n| n >= 200), "too few paths tested: {tested:?}");
    }

    /// The weights of the strategies taken for `x` (the pinhole … x_k,
    /// x_k on emitter `e`, possibly at infinity) and their sum; `None` if
    /// fewer than two are taken.
    fn weights_of(bdpt: &Bdpt, c: &Ctx<Rgb>, x: &[Vertex<Rgb>], e: usize) -> Option<(f64, Vec<((usize, usize), f32)>)> {
        let k = x.len() - 1;
        let mut sum = 0.0f64;
        let mut weights = vec![];
        for t in 1..=k + 1 {
            let s = k + 1 - t;
            let (cam, light) = split(c, x, e, t);
            let delta_light = c.scene.emitters[e].is_delta();
            let taken = bdpt.allowed(s, t) && !cam[t - 1].delta && (s < 2 || !light[s - 1].delta) && !(s == 0 && delta_light);
            if !taken {
                continue;
            }
            let w = match (s, t) {
                (1, _) => bdpt.mis_weight(c, &cam, &[], Some(&light[0]), 1, t),
                (_, 1) => bdpt.mis_weight(c, &cam, &light, Some(&cam[0]), s, 1),
                _ => bdpt.mis_weight(c, &cam, &light, None, s, t),
            };
            weights.push(((s, t), w));
            sum += w as f64;
        }
        (weights.len() > 1).then_some((sum, weights))
    }

    /// Paths lit from infinity: camera walks that leave an open scene
    /// (tests/scenes/sky-sun-glass.xml) under its constant sky, and every
    /// prefix of a walk ending at a smooth vertex continued to its
    /// directional sun. Light subpaths start on the disk of the scene's
    /// bounding sphere (densities 1/(π R²) at the first hit, the direction's
    /// own at the emitter), camera subpaths escape with the BSDF's density:
    /// the weights of the strategies taken, by every option setting, sum to
    /// one (s = 0 is not taken for the delta sun).
    #[test]
    fn weights_sum_to_one_for_emitters_at_infinity() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/scenes/sky-sun-glass.xml");
        let params = HashMap::from([("res".to_string(), "16".to_string())]);
        let scene = load_file(&path, &LoadOptions { params, ..Default::default() }).expect("scene");
        let crate::sensor::Camera::Perspective(camera) = &scene.camera else { panic!("perspective") };
        let c = Ctx::<Rgb> { scene: &scene, camera, wl: &() };
        let sky = scene.environment.expect("sky") as usize;
        let sun = scene.emitters.iter().position(|e| matches!(e, Emitter::Directional(_))).expect("sun");
        let Emitter::Directional(light) = &scene.emitters[sun] else { unreachable!() };
        let mut tested = [[0usize; 2]; 4];
        for (n, (light_image, sample_direct)) in [(true, true), (false, true), (true, false), (false, false)].into_iter().enumerate() {
            let bdpt = Bdpt { max_depth: 7, rr_depth: 100, light_image, sample_direct, hide_emitters: false, strategy_s: None, strategy_t: None, mis: true };
            for index in 0..12000 {
                let (x, y) = (index % 16, index / 16 % 16);
                let mut sampler = Sampler::start(&scene.sampler, x, y, index);
                let pos = (Vec2::new(x as f32, y as f32) + sampler.next_2d()) / 16.0;
                let ray = scene.camera.sample_ray(pos, &mut sampler);
                let pinhole = Vertex::pinhole(camera.origin());
                let mut walk = vec![pinhole];
                let escape = bdpt.walk(&scene, camera, ray, Rgb::splat(1.0), camera_pdf(camera, ray.d), &mut sampler, &mut (), TransportMode::Radiance, 7, &mut walk);
                let at_infinity = |e: usize, last: &Vertex<Rgb>, d: Vec3, pdf_fwd: f32| Vertex {
                    kind: Kind::Infinite(e),
                    p: last.p - d,
                    ng: Vec3::ZERO,
                    ns: d,
                    si: None,
                    ctx: BsdfContext::RADIANCE,
                    beta: Rgb::zero(),
                    delta: false,
                    pdf_fwd,
                    pdf_rev: 0.0,
                };
                let mut check = |x: &[Vertex<Rgb>], e: usize, which: usize| {
                    if let Some((sum, weights)) = weights_of(&bdpt, &c, x, e) {
                        tested[n][which] += 1;
                        assert!((sum - 1.0).abs() < 1e-3, "light_image {light_image}, sample_direct {sample_direct}, emitter {e}: weights {weights:?} sum to {sum}");
                    }
                };
                if let Some(esc) = escape.filter(|esc| !esc.delta) {
                    let mut x = walk.clone();
                    let last = x[x.len() - 1];
                    x.push(at_infinity(sky, &last, -esc.d, esc.pdf));
                    check(&x, sky, 0);
                }
                for k in 1..walk.len() {
                    if walk[k].delta || !walk[k].connectible(&scene) {
                        continue;
                    }
                    let mut x = walk[..=k].to_vec();
                    x[k].delta = false;
                    let last = x[k];
                    x.push(at_infinity(sun, &last, light.direction, 0.0));
                    check(&x, sun, 1);
                }
            }
        }
        eprintln!("paths with two strategies or more (sky, sun): {tested:?}");
        assert!(tested.iter().all(|t| t.iter().all(|&n| n >= 200)), "too few paths tested: {tested:?}");
    }
}
