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
//! `scenes/many-lights.xml` several times Mitsuba's 1/(relMSE·s), see
//! docs/performance.md; with one emitter all three choose the same). `ptracer` takes
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
//! d_far the distance to its farthest corner. The binary tree is then
//! collapsed into a four-wide one (each node's children are a binary
//! node's grandchildren), and selection walks from the root to one emitter
//! choosing child k of a node with probability
//!
//! 0.7 · near_k / Σ_j near_j + 0.3 · far_k / Σ_j far_j
//!
//! (weights measured on `scenes/many-lights.xml`: near alone errs where a
//! node's box is close but its emitters are not, far alone where the
//! distance varies across a box). Both importances are zero exactly where
//! Φ′ is, so a child that can reach p keeps a positive probability. The
//! probability of an emitter is the product of those choices, recomputed
//! by the same walk for multiple importance sampling (so it is exact, and
//! zero exactly where selection cannot pick it). A node holds its four
//! children's bounds as structure of arrays (256 bytes), so one pass of
//! four-lane SIMD arithmetic weighs all four; traversal allocates nothing
//! and stays in f32. (On `scenes/many-lights.xml` this halved the cost of
//! selection against the binary tree's two scalar evaluations a level.)

use super::Emitter;
use crate::geometry::{Shape, ShapeGeometry, SurfaceInteraction};
use crate::math::sampling::DiscreteDistribution;
use crate::math::PI;
use glam::{Vec3, Vec4};

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
    /// The light BVH over the finite emitters with positive flux, four
    /// children a node (empty unless the strategy is `bvh`); the root is
    /// node 0.
    nodes: Vec<Node4>,
    /// Per emitter: its leaf's path from the root (bits 2k, 2k + 1: the
    /// child taken at depth k) and its depth; `None` for emitters not in
    /// the BVH.
    trail: Vec<Option<(u128, u32)>>,
    /// Weight of the near bound in a child's probability (the far bound
    /// has the rest); see [`Node4::importance`].
    near_weight: f32,
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

/// A node of the binary light BVH the build makes (and [`Node4`] is made
/// from): the box, the cone of normals (axis, cos θ_o, sin θ_o), cos θ_e
/// and the flux; `index` is the emitter of a leaf or, for an interior node,
/// its second child's node index (the first child follows the node), with
/// the top bit set for leaves.
#[derive(Clone, Copy, Debug)]
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

/// A node of the light BVH as traversal reads it: the bounds of its (up
/// to) four children, one per lane, as structure of arrays (256 bytes,
/// four cache lines), so that one pass of lane-wise arithmetic (which the
/// compiler turns into SIMD) weighs all four. Per lane: the box's centre
/// and half extent, the cone of normals (axis, cos θ_o, sin θ_o), cos θ_e,
/// the flux, the radius of the bounding sphere, the floor of the near
/// distance (see [`Node4::importance`]), and the child: an emitter (with
/// [`LEAF`] set) or a node index. An empty lane has zero flux.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
struct Node4 {
    cx: Vec4,
    cy: Vec4,
    cz: Vec4,
    hx: Vec4,
    hy: Vec4,
    hz: Vec4,
    wx: Vec4,
    wy: Vec4,
    wz: Vec4,
    phi: Vec4,
    cos_o: Vec4,
    sin_o: Vec4,
    cos_e: Vec4,
    r: Vec4,
    near_floor: Vec4,
    child: [u32; 4],
}

/// Lane-wise square root (one SIMD instruction where there is SSE).
#[inline(always)]
fn sqrt4(v: Vec4) -> Vec4 {
    #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
    #[allow(unused_unsafe)]
    // SAFETY: SSE2 is enabled at compile time (checked by the cfg above).
    return unsafe { Vec4::from(core::arch::x86_64::_mm_sqrt_ps(v.into())) };
    #[allow(unreachable_code)]
    v.sqrt()
}

/// Lane-wise 1/√v: the SSE estimate refined by one Newton step (about 22
/// bits, against the 24 of a division; selection and its pmf use the same
/// arithmetic, so they agree exactly). Lanes where v is 0 are not finite
/// (the caller masks them).
#[inline(always)]
fn rsqrt4(v: Vec4) -> Vec4 {
    #[cfg(all(target_arch = "x86_64", target_feature = "sse"))]
    #[allow(unused_unsafe)]
    // SAFETY: SSE is enabled at compile time (checked by the cfg above).
    {
        let y = unsafe { Vec4::from(core::arch::x86_64::_mm_rsqrt_ps(v.into())) };
        return y * (Vec4::splat(1.5) - Vec4::splat(0.5) * v * y * y);
    }
    #[allow(unreachable_code)]
    (Vec4::ONE / v.sqrt())
}

impl Node4 {
    fn empty() -> Node4 {
        Node4 {
            cx: Vec4::ZERO,
            cy: Vec4::ZERO,
            cz: Vec4::ZERO,
            hx: Vec4::ZERO,
            hy: Vec4::ZERO,
            hz: Vec4::ZERO,
            wx: Vec4::ZERO,
            wy: Vec4::ZERO,
            wz: Vec4::ONE,
            phi: Vec4::ZERO,
            cos_o: Vec4::ONE,
            sin_o: Vec4::ZERO,
            cos_e: Vec4::ONE,
            r: Vec4::ZERO,
            near_floor: Vec4::ONE,
            child: [u32::MAX; 4],
        }
    }

    /// Lane `k` from a node of the binary build; `child` as stored.
    fn set(&mut self, k: usize, n: &Node, child: u32, near_clamp: f32) {
        let (c, h) = ((n.lo + n.hi) * 0.5, (n.hi - n.lo) * 0.5);
        (self.cx[k], self.cy[k], self.cz[k]) = (c.x, c.y, c.z);
        (self.hx[k], self.hy[k], self.hz[k]) = (h.x, h.y, h.z);
        (self.wx[k], self.wy[k], self.wz[k]) = (n.w.x, n.w.y, n.w.z);
        self.phi[k] = n.phi;
        self.cos_o[k] = n.cos_o;
        self.sin_o[k] = n.sin_o;
        self.cos_e[k] = n.cos_e;
        self.r[k] = n.r;
        self.near_floor[k] = (near_clamp * n.r * n.r).max(1e-12);
        self.child[k] = child;
    }

    /// How much light each child's emitters may send to `at`, bounded two
    /// ways (see the module documentation), as (Φ′, near², far²) per lane:
    /// the flux times the orientation bound, and the squared distances to
    /// the nearest point of the box (at least `near_floor`: a fraction of
    /// the squared half-diagonal) and to its farthest corner; the near and
    /// far importance are Φ′ / near² and Φ′ / far². Φ′ is zero exactly
    /// where no emitter of the child can reach `at` (and in empty lanes).
    /// Branch-free, the four lanes computed together.
    #[inline(always)]
    fn importance(&self, at: &ShadingPoint) -> (Vec4, Vec4, Vec4) {
        let (one, zero) = (Vec4::ONE, Vec4::ZERO);
        let vx = Vec4::splat(at.p.x) - self.cx;
        let vy = Vec4::splat(at.p.y) - self.cy;
        let vz = Vec4::splat(at.p.z) - self.cz;
        let dc2 = vx * vx + vy * vy + vz * vz;
        // Direction from the centre to the point; the angle it makes with
        // the cone's axis, reduced by the cone and by the angle θ_b the
        // bounding sphere subtends. (Meaningless inside the bounding
        // sphere, where the lane takes 1 below.)
        let inv_dist = rsqrt4(dc2);
        let cos_w = ((self.wx * vx + self.wy * vy + self.wz * vz) * inv_dist).max(-one).min(one);
        let sin_w = sqrt4((one - cos_w * cos_w).max(zero));
        let sin_b = (self.r * inv_dist).min(one);
        let cos_b = sqrt4((one - sin_b * sin_b).max(zero));
        let within = cos_w.cmpgt(self.cos_o);
        let cos_x = Vec4::select(within, one, cos_w * self.cos_o + sin_w * self.sin_o);
        let sin_x = Vec4::select(within, zero, sin_w * self.cos_o - cos_w * self.sin_o);
        let cos_p = Vec4::select(cos_x.cmpgt(cos_b), one, cos_x * cos_b + sin_x * sin_b);
        let incidence = if at.n == Vec3::ZERO {
            one
        } else {
            let (nx, ny, nz) = (Vec4::splat(at.n.x), Vec4::splat(at.n.y), Vec4::splat(at.n.z));
            let cos_i = ((vx * nx + vy * ny + vz * nz) * inv_dist).abs().min(one);
            let sin_i = sqrt4((one - cos_i * cos_i).max(zero));
            Vec4::select(cos_i.cmpgt(cos_b), one, cos_i * cos_b + sin_i * sin_b)
        };
        let orient = Vec4::select(cos_p.cmpgt(self.cos_e), (cos_p * incidence).max(zero), zero);
        // Inside the bounding sphere every direction may reach p.
        let orient = Vec4::select(dc2.cmple(self.r * self.r), one, orient);
        let (ax, ay, az) = (vx.abs(), vy.abs(), vz.abs());
        let (nx, ny, nz) = ((ax - self.hx).max(zero), (ay - self.hy).max(zero), (az - self.hz).max(zero));
        let near2 = (nx * nx + ny * ny + nz * nz).max(self.near_floor);
        let (gx, gy, gz) = (ax + self.hx, ay + self.hy, az + self.hz);
        let far2 = (gx * gx + gy * gy + gz * gz).max(Vec4::splat(1e-12));
        (self.phi * orient, near2, far2)
    }
}

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
}

/// The most levels the tree may have (bit trails are 128 bits, two a
/// four-wide level, at most one a binary level); past
/// `BALANCED_FROM` nodes split by count, so this is never reached.
const BALANCED_FROM: u32 = 32;

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
                // The loader never lets a curve or an SDF grid emit.
                ShapeGeometry::Curves(_) | ShapeGeometry::SdfGrid(_) => return None,
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
        };

        if strategy == LightSampling::Bvh {
            let mut items: Vec<(u32, LightBounds)> =
                bounds.iter().enumerate().filter_map(|(i, b)| b.filter(|b| b.phi > 0.0).map(|b| (i as u32, b))).collect();
            if !items.is_empty() {
                let mut binary = vec![];
                build(&mut binary, &mut items, 0);
                selector.collapse(&binary, 0, 0, 0);
            }
        }
        selector
    }

    /// Appends the four-wide node for the binary node `at` (the root may be
    /// a leaf; every other node given is interior): its lanes are `at`'s
    /// grandchildren, or its child where that is a leaf. `bits` and `depth`
    /// are the node's path from the root. Returns the node's index.
    fn collapse(&mut self, binary: &[Node], at: usize, bits: u128, depth: u32) -> u32 {
        let mut lanes = [0usize; 4];
        let mut count = 0;
        if binary[at].leaf() {
            lanes[0] = at;
            count = 1;
        } else {
            for c in [at + 1, binary[at].target()] {
                if binary[c].leaf() {
                    lanes[count] = c;
                    count += 1;
                } else {
                    lanes[count] = c + 1;
                    lanes[count + 1] = binary[c].target();
                    count += 2;
                }
            }
        }
        let index = self.nodes.len();
        self.nodes.push(Node4::empty());
        for (k, &lane) in lanes[..count].iter().enumerate() {
            let n = binary[lane];
            let path = bits | ((k as u128) << (2 * depth));
            let child = if n.leaf() {
                self.trail[n.target()] = Some((path, depth + 1));
                n.target() as u32 | LEAF
            } else {
                self.collapse(binary, lane, path, depth + 1)
            };
            self.nodes[index].set(k, &n, child, NEAR_CLAMP);
        }
        debug_assert!(index < LEAF as usize);
        index as u32
    }

    pub fn strategy(&self) -> LightSampling {
        self.strategy
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
            let p = self.child_probabilities(nd, at)?;
            // The lane whose interval of u holds u (the last one with a
            // positive probability if rounding left u past them all).
            let (mut lane, mut lo, mut cum) = (usize::MAX, 0.0f32, 0.0f32);
            for (k, &pk) in p.iter().enumerate() {
                if pk > 0.0 {
                    lane = k;
                    lo = cum;
                    cum += pk;
                    if u < cum {
                        break;
                    }
                }
            }
            let pk = *p.get(lane)?;
            u = ((u - lo) / pk).clamp(0.0, 1.0 - f32::EPSILON);
            pmf *= pk;
            let child = nd.child[lane];
            if child & LEAF != 0 {
                return Some(((child & !LEAF) as usize, pmf, u));
            }
            node = child as usize;
        }
    }

    /// The probabilities of descending to each child of `node` for `at`:
    /// the near and far bounds' shares, mixed by `near_weight`; exactly 0
    /// where a child cannot reach `at`. `None` where none can.
    #[inline(always)]
    fn child_probabilities(&self, node: &Node4, at: &ShadingPoint) -> Option<[f32; 4]> {
        let (f, near2, far2) = node.importance(at);
        let (a, b) = (f / near2, f / far2);
        let (sa, sb) = (a.element_sum(), b.element_sum());
        if sa > 0.0 && sb > 0.0 && sa.is_finite() && sb.is_finite() {
            return Some((a * (self.near_weight / sa) + b * ((1.0 - self.near_weight) / sb)).to_array());
        }
        // Degenerate (under- or overflow): the reachable children alike.
        let f = f.to_array();
        let reach = f.iter().filter(|&&x| x > 0.0).count();
        (reach > 0).then(|| f.map(|x| if x > 0.0 { 1.0 / reach as f32 } else { 0.0 }))
    }

    fn pmf_bvh(&self, index: usize, at: &ShadingPoint) -> f32 {
        let Some((bits, depth)) = self.trail[index] else {
            return if self.infinite.contains(&(index as u32)) { self.p_infinite } else { 0.0 };
        };
        let mut pmf = 1.0 - self.p_infinite * self.infinite.len() as f32;
        let mut node = 0usize;
        for level in 0..depth {
            let nd = &self.nodes[node];
            let Some(p) = self.child_probabilities(nd, at) else { return 0.0 };
            let lane = ((bits >> (2 * level)) & 3) as usize;
            pmf *= p[lane];
            if !(pmf > 0.0) {
                return 0.0;
            }
            node = nd.child[lane] as usize;
        }
        pmf
    }
}

/// Builds the binary subtree over `items` at `depth` into `nodes`; returns
/// its node index.
fn build(nodes: &mut Vec<Node>, items: &mut [(u32, LightBounds)], depth: u32) -> usize {
    let index = nodes.len();
    if let [(emitter, b)] = items {
        nodes.push(Node::new(b, *emitter, true));
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
    nodes.push(Node::new(&total, 0, false));
    let (left, right) = items.split_at_mut(mid);
    build(nodes, left, depth + 1);
    let second = build(nodes, right, depth + 1);
    nodes[index].index = second as u32;
    debug_assert!(second < LEAF as usize);
    index
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
            // The light in lane 1 of a node; the other lanes empty.
            let mut node = Node4::empty();
            node.set(1, &b, LEAF, clamp);
            let b = |at: &ShadingPoint| {
                let (flux, near2, far2) = node.importance(at);
                let (flux, near2, far2) = (flux.to_array(), near2.to_array(), far2.to_array());
                for k in [0, 2, 3] {
                    assert_eq!(flux[k], 0.0);
                }
                assert!(near2[1] > 0.0 && far2[1] >= near2[1], "{near2:?} {far2:?}");
                flux[1] / near2[1]
            };
            assert!(b(&ShadingPoint { p: Vec3::new(0.3, 0.0, 2.0), n: -Vec3::Z }) > 0.0);
            assert!(b(&ShadingPoint { p: Vec3::new(5.0, 0.0, 0.01), n: Vec3::Z }) > 0.0);
            assert_eq!(b(&ShadingPoint { p: Vec3::new(0.0, 0.0, -2.0), n: Vec3::Z }), 0.0);
            // Inside the bounding sphere, behind it too: every direction counts.
            assert!(b(&ShadingPoint { p: Vec3::new(0.0, 0.0, -0.5), n: Vec3::Z }) > 0.0);
            // Closer is more important.
            let near = b(&ShadingPoint::at(Vec3::new(0.0, 0.0, 3.0)));
            let far = b(&ShadingPoint::at(Vec3::new(0.0, 0.0, 30.0)));
            assert!(near > 50.0 * far);
        }
    }

    /// The four-wide importance against a scalar transcription of the
    /// bound (pbrt-v4's `LightBounds::Importance` up to the distance), at
    /// random points, normals and cones.
    #[test]
    fn four_wide_importance_matches_the_scalar_bound() {
        let mut r = Pcg32::new(7, 3);
        let mut f32s = |lo: f32, hi: f32| lo + (hi - lo) * r.next_f32();
        for _ in 0..2000 {
            let mut node = Node4::empty();
            let mut nodes = vec![];
            for k in 0..4 {
                let c = Vec3::new(f32s(-2.0, 2.0), f32s(-2.0, 2.0), f32s(-2.0, 2.0));
                let h = Vec3::new(f32s(0.0, 0.5), f32s(0.0, 0.5), f32s(0.0, 0.5));
                let w = Vec3::new(f32s(-1.0, 1.0), f32s(-1.0, 1.0), f32s(-1.0, 1.0)).normalize_or(Vec3::Z);
                let n = Node::new(&LightBounds::new(c - h, c + h, w, f32s(0.1, 10.0), f32s(-1.0, 1.0), f32s(-0.5, 1.0)), k as u32, true);
                node.set(k, &n, k as u32 | LEAF, NEAR_CLAMP);
                nodes.push(n);
            }
            let p = Vec3::new(f32s(-4.0, 4.0), f32s(-4.0, 4.0), f32s(-4.0, 4.0));
            let n = if f32s(0.0, 1.0) < 0.3 { Vec3::ZERO } else { Vec3::new(f32s(-1.0, 1.0), f32s(-1.0, 1.0), f32s(-1.0, 1.0)).normalize_or(Vec3::Z) };
            let at = ShadingPoint { p, n };
            let f = node.importance(&at).0.to_array();
            for (k, nd) in nodes.iter().enumerate() {
                // Scalar: angles by acos, as pbrt-v4 writes it.
                let v = p - (nd.lo + nd.hi) * 0.5;
                let d = v.length();
                let mut cutoff = false;
                let expected = if d <= nd.r {
                    nd.phi
                } else {
                    let theta_w = (nd.w.dot(v) / d).clamp(-1.0, 1.0).acos();
                    let theta_b = (nd.r / d).min(1.0).asin();
                    let theta_o = nd.cos_o.clamp(-1.0, 1.0).acos();
                    let theta_p = (theta_w - theta_o - theta_b).max(0.0);
                    cutoff = (theta_p.cos() - nd.cos_e).abs() < 1e-3;
                    if theta_p.cos() <= nd.cos_e {
                        0.0
                    } else {
                        let inc = if n == Vec3::ZERO { 1.0 } else { ((v.dot(n) / d).abs().min(1.0).acos() - theta_b).max(0.0).cos() };
                        nd.phi * (theta_p.cos() * inc).max(0.0)
                    }
                };
                // At the cutoff cos θ′ = cos θ_e either may round to zero.
                assert!((f[k] - expected).abs() <= 2e-3 * nd.phi || cutoff, "lane {k}: {} vs {expected} at {at:?}, {nd:?}", f[k]);
                assert_eq!(f[k] > 0.0, expected > 0.0 || cutoff && f[k] > 0.0, "lane {k}: {} vs {expected}", f[k]);
            }
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
