//! Compressed wide nodes for big BVHs: the eight child boxes of a node as
//! 8-bit offsets against the node's own box, after Ylitie, Karras and
//! Laine, "Efficient incoherent ray traversal on GPUs through compressed
//! wide BVHs" (HPG 2017), and Embree's quantized BVH8 nodes.
//!
//! A `QNode` is 96 bytes (two cache lines at most, against the 224 bytes
//! of the full `Node`): the box origin (the minimum corner, 3 f32), one
//! power-of-two scale per axis (as its exponent, 3 i8), a mask of the
//! used slots, the six rows of eight quantized planes (lo x, y, z, hi x,
//! y, z as u8) and the eight child words, which code children exactly as
//! `Node::children` does.
//!
//! A plane decodes as `q · 2^e + origin`. The product is exact (an 8-bit
//! integer times a power of two), so the one rounding is that of the sum,
//! the same with or without a fused multiply-add: the build computes the
//! decoded planes with the very operations the traversal uses and moves
//! each quantized plane outwards until its decoded value lies on the
//! outer side of the exact one. A child's decoded box therefore always
//! contains its exact box: a ray can only enter more boxes, never fewer,
//! so the closest hit (its t) is the same as with full nodes; only when
//! two primitives are hit at exactly the same t can the changed visiting
//! order report the other one.
//!
//! The traversal decodes the planes (one widening load, one conversion
//! and one multiply-add per row) and then runs the same conservative slab
//! test as for full nodes.
//!
//! Which BVHs use them: only those built with `SNELL_NODES=quantized`
//! (`quantizes` in `accel.rs` says why: measured slower per sample at 1 M
//! and 4 M triangles, for 58 % less node memory).

use super::simd::Lanes;
use super::{Node, RayData, WIDTH};

/// A wide node with quantized child boxes (see the module documentation).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
pub(super) struct QNode {
    origin: [f32; 3],
    /// Scale exponents: a step on axis a is 2^exp[a].
    exp: [i8; 3],
    /// Bit i: slot i holds a child.
    valid: u8,
    /// Quantized planes: `q[0..3]` minima on x, y, z, `q[3..6]` maxima.
    q: [[u8; WIDTH]; 6],
    /// As `Node::children`.
    pub(super) children: [u32; WIDTH],
}

const _: () = assert!(std::mem::size_of::<QNode>() == 96);

/// 2^e as an f32, for e in −126..=127.
#[inline(always)]
fn pow2(e: i8) -> f32 {
    f32::from_bits(((e as i32 + 127) as u32) << 23)
}

/// The decoded plane: `q · s + origin`, as the traversal computes it.
#[inline(always)]
fn decode(q: u8, s: f32, origin: f32) -> f32 {
    (q as f32).mul_add(s, origin)
}

impl QNode {
    /// The quantized form of `node`, whose used slots have finite boxes.
    pub(super) fn new(node: &Node) -> QNode {
        let mut valid = 0u8;
        let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
        for i in 0..WIDTH {
            if node.b[0][i] <= node.b[3][i] {
                valid |= 1 << i;
                for a in 0..3 {
                    lo[a] = lo[a].min(node.b[a][i]);
                    hi[a] = hi[a].max(node.b[a + 3][i]);
                }
            }
        }
        let mut q = [[0u8; WIDTH]; 6];
        let mut exp = [0i8; 3];
        if valid == 0 {
            return QNode { origin: [0.0; 3], exp, valid, q, children: node.children };
        }
        for a in 0..3 {
            // The smallest e with extent ≤ 255 · 2^e (exact in f64).
            let extent = hi[a] as f64 - lo[a] as f64;
            let mut e = -126i32;
            if extent > 0.0 {
                e = (extent / 255.0).log2().ceil() as i32;
                while e > -126 && extent <= 255.0 * 2f64.powi(e - 1) {
                    e -= 1;
                }
                while extent > 255.0 * 2f64.powi(e) {
                    e += 1;
                }
            }
            let e = e.clamp(-126, 127);
            exp[a] = e as i8;
            let s = pow2(exp[a]);
            let origin = lo[a];
            for i in (0..WIDTH).filter(|&i| valid >> i & 1 != 0) {
                let (clo, chi) = (node.b[a][i], node.b[a + 3][i]);
                // Nearest guesses, then outwards until conservative: q = 0
                // decodes to the origin (≤ every minimum) and q = 255 to at
                // least the node's maximum (≥ every maximum).
                let mut ql = ((clo as f64 - origin as f64) / s as f64).floor().clamp(0.0, 255.0) as u8;
                while ql > 0 && decode(ql, s, origin) > clo {
                    ql -= 1;
                }
                let mut qh = ((chi as f64 - origin as f64) / s as f64).ceil().clamp(0.0, 255.0) as u8;
                while qh < 255 && decode(qh, s, origin) < chi {
                    qh += 1;
                }
                q[a][i] = ql;
                q[a + 3][i] = qh;
            }
            lo[a] = origin;
        }
        QNode { origin: lo, exp, valid, q, children: node.children }
    }

    /// The decoded box of slot `i` (min, max), as the traversal sees it.
    #[cfg(test)]
    pub(super) fn child_box(&self, i: usize) -> Option<([f32; 3], [f32; 3])> {
        if self.valid >> i & 1 == 0 {
            return None;
        }
        let d = |row: usize, a: usize| decode(self.q[row][i], pow2(self.exp[a]), self.origin[a]);
        Some(([d(0, 0), d(1, 1), d(2, 2)], [d(3, 0), d(4, 1), d(5, 2)]))
    }
}

impl<V: Lanes> RayData<V> {
    /// `slab` for a quantized node: entry distances and the mask of the
    /// children the ray enters within [0, tmax].
    #[inline(always)]
    pub(super) fn slab_q(&self, node: &QNode, tmax: f32) -> (V, u32) {
        let s = [V::splat(pow2(node.exp[0])), V::splat(pow2(node.exp[1])), V::splat(pow2(node.exp[2]))];
        let o = [V::splat(node.origin[0]), V::splat(node.origin[1]), V::splat(node.origin[2])];
        // `rows` holds byte offsets of rows of f32 (`Node::b`); the same
        // rows of u8 lie at a quarter of them.
        const _: () = assert!(std::mem::size_of::<[f32; WIDTH]>() == 4 * std::mem::size_of::<[u8; WIDTH]>());
        let q = node.q.as_ptr() as *const u8;
        // SAFETY: `rows` holds offsets of whole rows of the six (`OCTANT_ROWS`).
        let row = |i: usize| V::from_u8(unsafe { &*(q.add(self.rows[i] as usize / 4) as *const [u8; WIDTH]) });
        let plane = |i: usize, a: usize| row(i).mul_add(s[a], o[a]);
        let tnx = plane(0, 0).mul_sub(self.inv[0], self.oinv_n[0]);
        let tny = plane(1, 1).mul_sub(self.inv[1], self.oinv_n[1]);
        let tnz = plane(2, 2).mul_sub(self.inv[2], self.oinv_n[2]);
        let tfx = plane(3, 0).mul_sub(self.inv[0], self.oinv_f[0]);
        let tfy = plane(4, 1).mul_sub(self.inv[1], self.oinv_f[1]);
        let tfz = plane(5, 2).mul_sub(self.inv[2], self.oinv_f[2]);
        let tnear = tnx.max(tny).max(tnz.max(V::splat(0.0)));
        let tfar = tfx.min(tfy).min(tfz.min(V::splat(tmax)));
        (tnear, tnear.le(tfar * V::splat(super::FAR)).bitmask() & node.valid as u32)
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::{random_mesh, shape};
    use super::super::{Accel, Hit, Node, Ray, SimdLevel, WIDTH};
    use super::*;
    use crate::geometry::shape::ShapeGeometry;
    use crate::geometry::sphere::Sphere;
    use crate::math::sampling::square_to_uniform_sphere;
    use crate::math::{Pcg32, Transform};
    use glam::{Mat4, Vec2, Vec3};

    /// Decoded child boxes contain the exact ones (every slot, every
    /// axis) and are at most about one step larger on each side, for boxes
    /// near and far from the origin, tiny, flat, huge and subnormal.
    #[test]
    fn quantized_boxes_are_conservative_and_tight() {
        let mut rng = Pcg32::new(3, 11);
        let (mut checked, mut empty_slots) = (0, 0);
        for k in 0..20000 {
            // Per node: a centre, a size and how many slots are used.
            let centre = [0.0, 1.0, -3.5e3, 1e6, -2.5e7, 1e30, 3e-39][k % 7] as f32;
            let size = [1.0, 1e-3, 1e-6, 0.0, 37.0, 1e20, 2e-39][(k / 7) % 7] as f32;
            let used = 1 + (k % WIDTH);
            let (inf, ninf) = ([f32::INFINITY; WIDTH], [f32::NEG_INFINITY; WIDTH]);
            let mut node = Node { b: [inf, inf, inf, ninf, ninf, ninf], children: [0; WIDTH] };
            for i in 0..used {
                for a in 0..3 {
                    let mut x = centre + size * (rng.next_f32() - 0.5);
                    let mut y = if k % 5 == 0 { x } else { centre + size * (rng.next_f32() - 0.5) };
                    if x > y {
                        std::mem::swap(&mut x, &mut y);
                    }
                    node.b[a][i] = x;
                    node.b[a + 3][i] = y;
                }
                node.children[i] = i as u32 + 7;
            }
            let q = QNode::new(&node);
            assert_eq!(q.children, node.children);
            for i in 0..WIDTH {
                let Some((lo, hi)) = q.child_box(i) else {
                    assert!(i >= used, "node {k}: slot {i} lost");
                    empty_slots += 1;
                    continue;
                };
                assert!(i < used, "node {k}: empty slot {i} decoded");
                for a in 0..3 {
                    let (clo, chi) = (node.b[a][i], node.b[a + 3][i]);
                    assert!(lo[a] <= clo && chi <= hi[a], "node {k} slot {i} axis {a}: [{clo}, {chi}] not in [{}, {}]", lo[a], hi[a]);
                    let step = pow2(q.exp[a]);
                    let slack = step + 4.0 * f32::EPSILON * clo.abs().max(chi.abs());
                    assert!(clo - lo[a] <= slack && hi[a] - chi <= slack, "node {k} slot {i} axis {a}: [{clo}, {chi}] in [{}, {}], step {step}", lo[a], hi[a]);
                }
                checked += 1;
            }
        }
        assert!(checked > 80000 && empty_slots > 30000, "{checked} {empty_slots}");
    }

    /// Random rays find the same closest-hit distance (bit for bit) and the
    /// same occlusion through quantized nodes as through full ones, at every
    /// instruction-set level, with instanced groups, spheres, degenerate
    /// triangles and meshes in leaf order (direct leaves); the primitive
    /// and barycentrics differ only for exact ties in t.
    #[test]
    fn quantized_nodes_give_the_same_hits() {
        let mut rng = Pcg32::new(23, 6);
        let mut shapes = vec![];
        for k in 0..3 {
            let centre = Vec3::new(k as f32 - 1.0, 0.2 * k as f32, 0.0);
            shapes.push(shape(ShapeGeometry::Mesh(random_mesh(&mut rng, 600 + 300 * k, centre))));
            shapes.push(shape(ShapeGeometry::Sphere(Sphere { center: centre + Vec3::Z, radius: 0.25, to_object: Transform::IDENTITY, flip_normals: false })));
        }
        let instances: Vec<(Transform, u32)> = (0..3)
            .map(|i| (Transform::from_matrix(Mat4::from_translation(Vec3::new(0.0, i as f32 - 1.0, 1.5)) * Mat4::from_rotation_y(i as f32)).unwrap(), 0))
            .collect();
        let (top, groups) = ([0u32, 1, 3], [vec![2u32, 4, 5]]);
        let key = |h: &Option<Hit>| h.map(|h| (h.t.to_bits(), h.shape, h.prim, h.instance, h.bary.0.to_bits(), h.bary.1.to_bits()));
        for level in SimdLevel::ALL.into_iter().filter(|l| l.supported()) {
            for ordered in [false, true] {
                let mut sh = shapes.clone();
                let mut accel = Accel::build_instanced(&sh, &top, &groups, &instances);
                if ordered {
                    accel.gather_triangles();
                    accel.leaf_order(&mut sh, true);
                }
                accel.set_simd_level(level);
                let rays: Vec<Ray> = (0..5000)
                    .map(|i| {
                        let o = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 6.0 - 3.0;
                        let mut d = square_to_uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32()));
                        if i % 7 == 0 {
                            d = [Vec3::X, -Vec3::Y, Vec3::Z, Vec3::new(1.0, 1.0, 0.0).normalize()][i % 4];
                        }
                        Ray { o, d, tmax: if i % 3 == 0 { rng.next_f32() * 4.0 } else { f32::INFINITY } }
                    })
                    .collect();
                let full: Vec<(Option<Hit>, bool)> = rays.iter().map(|r| (accel.intersect(r), accel.occluded(r))).collect();
                assert!(!accel.quantized());
                let bytes = accel.memory_bytes();
                accel.quantize_nodes();
                assert!(accel.quantized() && accel.groups[0].quantized());
                assert!(accel.memory_bytes() < bytes);
                let (mut hits, mut ties) = (0, 0);
                for (i, (ray, (a, occ))) in rays.iter().zip(&full).enumerate() {
                    let b = accel.intersect(ray);
                    assert_eq!(a.map(|h| h.t.to_bits()), b.map(|h| h.t.to_bits()), "{level:?} ordered {ordered}, ray {i}");
                    hits += a.is_some() as usize;
                    ties += (key(a) != key(&b)) as usize;
                    assert_eq!(*occ, accel.occluded(ray), "{level:?} ordered {ordered}, ray {i}");
                }
                assert!(hits > 1500 && ties * 100 <= hits, "{level:?} ordered {ordered}: {hits} hits, {ties} ties reported differently");
            }
        }
    }
}
