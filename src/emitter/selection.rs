//! Emitter selection: which emitter a shading point samples next-event
//! estimation from, and with what probability.
//!
//! Every integrator that samples emitters (`direct`, `path`, `ptracer`)
//! takes the strategy as its `light_sampling` parameter:
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `light_sampling` | string | `bvh` (`ptracer`: `power`) | `uniform`: every emitter equally likely (Mitsuba's choice); `power`: in proportion to each emitter's flux; `bvh`: a light BVH that weighs flux by distance and orientation to the shading point |
//!
//! ```xml
//! <integrator type="path">
//!     <string name="light_sampling" value="uniform"/>
//! </integrator>
//! ```
//!
//! (Mitsuba 3 does not know `light_sampling` and refuses a scene that sets
//! it; it chooses uniformly.) The default is `bvh`, the most efficient in
//! every scene measured (`tools/light_efficiency.py`: on
//! `scenes/many-lights.xml` several times Mitsuba's 1/(relMSE·s), see the
//! README; with one emitter all three choose the same). `ptracer` takes
//! only `uniform` or `power` and defaults to `power`: a light path starts
//! before there is a point to weigh distance and orientation by.
//!
//! **Flux.** `power` and `bvh` weigh an emitter by its flux Φ in watts (of the
//! mean of its RGB channels): an area light of radiance L (a texture: its
//! mean) on a shape of area A emits Φ = π L A from its front side; a point
//! light of intensity I, Φ = 4π I; a spot light, I times the solid angle of
//! its beam (the cone up to the middle of its falloff); a projector, π ·
//! scale · mean(E) times the area of its image plane at distance one.
//!
//! **Infinite emitters** (`constant`, `envmap`, `directional`) have no
//! position to weigh distance by, and their flux depends on how big the
//! scene is. As pbrt-v4 does, `power` and `bvh` give each of them the fixed
//! probability 1 / (number of infinite emitters + 1), and the finite ones
//! share the rest (all of it when there is no infinite emitter).
//!
//! **The light BVH** (after pbrt-v4's `BVHLightSampler`, Conty Estevez and
//! Kulla 2018): every finite emitter is bounded by a box, its flux and a cone
//! of emission — a cone of normals (axis w, half-angle θ_o) widened by θ_e,
//! the angle beyond a normal into which it still emits (π/2 for a diffuse
//! surface). A binary tree is built over these bounds by the surface area and
//! orientation heuristic (pbrt's cost: flux × the orientation measure M_Ω ×
//! surface area, thin boxes penalised). At a shading point p with normal n,
//! a node's emitters can send at most
//!
//! Φ′ = Φ · cos θ′ · |cos θ′_i|
//!
//! towards p, where θ′ = max(0, θ_w − θ_o − θ_b) with θ_w the angle between w
//! and the direction from the box's centre to p and θ_b the half-angle its
//! bounding sphere subtends from p (Φ′ = 0 past θ_o + θ_e: the emitters of
//! the node cannot reach p), and θ′_i = max(0, θ_i − θ_b) the angle of
//! incidence at p, reduced likewise; inside the bounding sphere every
//! direction counts (cos = 1). This is pbrt-v4's `LightBounds::Importance`
//! up to the distance. pbrt divides by the squared distance to the box's
//! centre clamped to the squared half-diagonal, which for a point inside a
//! big node's bounding sphere — near a wide spread of lights, i.e. almost
//! everywhere in the top levels of the tree — leaves the choice to flux
//! alone. Here (as Blender Cycles' light tree does) a node has two
//! importances, Φ′ / d²_near and Φ′ / d²_far, with d_near the distance from p
//! to the nearest point of the box (at least √0.001 half-diagonals) and
//! d_far the distance to its farthest corner, and selection walks from the
//! root to one emitter choosing the first child with probability
//!
//! 0.7 · near₀ / (near₀ + near₁) + 0.3 · far₀ / (far₀ + far₁)
//!
//! (weights measured on `scenes/many-lights.xml`: near alone errs where a
//! node's box is close but its emitters are not, far alone where the
//! distance varies across a box). Both importances are zero exactly where
//! Φ′ is, so a child that can reach p keeps a positive probability. The
//! probability of an emitter is the product of those choices, recomputed
//! by the same walk for multiple importance sampling (so it is exact, and
//! zero exactly where selection cannot pick it). Traversal reads 64-byte
//! nodes, allocates nothing and stays in f32.

use super::Emitter;
use crate::geometry::{Shape, ShapeGeometry, SurfaceInteraction};
use crate::math::sampling::DiscreteDistribution;
use crate::math::PI;
use glam::Vec3;

/// How emitters are chosen; see the module documentation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LightSampling {
    Uniform,
    Power,
    Bvh,
}

impl LightSampling {
    /// The strategy when the integrator names none (see the module
    /// documentation).
    pub const DEFAULT: LightSampling = LightSampling::Bvh;
    /// The default of `ptracer`, whose light paths start with no shading
    /// point to weigh emitters by.
    pub const DEFAULT_LIGHT_PATHS: LightSampling = LightSampling::Power;

    /// The names the `light_sampling` parameter accepts.
    pub const NAMES: [&'static str; 3] = ["uniform", "power", "bvh"];

    pub fn from_name(name: &str) -> Option<LightSampling> {
        match name {
            "uniform" => Some(LightSampling::Uniform),
            "power" => Some(LightSampling::Power),
            "bvh" => Some(LightSampling::Bvh),
            _ => None,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            LightSampling::Uniform => "uniform",
            LightSampling::Power => "power",
            LightSampling::Bvh => "bvh",
        }
    }
}

/// The point emitters are selected for: a position and a normal (the zero
/// vector when there is no surface, e.g. in a medium). The light BVH uses
/// the normal only through |cos|, so both sides of a surface count.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadingPoint {
    pub p: Vec3,
    pub n: Vec3,
}

impl ShadingPoint {
    /// A point with no surface orientation.
    pub fn at(p: Vec3) -> ShadingPoint {
        ShadingPoint { p, n: Vec3::ZERO }
    }
}

impl From<&SurfaceInteraction> for ShadingPoint {
    #[inline]
    fn from(si: &SurfaceInteraction) -> ShadingPoint {
        ShadingPoint { p: si.p, n: si.frame.n }
    }
}

/// Chooses emitters by a [`LightSampling`] strategy. Built once per scene
/// from its emitters and shapes.
#[derive(Clone, Debug)]
pub struct LightSelector {
    strategy: LightSampling,
    count: usize,
    /// Probability of each infinite emitter (power and bvh).
    p_infinite: f32,
    infinite: Vec<u32>,
    /// Over all emitters: flux for the finite ones, scaled so that every
    /// infinite one has `p_infinite` (for `power`, and for light paths).
    power: DiscreteDistribution,
    /// The light BVH over the finite emitters with positive flux (empty
    /// unless the strategy is `bvh`).
    nodes: Vec<Node>,
    /// Per emitter: its leaf's path from the root (bit k set: the second
    /// child at depth k) and its depth; `None` for emitters not in the BVH.
    trail: Vec<Option<(u64, u32)>>,
    /// Weight of the near bound in a child's probability (the far bound
    /// has the rest), and the clamp of the near distance (times the
    /// squared half-diagonal); see [`Node::importance`].
    near_weight: f32,
    near_clamp: f32,
}

/// An emitter's spatial and directional bounds (one leaf, or the union
/// over a node).
#[derive(Clone, Copy, Debug)]
struct LightBounds {
    lo: Vec3,
    hi: Vec3,
    /// Axis of the cone of normals.
    w: Vec3,
    phi: f32,
    cos_o: f32,
    cos_e: f32,
    /// sin θ_o and the box's centre.
    sin_o: f32,
    pc: Vec3,
}

/// A node of the light BVH as traversal reads it: 64 bytes, one cache
/// line. The box, the cone of normals (axis, cos θ_o, sin θ_o), cos θ_e
/// and the flux; `index` is the emitter of a leaf or, for an interior node,
/// its second child's node index (the first child follows the node), with
/// the top bit set for leaves.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
struct Node {
    lo: Vec3,
    hi: Vec3,
    w: Vec3,
    phi: f32,
    cos_o: f32,
    sin_o: f32,
    cos_e: f32,
    index: u32,
    /// Half the box's diagonal: the radius of its bounding sphere.
    r: f32,
}

const LEAF: u32 = 1 << 31;

impl Node {
    fn new(b: &LightBounds, index: u32, leaf: bool) -> Node {
        let r = ((b.hi - b.lo) * 0.5).length();
        Node { lo: b.lo, hi: b.hi, w: b.w, phi: b.phi, cos_o: b.cos_o, sin_o: b.sin_o, cos_e: b.cos_e, index: index | if leaf { LEAF } else { 0 }, r }
    }

    #[inline]
    fn leaf(&self) -> bool {
        self.index & LEAF != 0
    }

    #[inline]
    fn target(&self) -> usize {
        (self.index & !LEAF) as usize
    }

    /// How much light this node's emitters may send to `at`, bounded two
    /// ways (see the module documentation), as (Φ′, near², far²): the flux
    /// times the orientation bound, and the squared distances to the
    /// nearest point of the box (at least `clamp` times the squared
    /// half-diagonal) and to its farthest corner; the near and far
    /// importance are Φ′ / near² and Φ′ / far². Φ′ is zero exactly where no
    /// emitter of the node can reach `at`.
    #[inline(always)]
    fn importance(&self, at: &ShadingPoint, clamp: f32) -> (f32, f32, f32) {
        let half = (self.hi - self.lo) * 0.5;
        let v = at.p - (self.lo + self.hi) * 0.5;
        let r2 = self.r * self.r;
        let dc2 = v.length_squared();
        let orient = if dc2 <= r2 {
            // Inside the bounding sphere: every direction may reach p.
            1.0
        } else {
            // Direction from the centre to the point; the angle it makes
            // with the cone's axis, reduced by the cone and by the angle
            // θ_b the bounding sphere subtends.
            let inv_dist = 1.0 / dc2.sqrt();
            let cos_w = (self.w.dot(v) * inv_dist).clamp(-1.0, 1.0);
            let sin_w = sin_of(cos_w);
            let sin_b = (self.r * inv_dist).min(1.0);
            let cos_b = sin_of(sin_b);
            let cos_x = cos_sub_clamped(sin_w, cos_w, self.sin_o, self.cos_o);
            let sin_x = sin_sub_clamped(sin_w, cos_w, self.sin_o, self.cos_o);
            let cos_p = cos_sub_clamped(sin_x, cos_x, sin_b, cos_b);
            if cos_p <= self.cos_e {
                return (0.0, 1.0, 1.0);
            }
            let mut o = cos_p;
            if at.n != Vec3::ZERO {
                let cos_i = (v.dot(at.n) * inv_dist).abs().min(1.0);
                o *= cos_sub_clamped(sin_of(cos_i), cos_i, sin_b, cos_b);
            }
            o
        };
        let a = v.abs();
        let near2 = (a - half).max(Vec3::ZERO).length_squared().max(clamp * r2).max(1e-12);
        let far2 = (a + half).length_squared().max(1e-12);
        (self.phi * orient.max(0.0), near2, far2)
    }
}

/// The most levels the tree may have (bit trails are 64 bits); past
/// `BALANCED_FROM` nodes split by count, so this is never reached.
const BALANCED_FROM: u32 = 32;

/// cos(max(0, a − b)) from the sines and cosines of a and b in [0, π].
#[inline]
fn cos_sub_clamped(sin_a: f32, cos_a: f32, sin_b: f32, cos_b: f32) -> f32 {
    if cos_a > cos_b { 1.0 } else { cos_a * cos_b + sin_a * sin_b }
}

/// sin(max(0, a − b)), as [`cos_sub_clamped`].
#[inline]
fn sin_sub_clamped(sin_a: f32, cos_a: f32, sin_b: f32, cos_b: f32) -> f32 {
    if cos_a > cos_b { 0.0 } else { sin_a * cos_b - cos_a * sin_b }
}

#[inline]
fn sin_of(cos: f32) -> f32 {
    (1.0 - cos * cos).max(0.0).sqrt()
}

/// The angle between two unit vectors, accurate near 0 and π.
fn angle_between(a: Vec3, b: Vec3) -> f32 {
    if a.dot(b) < 0.0 {
        PI - 2.0 * ((a + b).length() / 2.0).min(1.0).asin()
    } else {
        2.0 * ((b - a).length() / 2.0).min(1.0).asin()
    }
}

/// The cone (axis, half-angle) holding both cones.
fn cone_union(wa: Vec3, ta: f32, wb: Vec3, tb: f32) -> (Vec3, f32) {
    let ((wa, ta), (wb, tb)) = if ta >= tb { ((wa, ta), (wb, tb)) } else { ((wb, tb), (wa, ta)) };
    if ta >= PI {
        return (wa, PI);
    }
    let td = angle_between(wa, wb);
    if (td + tb).min(PI) <= ta {
        return (wa, ta);
    }
    let t = (ta + td + tb) / 2.0;
    if t >= PI {
        return (wa, PI);
    }
    let axis = wa.cross(wb);
    if axis.length_squared() < 1e-12 {
        return (wa, PI);
    }
    let w = glam::Quat::from_axis_angle(axis.normalize(), t - ta) * wa;
    (w.normalize_or_zero(), t)
}

/// The solid-angle measure of a cone of normals (θ_o) widened by θ_e: the
/// orientation term of the build's cost.
fn orientation_measure(cos_o: f32, cos_e: f32) -> f32 {
    let theta_o = cos_o.clamp(-1.0, 1.0).acos();
    let theta_e = cos_e.clamp(-1.0, 1.0).acos();
    let theta_w = (theta_o + theta_e).min(PI);
    let sin_o = sin_of(cos_o);
    2.0 * PI * (1.0 - cos_o)
        + PI / 2.0 * (2.0 * theta_w * sin_o - (theta_o - 2.0 * theta_w).cos() - 2.0 * theta_o * sin_o + cos_o)
}

impl LightBounds {
    fn new(lo: Vec3, hi: Vec3, w: Vec3, phi: f32, cos_o: f32, cos_e: f32) -> LightBounds {
        LightBounds { lo, hi, w, phi, cos_o, cos_e, sin_o: sin_of(cos_o), pc: (lo + hi) * 0.5 }
    }

    fn union(&self, o: &LightBounds) -> LightBounds {
        if self.phi <= 0.0 {
            return *o;
        }
        if o.phi <= 0.0 {
            return *self;
        }
        let (w, theta) = cone_union(self.w, self.cos_o.clamp(-1.0, 1.0).acos(), o.w, o.cos_o.clamp(-1.0, 1.0).acos());
        LightBounds::new(self.lo.min(o.lo), self.hi.max(o.hi), w, self.phi + o.phi, theta.cos(), self.cos_e.min(o.cos_e))
    }

    fn centroid(&self) -> Vec3 {
        self.pc
    }

    fn surface_area(&self) -> f32 {
        let d = self.hi - self.lo;
        2.0 * (d.x * d.y + d.y * d.z + d.z * d.x)
    }
}

/// Flux (mean over RGB) of a colour-like triple, negative parts ignored.
fn rgb_flux(c: [f32; 3]) -> f32 {
    (c[0].max(0.0) + c[1].max(0.0) + c[2].max(0.0)) / 3.0
}

/// Mean value of a texture of emitted light, its largest if the mean is not
/// positive (so an emitting texture never gets zero flux).
fn texture_mean(t: &crate::texture::Texture) -> f32 {
    let m = t.mean();
    if m > 0.0 { m } else { t.max_value().max(0.0) }
}

/// The emission bounds of emitter `e`; `None` for infinite emitters.
fn bounds_of(e: &Emitter, shapes: &[Shape]) -> Option<LightBounds> {
    let cos_half_pi = 0.0;
    match e {
        Emitter::Area(a) => {
            let shape = shapes.get(a.shape as usize)?;
            let radiance = match &a.texture {
                Some(t) => texture_mean(t),
                None => rgb_flux(a.radiance.rgb.0),
            };
            let phi = PI * radiance * shape.area();
            let (lo, hi, w, cos_o) = match &shape.geometry {
                ShapeGeometry::Mesh(m) => {
                    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
                    for p in &m.positions {
                        lo = lo.min(*p);
                        hi = hi.max(*p);
                    }
                    // The cone of every face normal and every shading normal
                    // (which decides the side that emits).
                    let mut cone: Option<(Vec3, f32)> = None;
                    let mut add = |n: Vec3| {
                        if n != Vec3::ZERO {
                            cone = Some(match cone {
                                None => (n, 0.0),
                                Some((w, t)) => cone_union(w, t, n, 0.0),
                            });
                        }
                    };
                    for i in 0..m.triangles.len() {
                        add(m.face_normal(i));
                    }
                    if let Some(ns) = &m.normals {
                        for n in ns {
                            add(*n);
                        }
                    }
                    let (w, t) = cone.unwrap_or((Vec3::Z, PI));
                    (lo, hi, w, if t >= PI { -1.0 } else { t.cos() })
                }
                ShapeGeometry::Sphere(s) => (s.center - Vec3::splat(s.radius), s.center + Vec3::splat(s.radius), Vec3::Z, -1.0),
                ShapeGeometry::Disk(d) => {
                    let c = d.to_world.point(Vec3::ZERO);
                    let (x, y) = (d.to_world.vector(Vec3::X), d.to_world.vector(Vec3::Y));
                    let ext = (x * x + y * y).powf(0.5);
                    (c - ext, c + ext, d.normal, 1.0)
                }
                ShapeGeometry::Cylinder(c) => {
                    let (lo, hi) = c.bounds();
                    (lo, hi, c.to_world.vector(Vec3::Z).normalize_or(Vec3::Z), 0.0)
                }
            };
            Some(LightBounds::new(lo, hi, w, phi, cos_o, cos_half_pi))
        }
        Emitter::Point(l) => {
            Some(LightBounds::new(l.position, l.position, Vec3::Z, 4.0 * PI * rgb_flux(l.intensity.rgb.0), -1.0, cos_half_pi))
        }
        Emitter::Spot(s) => {
            let (cutoff, beam) = (s.cos_cutoff.clamp(-1.0, 1.0).acos(), s.cos_beam_width.clamp(-1.0, 1.0).acos());
            let solid_angle = 2.0 * PI * (1.0 - 0.5 * (s.cos_cutoff + s.cos_beam_width));
            let phi = rgb_flux(s.intensity.rgb.0) * s.texture_mean() * solid_angle;
            // A small margin keeps the cone's edge inside (a delta light
            // must never get probability zero where it shines).
            let theta_e = (cutoff - beam).max(0.0) + 1e-3;
            Some(LightBounds::new(s.position, s.position, s.axis, phi, s.cos_beam_width, theta_e.cos()))
        }
        Emitter::Projector(p) => {
            let (pos, axis) = p.position_axis();
            let (tx, ty) = (p.tan_half_x, p.tan_half_x / p.aspect);
            let phi = PI * p.scale * texture_mean(&p.irradiance) * (2.0 * tx) * (2.0 * ty);
            let cos_o = 1.0 / (1.0 + tx * tx + ty * ty).sqrt();
            Some(LightBounds::new(pos, pos, axis, phi, cos_o, cos_half_pi))
        }
        Emitter::Constant(_) | Emitter::EnvMap(_) | Emitter::Directional(_) => None,
    }
}

impl LightSelector {
    /// The selector for `strategy` over `emitters` (area emitters' shapes
    /// in `shapes`).
    pub fn new(strategy: LightSampling, emitters: &[Emitter], shapes: &[Shape]) -> LightSelector {
        let bounds: Vec<Option<LightBounds>> = emitters.iter().map(|e| bounds_of(e, shapes)).collect();
        let infinite: Vec<u32> = (0..emitters.len() as u32).filter(|&i| bounds[i as usize].is_none()).collect();
        // An emitter that emits must not get zero flux from rounding or an
        // odd spectrum: give it the smallest positive flux seen.
        let min_phi = bounds.iter().flatten().map(|b| b.phi).filter(|&p| p > 0.0 && p.is_finite()).fold(f32::INFINITY, f32::min);
        let mut bounds = bounds;
        for (b, e) in bounds.iter_mut().zip(emitters) {
            if let Some(b) = b {
                if !(b.phi > 0.0 && b.phi.is_finite()) {
                    b.phi = if emits(e) { if min_phi.is_finite() { min_phi } else { 1.0 } } else { 0.0 };
                }
            }
        }
        let finite_phi: f64 = bounds.iter().flatten().map(|b| b.phi as f64).sum();
        let has_finite = finite_phi > 0.0;
        let p_infinite = if infinite.is_empty() { 0.0 } else { 1.0 / (infinite.len() + usize::from(has_finite)) as f32 };
        let finite_share = 1.0 - p_infinite * infinite.len() as f32;
        let power = DiscreteDistribution::new(bounds.iter().map(|b| match b {
            None => p_infinite,
            Some(b) => (finite_share as f64 * b.phi as f64 / finite_phi.max(f64::MIN_POSITIVE)) as f32,
        }));
        let mut selector = LightSelector {
            strategy,
            count: emitters.len(),
            p_infinite,
            infinite,
            power,
            nodes: vec![],
            trail: vec![None; emitters.len()],
            near_weight: NEAR_WEIGHT,
            near_clamp: NEAR_CLAMP,
        };

        if strategy == LightSampling::Bvh {
            let mut items: Vec<(u32, LightBounds)> =
                bounds.iter().enumerate().filter_map(|(i, b)| b.filter(|b| b.phi > 0.0).map(|b| (i as u32, b))).collect();
            if !items.is_empty() {
                selector.build(&mut items, 0, 0);
            }
        }
        selector
    }

    pub fn strategy(&self) -> LightSampling {
        self.strategy
    }

    /// Builds the subtree over `items` (bit trail `bits` at `depth`);
    /// returns its node index.
    fn build(&mut self, items: &mut [(u32, LightBounds)], bits: u64, depth: u32) -> usize {
        let index = self.nodes.len();
        if let [(emitter, b)] = items {
            self.nodes.push(Node::new(b, *emitter, true));
            self.trail[*emitter as usize] = Some((bits, depth));
            return index;
        }
        let total = items.iter().skip(1).fold(items[0].1, |acc, (_, b)| acc.union(b));
        let split = if depth >= BALANCED_FROM { None } else { best_split(items, &total) };
        let mid = match split {
            Some((axis, at)) => {
                let key = |b: &LightBounds| b.centroid()[axis];
                items.sort_by(|a, b| key(&a.1).total_cmp(&key(&b.1)));
                items.partition_point(|(_, b)| key(b) < at).clamp(1, items.len() - 1)
            }
            None => {
                let extent = total.hi - total.lo;
                let axis = if extent.x >= extent.y && extent.x >= extent.z { 0 } else if extent.y >= extent.z { 1 } else { 2 };
                items.sort_by(|a, b| a.1.centroid()[axis].total_cmp(&b.1.centroid()[axis]));
                items.len() / 2
            }
        };
        self.nodes.push(Node::new(&total, 0, false));
        let (left, right) = items.split_at_mut(mid);
        self.build(left, bits, depth + 1);
        let second = self.build(right, bits | (1u64 << depth), depth + 1);
        self.nodes[index].index = second as u32;
        debug_assert!(second < LEAF as usize);
        index
    }

    /// Picks an emitter for `u` in [0, 1) to light `at`: its index, the
    /// probability of that choice, and `u` re-scaled to [0, 1) within it.
    #[inline]
    pub fn select(&self, u: f32, at: &ShadingPoint) -> Option<(usize, f32, f32)> {
        let n = self.count;
        if n == 0 {
            return None;
        }
        if n == 1 {
            return (self.strategy == LightSampling::Uniform || self.power.sum() > 0.0).then_some((0, 1.0, u));
        }
        match self.strategy {
            LightSampling::Uniform => {
                let scaled = u * n as f32;
                let index = (scaled as usize).min(n - 1);
                Some((index, 1.0 / n as f32, (scaled - index as f32).min(1.0 - f32::EPSILON)))
            }
            LightSampling::Power => self.select_power(u),
            LightSampling::Bvh => self.select_bvh(u, at),
        }
    }

    /// The probability with which [`LightSelector::select`] picks emitter
    /// `index` to light `at`.
    #[inline]
    pub fn pmf(&self, index: usize, at: &ShadingPoint) -> f32 {
        let n = self.count;
        if index >= n {
            return 0.0;
        }
        if n == 1 {
            return if self.strategy == LightSampling::Uniform || self.power.sum() > 0.0 { 1.0 } else { 0.0 };
        }
        match self.strategy {
            LightSampling::Uniform => 1.0 / n as f32,
            LightSampling::Power => self.power.pmf(index),
            LightSampling::Bvh => self.pmf_bvh(index, at),
        }
    }

    /// Picks an emitter for `u` independently of any shading point (the
    /// start of a light path): uniformly for `uniform`, else by power.
    pub fn select_emission(&self, u: f32) -> Option<(usize, f32, f32)> {
        match self.strategy {
            LightSampling::Uniform => self.select(u, &ShadingPoint::at(Vec3::ZERO)),
            _ => self.select_power(u),
        }
    }

    /// The probability with which [`LightSelector::select_emission`] picks
    /// emitter `index`.
    pub fn pmf_emission(&self, index: usize) -> f32 {
        match self.strategy {
            LightSampling::Uniform => self.pmf(index, &ShadingPoint::at(Vec3::ZERO)),
            _ if index < self.count && self.power.sum() > 0.0 => self.power.pmf(index),
            _ => 0.0,
        }
    }

    fn select_power(&self, u: f32) -> Option<(usize, f32, f32)> {
        if self.count == 0 || !(self.power.sum() > 0.0) {
            return None;
        }
        let (index, scaled) = self.power.sample_reuse(u);
        let pmf = self.power.pmf(index);
        (pmf > 0.0).then_some((index, pmf, scaled))
    }

    fn select_bvh(&self, mut u: f32, at: &ShadingPoint) -> Option<(usize, f32, f32)> {
        let p_inf = self.p_infinite;
        if u < p_inf * self.infinite.len() as f32 {
            let k = ((u / p_inf) as usize).min(self.infinite.len() - 1);
            let scaled = (u / p_inf - k as f32).clamp(0.0, 1.0 - f32::EPSILON);
            return Some((self.infinite[k] as usize, p_inf, scaled));
        }
        if self.nodes.is_empty() {
            return None;
        }
        let finite = 1.0 - p_inf * self.infinite.len() as f32;
        u = ((u - p_inf * self.infinite.len() as f32) / finite).clamp(0.0, 1.0 - f32::EPSILON);
        let mut pmf = finite;
        let mut node = 0usize;
        loop {
            let nd = &self.nodes[node];
            if nd.leaf() {
                // A child is only chosen with positive importance; the root
                // (a single finite emitter) is checked here.
                return (node != 0 || nd.importance(at, self.near_clamp).0 > 0.0).then_some((nd.target(), pmf, u));
            }
            let (first, second) = (node + 1, nd.target());
            let p0 = self.first_child_probability(first, second, at)?;
            if u < p0 {
                u = (u / p0).min(1.0 - f32::EPSILON);
                pmf *= p0;
                node = first;
            } else {
                let p1 = 1.0 - p0;
                u = ((u - p0) / p1).clamp(0.0, 1.0 - f32::EPSILON);
                pmf *= p1;
                node = second;
            }
        }
    }

    /// The probability of descending to the `first` child rather than the
    /// `second` one for `at`: the near and far bounds' shares of the two
    /// children, mixed by `near_weight`. Exactly 0 or 1 where only one child
    /// can reach `at`; `None` where neither can.
    #[inline(always)]
    fn first_child_probability(&self, first: usize, second: usize, at: &ShadingPoint) -> Option<f32> {
        let (f0, n0, g0) = self.nodes[first].importance(at, self.near_clamp);
        let (f1, n1, g1) = self.nodes[second].importance(at, self.near_clamp);
        if !(f1 > 0.0) {
            return (f0 > 0.0).then_some(1.0);
        }
        if !(f0 > 0.0) {
            return Some(0.0);
        }
        // f0/n0 / (f0/n0 + f1/n1), and likewise for the far bound, without
        // the divisions.
        let (a, b) = (f0 * n1, f1 * n0);
        let (c, d) = (f0 * g1, f1 * g0);
        let p0 = self.near_weight * a / (a + b) + (1.0 - self.near_weight) * c / (c + d);
        Some(if p0.is_finite() { p0.clamp(0.0, 1.0) } else { 0.5 })
    }

    fn pmf_bvh(&self, index: usize, at: &ShadingPoint) -> f32 {
        let Some((bits, depth)) = self.trail[index] else {
            return if self.infinite.contains(&(index as u32)) { self.p_infinite } else { 0.0 };
        };
        let mut pmf = 1.0 - self.p_infinite * self.infinite.len() as f32;
        let mut node = 0usize;
        for k in 0..depth {
            let (first, second) = (node + 1, self.nodes[node].target());
            let Some(p0) = self.first_child_probability(first, second, at) else { return 0.0 };
            if bits & (1u64 << k) == 0 {
                pmf *= p0;
                node = first;
            } else {
                pmf *= 1.0 - p0;
                node = second;
            }
            if !(pmf > 0.0) {
                return 0.0;
            }
        }
        if depth > 0 || self.nodes[node].importance(at, self.near_clamp).0 > 0.0 { pmf } else { 0.0 }
    }
}

/// Whether an emitter sends out any light at all.
fn emits(e: &Emitter) -> bool {
    match e {
        Emitter::Area(a) => !a.is_black(),
        Emitter::Point(l) => !l.intensity.is_zero(),
        Emitter::Spot(s) => !s.intensity.is_zero(),
        Emitter::Projector(p) => p.scale > 0.0 && p.irradiance.max_value() > 0.0,
        _ => true,
    }
}

/// The weight of the near bound in a child's probability, and the clamp of
/// the near distance in squared half-diagonals (see [`Node::importance`]).
const NEAR_WEIGHT: f32 = 0.7;
const NEAR_CLAMP: f32 = 0.001;

/// Number of buckets per axis of the binned build.
const BUCKETS: usize = 12;

/// The split (axis, centroid coordinate) of least surface area and
/// orientation cost, or `None` if no split beats keeping the node whole.
fn best_split(items: &[(u32, LightBounds)], total: &LightBounds) -> Option<(usize, f32)> {
    let (mut clo, mut chi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for (_, b) in items {
        clo = clo.min(b.centroid());
        chi = chi.max(b.centroid());
    }
    let extent = total.hi - total.lo;
    let max_extent = extent.max_element();
    let cost = |b: &LightBounds| b.phi * orientation_measure(b.cos_o, b.cos_e) * b.surface_area().max(1e-12);
    let mut best: Option<(f32, usize, f32)> = None;
    for axis in 0..3 {
        let (lo, hi) = (clo[axis], chi[axis]);
        if !(hi > lo) {
            continue;
        }
        let mut buckets: [Option<LightBounds>; BUCKETS] = [None; BUCKETS];
        let bucket_of = |c: f32| (((c - lo) / (hi - lo) * BUCKETS as f32) as usize).min(BUCKETS - 1);
        for (_, b) in items {
            let k = bucket_of(b.centroid()[axis]);
            buckets[k] = Some(match buckets[k] {
                None => *b,
                Some(acc) => acc.union(b),
            });
        }
        // Thin boxes along this axis are penalised, as pbrt does.
        let kr = if extent[axis] > 0.0 { max_extent / extent[axis] } else { 1.0 };
        for split in 1..BUCKETS {
            let side = |range: std::ops::Range<usize>| {
                buckets[range].iter().flatten().fold(None, |acc: Option<LightBounds>, b| Some(acc.map_or(*b, |a| a.union(b))))
            };
            let (Some(a), Some(b)) = (side(0..split), side(split..BUCKETS)) else { continue };
            let c = kr * (cost(&a) + cost(&b));
            if best.is_none_or(|(bc, _, _)| c < bc) {
                best = Some((c, axis, lo + (hi - lo) * split as f32 / BUCKETS as f32));
            }
        }
    }
    best.map(|(_, axis, at)| (axis, at))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Pcg32;

    #[test]
    fn cone_union_holds_both_cones() {
        let (w, t) = cone_union(Vec3::Z, 0.1, Vec3::X, 0.2);
        for (v, a) in [(Vec3::Z, 0.1f32), (Vec3::X, 0.2)] {
            assert!(angle_between(w, v) + a <= t + 1e-4, "{w:?} {t}");
        }
        assert!(t < PI / 2.0);
        assert_eq!(cone_union(Vec3::Z, PI, Vec3::X, 0.0).1, PI);
    }

    #[test]
    fn importance_is_zero_behind_a_one_sided_light_and_positive_in_front() {
        let b = Node::new(&LightBounds::new(Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, 1.0, 0.0), Vec3::Z, 1.0, 1.0, 0.0), 0, true);
        for clamp in [0.0, NEAR_CLAMP, 1.0] {
        let b = |at: &ShadingPoint| {
            let (flux, near2, far2) = b.importance(at, clamp);
            assert!(near2 > 0.0 && far2 >= near2, "{near2} {far2}");
            flux / near2
        };
        assert!(b(&ShadingPoint { p: Vec3::new(0.3, 0.0, 2.0), n: -Vec3::Z }) > 0.0);
        assert!(b(&ShadingPoint { p: Vec3::new(5.0, 0.0, 0.01), n: Vec3::Z }) > 0.0);
        assert_eq!(b(&ShadingPoint { p: Vec3::new(0.0, 0.0, -2.0), n: Vec3::Z }), 0.0);
        // Closer is more important.
        let near = b(&ShadingPoint::at(Vec3::new(0.0, 0.0, 3.0)));
        let far = b(&ShadingPoint::at(Vec3::new(0.0, 0.0, 30.0)));
        assert!(near > 50.0 * far);
        }
    }

    #[test]
    fn orientation_measure_of_a_hemisphere_emitter_and_a_sphere() {
        // A plane (θ_o = 0, θ_e = π/2): the cosine-weighted hemisphere, π.
        assert!((orientation_measure(1.0, 0.0) - PI).abs() < 1e-4);
        // θ_o = π: every direction, 4π.
        assert!((orientation_measure(-1.0, 0.0) - 4.0 * PI).abs() < 1e-3);
        let mut r = Pcg32::new(1, 2);
        for _ in 0..100 {
            let (a, b) = (r.next_f32() * 2.0 - 1.0, r.next_f32());
            assert!(orientation_measure(a, b).is_finite());
        }
    }
}
