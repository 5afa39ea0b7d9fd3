//! Batched ("stream") queries of the BVH: closest hits and occlusion of a
//! whole queue of rays per call, for the wavefront path tracer
//! (`crate::integrator::wavefront`).
//!
//! | query | how |
//! |---|---|
//! | [`Accel::intersect_stream`] | one SIMD level dispatch per batch, then the single-ray closest-hit traversal (8 child boxes per instruction) for each ray in turn, compiled inside the batch loop |
//! | [`Accel::occluded_stream`] | packets of 8 rays (one ray per lane): each child box of a node is tested against all 8 rays at once, each ray carries its own mask of the nodes it enters, so it visits exactly the nodes its single-ray traversal visits; leaves test the rays that reach them one by one |
//!
//! Why this split: closest hits must be bit-identical to the single-ray
//! traversal (the wavefront renderer promises the same image as `path`),
//! and with ties on shared edges the order of visits decides which
//! triangle is reported, so the closest-hit query keeps the single-ray
//! order. Occlusion is a yes/no answer independent of the order of visits,
//! so it may be traced as a packet; the slab test per lane is the very
//! expression of the single-ray test (same near/far planes, same fused
//! multiply-subtract, same conservative widening), so every ray enters the
//! same boxes as alone and gets the same answer.
//!
//! Which instruction set runs is `Accel::simd_level` (`SNELL_SIMD`), as for
//! the single-ray queries. Scenes with instances take the single-ray
//! traversal for occlusion too.

use super::{Accel, Closest, Hit, LEAF, Lanes, RayData, STACK, WIDTH, lanes_of};
#[cfg(target_arch = "x86_64")]
use super::Avx;
use super::{Portable, SimdLevel};
use crate::geometry::Ray;
use glam::Vec3A;
use std::mem::MaybeUninit;
use std::sync::OnceLock;

/// Rays per occlusion packet: one per lane of the 8-wide node test.
const RAYS: usize = 8;

impl Accel {
    /// The closest hit of every ray of `rays` into `hits` (same length),
    /// bit for bit what [`Accel::intersect`] returns for each.
    pub fn intersect_stream(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        assert_eq!(rays.len(), hits.len());
        match self.level {
            // SAFETY: `level` is only ever set to a level the CPU supports.
            #[cfg(target_arch = "x86_64")]
            SimdLevel::Avx512 => unsafe { self.closest_stream_avx512(rays, hits) },
            #[cfg(target_arch = "x86_64")]
            SimdLevel::Avx2 => unsafe { self.closest_stream_avx2(rays, hits) },
            _ => self.closest_stream::<Portable>(rays, hits),
        }
    }

    /// Whether anything lies on each ray of `rays` before its `tmax`, into
    /// `out` (same length): what [`Accel::occluded`] answers for each.
    pub fn occluded_stream(&self, rays: &[Ray], out: &mut [bool]) {
        assert_eq!(rays.len(), out.len());
        match self.level {
            // SAFETY: as above.
            #[cfg(target_arch = "x86_64")]
            SimdLevel::Avx512 => unsafe { self.occluded_stream_avx512(rays, out) },
            #[cfg(target_arch = "x86_64")]
            SimdLevel::Avx2 => unsafe { self.occluded_stream_avx2(rays, out) },
            _ => self.occluded_stream_lanes::<Portable>(rays, out),
        }
    }

    #[inline(always)]
    fn closest_stream<V: Lanes>(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        // Instances and quantized nodes take the single-ray traversal.
        if !self.instances.is_empty() || self.nodes.is_empty() || packets_off() {
            for (ray, hit) in rays.iter().zip(hits.iter_mut()) {
                *hit = self.closest_lanes::<V>(ray);
            }
            return;
        }
        for (rays, hits) in rays.chunks(RAYS).zip(hits.chunks_mut(RAYS)) {
            if coherent(rays) {
                self.closest_packet::<V>(rays, hits);
            } else {
                for (ray, hit) in rays.iter().zip(hits.iter_mut()) {
                    *hit = self.closest_lanes::<V>(ray);
                }
            }
        }
    }

    /// Closest hits of up to 8 rays as a packet (a BVH of full nodes
    /// without instances): each child box is tested against all rays at
    /// once, each ray with its own reach (`Closest::reach`), children are
    /// visited front to back along the rays' mean direction, and leaves
    /// test the rays that reach them one by one (`leaf_closest`, the
    /// single-ray leaf test). The tie rule makes the answer independent of
    /// the visiting order, so it is the single-ray traversal's.
    #[inline(always)]
    fn closest_packet<V: Lanes>(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        let n = rays.len();
        let (mut inv, mut oinv_n, mut oinv_f) = ([[0.0f32; RAYS]; 3], [[0.0f32; RAYS]; 3], [[0.0f32; RAYS]; 3]);
        let mut reach = [-1.0f32; RAYS];
        let mut best = [Closest::new(-1.0, 0); RAYS];
        let mut dsum = Vec3A::ZERO;
        // The single-ray lanes of each ray, for the leaves.
        let mut rd: [MaybeUninit<RayData<V>>; RAYS] = [const { MaybeUninit::uninit() }; RAYS];
        for k in 0..n {
            let (i, on, of) = slab_constants(&rays[k]);
            for a in 0..3 {
                inv[a][k] = i[a];
                oinv_n[a][k] = on[a];
                oinv_f[a][k] = of[a];
            }
            best[k] = Closest::new(rays[k].tmax, 0);
            reach[k] = best[k].reach();
            dsum += Vec3A::from(rays[k].d);
            rd[k].write(RayData::<V>::new(&rays[k]));
        }
        let inv = [V::from_array(inv[0]), V::from_array(inv[1]), V::from_array(inv[2])];
        let oinv_n = [V::from_array(oinv_n[0]), V::from_array(oinv_n[1]), V::from_array(oinv_n[2])];
        let oinv_f = [V::from_array(oinv_f[0]), V::from_array(oinv_f[1]), V::from_array(oinv_f[2])];
        let mut reach_v = V::from_array(reach);
        let zero = V::splat(0.0);
        let neg = [inv[0].lt(zero), inv[1].lt(zero), inv[2].lt(zero)];
        let far = V::splat(super::FAR);
        let all = lanes_of(n);
        // Pending nodes: child word and the mask of rays entering it, and
        // those rays' entry distances (to drop the rays whose hit came
        // nearer since).
        let mut stack: [MaybeUninit<(u32, u32, V)>; STACK] = [const { MaybeUninit::uninit() }; STACK];
        let mut sp = 0usize;
        let (mut cur, mut active) = (0u32, all);
        loop {
            if cur & LEAF == 0 {
                let node = &self.nodes[cur as usize];
                let mut entered = [(0.0f32, 0u32, 0u32, zero); WIDTH];
                let mut k = 0;
                for c in 0..WIDTH {
                    // Empty slots hold an inverted box; skip the test.
                    if node.b[0][c] > node.b[3][c] {
                        continue;
                    }
                    let mut tn = [zero; 3];
                    let mut tf = [zero; 3];
                    for a in 0..3 {
                        let (lo, hi) = (V::splat(node.b[a][c]), V::splat(node.b[3 + a][c]));
                        let flip = (lo.xor(hi)) & neg[a];
                        let (near, farp) = (lo.xor(flip), hi.xor(flip));
                        tn[a] = near.mul_sub(inv[a], oinv_n[a]);
                        tf[a] = farp.mul_sub(inv[a], oinv_f[a]);
                    }
                    let tnear = tn[0].max(tn[1]).max(tn[2].max(zero));
                    let tfar = tf[0].min(tf[1]).min(tf[2].min(reach_v));
                    let enter = tnear.le(tfar * far).bitmask() & active;
                    if enter == 0 {
                        continue;
                    }
                    // Order: the box centre along the mean direction.
                    let key = (node.b[0][c] + node.b[3][c]) * dsum.x + (node.b[1][c] + node.b[4][c]) * dsum.y + (node.b[2][c] + node.b[5][c]) * dsum.z;
                    // Insertion sort, farthest first.
                    let mut j = k;
                    while j > 0 && entered[j - 1].0 < key {
                        entered[j] = entered[j - 1];
                        j -= 1;
                    }
                    entered[j] = (key, node.children[c], enter, tnear);
                    k += 1;
                }
                if k > 0 {
                    for e in &entered[..k - 1] {
                        stack[sp].write((e.1, e.2, e.3));
                        sp += 1;
                    }
                    (cur, active) = (entered[k - 1].1, entered[k - 1].2);
                    continue;
                }
            } else {
                let mut m = active;
                let mut changed = false;
                while m != 0 {
                    let k = m.trailing_zeros() as usize;
                    m &= m - 1;
                    // SAFETY: lanes of `active` are below `n`, written above.
                    let r = unsafe { rd[k].assume_init_ref() };
                    let before = best[k].t;
                    self.leaf_closest::<false, V>(cur, r, &rays[k], &mut best[k]);
                    if best[k].t != before {
                        reach[k] = best[k].reach();
                        changed = true;
                    }
                }
                if changed {
                    reach_v = V::from_array(reach);
                }
            }
            // Pop a pending node some ray still reaches.
            loop {
                if sp == 0 {
                    for (k, h) in hits.iter_mut().enumerate() {
                        *h = best[k].hit();
                    }
                    return;
                }
                sp -= 1;
                // SAFETY: entries below `sp` were written before.
                let (c, m, tnear) = unsafe { stack[sp].assume_init() };
                let m = m & tnear.le(reach_v * far).bitmask();
                if m != 0 {
                    (cur, active) = (c, m);
                    break;
                }
            }
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn closest_stream_avx2(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        self.closest_stream::<Avx>(rays, hits)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,avx512f,avx512vl,avx512dq,avx512bw")]
    fn closest_stream_avx512(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        self.closest_stream::<Avx>(rays, hits)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn occluded_stream_avx2(&self, rays: &[Ray], out: &mut [bool]) {
        self.occluded_stream_lanes::<Avx>(rays, out)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,avx512f,avx512vl,avx512dq,avx512bw")]
    fn occluded_stream_avx512(&self, rays: &[Ray], out: &mut [bool]) {
        self.occluded_stream_lanes::<Avx>(rays, out)
    }

    #[inline(always)]
    fn occluded_stream_lanes<V: Lanes>(&self, rays: &[Ray], out: &mut [bool]) {
        // Instances and quantized nodes (whose `nodes` is empty) take the
        // single-ray traversal.
        if !self.instances.is_empty() || self.nodes.is_empty() {
            for (ray, o) in rays.iter().zip(out.iter_mut()) {
                *o = self.occluded_lanes::<V>(ray);
            }
            return;
        }
        for (rays, out) in rays.chunks(RAYS).zip(out.chunks_mut(RAYS)) {
            let m = self.occluded_packet::<V>(rays);
            for (k, o) in out.iter_mut().enumerate() {
                *o = m & (1 << k) != 0;
            }
        }
    }

    /// Any-hit of up to 8 rays as a packet (a BVH without instances); the
    /// mask of the occluded ones.
    #[inline(always)]
    fn occluded_packet<V: Lanes>(&self, rays: &[Ray]) -> u32 {
        let n = rays.len();
        // Per lane, the single-ray slab constants of its ray (plain loops:
        // closures and `array::from_fn` would be compiled outside the
        // caller's target features and not inlined).
        let (mut inv, mut oinv_n, mut oinv_f) = ([[0.0f32; RAYS]; 3], [[0.0f32; RAYS]; 3], [[0.0f32; RAYS]; 3]);
        let mut tmax = [-1.0f32; RAYS];
        for k in 0..n {
            let (i, on, of) = slab_constants(&rays[k]);
            for a in 0..3 {
                inv[a][k] = i[a];
                oinv_n[a][k] = on[a];
                oinv_f[a][k] = of[a];
            }
            tmax[k] = rays[k].tmax;
        }
        let inv = [V::from_array(inv[0]), V::from_array(inv[1]), V::from_array(inv[2])];
        let oinv_n = [V::from_array(oinv_n[0]), V::from_array(oinv_n[1]), V::from_array(oinv_n[2])];
        let oinv_f = [V::from_array(oinv_f[0]), V::from_array(oinv_f[1]), V::from_array(oinv_f[2])];
        let tmax = V::from_array(tmax);
        // All-ones lanes where the ray runs towards −axis: its near plane
        // is the box's maximum there.
        let zero0 = V::splat(0.0);
        let neg = [inv[0].lt(zero0), inv[1].lt(zero0), inv[2].lt(zero0)];
        let zero = V::splat(0.0);
        let far = V::splat(super::FAR);
        let mut blocked = 0u32;
        let all = lanes_of(n);
        let mut stack = [(0u32, 0u32); STACK];
        let mut sp = 0usize;
        let (mut cur, mut active) = (0u32, all);
        loop {
            if cur & LEAF == 0 {
                let node = &self.nodes[cur as usize];
                let mut first = None;
                for c in 0..WIDTH {
                    let child = node.children[c];
                    // Empty slots hold an inverted box; skip the test.
                    if node.b[0][c] > node.b[3][c] {
                        continue;
                    }
                    let mut tn = [zero; 3];
                    let mut tf = [zero; 3];
                    for a in 0..3 {
                        let (lo, hi) = (V::splat(node.b[a][c]), V::splat(node.b[3 + a][c]));
                        let flip = (lo.xor(hi)) & neg[a];
                        let (near, farp) = (lo.xor(flip), hi.xor(flip));
                        tn[a] = near.mul_sub(inv[a], oinv_n[a]);
                        tf[a] = farp.mul_sub(inv[a], oinv_f[a]);
                    }
                    let tnear = tn[0].max(tn[1]).max(tn[2].max(zero));
                    let tfar = tf[0].min(tf[1]).min(tf[2].min(tmax));
                    let enter = tnear.le(tfar * far).bitmask() & active;
                    if enter == 0 {
                        continue;
                    }
                    match first {
                        None => first = Some((child, enter)),
                        Some(_) => {
                            stack[sp] = (child, enter);
                            sp += 1;
                        }
                    }
                }
                if let Some((child, enter)) = first {
                    cur = child;
                    active = enter;
                    continue;
                }
            } else {
                let mut m = active;
                while m != 0 {
                    let k = m.trailing_zeros() as usize;
                    m &= m - 1;
                    if blocked & (1 << k) == 0 && self.leaf_occludes::<false, V>(cur, &RayData::<V>::new(&rays[k]), &rays[k], rays[k].tmax) {
                        blocked |= 1 << k;
                    }
                }
                if blocked == all {
                    return blocked;
                }
            }
            // Pop a pending node some unoccluded ray still enters.
            loop {
                if sp == 0 {
                    return blocked;
                }
                sp -= 1;
                let (c, m) = stack[sp];
                let m = m & !blocked;
                if m != 0 {
                    (cur, active) = (c, m);
                    break;
                }
            }
        }
    }
}

/// Whether a packet of rays is worth tracing together: all run into the
/// same octant and start within a small ball (camera rays of one pixel or
/// a few neighbours; after a bounce rays rarely are).
#[inline(always)]
fn coherent(rays: &[Ray]) -> bool {
    if rays.len() < 4 {
        return false;
    }
    let sign = |r: &Ray| (r.d.x < 0.0) as u32 | ((r.d.y < 0.0) as u32) << 1 | ((r.d.z < 0.0) as u32) << 2;
    let (s0, o0) = (sign(&rays[0]), rays[0].o);
    let mut ok = true;
    for r in &rays[1..] {
        let dist = (r.o - o0).abs();
        ok &= sign(r) == s0 && dist.max_element() <= 1e-3 * (1.0 + o0.abs().max_element());
    }
    ok
}

/// `SNELL_PACKETS=0` traces every closest hit as a single ray (for
/// measurements; the hits are the same).
fn packets_off() -> bool {
    static OFF: OnceLock<bool> = OnceLock::new();
    *OFF.get_or_init(|| std::env::var("SNELL_PACKETS").is_ok_and(|v| v == "0"))
}

/// The inverse direction and the two origin offsets of the slab test, as
/// `RayData::new` computes them (the same operations, so the same bits).
#[inline(always)]
fn slab_constants(ray: &Ray) -> (Vec3A, Vec3A, Vec3A) {
    let o = Vec3A::from(ray.o);
    let d = Vec3A::from(ray.d);
    let tiny = Vec3A::splat(1e-20);
    let d_safe = Vec3A::select(d.abs().cmplt(tiny), tiny.copysign(d), d);
    let inv = Vec3A::ONE / d_safe;
    let oinv = o * inv;
    let err = oinv.abs() * super::REL;
    (inv, oinv + err, oinv - err)
}

#[cfg(test)]
mod tests {
    use super::super::tests::{shape, triangle_soup};
    use super::super::{Accel, SimdLevel};
    use crate::geometry::shape::{Shape, ShapeGeometry};
    use crate::geometry::sphere::Sphere;
    use crate::geometry::Ray;
    use crate::math::sampling::square_to_uniform_sphere;
    use crate::math::{Pcg32, Transform};
    use glam::{Vec2, Vec3};

    /// Random triangles and spheres, and random rays among them: short and
    /// infinite, axis-parallel, and bundles converging on one point (as
    /// shadow rays to a small light).
    fn scene(seed: u64) -> (Vec<Shape>, Vec<Ray>) {
        let mut rng = Pcg32::new(seed, 3);
        let mut shapes = vec![shape(ShapeGeometry::Mesh(triangle_soup(&mut rng, 1500, 0.7)))];
        let mut r3 = || Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
        for _ in 0..6 {
            let center = r3() * 4.0 - 2.0;
            shapes.push(shape(ShapeGeometry::Sphere(Sphere { center, radius: 0.2, to_object: Transform::IDENTITY, flip_normals: false })));
        }
        let mut rng = Pcg32::new(seed ^ 0x55, 9);
        let mut rays = vec![];
        let target = Vec3::new(0.1, 2.5, 0.2);
        for i in 0..3000 {
            let o = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 5.0 - 2.5;
            let ray = match i % 4 {
                0 => {
                    let v = target - o;
                    Ray { o, d: v.normalize(), tmax: v.length() * 0.999 }
                }
                1 => Ray { o, d: [Vec3::X, -Vec3::Y, Vec3::Z, -Vec3::X][i % 7 % 4], tmax: f32::INFINITY },
                _ => {
                    let d = square_to_uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32()));
                    Ray { o, d, tmax: if i % 3 == 0 { rng.next_f32() * 4.0 } else { f32::INFINITY } }
                }
            };
            rays.push(ray);
        }
        (shapes, rays)
    }

    #[test]
    fn stream_queries_agree_with_single_rays_at_every_level() {
        for seed in [1, 2, 3] {
            let (shapes, rays) = scene(seed);
            let mut accel = Accel::build(&shapes);
            for level in SimdLevel::ALL.into_iter().filter(|l| l.supported()) {
                accel.set_simd_level(level);
                let mut hits = vec![None; rays.len()];
                accel.intersect_stream(&rays, &mut hits);
                let mut blocked = vec![false; rays.len()];
                accel.occluded_stream(&rays, &mut blocked);
                let (mut n_hit, mut n_blocked) = (0, 0);
                for (i, ray) in rays.iter().enumerate() {
                    let single = accel.intersect(ray);
                    match (single, hits[i]) {
                        (None, None) => {}
                        (Some(a), Some(b)) => {
                            n_hit += 1;
                            assert_eq!((a.t.to_bits(), a.bary.0.to_bits(), a.bary.1.to_bits(), a.shape, a.prim), (b.t.to_bits(), b.bary.0.to_bits(), b.bary.1.to_bits(), b.shape, b.prim), "{level:?} ray {i}");
                        }
                        (a, b) => panic!("{level:?} ray {i}: single {a:?}, stream {b:?}"),
                    }
                    assert_eq!(accel.occluded(ray), blocked[i], "{level:?} ray {i}: occlusion");
                    n_blocked += blocked[i] as usize;
                }
                // Both answers must be exercised.
                assert!(n_hit > 500 && n_blocked > 500 && n_blocked < rays.len() - 300, "{n_hit} {n_blocked}");
            }
        }
    }

    #[test]
    fn stream_queries_of_an_empty_scene_and_odd_batch_sizes() {
        let accel = Accel::build(&[]);
        let rays = vec![Ray { o: Vec3::ZERO, d: Vec3::X, tmax: f32::INFINITY }; 3];
        let mut hits = vec![None; 3];
        accel.intersect_stream(&rays, &mut hits);
        assert!(hits.iter().all(Option::is_none));
        let mut blocked = vec![true; 3];
        accel.occluded_stream(&rays, &mut blocked);
        assert!(blocked.iter().all(|b| !b));
        let (shapes, rays) = scene(7);
        let accel = Accel::build(&shapes);
        for n in [1, 7, 9, 17] {
            let mut blocked = vec![false; n];
            accel.occluded_stream(&rays[..n], &mut blocked);
            for i in 0..n {
                assert_eq!(blocked[i], accel.occluded(&rays[i]), "batch {n} ray {i}");
            }
        }
    }
}
