//! The acceleration structure: an 8-wide BVH over every primitive of every
//! shape. It is built as a binary SAH BVH (`accel/build.rs`, parallel) and
//! collapsed, SAH-optimally (`accel/collapse.rs`), to nodes that keep their eight child boxes in SoA form, so one
//! SIMD slab test checks all of them. The traversal is generic over the
//! lanes type of `accel/simd.rs` and compiled three times: AVX-512, AVX2 +
//! FMA and portable (SSE2 / NEON); which one runs is chosen at run time
//! from the CPU (`SimdLevel`, overridable with `SNELL_SIMD`). Leaves refer to triangles by index into
//! their mesh (whose vertex and index buffers the BVH shares, see
//! `mesh::Shared`). A leaf's triangles are tested eight at a time by a SIMD
//! Möller–Trumbore, from lanes stored ready in SoA form (BVHs up to
//! `PACKED_MAX_TRIANGLES` triangles), or, for bigger ones, gathered from
//! the mesh at each visit (no copy of the geometry, 45 % slower on the
//! Cornell box). Spheres and disks are tested one by one.
//!
//! Nodes can also be stored quantized (`accel/quant.rs`, 96 instead of 224
//! bytes, opt-in with `SNELL_NODES=quantized`); the traversal is then
//! compiled once more for them (`closest::<_, true, _, _>`).
//!
//! Memory per triangle: 8 bytes of reference, plus about 16 of nodes and
//! leaves, plus 36 when the triangles are kept as lanes; the mesh itself
//! holds the vertices (12 bytes per vertex) and indices (12 per triangle).
//!
//! Ties: when several primitives are hit at the same t (an edge or vertex
//! shared by triangles, coincident shapes), the lowest (shape, primitive,
//! instance) is reported, whatever order the traversal met them in
//! (`Closest`), so that packets (`accel/stream.rs`) and single rays agree
//! bit for bit.
//!
//! Instancing (Mitsuba's `shapegroup` + `instance`) makes it two-level:
//! each shape group gets its own BVH, built once, and each instance is one
//! primitive of the top-level BVH (its group's box under its transform).
//! A ray reaching an instance is moved into the group's space by the
//! inverse transform (its direction is not renormalised, so distances t
//! stay the same) and traced through the group's BVH. Scenes without
//! instances never take that path.
//!
//! Why our own and not a crate: it replaced `obvhs` (a binary BVH walked one
//! box at a time) after measuring 9 % fewer instructions per sample and
//! 11 % more samples/s on the Cornell box (2.30 → 2.56 M/s); scenes here are
//! small, so the per-ray constant costs dominate, and 8-wide nodes and
//! packets pay those once per eight boxes or triangles.

mod build;
mod collapse;
mod quant;
mod simd;
mod stats;
mod stream;

use super::curve::CurvePiece;
use super::cylinder::Cylinder;
use super::disk::Disk;
use super::mesh::Shared;
use super::sdfgrid::SdfGrid;
use super::shape::{Shape, ShapeGeometry};
use super::sphere::Sphere;
use super::Ray;
use crate::math::Transform;
use build::{Aabb, Item, OTHER, PACKET};
use quant::QNode;
use glam::{Vec3, Vec3A};
#[cfg(target_arch = "x86_64")]
use simd::Avx;
use simd::{Lanes, Portable};
pub use simd::Level as SimdLevel;
use stats::count;
use std::mem::MaybeUninit;

/// Intersection data of one primitive (scalar form: non-triangles in
/// leaves, and the reference for tests).
#[derive(Clone, Debug)]
enum PrimGeom {
    Triangle { v0: Vec3A, e1: Vec3A, e2: Vec3A },
    Sphere { center: Vec3, radius: f32 },
    Disk { to_object: Box<Transform> },
    /// World → object, radius, length.
    Cylinder(Box<(Transform, f32, f32)>),
    /// A linear curve segment or a piece of a B-spline segment.
    Curve(Box<CurvePiece>),
    /// A signed distance field grid (one primitive; it walks its own voxels).
    Sdf(Box<SdfGrid>),
    /// Index into `Accel::instances`.
    Instance(u32),
}

/// One placement of a shape group: its group-to-world transform (with the
/// inverse) and which group.
#[derive(Clone, Debug)]
pub struct Instance {
    pub to_world: Transform,
    pub group: u32,
}

/// `Hit::instance` of a hit on a shape that is not instanced.
pub const NO_INSTANCE: u32 = u32::MAX;

#[derive(Clone, Copy, Debug)]
pub struct PrimRef {
    pub shape: u32,
    pub prim: u32,
}

#[derive(Clone, Copy, Debug)]
pub struct Hit {
    pub t: f32,
    /// Barycentrics (b1, b2) of a triangle hit; zero for other primitives.
    pub bary: (f32, f32),
    pub shape: u32,
    pub prim: u32,
    /// The instance the hit shape belongs to, or [`NO_INSTANCE`].
    pub instance: u32,
}

/// Children per node.
const WIDTH: usize = 8;

/// Eight child boxes in SoA form: `b[0..3]` the minima on x, y, z, `b[3..6]`
/// the maxima. Empty slots have an inverted (+∞, −∞) box.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
struct Node {
    b: [[f32; WIDTH]; 6],
    /// A node index, or `LEAF | leaf index`.
    children: [u32; WIDTH],
}

const LEAF: u32 = 1 << 31;

/// A leaf of triangles alone coded in the child word itself (`LEAF |
/// DIRECT | first << 3 | (n − 1)`), which saves the dependent load of
/// `leaves` (and `tris`) at every leaf visit. In a BVH that keeps lanes
/// (`Accel::code_packed_leaves`): lanes and `tris` `first .. first + n`
/// (`tris` only read for a hit). Else (`Accel::direct_leaves`, after the
/// meshes were stored in leaf order): triangles `first .. first + n` of the
/// mesh `Accel::direct`, read straight from its index buffer. (`first`
/// above the count keeps the order of equally near leaves on the
/// traversal stack.)
const DIRECT: u32 = 1 << 30;
/// The largest `first` of a `DIRECT` leaf.
const DIRECT_FIRST: u32 = (1 << 27) - 1;

/// A leaf: triangles `tris[tri_start..tri_end]` (and the same lanes of
/// `Accel::lanes` when the BVH keeps them), then `others[other_start..other_end]`.
#[derive(Clone, Copy, Debug)]
struct Leaf {
    tri_start: u32,
    tri_end: u32,
    other_start: u32,
    other_end: u32,
}

/// A triangle of a leaf: which of `Accel::meshes`, and which triangle of it.
#[derive(Clone, Copy, Debug)]
struct TriRef {
    mesh: u32,
    prim: u32,
}

/// The vertex and index buffers of one mesh (shared with the mesh), and
/// its shape index.
#[derive(Clone, Debug)]
struct MeshRef {
    positions: Shared<Vec3>,
    triangles: Shared<[u32; 3]>,
    shape: u32,
}

/// `PACKET` triangles gathered from their meshes, one SIMD lane each: v0,
/// −e1 = v0 − v1, e2 = v2 − v0 and the unnormalised normal e2 × e1.
/// Unused lanes are degenerate (all zero), which the test rejects.
#[derive(Clone, Copy, Debug)]
struct TriPacket<V> {
    v0: [V; 3],
    e1n: [V; 3],
    e2: [V; 3],
    ng: [V; 3],
}

/// The triangles of every leaf stored ready for the test, in the order of
/// `Accel::tris`, in blocks of `PACKET` triangles: block b holds triangles
/// 8b .. 8b + 8 as nine rows of eight floats (v0, −e1 = v0 − v1, e2 = v2 −
/// v0, each x, y, z), 288 contiguous bytes. A leaf's chunk of up to
/// `PACKET` triangles from `first` reads block `first / 8` (unaligned
/// loads from lane `first % 8`: lanes past the chunk hold the next row's
/// floats) and, when the chunk runs past the block, the next block too
/// (`Lanes::window` joins the two). Lanes past the chunk are masked out of
/// the hits. The normal e2 × e1 is recomputed at test time (cheaper than
/// loading it). 36 bytes per triangle, whatever the leaves' fill.
///
/// Why blocks: nine rows of the whole BVH's length (the layout before)
/// put a leaf's nine loads on nine pages megabytes apart; on the 1 M
/// triangle mesh the loads of the leaves' lanes and of the nodes were the
/// two places the traversal waited most (perf: 18 and 25 % of the
/// occlusion packets' cycles).
#[derive(Clone, Debug, Default)]
struct TriLanes {
    f: Vec<f32>,
}

/// Floats per block of `TriLanes`.
const BLOCK: usize = 9 * PACKET;

/// BVHs over at most this many triangles keep their leaves' triangles as
/// `TriLanes`; larger ones gather them from the mesh at every leaf visit.
/// Measured on the Cornell box (AVX-512, 2 threads): gathering costs 45 %
/// more CPU time per sample, since the vertices are scattered to the stack
/// lane by lane and read back as vectors; the lanes cost 36 bytes per
/// triangle, which only matters for big meshes. `SNELL_TRIANGLES=packed|indexed` forces one
/// (for tests and measurements).
pub const PACKED_MAX_TRIANGLES: u64 = 1 << 21;

/// How a BVH reads its leaves' triangles.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Storage {
    /// From `TriLanes` (the default up to `PACKED_MAX_TRIANGLES`).
    Packed,
    /// Gathered from the meshes as they were loaded.
    Indexed,
    /// Gathered from the meshes after their triangles and vertices were
    /// renumbered in leaf order (`Accel::store_meshes_in_leaf_order`; the
    /// default above `PACKED_MAX_TRIANGLES`).
    Ordered,
}

/// The storage of a BVH over `n_tris` triangles: by size, or as
/// `SNELL_TRIANGLES=packed|indexed|ordered` forces.
fn storage(n_tris: u64) -> Storage {
    static FORCED: std::sync::OnceLock<Option<Storage>> = std::sync::OnceLock::new();
    let forced = FORCED.get_or_init(|| match std::env::var("SNELL_TRIANGLES").as_deref().map(str::trim) {
        Ok("packed") => Some(Storage::Packed),
        Ok("indexed") => Some(Storage::Indexed),
        Ok("ordered") => Some(Storage::Ordered),
        Ok(other) => {
            eprintln!("warning: SNELL_TRIANGLES={other:?} is not one of packed, indexed, ordered; choosing by size");
            None
        }
        Err(_) => None,
    });
    forced.unwrap_or(if n_tris <= PACKED_MAX_TRIANGLES { Storage::Packed } else { Storage::Ordered })
}

/// Whether a BVH over `n_tris` triangles keeps packets.
fn keeps_packets(n_tris: u64) -> bool {
    storage(n_tris) == Storage::Packed
}

/// Whether a BVH stores its nodes quantized (`quant.rs`): only when
/// `SNELL_NODES=quantized` asks for it (`full`, the default, keeps them
/// full). Measured on the 1 M and 4 M-triangle benchmark meshes (AVX-512,
/// 2 threads, medians of 3): quantized nodes take 58 % less memory (4.4
/// instead of 10.3 bytes per triangle at 4 M) but cost 1 % (1 M) and 5 %
/// (4 M) more CPU time per sample, as decoding the planes costs more than
/// the cache misses it saves; nor do they lower the peak memory, which the
/// build reaches. So they are left for scenes whose BVH must be small.
fn quantizes(_n_tris: u64) -> bool {
    static FORCED: std::sync::OnceLock<Option<bool>> = std::sync::OnceLock::new();
    let forced = FORCED.get_or_init(|| match std::env::var("SNELL_NODES").as_deref().map(str::trim) {
        Ok("full") => Some(false),
        Ok("quantized") => Some(true),
        Ok(other) => {
            eprintln!("warning: SNELL_NODES={other:?} is not one of full, quantized; choosing by size");
            None
        }
        Err(_) => None,
    });
    forced.unwrap_or(false)
}

/// Every child word of the full and the quantized nodes.
fn child_words<'a>(nodes: &'a mut [Node], qnodes: &'a mut [QNode]) -> impl Iterator<Item = &'a mut u32> {
    nodes.iter_mut().flat_map(|n| n.children.iter_mut()).chain(qnodes.iter_mut().flat_map(|n| n.children.iter_mut()))
}

impl<V: Lanes> TriPacket<V> {
    /// The packet of vertex v0 and edges −e1 and e2; the normal e2 × e1 is
    /// computed product by product as the scalar cross product rounds
    /// (with e1 = −(−e1), exactly).
    #[inline(always)]
    fn new(v0: [V; 3], e1n: [V; 3], e2: [V; 3]) -> TriPacket<V> {
        let ng = [e2[2] * e1n[1] - e2[1] * e1n[2], e2[0] * e1n[2] - e2[2] * e1n[0], e2[1] * e1n[0] - e2[0] * e1n[1]];
        TriPacket { v0, e1n, e2, ng }
    }
}

/// The eight floats from `p + i`.
///
/// # Safety
/// They must lie inside one allocation.
#[inline(always)]
unsafe fn load_at<V: Lanes>(p: *const f32, i: usize) -> V {
    V::load(unsafe { &*(p.add(i) as *const [f32; PACKET]) })
}

/// The hit mask of the first `n` lanes.
#[inline(always)]
fn lanes_of(n: usize) -> u32 {
    (1u32 << n) - 1
}

/// Leaves hold at most this many primitives.
const MAX_LEAF: usize = PACKET;

/// Scenes of at most this many primitives build their binary tree down to
/// single primitives and leave the grouping into leaves (of up to
/// `MAX_LEAF`) to the collapse's cost model, which can then fill the free
/// slots of a small root: the Cornell box gets 8 leaves instead of 5, its
/// rays enter 1.85 instead of 2.28 leaves (shadow rays 1.35 instead of
/// 2.06) and it renders in 3 % less CPU time, with the same hits (the tie
/// rule). Larger scenes keep binary leaves of `MAX_LEAF`: on 1 M and 4 M
/// triangle meshes finer binary leaves cost build time and 50 % more peak
/// memory for no measured render gain (`collapse.rs`).
const SMALL_BUILD: usize = 65_536;
/// Traversal stack capacity; the build bounds tree depth well below it.
const STACK: usize = 256;

pub struct Accel {
    /// Root first; empty when there is nothing to hit or when the nodes
    /// are stored quantized instead.
    nodes: Vec<Node>,
    /// The nodes in quantized form (`quant.rs`), root first; empty unless
    /// `quantizes` chose them (then `nodes` is empty).
    qnodes: Vec<QNode>,
    leaves: Vec<Leaf>,
    tris: Vec<TriRef>,
    /// Leaf triangles ready for the test; empty when they are gathered
    /// from `meshes` instead (`keeps_packets`).
    lanes: TriLanes,
    meshes: Vec<MeshRef>,
    others: Vec<PrimGeom>,
    other_refs: Vec<PrimRef>,
    /// One BVH per shape group, and the instances placing them.
    groups: Vec<Accel>,
    instances: Vec<Instance>,
    /// The mesh (index into `meshes`) of the `DIRECT` leaves; `u32::MAX`
    /// when there are none.
    direct: u32,
    /// Bounds of everything (min, max); inverted when empty.
    extent: (Vec3, Vec3),
    /// The instruction set the traversal runs with.
    level: SimdLevel,
    /// The tree's SAH cost (a node visit 1, a leaf packet or other
    /// primitive 1), for `stats`.
    sah: f64,
    /// Whether the traversal prefetches the children it pushes
    /// (`Accel::prefetch`).
    prefetches: bool,
}

/// BVHs whose nodes and lanes take more bytes than this (about a core's
/// L2 cache) prefetch the children they push.
const PREFETCH_MIN_BYTES: usize = 1 << 20;

#[cfg(feature = "trav-stats")]
impl Drop for Accel {
    fn drop(&mut self) {
        stats::report(self.sah, self.nodes.len() + self.qnodes.len(), self.leaves.len());
    }
}

fn prim_geom(shape: &Shape, prim: usize) -> (PrimGeom, Aabb) {
    match &shape.geometry {
        ShapeGeometry::Mesh(m) => {
            let [a, b, c] = m.vertices(prim);
            let (a, b, c) = (Vec3A::from(a), Vec3A::from(b), Vec3A::from(c));
            let aabb = Aabb { lo: a.min(b).min(c), hi: a.max(b).max(c) };
            (PrimGeom::Triangle { v0: a, e1: b - a, e2: c - a }, aabb)
        }
        ShapeGeometry::Sphere(s) => {
            let r = Vec3A::splat(s.radius);
            let c: Vec3A = s.center.into();
            (PrimGeom::Sphere { center: s.center, radius: s.radius }, Aabb { lo: c - r, hi: c + r })
        }
        ShapeGeometry::Disk(d) => {
            let mut aabb = Aabb::EMPTY;
            // The disk lies inside the transformed square [-1,1]² × {0}.
            for (x, y) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                aabb = aabb.grow(d.to_world.point(Vec3::new(x, y, 0.0)).into());
            }
            let to_object = Transform { matrix: d.to_world.inverse, inverse: d.to_world.matrix };
            (PrimGeom::Disk { to_object: Box::new(to_object) }, aabb)
        }
        ShapeGeometry::Cylinder(c) => {
            let (lo, hi) = c.bounds();
            let to_object = Transform { matrix: c.to_world.inverse, inverse: c.to_world.matrix };
            (PrimGeom::Cylinder(Box::new((to_object, c.radius, c.length))), Aabb { lo: lo.into(), hi: hi.into() })
        }
        ShapeGeometry::Curves(c) => {
            let (lo, hi) = c.piece_bounds(prim as u32);
            (PrimGeom::Curve(Box::new(c.piece_data(prim as u32))), Aabb { lo: lo.into(), hi: hi.into() })
        }
        ShapeGeometry::SdfGrid(g) => {
            let (lo, hi) = g.bounds();
            (PrimGeom::Sdf(Box::new(g.clone())), Aabb { lo: lo.into(), hi: hi.into() })
        }
    }
}

/// Hit distance (infinite on a miss) and, for triangles, barycentrics.
///
/// Never inlined: in the traversal's leaves the compiler hoisted this
/// test's per-ray terms (the direction's squared length in f64 for the
/// sphere, its lanes for the others) out of the node loop, into every
/// ray's setup and its register spills, whether or not the scene has any
/// such primitive. A call where one is met costs less. (Plain IEEE
/// operations without fused multiply-adds: the same bits however compiled.)
#[inline(never)]
fn intersect_prim_bary(g: &PrimGeom, o: Vec3A, d: Vec3A, tmax: f32) -> (f32, f32, f32) {
    const MISS: (f32, f32, f32) = (f32::INFINITY, 0.0, 0.0);
    match g {
        PrimGeom::Triangle { v0, e1, e2 } => {
            // Möller–Trumbore.
            let pvec = d.cross(*e2);
            let det = e1.dot(pvec);
            if det.abs() < 1e-12 {
                return MISS;
            }
            let inv = 1.0 / det;
            let tvec = o - *v0;
            let u = tvec.dot(pvec) * inv;
            if !(0.0..=1.0).contains(&u) {
                return MISS;
            }
            let qvec = tvec.cross(*e1);
            let v = d.dot(qvec) * inv;
            if v < 0.0 || u + v > 1.0 {
                return MISS;
            }
            let t = e2.dot(qvec) * inv;
            if t > 0.0 && t < tmax { (t, u, v) } else { MISS }
        }
        PrimGeom::Sphere { center, radius } => (Sphere::intersect(*center, *radius, o.into(), d.into(), tmax), 0.0, 0.0),
        PrimGeom::Disk { to_object } => (Disk::intersect(to_object, o.into(), d.into(), tmax), 0.0, 0.0),
        PrimGeom::Cylinder(c) => (Cylinder::intersect(&c.0, c.1, c.2, o.into(), d.into(), tmax), 0.0, 0.0),
        // The curve parameter rides in the first barycentric.
        PrimGeom::Curve(c) => {
            let (t, u) = c.intersect(o.into(), d.into(), tmax);
            (t, u, 0.0)
        }
        PrimGeom::Sdf(g) => (g.intersect(o.into(), d.into(), tmax), 0.0, 0.0),
        // Instances are traced by `Accel` itself; never reached.
        PrimGeom::Instance(_) => MISS,
    }
}

/// Per-ray constants of the SIMD tests.
struct RayData<V> {
    o: Vec3A,
    d: Vec3A,
    /// Splatted origin and direction, for the triangle packets.
    o8: [V; 3],
    d8: [V; 3],
    /// Slab test: entry distance on an axis is `plane · inv − oinv_n`,
    /// exit distance `plane · inv − oinv_f` (one FMA each). The inverse
    /// direction has zero components replaced by tiny ones (no NaN); the
    /// two offsets are o·inv ± a bound on its rounding error, and exit
    /// distances are scaled up by `FAR` before the comparison, so that the
    /// test is conservative: it never loses a box the exact ray enters.
    inv: [V; 3],
    oinv_n: [V; 3],
    oinv_f: [V; 3],
    /// Byte offsets into `Node::b` of the near planes (x, y, z) then the
    /// far planes: `OCTANT_ROWS` of the ray's octant. Offsets rather than
    /// row numbers: a node visit loads its six rows without scaling them;
    /// the table's row rather than a copy: a ray's setup copies nothing.
    rows: &'static [u32; 6],
}

/// Per direction octant (bit a set: the ray runs towards −axis a), the
/// byte offsets into `Node::b` of the near then far planes on x, y, z:
/// the minimum (row a) is near where the ray runs towards +axis, the
/// maximum (row 3 + a) where it runs towards −axis.
static OCTANT_ROWS: [[u32; 6]; 8] = {
    let row = std::mem::size_of::<[f32; WIDTH]>() as u32;
    let mut t = [[0u32; 6]; 8];
    let mut oct = 0;
    while oct < 8 {
        let mut a = 0;
        while a < 3 {
            let neg = (oct >> a) as u32 & 1;
            t[oct][a] = (a as u32 + 3 * neg) * row;
            t[oct][3 + a] = (a as u32 + 3 * (1 - neg)) * row;
            a += 1;
        }
        oct += 1;
    }
    t
};

/// 2⁻²¹: covers the relative rounding of 1/d and of the slab FMAs.
const REL: f32 = 4.0 * f32::EPSILON;
const FAR: f32 = 1.0 + 2.0 * REL;

impl<V: Lanes> RayData<V> {
    #[inline(always)]
    fn new(ray: &Ray) -> RayData<V> {
        let o = Vec3A::from(ray.o);
        let d = Vec3A::from(ray.d);
        let tiny = Vec3A::splat(1e-20);
        let d_safe = Vec3A::select(d.abs().cmplt(tiny), tiny.copysign(d), d);
        let inv = Vec3A::ONE / d_safe;
        let oinv = o * inv;
        let err = oinv.abs() * REL;
        let (oinv_n, oinv_f) = (oinv + err, oinv - err);
        let octant = inv.cmplt(Vec3A::ZERO).bitmask() as usize;
        let s = |v: Vec3A| [V::splat(v.x), V::splat(v.y), V::splat(v.z)];
        RayData {
            o,
            d,
            o8: s(o),
            d8: s(d),
            inv: s(inv),
            oinv_n: s(oinv_n),
            oinv_f: s(oinv_f),
            // (`& 7`: a 3-bit mask; lets the index go unchecked.)
            rows: &OCTANT_ROWS[octant & 7],
        }
    }

    /// Entry distances into the children and the mask of those the ray
    /// enters within [0, tmax].
    #[inline(always)]
    fn slab(&self, node: &Node, tmax: f32) -> (V, u32) {
        let r = self.rows;
        let [nx, ny, nz, fx, fy, fz]: [V; 6] = [row(node, r[0]), row(node, r[1]), row(node, r[2]), row(node, r[3]), row(node, r[4]), row(node, r[5])];
        let tnx = nx.mul_sub(self.inv[0], self.oinv_n[0]);
        let tny = ny.mul_sub(self.inv[1], self.oinv_n[1]);
        let tnz = nz.mul_sub(self.inv[2], self.oinv_n[2]);
        let tfx = fx.mul_sub(self.inv[0], self.oinv_f[0]);
        let tfy = fy.mul_sub(self.inv[1], self.oinv_f[1]);
        let tfz = fz.mul_sub(self.inv[2], self.oinv_f[2]);
        let tnear = tnx.max(tny).max(tnz.max(V::splat(0.0)));
        let tfar = tfx.min(tfy).min(tfz.min(V::splat(tmax)));
        (tnear, tnear.le(tfar * V::splat(FAR)).bitmask())
    }

    /// Möller–Trumbore on a packet, divisions deferred: returns the
    /// numerators of t, b1, b2 and |det|, all with det's sign removed, and
    /// the mask of hits in (0, tmax).
    ///
    /// `LOOSE` (closest hits): the mask keeps t ≤ tmax with a few ulps to
    /// spare instead of t < tmax, so that every triangle whose rounded t
    /// (as `closest_in` divides it) is at most tmax passes; `closest_in`
    /// then compares the rounded t exactly (the tie rule needs hits at
    /// exactly tmax).
    #[inline(always)]
    fn triangles<const LOOSE: bool>(&self, p: &TriPacket<V>, tmax: f32) -> ([V; 4], u32) {
        moller_trumbore::<LOOSE, V>(&self.o8, &self.d8, p, V::splat(tmax))
    }
}

/// The row of `node`'s boxes at byte offset `offset`, one of `OCTANT_ROWS`.
/// (A function, not a closure: closures are compiled without the caller's
/// target features and were not always inlined.)
#[inline(always)]
fn row<V: Lanes>(node: &Node, offset: u32) -> V {
    debug_assert!(offset as usize % std::mem::size_of::<[f32; WIDTH]>() == 0 && (offset as usize) < std::mem::size_of_val(&node.b));
    // SAFETY: `OCTANT_ROWS` holds offsets of whole rows of `b` only.
    V::load(unsafe { &*((node.b.as_ptr() as *const u8).add(offset as usize) as *const [f32; WIDTH]) })
}

/// Möller–Trumbore lane by lane (see `RayData::triangles`): lane k tests
/// the ray (`o[..][k]`, `d[..][k]`) against the triangle in lane k of `p`
/// up to `tmax[k]`. The single-ray test splats one ray over the lanes of a
/// leaf's triangles; an occlusion packet (`stream.rs`) splats one triangle
/// over its rays. Each lane's result depends on that lane's inputs alone
/// and both go through this one expression, so a ray meets a triangle
/// with the same bits either way.
#[inline(always)]
fn moller_trumbore<const LOOSE: bool, V: Lanes>(o: &[V; 3], d: &[V; 3], p: &TriPacket<V>, tmax: V) -> ([V; 4], u32) {
    let [dx, dy, dz] = *d;
    // c = v0 − o, r = d × c
    let cx = p.v0[0] - o[0];
    let cy = p.v0[1] - o[1];
    let cz = p.v0[2] - o[2];
    let rx = dy.mul_sub(cz, dz * cy);
    let ry = dz.mul_sub(cx, dx * cz);
    let rz = dx.mul_sub(cy, dy * cx);
    let det = dx.mul_add(p.ng[0], dy.mul_add(p.ng[1], dz * p.ng[2]));
    let u = p.e2[0].mul_add(rx, p.e2[1].mul_add(ry, p.e2[2] * rz));
    let v = p.e1n[0].mul_add(rx, p.e1n[1].mul_add(ry, p.e1n[2] * rz));
    let t = cx.mul_add(p.ng[0], cy.mul_add(p.ng[1], cz * p.ng[2]));
    let sign = det.sign();
    let adet = det.xor(sign);
    let (t, u, v) = (t.xor(sign), u.xor(sign), v.xor(sign));
    let zero = V::splat(0.0);
    let ok = V::splat(1e-12).le(adet)
        & zero.le(u)
        & zero.le(v)
        & (u + v).le(adet)
        & zero.lt(t)
        & if LOOSE { t.le(tmax * adet * V::splat(1.0 + 8.0 * f32::EPSILON)) } else { t.lt(tmax * adet) };
    ([t, u, v, adet], ok.bitmask())
}

impl<V: Lanes> RayData<V> {
    /// The hit among the first `n` lanes of the packet that `best` accepts
    /// and that beats the others under the tie rule (nearest t, then lowest
    /// `key` of the lane), as (lane, t, b1, b2); the divisions only for a
    /// packet with a hit, the keys only for equal t.
    #[inline(always)]
    fn closest_in(&self, p: &TriPacket<V>, n: usize, best: &Closest, key: impl Fn(usize) -> u128) -> Option<(usize, f32, f32, f32)> {
        let ([t, u, v, adet], mask) = self.triangles::<true>(p, best.t);
        let mut mask = mask & lanes_of(n);
        if mask == 0 {
            return None;
        }
        let inv = V::splat(1.0) / adet;
        let (t, u, v) = ((t * inv).to_array(), u * inv, v * inv);
        // The leader so far: `best` itself (lane None), then lanes; its key
        // computed when a tie needs it.
        let (mut lane, mut lt, mut lk) = (None, best.t, Some(best.key));
        while mask != 0 {
            let i = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            if t[i] < lt {
                (lane, lt, lk) = (Some(i), t[i], None);
            } else if t[i] == lt {
                let k = key(i);
                let cur = match (lk, lane) {
                    (Some(k), _) => k,
                    (None, Some(l)) => key(l),
                    (None, None) => u128::MAX,
                };
                if k < cur {
                    (lane, lk) = (Some(i), Some(k));
                } else {
                    lk = Some(cur);
                }
            }
        }
        let lane = lane?;
        Some((lane, t[lane], u.to_array()[lane], v.to_array()[lane]))
    }
}

/// The tie key of a hit: among hits at the same t the lowest (shape,
/// primitive, instance) wins, whatever the order in which the traversal
/// meets them, so that any visiting order (single ray, packets) reports
/// the same hit.
#[inline(always)]
fn tie_key(shape: u32, prim: u32, instance: u32) -> u128 {
    (shape as u128) << 64 | (prim as u128) << 32 | instance as u128
}

/// The closest hit of one ray so far.
#[derive(Clone, Copy, Debug)]
struct Closest {
    /// Its distance; the ray's tmax before a hit.
    t: f32,
    /// Its `tie_key`; before a hit 0 (a hit at exactly the ray's tmax is
    /// refused: the ray covers [0, tmax)) or `u128::MAX` (a group's
    /// traversal for an instance, whose hits at tmax the caller weighs).
    key: u128,
    b1: f32,
    b2: f32,
    found: bool,
}

impl Closest {
    #[inline(always)]
    fn new(tmax: f32, key: u128) -> Closest {
        Closest { t: tmax, key, b1: 0.0, b2: 0.0, found: false }
    }

    /// Whether a hit at `t` with `key` beats this one.
    #[inline(always)]
    fn accepts(&self, t: f32, key: u128) -> bool {
        t < self.t || (t == self.t && key < self.key)
    }

    #[inline(always)]
    fn set(&mut self, t: f32, key: u128, b1: f32, b2: f32) {
        *self = Closest { t, key, b1, b2, found: true };
    }

    /// Distance up to which boxes are entered: a little beyond `t`, so that
    /// a box holding a triangle hit at exactly `t` (a tie) is never culled
    /// by the rounding of its entry distance, whichever hit was found first.
    #[inline(always)]
    fn reach(&self) -> f32 {
        self.t * REACH
    }

    #[inline(always)]
    fn hit(&self) -> Option<Hit> {
        self.found.then(|| Hit { t: self.t, bary: (self.b1, self.b2), shape: (self.key >> 64) as u32, prim: (self.key >> 32) as u32, instance: self.key as u32 })
    }
}

/// `Closest::reach`'s margin: 2⁻¹².
const REACH: f32 = 1.0 + 1.0 / 4096.0;

/// The triangles `tris` (at most `PACKET`, vertex indices into
/// `positions`), one lane each, as `Accel::gather` makes them; lanes past
/// `tris.len()` are zero.
#[inline(always)]
fn gather_run<V: Lanes>(positions: &[Vec3], tris: &[[u32; 3]]) -> TriPacket<V> {
    let mut f = [[[0.0f32; PACKET]; 3]; 3];
    for (lane, tri) in tris.iter().enumerate() {
        for (k, &v) in tri.iter().enumerate() {
            let p = positions[v as usize];
            f[k][0][lane] = p.x;
            f[k][1][lane] = p.y;
            f[k][2][lane] = p.z;
        }
    }
    packet_of_corners(f)
}

/// The packet of triangles whose corners (corner, axis, lane) were gathered
/// into `f`: the form both gathers end in.
#[inline(always)]
fn packet_of_corners<V: Lanes>(f: [[[f32; PACKET]; 3]; 3]) -> TriPacket<V> {
    let [v0, v1, v2] = f.map(|c| c.map(V::from_array));
    let e2 = [v2[0] - v0[0], v2[1] - v0[1], v2[2] - v0[2]];
    let e1n = [v0[0] - v1[0], v0[1] - v1[1], v0[2] - v1[2]];
    TriPacket::new(v0, e1n, e2)
}

impl Accel {
    pub fn build(shapes: &[Shape]) -> Accel {
        let all: Vec<u32> = (0..shapes.len() as u32).collect();
        Self::build_instanced(shapes, &all, &[], &[])
    }

    /// A BVH over the shapes `top` (indices into `shapes`) and the
    /// `instances` (transform, group) of the shape `groups` (each a list of
    /// indices into `shapes`). Each group's BVH is built once.
    pub fn build_instanced(shapes: &[Shape], top: &[u32], groups: &[Vec<u32>], instances: &[(Transform, u32)]) -> Accel {
        let group_accels: Vec<Accel> = groups.iter().map(|members| Self::build_instanced(shapes, members, &[], &[])).collect();
        let mut meshes = vec![];
        // First triangle id of each mesh; triangle ids number the triangles
        // of all meshes in order.
        let mut mesh_first = vec![];
        let mut items: Vec<Item> = vec![];
        let mut others = vec![];
        let mut other_refs = vec![];
        let mut extent = Aabb::EMPTY;
        // Flat primitives have zero-thickness boxes; pad them so the slab
        // test never rejects a hit on an axis-aligned face.
        let padded = |aabb: Aabb, rel: f32| {
            let pad = Vec3A::splat(rel) * (1.0 + aabb.hi.abs().max(aabb.lo.abs()).max_element());
            Aabb { lo: aabb.lo - pad, hi: aabb.hi + pad }
        };
        let mut n_tris = 0u64;
        for &si in top {
            if let ShapeGeometry::Mesh(m) = &shapes[si as usize].geometry {
                n_tris += m.triangles.len() as u64;
            }
        }
        assert!(n_tris < OTHER as u64, "too many triangles for one BVH ({n_tris})");
        items.reserve(n_tris as usize);
        for &si in top {
            let shape = &shapes[si as usize];
            if let ShapeGeometry::Mesh(m) = &shape.geometry {
                use rayon::prelude::*;
                let first = mesh_first.last().map_or(0, |&f| f + meshes.last().map_or(0, |m: &MeshRef| m.triangles.len() as u32));
                let (pos, tris) = (&m.positions, &m.triangles);
                let tri_box = |&[a, b, c]: &[u32; 3]| {
                    let (a, b, c) = (Vec3A::from(pos[a as usize]), Vec3A::from(pos[b as usize]), Vec3A::from(pos[c as usize]));
                    Aabb { lo: a.min(b).min(c), hi: a.max(b).max(c) }
                };
                items.par_extend(tris.par_iter().enumerate().map(|(p, t)| Item::new(padded(tri_box(t), 1e-6), first + p as u32)));
                extent = extent.union(tris.par_iter().map(tri_box).reduce(|| Aabb::EMPTY, Aabb::union));
                mesh_first.push(first);
                meshes.push(MeshRef { positions: m.positions.clone(), triangles: m.triangles.clone(), shape: si });
                continue;
            }
            for p in 0..shape.primitive_count() {
                let (g, aabb) = prim_geom(shape, p);
                extent = extent.grow(aabb.lo).grow(aabb.hi);
                items.push(Item::new(padded(aabb, 1e-6), OTHER | others.len() as u32));
                others.push(g);
                other_refs.push(PrimRef { shape: si, prim: p as u32 });
            }
        }
        let mut kept = vec![];
        for (to_world, group) in instances {
            let (lo, hi) = group_accels[*group as usize].extent;
            if lo.x > hi.x {
                continue; // an empty group
            }
            let mut aabb = Aabb::EMPTY;
            for k in 0..8 {
                let c = Vec3::new([lo.x, hi.x][k & 1], [lo.y, hi.y][(k >> 1) & 1], [lo.z, hi.z][k >> 2]);
                aabb = aabb.grow(to_world.point(c).into());
            }
            extent = extent.grow(aabb.lo).grow(aabb.hi);
            items.push(Item::new(padded(aabb, 1e-5), OTHER | others.len() as u32));
            others.push(PrimGeom::Instance(kept.len() as u32));
            other_refs.push(PrimRef { shape: u32::MAX, prim: kept.len() as u32 });
            kept.push(Instance { to_world: *to_world, group: *group });
        }
        let mut accel = Accel {
            nodes: vec![],
            qnodes: vec![],
            leaves: vec![],
            tris: vec![],
            lanes: TriLanes::default(),
            meshes,
            others: vec![],
            other_refs: vec![],
            groups: group_accels,
            instances: kept,
            direct: u32::MAX,
            extent: (extent.lo.into(), extent.hi.into()),
            level: SimdLevel::current(),
            sah: 0.0,
            prefetches: false,
        };
        if items.is_empty() {
            return accel;
        }
        // Small scenes: the binary tree down to single primitives, and the
        // collapse groups them into leaves (see `SMALL_BUILD`).
        let bin_leaf = if items.len() <= SMALL_BUILD { 1 } else { MAX_LEAF };
        let bvh2 = build::build(items, bin_leaf);
        // Exact or upper-bound capacities: no vector doubles (and copies)
        // while the binary tree is still alive, and unused capacity is
        // never touched (no resident memory) before `shrink_to_fit`.
        let n_leaves = bvh2.nodes.iter().filter(|n| !n.is_inner()).count();
        accel.tris.reserve_exact(n_tris as usize);
        accel.leaves.reserve_exact(n_leaves);
        accel.nodes.reserve_exact(n_leaves);
        let (max_depth, sah) = collapse::Collapse::new(&bvh2, &mesh_first, &others, &other_refs, &mut accel).run();
        accel.sah = sah / (bvh2.nodes[0].bounds().half_area() as f64).max(f64::MIN_POSITIVE);
        assert!((WIDTH as u32 - 1) * max_depth + 1 < STACK as u32, "BVH too deep for the traversal stack");
        drop(bvh2);
        accel.nodes.shrink_to_fit();
        accel.leaves.shrink_to_fit();
        accel.tris.shrink_to_fit();
        if n_tris > 0 && keeps_packets(n_tris) {
            accel.store_lanes();
            accel.code_packed_leaves();
        }
        if quantizes(n_tris) {
            accel.quantize_nodes_here();
        }
        accel.prefetches = accel.nodes.len() * std::mem::size_of::<Node>() + accel.lanes.f.len() * 4 > PREFETCH_MIN_BYTES;
        accel
    }

    /// Replaces the full nodes of this BVH (not its groups') by quantized ones.
    fn quantize_nodes_here(&mut self) {
        if self.nodes.is_empty() {
            return;
        }
        let mut q = Vec::with_capacity(self.nodes.len());
        q.extend(self.nodes.iter().map(QNode::new));
        self.qnodes = q;
        self.nodes = Vec::new();
    }

    /// Stores the nodes of this BVH and its groups quantized (for tests
    /// and measurements; `quantizes` chooses at build time).
    pub fn quantize_nodes(&mut self) {
        self.quantize_nodes_here();
        self.groups.iter_mut().for_each(Accel::quantize_nodes);
    }

    /// Whether the nodes are stored quantized.
    pub fn quantized(&self) -> bool {
        !self.qnodes.is_empty()
    }

    /// Fills `lanes` from the meshes, in the order of `tris`.
    fn store_lanes(&mut self) {
        // Whole blocks, and one row more: the unaligned loads of the last
        // block's last row read up to 7 floats past it.
        let mut f = vec![0.0f32; self.tris.len().div_ceil(PACKET) * BLOCK + PACKET];
        for (i, r) in self.tris.iter().enumerate() {
            let m = &self.meshes[r.mesh as usize];
            let [i0, i1, i2] = m.triangles[r.prim as usize];
            let (v0, v1, v2) = (m.positions[i0 as usize], m.positions[i1 as usize], m.positions[i2 as usize]);
            // The same subtractions `gather` does, so hits are identical.
            let (e1n, e2) = (v0 - v1, v2 - v0);
            let block = i / PACKET * BLOCK;
            for (row, x) in [v0, e1n, e2].iter().flat_map(|v| v.to_array()).enumerate() {
                f[block + row * PACKET + i % PACKET] = x;
            }
        }
        self.lanes = TriLanes { f };
    }

    /// The triangles `refs` (at most `PACKET`) gathered from their meshes.
    #[inline(always)]
    fn gather<V: Lanes>(&self, refs: &[TriRef]) -> TriPacket<V> {
        let mut f = [[[0.0f32; PACKET]; 3]; 3];
        for (lane, r) in refs.iter().enumerate() {
            let m = &self.meshes[r.mesh as usize];
            let [a, b, c] = m.triangles[r.prim as usize];
            for (k, v) in [a, b, c].into_iter().enumerate() {
                let p = m.positions[v as usize];
                f[k][0][lane] = p.x;
                f[k][1][lane] = p.y;
                f[k][2][lane] = p.z;
            }
        }
        packet_of_corners(f)
    }

    /// The triangles `refs`, which are `tris[first..]`: loaded from the
    /// stored lanes (`PACKED`, as `keeps_packets`), or gathered from the
    /// meshes. Lanes past `refs.len()` hold other triangles or other
    /// floats: callers mask them out.
    #[inline(always)]
    fn packet<const PACKED: bool, V: Lanes>(&self, first: usize, refs: &[TriRef]) -> TriPacket<V> {
        if PACKED { self.lanes_at(first, refs.len()) } else { self.gather(refs) }
    }

    /// The stored lanes of `tris[first..first + n]` (`first + n` ≤
    /// `tris.len()`, `n` ≤ `PACKET`); lanes past `n` hold other floats.
    #[inline(always)]
    fn lanes_at<V: Lanes>(&self, first: usize, n: usize) -> TriPacket<V> {
        let f = &self.lanes.f;
        let (block, o) = (first / PACKET * BLOCK, first % PACKET);
        // Both blocks when the chunk runs into the next one.
        let two = o + n > PACKET;
        assert!(block + if two { 2 * BLOCK } else { BLOCK + PACKET } <= f.len());
        // (Loops, not closures: closures are compiled without the caller's
        // target features and, here, were not inlined.)
        let p = f.as_ptr();
        let mut l = [V::splat(0.0); 9];
        // SAFETY (both loops): the reads end at most at block + 2 · BLOCK
        // when `two`, else at block + BLOCK + PACKET, within `f` (asserted).
        if two {
            for (row, l) in l.iter_mut().enumerate() {
                *l = unsafe { load_at::<V>(p, block + row * PACKET).window(load_at(p, block + BLOCK + row * PACKET), o) };
            }
        } else {
            for (row, l) in l.iter_mut().enumerate() {
                *l = unsafe { load_at(p, block + row * PACKET + o) };
            }
        }
        TriPacket::new([l[0], l[1], l[2]], [l[3], l[4], l[5]], [l[6], l[7], l[8]])
    }

    /// Asks the cache for child `c` (a full node, the lanes of a `DIRECT`
    /// leaf that keeps them, or else its triangles' indices) ahead of its
    /// visit: the traversal pushes the children it will visit later, and
    /// their loads, mostly misses on big meshes, then overlap with the work
    /// on the nearest.
    /// Only in BVHs bigger than `PREFETCH_MIN_BYTES`: in small ones
    /// everything is in cache and the prefetches cost (Cornell box: 4 %
    /// more CPU time; 1 M-triangle mesh: 4 % less).
    #[inline(always)]
    fn prefetch(&self, c: u32) {
        if !self.prefetches {
            return;
        }
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
            let (p, lines) = if c & LEAF == 0 {
                (self.nodes.as_ptr().wrapping_add(c as usize) as *const i8, 4)
            } else if c & DIRECT != 0 && !self.lanes.f.is_empty() {
                let first = ((c & !(LEAF | DIRECT)) >> 3) as usize;
                (self.lanes.f.as_ptr().wrapping_add(first / PACKET * BLOCK) as *const i8, 5)
            } else if c & DIRECT != 0 {
                // Gathered from the mesh: its run of corner indices (at most
                // eight triangles, 96 bytes); the corners depend on them.
                let (first, n) = (((c & !(LEAF | DIRECT)) >> 3) as usize, (c & 7) as usize + 1);
                if let Some(mesh) = self.meshes.get(self.direct as usize) {
                    crate::geometry::prefetch(mesh.triangles.get(first));
                    crate::geometry::prefetch(mesh.triangles.get(first + n - 1));
                }
                return;
            } else {
                return;
            };
            for k in 0..lines {
                // SAFETY: a prefetch never faults, whatever the address.
                unsafe { _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(64 * k)) };
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = c;
    }

    /// Drops the stored packets (also of the instanced groups): the traversal
    /// gathers triangles from the meshes, as BVHs above
    /// `PACKED_MAX_TRIANGLES` do (for tests and measurements).
    pub fn gather_triangles(&mut self) {
        if self.keeps_packets() {
            // `DIRECT` words back to leaf indices: the leaf with triangles
            // that starts at `first` (leaves are in `tris` order; leaves of
            // other primitives alone start where the next one does).
            let leaves = &self.leaves;
            for c in child_words(&mut self.nodes, &mut self.qnodes) {
                if *c & (LEAF | DIRECT) == LEAF | DIRECT {
                    let first = (*c & !(LEAF | DIRECT)) >> 3;
                    let mut i = leaves.partition_point(|l| l.tri_start < first);
                    while leaves[i].tri_end == leaves[i].tri_start {
                        i += 1;
                    }
                    *c = LEAF | i as u32;
                }
            }
        }
        self.lanes = TriLanes::default();
        self.groups.iter_mut().for_each(Accel::gather_triangles);
    }

    /// Renumbers the triangles of the meshes this BVH (or a group's)
    /// gathers from in the order of its leaves, and their vertices by first
    /// use in that order (`Mesh::reorder`), for BVHs whose storage is
    /// `Storage::Ordered` (by default those over `PACKED_MAX_TRIANGLES`
    /// triangles): a leaf's triangle indices are then consecutive in the
    /// index buffer and its vertices mostly neighbours, where the input
    /// order could scatter them over the whole mesh (a cache miss per
    /// lane). Hits are the same bits under the new triangle numbers; the
    /// scene must call this before anything keeps triangle numbers (mesh
    /// attribute tables, emitter sampling). A mesh some other BVH also
    /// reads keeps its order. Other BVHs are left as they are, so images of
    /// scenes below the limit do not change.
    pub fn store_meshes_in_leaf_order(&mut self, shapes: &mut [Shape]) {
        self.leaf_order(shapes, false);
    }

    /// `store_meshes_in_leaf_order`; `force`: whatever the storage.
    fn leaf_order(&mut self, shapes: &mut [Shape], force: bool) {
        fn count(a: &Accel, uses: &mut [u32]) {
            a.meshes.iter().for_each(|m| uses[m.shape as usize] += 1);
            a.groups.iter().for_each(|g| count(g, uses));
        }
        fn reorder(a: &mut Accel, shapes: &mut [Shape], uses: &[u32], force: bool) {
            for g in &mut a.groups {
                reorder(g, shapes, uses, force);
            }
            if a.tris.is_empty() || !(force || storage(a.tris.len() as u64) == Storage::Ordered) {
                return;
            }
            // Each mesh's triangles in leaf order, one run per mesh.
            let mut start = Vec::with_capacity(a.meshes.len() + 1);
            start.push(0usize);
            for m in &a.meshes {
                start.push(start.last().copied().unwrap_or(0) + m.triangles.len());
            }
            let mut cursor = start.clone();
            let mut order = vec![0u32; a.tris.len()];
            for r in &a.tris {
                order[cursor[r.mesh as usize]] = r.prim;
                cursor[r.mesh as usize] += 1;
            }
            let mut done = vec![false; a.meshes.len()];
            for (mi, m) in a.meshes.iter_mut().enumerate() {
                let ShapeGeometry::Mesh(mesh) = &mut shapes[m.shape as usize].geometry else { continue };
                if uses[m.shape as usize] != 1 || cursor[mi] != start[mi + 1] || mesh.triangles.len() != m.triangles.len() {
                    continue;
                }
                // Drop the BVH's references first: the old buffers are freed
                // as the mesh replaces them.
                m.positions = Vec::new().into();
                m.triangles = Vec::new().into();
                mesh.reorder(&order[start[mi]..start[mi + 1]]);
                m.positions = mesh.positions.clone();
                m.triangles = mesh.triangles.clone();
                done[mi] = true;
            }
            drop(order);
            cursor.copy_from_slice(&start);
            for r in &mut a.tris {
                let mi = r.mesh as usize;
                if done[mi] {
                    r.prim = (cursor[mi] - start[mi]) as u32;
                    cursor[mi] += 1;
                }
            }
            // The biggest renumbered mesh's leaves go into the child words.
            let biggest = (0..a.meshes.len()).filter(|&mi| done[mi]).max_by_key(|&mi| a.meshes[mi].triangles.len());
            if let Some(mi) = biggest {
                a.direct_leaves(mi as u32);
            }
        }
        let mut uses = vec![0u32; shapes.len()];
        count(self, &mut uses);
        reorder(self, shapes, &uses, force);
    }

    /// Codes every leaf of triangles alone as a `DIRECT` child word, for a
    /// BVH that keeps its triangles as lanes.
    fn code_packed_leaves(&mut self) {
        for c in child_words(&mut self.nodes, &mut self.qnodes) {
            if *c & (LEAF | DIRECT) != LEAF {
                continue;
            }
            let leaf = self.leaves[(*c & !LEAF) as usize];
            let n = leaf.tri_end - leaf.tri_start;
            if leaf.other_start == leaf.other_end && n > 0 && n as usize <= PACKET && leaf.tri_start <= DIRECT_FIRST {
                *c = LEAF | DIRECT | leaf.tri_start << 3 | (n - 1);
            }
        }
    }

    /// Turns every leaf holding only a run of consecutive triangles of mesh
    /// `mi` (and not stored as lanes) into a `DIRECT` child word; frees
    /// `leaves` and `tris` when no leaf is left that needs them.
    fn direct_leaves(&mut self, mi: u32) {
        if self.keeps_packets() || self.meshes[mi as usize].triangles.len() > DIRECT_FIRST as usize {
            return;
        }
        self.direct = mi;
        let mut left = 0usize;
        for c in child_words(&mut self.nodes, &mut self.qnodes) {
            if *c & (LEAF | DIRECT) != LEAF {
                continue;
            }
            let leaf = self.leaves[(*c & !LEAF) as usize];
            let refs = &self.tris[leaf.tri_start as usize..leaf.tri_end as usize];
            let run = leaf.other_start == leaf.other_end
                && !refs.is_empty()
                && refs.len() <= PACKET
                && refs.iter().enumerate().all(|(k, r)| r.mesh == mi && r.prim == refs[0].prim + k as u32);
            if run {
                *c = LEAF | DIRECT | refs[0].prim << 3 | (refs.len() as u32 - 1);
            } else {
                left += 1;
            }
        }
        // An empty node's children (a root with nothing) are no leaves.
        if left == 0 {
            self.leaves = Vec::new();
            self.tris = Vec::new();
        }
    }

    /// Whether leaf triangles are stored as packets (else gathered).
    pub fn keeps_packets(&self) -> bool {
        !self.lanes.f.is_empty()
    }

    /// Instance `i` of a hit (`Hit::instance`).
    pub fn instance(&self, i: u32) -> &Instance {
        &self.instances[i as usize]
    }

    /// The ray in the space of instance `i`'s group (same t along it).
    #[inline]
    fn instance_ray(&self, i: u32, ray: &Ray, tmax: f32) -> (&Accel, Ray) {
        let inst = &self.instances[i as usize];
        let local = Ray { o: inst.to_world.inverse_point(ray.o), d: inst.to_world.inverse_vector(ray.d), tmax };
        (&self.groups[inst.group as usize], local)
    }

    /// Bytes held by the acceleration structure (nodes, leaves, primitive
    /// data, groups and instance records) and by the mesh buffers it reads
    /// (shared with the meshes, counted once per BVH that uses them), for
    /// memory reports.
    pub fn memory_bytes(&self) -> usize {
        use std::mem::size_of;
        self.nodes.capacity() * size_of::<Node>()
            + self.qnodes.capacity() * size_of::<QNode>()
            + self.leaves.capacity() * size_of::<Leaf>()
            + self.tris.capacity() * size_of::<TriRef>()
            + self.lanes.f.capacity() * size_of::<f32>()
            + self.meshes.capacity() * size_of::<MeshRef>()
            + self.meshes.iter().map(|m| m.positions.len() * size_of::<Vec3>() + m.triangles.len() * size_of::<[u32; 3]>()).sum::<usize>()
            + self.others.capacity() * size_of::<PrimGeom>()
            + self.other_refs.capacity() * size_of::<PrimRef>()
            + self.instances.capacity() * size_of::<Instance>()
            + self.groups.iter().map(Accel::memory_bytes).sum::<usize>()
    }

    /// Bytes of the wide nodes alone (full or quantized; groups included).
    pub fn node_bytes(&self) -> usize {
        self.nodes.capacity() * std::mem::size_of::<Node>()
            + self.qnodes.capacity() * std::mem::size_of::<QNode>()
            + self.groups.iter().map(Accel::node_bytes).sum::<usize>()
    }

    /// Whether the tree is too big for a core's cache, so that its
    /// traversal prefetches (and the meshes behind it are likely cold too).
    pub fn prefetches(&self) -> bool {
        self.prefetches
    }

    /// The instruction set the traversal runs with.
    pub fn simd_level(&self) -> SimdLevel {
        self.level
    }

    /// Makes the traversal run with `level` (for tests and measurements).
    /// Panics if this CPU cannot run it (`SimdLevel::supported`).
    pub fn set_simd_level(&mut self, level: SimdLevel) {
        assert!(level.supported(), "this CPU cannot run {level:?}");
        self.level = level;
    }

    /// The closest hit along the ray before `ray.tmax`.
    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<Hit> {
        let mut hit = None;
        self.intersect_each(std::slice::from_ref(ray), std::slice::from_mut(&mut hit));
        hit
    }

    /// Whether anything lies on the ray before `ray.tmax`.
    #[inline]
    pub fn occluded(&self, ray: &Ray) -> bool {
        let mut blocked = false;
        self.occluded_each(std::slice::from_ref(ray), std::slice::from_mut(&mut blocked));
        blocked
    }

    /// The closest hit of each ray of `rays` into `hits` (same length), by
    /// the single-ray traversal, one ray after the other.
    pub(crate) fn intersect_each(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        match self.level {
            // SAFETY: `level` is only ever set to a level the CPU supports.
            #[cfg(target_arch = "x86_64")]
            SimdLevel::Avx512 => unsafe { self.closest_each_avx512(rays, hits) },
            #[cfg(target_arch = "x86_64")]
            SimdLevel::Avx2 => unsafe { self.closest_each_avx2(rays, hits) },
            _ => self.closest_each_portable(rays, hits),
        }
    }

    /// Whether anything lies on each ray of `rays` before its `tmax`, into
    /// `out` (same length), by the single-ray traversal.
    pub(crate) fn occluded_each(&self, rays: &[Ray], out: &mut [bool]) {
        match self.level {
            // SAFETY: as above.
            #[cfg(target_arch = "x86_64")]
            SimdLevel::Avx512 => unsafe { self.occluded_each_avx512(rays, out) },
            #[cfg(target_arch = "x86_64")]
            SimdLevel::Avx2 => unsafe { self.occluded_each_avx2(rays, out) },
            _ => self.occluded_each_portable(rays, out),
        }
    }

    // A copy of each traversal per level and per kind of BVH (instances or
    // not, quantized nodes or not, triangles kept as lanes or gathered):
    // what the BVH holds is decided here once per call, not at every ray,
    // node or leaf, and the code of what it lacks is compiled out. Each copy
    // is compiled once, in the functions below, never inlined: copies
    // inlined into their callers (the stream traversals' fallback) made the
    // traversal most of the crate's compile time. (An instanced group's
    // traversal stays inlined into its top level's: as a call it cost 3.5 %
    // on the rainbow's instanced droplets.)
    #[inline(always)]
    fn closest_each_lanes<V: Lanes>(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        match (self.instances.is_empty(), self.qnodes.is_empty(), self.keeps_packets()) {
            (true, true, true) => self.closest_each_of::<false, false, true, V>(rays, hits),
            (true, true, false) => self.closest_each_of::<false, false, false, V>(rays, hits),
            (false, true, true) => self.closest_each_of::<true, false, true, V>(rays, hits),
            (false, true, false) => self.closest_each_of::<true, false, false, V>(rays, hits),
            (true, false, true) => self.closest_each_of::<false, true, true, V>(rays, hits),
            (true, false, false) => self.closest_each_of::<false, true, false, V>(rays, hits),
            (false, false, true) => self.closest_each_of::<true, true, true, V>(rays, hits),
            (false, false, false) => self.closest_each_of::<true, true, false, V>(rays, hits),
        }
    }

    #[inline(always)]
    fn closest_each_of<const INSTANCES: bool, const Q: bool, const PACKED: bool, V: Lanes>(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        for (ray, hit) in rays.iter().zip(hits.iter_mut()) {
            let mut best = Closest::new(ray.tmax, 0);
            self.closest::<INSTANCES, Q, PACKED, V>(ray, &mut best);
            *hit = best.hit();
        }
    }

    #[inline(always)]
    fn occluded_each_lanes<V: Lanes>(&self, rays: &[Ray], out: &mut [bool]) {
        match (self.instances.is_empty(), self.qnodes.is_empty(), self.keeps_packets()) {
            (true, true, true) => self.occluded_each_of::<false, false, true, V>(rays, out),
            (true, true, false) => self.occluded_each_of::<false, false, false, V>(rays, out),
            (false, true, true) => self.occluded_each_of::<true, false, true, V>(rays, out),
            (false, true, false) => self.occluded_each_of::<true, false, false, V>(rays, out),
            (true, false, true) => self.occluded_each_of::<false, true, true, V>(rays, out),
            (true, false, false) => self.occluded_each_of::<false, true, false, V>(rays, out),
            (false, false, true) => self.occluded_each_of::<true, true, true, V>(rays, out),
            (false, false, false) => self.occluded_each_of::<true, true, false, V>(rays, out),
        }
    }

    #[inline(always)]
    fn occluded_each_of<const INSTANCES: bool, const Q: bool, const PACKED: bool, V: Lanes>(&self, rays: &[Ray], out: &mut [bool]) {
        for (ray, o) in rays.iter().zip(out.iter_mut()) {
            *o = self.any_hit::<INSTANCES, Q, PACKED, V>(ray);
        }
    }

    #[inline(never)]
    fn closest_each_portable(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        self.closest_each_lanes::<Portable>(rays, hits)
    }

    #[inline(never)]
    fn occluded_each_portable(&self, rays: &[Ray], out: &mut [bool]) {
        self.occluded_each_lanes::<Portable>(rays, out)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    #[inline(never)]
    fn closest_each_avx2(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        self.closest_each_lanes::<Avx>(rays, hits)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    #[inline(never)]
    fn occluded_each_avx2(&self, rays: &[Ray], out: &mut [bool]) {
        self.occluded_each_lanes::<Avx>(rays, out)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,avx512f,avx512vl,avx512dq,avx512bw")]
    #[inline(never)]
    fn closest_each_avx512(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        self.closest_each_lanes::<Avx>(rays, hits)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,avx512f,avx512vl,avx512dq,avx512bw")]
    #[inline(never)]
    fn occluded_each_avx512(&self, rays: &[Ray], out: &mut [bool]) {
        self.occluded_each_lanes::<Avx>(rays, out)
    }

    /// The traversal of an instanced group, whose node format and triangle
    /// storage may differ from the top level's.
    #[inline(always)]
    fn group_closest<V: Lanes>(&self, ray: &Ray, best: &mut Closest) {
        match (self.qnodes.is_empty(), self.keeps_packets()) {
            (true, true) => self.closest::<false, false, true, V>(ray, best),
            (true, false) => self.closest::<false, false, false, V>(ray, best),
            (false, true) => self.closest::<false, true, true, V>(ray, best),
            (false, false) => self.closest::<false, true, false, V>(ray, best),
        }
    }

    #[inline(always)]
    fn group_any_hit<V: Lanes>(&self, ray: &Ray) -> bool {
        match (self.qnodes.is_empty(), self.keeps_packets()) {
            (true, true) => self.any_hit::<false, false, true, V>(ray),
            (true, false) => self.any_hit::<false, false, false, V>(ray),
            (false, true) => self.any_hit::<false, true, true, V>(ray),
            (false, false) => self.any_hit::<false, true, false, V>(ray),
        }
    }

    /// Closest hit, improving on `best` (which it starts from); `INSTANCES`:
    /// this BVH may hold instances (whose groups are traced by the `false`
    /// copy: groups do not nest); `Q`: its nodes are the quantized ones;
    /// `PACKED`: it keeps its triangles as lanes (`keeps_packets`, which
    /// the caller must have checked).
    #[inline(always)]
    fn closest<const INSTANCES: bool, const Q: bool, const PACKED: bool, V: Lanes>(&self, ray: &Ray, best: &mut Closest) {
        if if Q { self.qnodes.is_empty() } else { self.nodes.is_empty() } {
            return;
        }
        count!(stats::CLOSEST, stats::RAYS, 1);
        self.closest_from::<INSTANCES, Q, PACKED, V>(&RayData::<V>::new(ray), ray, best, 0, stats::CLOSEST);
    }

    /// `closest` from node `start` down (a non-empty BVH), with the ray's
    /// lanes `r` made; `kind`: the `stats` counters it adds to.
    #[inline(always)]
    fn closest_from<const INSTANCES: bool, const Q: bool, const PACKED: bool, V: Lanes>(&self, r: &RayData<V>, ray: &Ray, best: &mut Closest, start: u32, kind: usize) {
        let _ = kind;
        debug_assert_eq!(PACKED, self.keeps_packets());
        // Entries: entry distance bits (non-negative floats order like
        // their bits) above the child code, so they sort as integers.
        let mut stack: [MaybeUninit<u64>; STACK] = [MaybeUninit::uninit(); STACK];
        let mut sp = 0usize;
        let mut cur = start;
        let single = if Q { self.qnodes.len() } else { self.nodes.len() } == 1;
        loop {
            if cur & LEAF == 0 {
                count!(kind, stats::NODES, 1);
                count!(kind, stats::BOXES, WIDTH);
                let ((tnear, mask), children) = if Q {
                    let node = &self.qnodes[cur as usize];
                    (r.slab_q(node, best.reach()), &node.children)
                } else {
                    let node = &self.nodes[cur as usize];
                    (r.slab(node, best.reach()), &node.children)
                };
                if mask != 0 {
                    let rest = mask & (mask - 1);
                    if rest == 0 {
                        cur = children[mask.trailing_zeros() as usize];
                        continue;
                    }
                    if single && mask & !Self::eager_leaves::<INSTANCES, V>(children) == 0 {
                        // A BVH of one node (a tiny scene, as the Cornell
                        // box), and the ray enters leaves alone: each is
                        // tested now, in slot order. The tie rule makes the
                        // hit independent of the order, and ordering and
                        // stacking them cost more than the few leaves a
                        // nearer hit would cull (callgrind: −10 % in the
                        // Cornell box's closest hits; in deeper BVHs culling
                        // pays, +2 % on a 2 k-triangle mesh's).
                        let mut m = mask;
                        while m != 0 {
                            let i = m.trailing_zeros() as usize;
                            m &= m - 1;
                            self.leaf_closest::<INSTANCES, PACKED, V>(children[i], r, ray, best, kind);
                        }
                    } else {
                        // Two or more: go to the nearest, push the others far
                        // to near so the nearest remaining pops first.
                        let t = tnear.to_array();
                        let mut keys = [0u64; WIDTH];
                        let mut k = 0;
                        let mut m = mask;
                        while m != 0 {
                            let i = m.trailing_zeros() as usize;
                            m &= m - 1;
                            let key = (t[i].to_bits() as u64) << 32 | children[i] as u64;
                            // SAFETY: `k` counts the bits of `mask` taken so far,
                            // and `mask` has one bit per child. (Lets the sort
                            // below go without bounds checks.)
                            unsafe { std::hint::assert_unchecked(k < WIDTH) };
                            // Insertion sort, descending.
                            let mut j = k;
                            while j > 0 && keys[j - 1] < key {
                                keys[j] = keys[j - 1];
                                j -= 1;
                            }
                            keys[j] = key;
                            k += 1;
                        }
                        for &key in &keys[..k - 1] {
                            if !Q {
                                self.prefetch(key as u32);
                            }
                            stack[sp].write(key);
                            sp += 1;
                        }
                        cur = keys[k - 1] as u32;
                        continue;
                    }
                }
            } else {
                self.leaf_closest::<INSTANCES, PACKED, V>(cur, r, ray, best, kind);
            }
            // Pop the nearest pending node still in reach.
            loop {
                if sp == 0 {
                    return;
                }
                sp -= 1;
                // SAFETY: entries below `sp` were written before.
                let key = unsafe { stack[sp].assume_init() };
                if f32::from_bits((key >> 32) as u32) <= best.reach() {
                    cur = key as u32;
                    break;
                }
            }
        }
    }

    /// The slots of `children` (a node's child words) that `closest_from`
    /// tests at once when a ray enters only such: leaves; where the BVH
    /// holds instances, only leaves of triangles alone (`DIRECT`: an
    /// instance's group is worth culling by a nearer hit).
    #[inline(always)]
    fn eager_leaves<const INSTANCES: bool, V: Lanes>(children: &[u32; WIDTH]) -> u32 {
        if INSTANCES {
            let mut m = 0;
            for (i, &c) in children.iter().enumerate() {
                m |= ((c & (LEAF | DIRECT) == LEAF | DIRECT) as u32) << i;
            }
            m
        } else {
            // `LEAF` is the sign bit: one load and one sign mask.
            // SAFETY: [u32; 8] and [f32; 8] have the same size and
            // alignment, and every bit pattern is an f32.
            V::load(unsafe { &*(children as *const [u32; WIDTH] as *const [f32; WIDTH]) }).bitmask()
        }
    }

    /// The hits in leaf `cur` (a child word with `LEAF` set) on `ray`
    /// (lanes `r`) that beat `best`, into it; instances are traced into
    /// their groups when `INSTANCES`; `PACKED` as `keeps_packets`. Shared
    /// by the single-ray and packet closest hits.
    #[inline(always)]
    fn leaf_closest<const INSTANCES: bool, const PACKED: bool, V: Lanes>(&self, cur: u32, r: &RayData<V>, ray: &Ray, best: &mut Closest, kind: usize) {
        let _ = kind;
        count!(kind, stats::LEAVES, 1);
        if cur & DIRECT != 0 {
            let (p, n) = self.direct_packet::<PACKED, V>(cur);
            count!(kind, stats::TRIS, n);
            let key = |lane: usize| self.direct_key::<PACKED>(cur, lane);
            if let Some((lane, t, u, v)) = r.closest_in(&p, n, best, key) {
                best.set(t, key(lane), u, v);
            }
            return;
        }
        let leaf = &self.leaves[(cur & !LEAF) as usize];
        for (k, refs) in self.tris[leaf.tri_start as usize..leaf.tri_end as usize].chunks(PACKET).enumerate() {
            let first = leaf.tri_start as usize + k * PACKET;
            count!(kind, stats::TRIS, refs.len());
            let key = |lane: usize| {
                let tri = refs[lane];
                tie_key(self.meshes[tri.mesh as usize].shape, tri.prim, NO_INSTANCE)
            };
            if let Some((lane, t, u, v)) = r.closest_in(&self.packet::<PACKED, V>(first, refs), refs.len(), best, key) {
                best.set(t, key(lane), u, v);
            }
        }
        for oi in leaf.other_start..leaf.other_end {
            let g = &self.others[oi as usize];
            if let (true, PrimGeom::Instance(i)) = (INSTANCES, g) {
                let (group, local) = self.instance_ray(*i, ray, best.t);
                let mut h = Closest::new(best.t, u128::MAX);
                group.group_closest::<V>(&local, &mut h);
                let key = h.key & !(u32::MAX as u128) | *i as u128;
                if h.found && best.accepts(h.t, key) {
                    best.set(h.t, key, h.b1, h.b2);
                }
                continue;
            }
            // Hits at exactly `best.t` too (the tie rule weighs them).
            // (u, v): a curve's parameter; zero for the other shapes.
            let (t, u, v) = intersect_prim_bary(g, r.o, r.d, best.t.next_up());
            let pr = self.other_refs[oi as usize];
            let key = tie_key(pr.shape, pr.prim, NO_INSTANCE);
            if best.accepts(t, key) {
                best.set(t, key, u, v);
            }
        }
    }

    /// Whether anything lies on `ray` before its tmax; the constants as for
    /// `closest`.
    #[inline(always)]
    fn any_hit<const INSTANCES: bool, const Q: bool, const PACKED: bool, V: Lanes>(&self, ray: &Ray) -> bool {
        if if Q { self.qnodes.is_empty() } else { self.nodes.is_empty() } {
            return false;
        }
        count!(stats::OCCLUDED, stats::RAYS, 1);
        self.any_hit_from::<INSTANCES, Q, PACKED, V>(&RayData::<V>::new(ray), ray, 0, stats::OCCLUDED)
    }

    /// `any_hit` from node `start` down (a non-empty BVH), with the ray's
    /// lanes `r` made; `kind`: the `stats` counters it adds to.
    #[inline(always)]
    fn any_hit_from<const INSTANCES: bool, const Q: bool, const PACKED: bool, V: Lanes>(&self, r: &RayData<V>, ray: &Ray, start: u32, kind: usize) -> bool {
        let _ = kind;
        debug_assert_eq!(PACKED, self.keeps_packets());
        let tmax = ray.tmax;
        let mut stack: [MaybeUninit<u32>; STACK] = [MaybeUninit::uninit(); STACK];
        let mut sp = 0usize;
        let mut cur = start;
        loop {
            if cur & LEAF == 0 {
                count!(kind, stats::NODES, 1);
                count!(kind, stats::BOXES, WIDTH);
                let ((_, mut mask), children) = if Q {
                    let node = &self.qnodes[cur as usize];
                    (r.slab_q(node, tmax), &node.children)
                } else {
                    let node = &self.nodes[cur as usize];
                    (r.slab(node, tmax), &node.children)
                };
                if mask != 0 {
                    cur = children[mask.trailing_zeros() as usize];
                    mask &= mask - 1;
                    while mask != 0 {
                        let c = children[mask.trailing_zeros() as usize];
                        if !Q {
                            self.prefetch(c);
                        }
                        stack[sp].write(c);
                        sp += 1;
                        mask &= mask - 1;
                    }
                    continue;
                }
            } else if self.leaf_occludes::<INSTANCES, PACKED, V>(cur, r, ray, tmax, kind) {
                return true;
            }
            if sp == 0 {
                return false;
            }
            sp -= 1;
            // SAFETY: entries below `sp` were written before.
            cur = unsafe { stack[sp].assume_init() };
        }
    }

    /// The triangles of `DIRECT` leaf `cur`, one a lane, and their count
    /// (lanes past it hold other floats); `PACKED` as `keeps_packets`.
    #[inline(always)]
    fn direct_packet<const PACKED: bool, V: Lanes>(&self, cur: u32) -> (TriPacket<V>, usize) {
        let (first, n) = (((cur & !(LEAF | DIRECT)) >> 3) as usize, (cur & 7) as usize + 1);
        let p = if PACKED {
            self.lanes_at::<V>(first, n)
        } else {
            let m = &self.meshes[self.direct as usize];
            gather_run::<V>(&m.positions, &m.triangles[first..first + n])
        };
        (p, n)
    }

    /// The tie key of triangle `lane` of `DIRECT` leaf `cur`; `PACKED` as
    /// `keeps_packets`.
    #[inline(always)]
    fn direct_key<const PACKED: bool>(&self, cur: u32, lane: usize) -> u128 {
        let first = ((cur & !(LEAF | DIRECT)) >> 3) as usize;
        if PACKED {
            let tri = self.tris[first + lane];
            tie_key(self.meshes[tri.mesh as usize].shape, tri.prim, NO_INSTANCE)
        } else {
            tie_key(self.meshes[self.direct as usize].shape, (first + lane) as u32, NO_INSTANCE)
        }
    }

    /// Whether anything in leaf `cur` (a child word with `LEAF` set) lies on
    /// `ray` (lanes `r`) before `tmax`; instances are traced into their
    /// groups when `INSTANCES`; `PACKED` as `keeps_packets`. Shared by the
    /// single-ray and packet any-hits.
    #[inline(always)]
    fn leaf_occludes<const INSTANCES: bool, const PACKED: bool, V: Lanes>(&self, cur: u32, r: &RayData<V>, ray: &Ray, tmax: f32, kind: usize) -> bool {
        let _ = kind;
        count!(kind, stats::LEAVES, 1);
        if cur & DIRECT != 0 {
            let (p, n) = self.direct_packet::<PACKED, V>(cur);
            count!(kind, stats::TRIS, n);
            return r.triangles::<false>(&p, tmax).1 & lanes_of(n) != 0;
        }
        let leaf = &self.leaves[(cur & !LEAF) as usize];
        for (k, refs) in self.tris[leaf.tri_start as usize..leaf.tri_end as usize].chunks(PACKET).enumerate() {
            let first = leaf.tri_start as usize + k * PACKET;
            count!(kind, stats::TRIS, refs.len());
            if r.triangles::<false>(&self.packet::<PACKED, V>(first, refs), tmax).1 & lanes_of(refs.len()) != 0 {
                return true;
            }
        }
        for oi in leaf.other_start..leaf.other_end {
            let g = &self.others[oi as usize];
            if let (true, PrimGeom::Instance(i)) = (INSTANCES, g) {
                let (group, local) = self.instance_ray(*i, ray, tmax);
                if group.group_any_hit::<V>(&local) {
                    return true;
                }
            } else if intersect_prim_bary(g, r.o, r.d, tmax).0 < tmax {
                return true;
            }
        }
        false
    }

    /// Bounding box of everything (min, max); a unit box around the origin when empty.
    pub fn bounds(&self, _shapes: &[Shape]) -> (Vec3, Vec3) {
        let (lo, hi) = self.extent;
        if lo.x > hi.x { (Vec3::splat(-1.0), Vec3::splat(1.0)) } else { (lo, hi) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::mesh::Mesh;
    use crate::math::Pcg32;
    use crate::math::sampling::square_to_uniform_sphere;
    use glam::{Mat4, Vec2};

    /// Closest hit by testing every primitive: (t, shape, prim, b1, b2).
    pub(super) fn brute_force(shapes: &[Shape], ray: &Ray) -> Option<(f32, u32, u32, f32, f32)> {
        let mut best = None;
        let mut tmax = ray.tmax;
        for (si, s) in shapes.iter().enumerate() {
            for p in 0..s.primitive_count() {
                let (g, _) = prim_geom(s, p);
                let (t, u, v) = intersect_prim_bary(&g, ray.o.into(), ray.d.into(), tmax);
                if t < tmax {
                    tmax = t;
                    best = Some((t, si as u32, p as u32, u, v));
                }
            }
        }
        best
    }

    /// t of primitive (shape, prim) along the ray, infinite on a miss.
    pub(super) fn prim_t(shapes: &[Shape], shape: u32, prim: u32, ray: &Ray) -> f32 {
        let (g, _) = prim_geom(&shapes[shape as usize], prim as usize);
        intersect_prim_bary(&g, ray.o.into(), ray.d.into(), ray.tmax).0
    }

    pub(super) fn shape(geometry: ShapeGeometry) -> Shape {
        Shape { geometry, bsdf: 0, emitter: None, tangent_frame: false, pass_through: false, reads_uv: true, interior: None, exterior: None }
    }

    /// Checks closest hits and occlusion of `n` random rays against brute
    /// force; returns how many rays hit something.
    fn check(shapes: &[Shape], n: usize, seed: u64, lo: Vec3, hi: Vec3) -> usize {
        check_at(None, shapes, n, seed, lo, hi)
    }

    /// `check` with the traversal forced to `level` (else the current one).
    fn check_at(level: Option<SimdLevel>, shapes: &[Shape], n: usize, seed: u64, lo: Vec3, hi: Vec3) -> usize {
        let mut accel = Accel::build(shapes);
        if let Some(level) = level {
            accel.set_simd_level(level);
        }
        let mut rng = Pcg32::new(seed, 7);
        let mut hits = 0;
        for i in 0..n {
            let o = lo + (hi - lo) * Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
            let mut d = square_to_uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32()));
            if i % 7 == 0 {
                // Axis-parallel directions stress the slab test.
                d = [Vec3::X, -Vec3::Y, Vec3::Z, Vec3::new(1.0, 1.0, 0.0).normalize()][i % 4];
            }
            let tmax = if i % 3 == 0 { rng.next_f32() * 5.0 } else { f32::INFINITY };
            let ray = Ray { o, d, tmax };
            let expected = brute_force(shapes, &ray);
            let got = accel.intersect(&ray);
            match (expected, got) {
                (None, None) => {}
                (Some((t, s, p, b1, b2)), Some(h)) => {
                    hits += 1;
                    assert!((h.t - t).abs() <= 1e-5 * t.max(1.0), "ray {i}: t {} vs brute force {t}", h.t);
                    if (h.shape, h.prim) == (s, p) {
                        assert!((h.bary.0 - b1).abs() < 1e-4 && (h.bary.1 - b2).abs() < 1e-4, "ray {i}: barycentrics {:?} vs {:?}", h.bary, (b1, b2));
                    } else {
                        // A tie (a shared edge): the reported primitive must be hit at the same t.
                        let t2 = prim_t(shapes, h.shape, h.prim, &ray);
                        assert!((t2 - t).abs() <= 1e-5 * t.max(1.0), "ray {i}: other primitive ({}, {}) at {t2} vs {t}", h.shape, h.prim);
                    }
                }
                (e, g) => panic!("ray {i}: brute force {e:?}, accel {g:?}"),
            }
            assert_eq!(accel.occluded(&ray), expected.is_some(), "ray {i}: occlusion");
            if let Some((t, ..)) = expected {
                // Nothing before the closest hit, up to the precision the
                // closest-hit check above allows (1e-5 absolute below t = 1).
                let before = (t * 0.999).min(t - 2e-5 * t.max(1.0));
                assert!(!accel.occluded(&Ray { tmax: before, ..ray }) || brute_force(shapes, &Ray { tmax: before, ..ray }).is_some());
            }
        }
        hits
    }

    #[test]
    fn bvh_agrees_with_brute_force() {
        let mut shapes = vec![];
        for i in 0..20 {
            let t = Transform::from_matrix(Mat4::from_translation(Vec3::new(i as f32 * 0.3 - 3.0, (i % 5) as f32 * 0.4, 0.5 * (i % 3) as f32))
                * Mat4::from_rotation_y(i as f32))
            .unwrap();
            let geometry = match i % 3 {
                0 => ShapeGeometry::Mesh(Mesh::cube(&t, false)),
                1 => ShapeGeometry::Sphere(Sphere { center: t.point(Vec3::ZERO), radius: 0.3, to_object: Transform::IDENTITY, flip_normals: false }),
                _ => ShapeGeometry::Disk(Disk::new(t, false)),
            };
            shapes.push(shape(geometry));
        }
        let hits = check(&shapes, 5000, 9, Vec3::new(-4.0, -1.0, -3.0), Vec3::new(4.0, 3.0, 3.0));
        assert!(hits > 500, "the test should exercise hits ({hits})");
    }

    #[test]
    fn random_soup_with_spheres_and_disks() {
        let mut rng = Pcg32::new(3, 1);
        let mut shapes = vec![shape(ShapeGeometry::Mesh(triangle_soup(&mut rng, 300, 0.6)))];
        let mut r3 = || Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
        for _ in 0..10 {
            let c = r3() * 4.0 - 2.0;
            let radius = 0.05 + r3().x * 0.3;
            shapes.push(shape(ShapeGeometry::Sphere(Sphere { center: c, radius, to_object: Transform::IDENTITY, flip_normals: false })));
            let t = Transform::from_matrix(Mat4::from_translation(r3() * 4.0 - 2.0) * Mat4::from_rotation_x(r3().x * 6.0) * Mat4::from_scale(Vec3::splat(0.3))).unwrap();
            shapes.push(shape(ShapeGeometry::Disk(Disk::new(t, false))));
        }
        let hits = check(&shapes, 20000, 5, Vec3::splat(-3.0), Vec3::splat(3.0));
        assert!(hits > 1000, "{hits}");
    }

    /// Both builds: a scene just above `SMALL_BUILD` (binary leaves of up to
    /// `MAX_LEAF`) and one below it (binary tree to single primitives,
    /// grouped by the collapse) answer as brute force does.
    #[test]
    fn small_and_large_builds_agree_with_brute_force() {
        let mut rng = Pcg32::new(31, 7);
        for n in [SMALL_BUILD + 1000, 2000] {
            let shapes = vec![shape(ShapeGeometry::Mesh(random_mesh(&mut rng, n, Vec3::ZERO)))];
            let hits = check(&shapes, if n > SMALL_BUILD { 300 } else { 3000 }, 17, Vec3::splat(-2.0), Vec3::splat(2.0));
            assert!(hits > 0, "{n} triangles: no hits");
        }
    }

    /// A closed, bumpy sphere of a few thousand triangles (shared edges and
    /// vertices), seen from inside and outside.
    #[test]
    fn big_mesh() {
        let (nu, nv) = (80, 40);
        let mut positions = vec![];
        for j in 0..=nv {
            for i in 0..nu {
                let (th, ph) = (std::f32::consts::PI * j as f32 / nv as f32, std::f32::consts::TAU * i as f32 / nu as f32);
                let r = 1.0 + 0.1 * (5.0 * ph).sin() * (3.0 * th).sin();
                positions.push(Vec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos()) * r + Vec3::new(10.0, -5.0, 3.0));
            }
        }
        let mut triangles = vec![];
        for j in 0..nv as u32 {
            for i in 0..nu as u32 {
                let a = j * nu as u32 + i;
                let b = j * nu as u32 + (i + 1) % nu as u32;
                triangles.push([a, b, b + nu as u32]);
                triangles.push([a, b + nu as u32, a + nu as u32]);
            }
        }
        assert!(triangles.len() >= 6000);
        let shapes = vec![shape(ShapeGeometry::Mesh(Mesh::new(positions, None, None, triangles, false)))];
        let c = Vec3::new(10.0, -5.0, 3.0);
        let hits = check(&shapes, 5000, 11, c - Vec3::splat(0.8), c + Vec3::splat(0.8));
        assert!(hits > 3000, "{hits}");
        check(&shapes, 5000, 12, c - Vec3::splat(3.0), c + Vec3::splat(3.0));
    }

    /// A random mesh with shared vertices, including degenerate triangles
    /// (repeated vertices, collinear vertices, zero area) and tiny ones.
    /// `n` separate triangles of size about `size` scattered over
    /// [-2, 2]³.
    pub(super) fn triangle_soup(rng: &mut Pcg32, n: u32, size: f32) -> Mesh {
        let mut r3 = || Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
        let (mut positions, mut triangles) = (vec![], vec![]);
        for i in 0..n {
            let c = r3() * 4.0 - 2.0;
            for _ in 0..3 {
                positions.push(c + (r3() - 0.5) * size);
            }
            triangles.push([3 * i, 3 * i + 1, 3 * i + 2]);
        }
        Mesh::new(positions, None, None, triangles, false)
    }

    pub(super) fn random_mesh(rng: &mut Pcg32, n_tris: usize, centre: Vec3) -> Mesh {
        let mut r3 = || Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
        let n_verts = n_tris / 2 + 3;
        let mut positions: Vec<Vec3> = (0..n_verts).map(|_| centre + (r3() - 0.5) * 3.0).collect();
        // Some vertices on a common line and some on an axis-aligned plane.
        for k in 0..n_verts / 10 {
            positions[k] = centre + Vec3::new(k as f32 * 0.01, 0.5, 0.5);
        }
        let mut triangles = vec![];
        for i in 0..n_tris {
            let v = |x: f32| ((x * n_verts as f32) as u32).min(n_verts as u32 - 1);
            let a = v(r3().x);
            let mut t = [a, v(r3().y), v(r3().z)];
            match i % 11 {
                0 => t[1] = t[0],                                 // two equal vertices
                1 => t = [t[0], t[0], t[0]],                       // a point
                2 => t = [0, 1, 2].map(|k| (k + i as u32) % (n_verts as u32 / 10)), // collinear
                3 => {
                    // tiny: two vertices close to the first
                    let p = positions[a as usize];
                    positions.push(p + Vec3::new(1e-4, 0.0, 0.0));
                    positions.push(p + Vec3::new(0.0, 1e-4, 0.0));
                    t = [a, positions.len() as u32 - 2, positions.len() as u32 - 1];
                }
                _ => {}
            }
            triangles.push(t);
        }
        Mesh::new(positions, None, None, triangles, false)
    }

    /// Several random meshes (with degenerate triangles) mixed with spheres in one BVH.
    #[test]
    fn random_meshes_with_degenerate_triangles() {
        let mut rng = Pcg32::new(21, 3);
        let mut shapes = vec![];
        for k in 0..4 {
            let centre = Vec3::new(k as f32 - 1.5, 0.3 * k as f32, 0.0);
            shapes.push(shape(ShapeGeometry::Mesh(random_mesh(&mut rng, 200 + 150 * k, centre))));
            shapes.push(shape(ShapeGeometry::Sphere(Sphere { center: centre + Vec3::Z, radius: 0.2, to_object: Transform::IDENTITY, flip_normals: false })));
        }
        let hits = check(&shapes, 10000, 23, Vec3::splat(-3.5), Vec3::splat(3.5));
        assert!(hits > 1500, "{hits}");
    }

    /// Every instruction-set level this CPU runs agrees with brute force
    /// (triangles with degenerate ones, spheres, disks), and AVX2 and
    /// AVX-512 give bit-identical hits.
    #[test]
    fn every_simd_level_agrees_with_brute_force() {
        let mut rng = Pcg32::new(31, 4);
        let mut shapes = vec![];
        for k in 0..3 {
            let centre = Vec3::new(k as f32 - 1.0, 0.2 * k as f32, 0.0);
            shapes.push(shape(ShapeGeometry::Mesh(random_mesh(&mut rng, 400 + 100 * k, centre))));
            shapes.push(shape(ShapeGeometry::Sphere(Sphere { center: centre + Vec3::Z, radius: 0.25, to_object: Transform::IDENTITY, flip_normals: false })));
            let t = Transform::from_matrix(Mat4::from_translation(centre - Vec3::Z) * Mat4::from_rotation_x(k as f32)).unwrap();
            shapes.push(shape(ShapeGeometry::Disk(Disk::new(t, false))));
        }
        let levels: Vec<SimdLevel> = SimdLevel::ALL.into_iter().filter(|l| l.supported()).collect();
        eprintln!("levels tested: {levels:?}");
        for &level in &levels {
            let hits = check_at(Some(level), &shapes, 6000, 41, Vec3::splat(-3.0), Vec3::splat(3.0));
            assert!(hits > 1000, "{level:?}: {hits}");
        }
        if levels.contains(&SimdLevel::Avx512) {
            let mut a = Accel::build(&shapes);
            let mut b = Accel::build(&shapes);
            a.set_simd_level(SimdLevel::Avx2);
            b.set_simd_level(SimdLevel::Avx512);
            let mut rng = Pcg32::new(8, 8);
            for _ in 0..5000 {
                let o = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 6.0 - 3.0;
                let d = square_to_uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32()));
                let ray = Ray::new(o, d);
                let key = |h: Option<Hit>| h.map(|h| (h.t.to_bits(), h.bary.0.to_bits(), h.bary.1.to_bits(), h.shape, h.prim));
                assert_eq!(key(a.intersect(&ray)), key(b.intersect(&ray)));
                assert_eq!(a.occluded(&ray), b.occluded(&ray));
            }
        }
    }

    /// Stored packets and triangles gathered from the meshes give
    /// bit-identical hits and occlusion at every level this CPU runs
    /// (meshes with degenerate triangles, instanced groups, spheres).
    #[test]
    fn stored_packets_equal_gathered_triangles() {
        let mut rng = Pcg32::new(17, 9);
        let mut shapes = vec![];
        for k in 0..3 {
            let centre = Vec3::new(k as f32 - 1.0, 0.2 * k as f32, 0.0);
            shapes.push(shape(ShapeGeometry::Mesh(random_mesh(&mut rng, 300 + 100 * k, centre))));
            shapes.push(shape(ShapeGeometry::Sphere(Sphere { center: centre + Vec3::Z, radius: 0.25, to_object: Transform::IDENTITY, flip_normals: false })));
        }
        let instances: Vec<(Transform, u32)> = (0..4)
            .map(|i| (Transform::from_matrix(Mat4::from_translation(Vec3::new(0.0, i as f32 - 1.5, 1.5)) * Mat4::from_rotation_y(i as f32)).unwrap(), 0))
            .collect();
        let packed = Accel::build_instanced(&shapes, &[0, 1, 3], &[vec![2, 4, 5]], &instances);
        assert!(packed.keeps_packets() && packed.groups[0].keeps_packets(), "small BVHs keep packets");
        let mut gathered = Accel::build_instanced(&shapes, &[0, 1, 3], &[vec![2, 4, 5]], &instances);
        gathered.gather_triangles();
        assert!(!gathered.keeps_packets() && !gathered.groups[0].keeps_packets());
        assert!(packed.memory_bytes() > gathered.memory_bytes());
        let key = |h: Option<Hit>| h.map(|h| (h.t.to_bits(), h.bary.0.to_bits(), h.bary.1.to_bits(), h.shape, h.prim, h.instance));
        let (mut hits, mut occluded) = (0, 0);
        for level in SimdLevel::ALL.into_iter().filter(|l| l.supported()) {
            let (mut a, mut b) = (Accel::build_instanced(&shapes, &[0, 1, 3], &[vec![2, 4, 5]], &instances), Accel::build_instanced(&shapes, &[0, 1, 3], &[vec![2, 4, 5]], &instances));
            b.gather_triangles();
            a.set_simd_level(level);
            b.set_simd_level(level);
            for i in 0..4000 {
                let o = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 6.0 - 3.0;
                let d = square_to_uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32()));
                let ray = Ray { o, d, tmax: if i % 3 == 0 { rng.next_f32() * 4.0 } else { f32::INFINITY } };
                let h = a.intersect(&ray);
                hits += h.is_some() as usize;
                assert_eq!(key(h), key(b.intersect(&ray)), "{level:?}, ray {i}");
                let occ = a.occluded(&ray);
                occluded += occ as usize;
                assert_eq!(occ, b.occluded(&ray), "{level:?}, ray {i}");
            }
        }
        assert!(hits > 1000 && occluded == hits, "{hits} hits, {occluded} occluded");
    }

    /// Meshes renumbered in leaf order (top level and an instanced group,
    /// with degenerate triangles): every ray gets the same hit (t and
    /// barycentric bits, the same triangle under its new number) and the
    /// same occlusion as before, gathered and at every level; a leaf's
    /// triangles are consecutive in their mesh.
    #[test]
    fn leaf_order_keeps_every_hit() {
        let mut rng = Pcg32::new(12, 5);
        let mut shapes = vec![];
        for k in 0..3 {
            let centre = Vec3::new(k as f32 - 1.0, 0.2 * k as f32, 0.0);
            shapes.push(shape(ShapeGeometry::Mesh(random_mesh(&mut rng, 500 + 100 * k, centre))));
            shapes.push(shape(ShapeGeometry::Sphere(Sphere { center: centre + Vec3::Z, radius: 0.25, to_object: Transform::IDENTITY, flip_normals: false })));
        }
        let instances: Vec<(Transform, u32)> = (0..3)
            .map(|i| (Transform::from_matrix(Mat4::from_translation(Vec3::new(0.0, i as f32 - 1.0, 1.5)) * Mat4::from_rotation_y(i as f32)).unwrap(), 0))
            .collect();
        let (top, groups) = ([0u32, 1, 3], [vec![2u32, 4, 5]]);
        for level in SimdLevel::ALL.into_iter().filter(|l| l.supported()) {
            let mut ordered_shapes = shapes.clone();
            let mut before = Accel::build_instanced(&shapes, &top, &groups, &instances);
            let mut after = Accel::build_instanced(&ordered_shapes, &top, &groups, &instances);
            after.gather_triangles();
            after.leaf_order(&mut ordered_shapes, true);
            for a in [&mut before, &mut after] {
                a.gather_triangles();
                a.set_simd_level(level);
            }
            // The biggest mesh's leaves became direct child words, the
            // others' stayed leaves.
            for accel in [&after, &after.groups[0]] {
                let codes = || accel.nodes.iter().flat_map(|n| n.children).filter(|c| c & LEAF != 0);
                let direct = codes().filter(|c| c & DIRECT != 0).count();
                assert!(accel.direct != u32::MAX && direct > 20 && codes().count() > direct, "{direct} direct leaves");
            }
            // Every leaf's triangles are a run of consecutive numbers.
            for accel in [&after, &after.groups[0]] {
                for leaf in &accel.leaves {
                    let refs = &accel.tris[leaf.tri_start as usize..leaf.tri_end as usize];
                    for w in refs.windows(2) {
                        assert!(w[0].mesh != w[1].mesh || w[1].prim == w[0].prim + 1, "{:?}", refs);
                    }
                }
            }
            let corners = |s: &[Shape], h: &Hit| match &s[h.shape as usize].geometry {
                ShapeGeometry::Mesh(m) => m.vertices(h.prim as usize).map(|v| v.to_array().map(f32::to_bits)),
                _ => [[h.prim; 3]; 3],
            };
            let (mut hits, mut renumbered) = (0, 0);
            for i in 0..4000 {
                let o = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 6.0 - 3.0;
                let d = square_to_uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32()));
                let ray = Ray { o, d, tmax: if i % 3 == 0 { rng.next_f32() * 4.0 } else { f32::INFINITY } };
                let (a, b) = (before.intersect(&ray), after.intersect(&ray));
                let key = |h: &Hit| (h.t.to_bits(), h.bary.0.to_bits(), h.bary.1.to_bits(), h.shape, h.instance);
                match (a, b) {
                    (None, None) => {}
                    (Some(a), Some(b)) => {
                        hits += 1;
                        renumbered += (a.prim != b.prim) as usize;
                        assert_eq!(key(&a), key(&b), "{level:?}, ray {i}");
                        assert_eq!(corners(&shapes, &a), corners(&ordered_shapes, &b), "{level:?}, ray {i}: another triangle");
                    }
                    (a, b) => panic!("{level:?}, ray {i}: {a:?} vs {b:?}"),
                }
                assert_eq!(before.occluded(&ray), after.occluded(&ray), "{level:?}, ray {i}");
            }
            assert!(hits > 1000 && renumbered > hits / 2, "{hits} hits, {renumbered} renumbered");
        }
    }

    /// A mesh of more triangles than one build thread takes, so the two
    /// halves of the top nodes are built in parallel.
    #[test]
    fn large_random_mesh_parallel_build() {
        let mut rng = Pcg32::new(5, 8);
        let shapes = vec![shape(ShapeGeometry::Mesh(random_mesh(&mut rng, 3 * build::PAR_MIN_FOR_TESTS, Vec3::ZERO)))];
        let hits = check(&shapes, 3000, 2, Vec3::splat(-2.0), Vec3::splat(2.0));
        assert!(hits > 1000, "{hits}");
        // The same tree as a serial build would make: every triangle in exactly one leaf.
        let accel = Accel::build(&shapes);
        let mut seen = vec![0u8; shapes[0].primitive_count()];
        for t in &accel.tris {
            seen[t.prim as usize] += 1;
        }
        assert!(seen.iter().all(|&c| c == 1));
    }

    /// Two-level BVH: random meshes placed by rotated, scaled and mirrored
    /// instances, against brute force over the same meshes transformed to world space.
    #[test]
    fn instanced_meshes_agree_with_brute_force() {
        let mut rng = Pcg32::new(77, 1);
        let group_shapes = vec![
            shape(ShapeGeometry::Mesh(random_mesh(&mut rng, 300, Vec3::ZERO))),
            shape(ShapeGeometry::Sphere(Sphere { center: Vec3::new(0.5, 0.0, 0.0), radius: 0.3, to_object: Transform::IDENTITY, flip_normals: false })),
            shape(ShapeGeometry::Mesh(random_mesh(&mut rng, 100, Vec3::new(0.0, 1.0, 0.0)))),
        ];
        // Shape 3 is a plain top-level mesh.
        let mut all = group_shapes.clone();
        all.push(shape(ShapeGeometry::Mesh(random_mesh(&mut rng, 150, Vec3::new(0.0, -3.0, 0.0)))));
        let mut instances = vec![];
        for k in 0..6 {
            let m = Mat4::from_translation(Vec3::new(3.0 * (k % 3) as f32 - 3.0, 3.0 * (k / 3) as f32, 0.0))
                * Mat4::from_rotation_y(k as f32 * 0.7)
                * Mat4::from_scale(Vec3::new(if k == 4 { -0.8 } else { 0.8 }, 0.6 + 0.1 * k as f32, 0.7));
            instances.push((Transform::from_matrix(m).unwrap(), 0u32));
        }
        let accel = Accel::build_instanced(&all, &[3], &[vec![0, 1, 2]], &instances);
        let mut hits = 0;
        for i in 0..4000 {
            let o = Vec3::new(rng.next_f32() * 10.0 - 5.0, rng.next_f32() * 9.0 - 4.5, rng.next_f32() * 6.0 - 3.0);
            let d = square_to_uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32()));
            let ray = Ray { o, d, tmax: if i % 4 == 0 { 2.0 } else { f32::INFINITY } };
            // Brute force: the top mesh in world space, each instance in its own space.
            let mut best: Option<(f32, u32, u32, u32)> = brute_force(&all[3..4], &ray).map(|(t, _, p, ..)| (t, 3, p, NO_INSTANCE));
            for (k, (tf, _)) in instances.iter().enumerate() {
                let local = Ray { o: tf.inverse_point(ray.o), d: tf.inverse_vector(ray.d), tmax: best.map_or(ray.tmax, |b| b.0) };
                if let Some((t, s, p, ..)) = brute_force(&group_shapes, &local) {
                    best = Some((t, s, p, k as u32));
                }
            }
            let got = accel.intersect(&ray);
            match (best, got) {
                (None, None) => {}
                (Some((t, s, p, inst)), Some(h)) => {
                    hits += 1;
                    assert!((h.t - t).abs() <= 1e-4 * t.max(1.0), "ray {i}: t {} vs {t}", h.t);
                    if (h.shape, h.prim, h.instance) != (s, p, inst) {
                        // A tie: the reported primitive is hit at the same t.
                        let tf = if h.instance == NO_INSTANCE { Transform::IDENTITY } else { instances[h.instance as usize].0 };
                        let local = Ray { o: tf.inverse_point(ray.o), d: tf.inverse_vector(ray.d), tmax: ray.tmax };
                        let t2 = prim_t(&all, h.shape, h.prim, &local);
                        assert!((t2 - t).abs() <= 1e-4 * t.max(1.0), "ray {i}: ({}, {}, {}) at {t2} vs {t}", h.shape, h.prim, h.instance);
                    }
                }
                (b, g) => panic!("ray {i}: brute force {b:?}, accel {g:?}"),
            }
            assert_eq!(accel.occluded(&ray), best.is_some(), "ray {i}: occlusion");
        }
        assert!(hits > 800, "{hits}");
    }

    #[test]
    fn empty_and_single() {
        let accel = Accel::build(&[]);
        assert!(accel.intersect(&Ray::new(Vec3::ZERO, Vec3::X)).is_none());
        assert!(!accel.occluded(&Ray::new(Vec3::ZERO, Vec3::X)));
        let shapes = vec![shape(ShapeGeometry::Sphere(Sphere { center: Vec3::new(3.0, 0.0, 0.0), radius: 1.0, to_object: Transform::IDENTITY, flip_normals: false }))];
        let accel = Accel::build(&shapes);
        let h = accel.intersect(&Ray::new(Vec3::ZERO, Vec3::X)).unwrap();
        assert!((h.t - 2.0).abs() < 1e-6);
        assert!(accel.occluded(&Ray::new(Vec3::ZERO, Vec3::X)));
        assert!(!accel.occluded(&Ray { tmax: 1.9, ..Ray::new(Vec3::ZERO, Vec3::X) }));
    }
}
