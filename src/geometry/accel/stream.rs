//! Batched ("stream") queries of the BVH: closest hits and occlusion of a
//! whole queue of rays per call, for the wavefront path tracer
//! (`crate::integrator::wavefront`).
//!
//! | query | how |
//! |---|---|
//! | [`Accel::intersect_stream`] | one SIMD level dispatch per batch; each group of 8 consecutive rays that is coherent (same direction octant, origins within 10⁻³ of each other: camera rays of one pixel) is traced as a packet (`closest_packet`), the others one by one with the single-ray traversal (8 child boxes per instruction), compiled inside the batch loop; a packet's leaf of triangles that at least half as many rays reach as it holds is tested triangle by triangle over all the rays at once, other leaves ray by ray |
//! | [`Accel::occluded_stream`] | packets of 8 rays (one ray per lane): each child box of a node is tested against all 8 rays at once, each ray carries its own mask of the nodes it enters, so it visits exactly the nodes its single-ray traversal visits; leaves as in the packets of closest hits (triangle by triangle over the rays, or ray by ray) |
//!
//! Why packets give the same closest hits: the traversal's answer does not
//! depend on the order of visits. Among hits at the same t the lowest
//! (shape, primitive, instance) wins (`Closest`, in `accel.rs`), the
//! triangle test lets through every triangle whose rounded t is at most the
//! current one and then compares exactly, and boxes are entered a little
//! beyond the current t; so a packet, which visits the children along the
//! rays' mean direction and not each ray's own front-to-back order,
//! reports what the single-ray traversal reports, bit for bit (the
//! wavefront renderer promises the same image as `path`). Occlusion is a
//! yes/no answer independent of the order anyway; its slab test per lane is
//! the very expression of the single-ray test (same near/far planes, same
//! fused multiply-subtract, same conservative widening). A leaf tested
//! triangle by triangle over a packet's rays (one ray per lane, the
//! triangle splatted) runs the single-ray triangle test's own code
//! (`moller_trumbore`) with the operands in other lanes, so every ray
//! meets every triangle with the same bits.
//!
//! Measured (AVX-512, 2 threads, machine at load 7-11, whole-process CPU
//! seconds): 1 M triangles -5 % (2 runs), 4 M -2 % (3 runs), the Cornell box
//! level: no gain yet clear of the noise. Incoherent rays (after a bounce) stay
//! single rays: a packet whose rays diverge tests 8 boxes per ray where
//! the single ray tests 8 per instruction. `SNELL_PACKETS=0` turns the
//! packets off (for measurements; the hits are the same).
//!
//! Which instruction set runs is `Accel::simd_level` (`SNELL_SIMD`), as for
//! the single-ray queries. Scenes with instances or quantized nodes take
//! the single-ray traversal for both queries.

use super::stats::{self, count};
use super::{Accel, Closest, DIRECT, Hit, LEAF, Lanes, Node, RayData, STACK, TriPacket, WIDTH, lanes_of, moller_trumbore};
#[cfg(target_arch = "x86_64")]
use super::Avx;
use super::{Portable, SimdLevel};
use crate::geometry::Ray;
use glam::Vec3A;
use std::mem::MaybeUninit;
use std::sync::OnceLock;

/// Rays per occlusion packet: one per lane of the 8-wide node test.
const RAYS: usize = 8;

/// A packet's per-lane slab constants: lane k holds ray k's single-ray
/// constants, so each lane's box test is the single-ray test's expression.
/// (Plain loops: closures and `array::from_fn` would be compiled outside
/// the caller's target features and not inlined.)
struct PacketSlabs<V> {
    inv: [V; 3],
    oinv_n: [V; 3],
    oinv_f: [V; 3],
    /// All-ones lanes where the ray runs towards −axis: its near plane is
    /// the box's maximum there.
    neg: [V; 3],
}

impl<V: Lanes> PacketSlabs<V> {
    /// The constants of the packet's rays (`p`), all lanes at once, by
    /// `RayData::new`'s operations lane by lane (each exact in IEEE
    /// arithmetic: the same bits as ray by ray, which cost 8 scalar setups
    /// and their transposition).
    #[inline(always)]
    fn new(p: &PacketRays<V>) -> Self {
        let (zero, tiny, rel) = (V::splat(0.0), V::splat(1e-20), V::splat(super::REL));
        let (mut inv, mut oinv_n, mut oinv_f, mut neg) = ([zero; 3], [zero; 3], [zero; 3], [zero; 3]);
        for a in 0..3 {
            let d = p.d[a];
            let sign = d.sign();
            // |d| < tiny: tiny with d's sign, else d (as `Vec3A::select`).
            let small = d.xor(sign).lt(tiny);
            let d_safe = d.xor(tiny.xor(sign).xor(d) & small);
            inv[a] = V::splat(1.0) / d_safe;
            let oinv = p.o[a] * inv[a];
            let err = oinv.xor(oinv.sign()) * rel;
            oinv_n[a] = oinv + err;
            oinv_f[a] = oinv - err;
            neg[a] = inv[a].lt(zero);
        }
        PacketSlabs { inv, oinv_n, oinv_f, neg }
    }

    /// Every lane's entry and exit distance through child `c`'s box, the
    /// exit capped at that lane's `limit`.
    #[inline(always)]
    fn child(&self, node: &Node, c: usize, limit: V) -> (V, V) {
        let zero = V::splat(0.0);
        let mut tn = [zero; 3];
        let mut tf = [zero; 3];
        for a in 0..3 {
            let (lo, hi) = (V::splat(node.b[a][c]), V::splat(node.b[3 + a][c]));
            let flip = (lo.xor(hi)) & self.neg[a];
            let (near, farp) = (lo.xor(flip), hi.xor(flip));
            tn[a] = near.mul_sub(self.inv[a], self.oinv_n[a]);
            tf[a] = farp.mul_sub(self.inv[a], self.oinv_f[a]);
        }
        (tn[0].max(tn[1]).max(tn[2].max(zero)), tf[0].min(tf[1]).min(tf[2].min(limit)))
    }
}

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
        // Instances and quantized nodes take the single-ray traversal (a
        // call: its eight kinds of BVH are compiled once, not again here).
        if !self.instances.is_empty() || self.nodes.is_empty() || packets_off() {
            self.intersect_each(rays, hits);
            return;
        }
        // The triangle storage decided once for the batch.
        if self.keeps_packets() { self.closest_batch::<true, V>(rays, hits) } else { self.closest_batch::<false, V>(rays, hits) }
    }

    /// `closest_stream` in a BVH of full nodes without instances whose
    /// triangles are kept as lanes (`PACKED`) or gathered.
    #[inline(always)]
    fn closest_batch<const PACKED: bool, V: Lanes>(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        for (rays, hits) in rays.chunks(RAYS).zip(hits.chunks_mut(RAYS)) {
            if coherent(rays) {
                self.closest_packet::<PACKED, V>(rays, hits);
            } else {
                for (ray, hit) in rays.iter().zip(hits.iter_mut()) {
                    let mut best = Closest::new(ray.tmax, 0);
                    self.closest::<false, false, PACKED, V>(ray, &mut best);
                    *hit = best.hit();
                }
            }
        }
    }

    /// Closest hits of up to 8 rays as a packet (a BVH of full nodes
    /// without instances): each child box is tested against all rays at
    /// once, each ray with its own reach (`Closest::reach`), children are
    /// visited front to back along the rays' mean direction, and leaves
    /// test their triangles over all the rays that reach them
    /// (`direct_leaf_closest_rays`) or those rays one by one
    /// (`leaf_closest`, the single-ray leaf test). The tie rule makes the
    /// answer independent of the visiting order, so it is the single-ray
    /// traversal's.
    #[inline(always)]
    fn closest_packet<const PACKED: bool, V: Lanes>(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        let n = rays.len();
        let lanes = PacketRays::<V>::new(rays);
        let slabs = PacketSlabs::new(&lanes);
        let mut reach = [-1.0f32; RAYS];
        let mut best = [Closest::new(-1.0, 0); RAYS];
        let mut dsum = Vec3A::ZERO;
        // The single-ray lanes of each ray, for the leaves.
        // made when a leaf or a split first needs them (the mask `made`).
        let mut rd: [MaybeUninit<RayData<V>>; RAYS] = [const { MaybeUninit::uninit() }; RAYS];
        let mut made = 0u32;
        for k in 0..n {
            best[k] = Closest::new(rays[k].tmax, 0);
            reach[k] = best[k].reach();
            dsum += Vec3A::from(rays[k].d);
        }
        let mut reach_v = V::from_array(reach);
        let zero = V::splat(0.0);
        let far = V::splat(super::FAR);
        let all = lanes_of(n);
        let min_rays = self.packet_min();
        count!(stats::CLOSEST_PACKET, stats::RAYS, n);
        // Pending nodes: child word and the mask of rays entering it, and
        // those rays' entry distances (to drop the rays whose hit came
        // nearer since).
        let mut stack: [MaybeUninit<(u32, u32, V)>; STACK] = [const { MaybeUninit::uninit() }; STACK];
        let mut sp = 0usize;
        let (mut cur, mut active) = (0u32, all);
        loop {
            if cur & (LEAF | DIRECT) == LEAF | DIRECT && splat_leaf(active, cur) {
                // Triangles alone, reached by at least half as many rays
                // as it holds: each triangle against all rays at once.
                if self.direct_leaf_closest_rays::<PACKED, V>(cur, &lanes, &mut best, active) {
                    for k in 0..n {
                        reach[k] = best[k].reach();
                    }
                    reach_v = V::from_array(reach);
                }
            } else if cur & LEAF == 0 && active.count_ones() < min_rays {
                // Too few rays left for the packet to pay: each goes on
                // alone below this node.
                let mut m = active;
                let mut changed = false;
                count!(stats::CLOSEST_PACKET, stats::SPLIT_OFF, active.count_ones());
                while m != 0 {
                    let k = m.trailing_zeros() as usize;
                    m &= m - 1;
                    if made & (1 << k) == 0 {
                        rd[k].write(RayData::<V>::new(&rays[k]));
                        made |= 1 << k;
                    }
                    // SAFETY: written just above or before (`made`).
                    let r = unsafe { rd[k].assume_init_ref() };
                    let before = best[k].t;
                    self.closest_from::<false, false, PACKED, V>(r, &rays[k], &mut best[k], cur, stats::CLOSEST_PACKET);
                    if best[k].t != before {
                        reach[k] = best[k].reach();
                        changed = true;
                    }
                }
                if changed {
                    reach_v = V::from_array(reach);
                }
            } else if cur & LEAF == 0 {
                let node = &self.nodes[cur as usize];
                count!(stats::CLOSEST_PACKET, stats::NODES, active.count_ones());
                let mut entered = [(0.0f32, 0u32, 0u32, zero); WIDTH];
                let mut k = 0;
                for c in 0..WIDTH {
                    // Empty slots hold an inverted box; skip the test.
                    if node.b[0][c] > node.b[3][c] {
                        continue;
                    }
                    count!(stats::CLOSEST_PACKET, stats::BOXES, RAYS);
                    let (tnear, tfar) = slabs.child(node, c, reach_v);
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
                        self.prefetch(e.1);
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
                    if made & (1 << k) == 0 {
                        rd[k].write(RayData::<V>::new(&rays[k]));
                        made |= 1 << k;
                    }
                    // SAFETY: written just above or before (`made`).
                    let r = unsafe { rd[k].assume_init_ref() };
                    let before = best[k].t;
                    self.leaf_closest::<false, PACKED, V>(cur, r, &rays[k], &mut best[k], stats::CLOSEST_PACKET);
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
            self.occluded_each(rays, out);
            return;
        }
        if self.keeps_packets() { self.occluded_batch::<true, V>(rays, out) } else { self.occluded_batch::<false, V>(rays, out) }
    }

    /// `occluded_stream` in a BVH of full nodes without instances whose
    /// triangles are kept as lanes (`PACKED`) or gathered.
    #[inline(always)]
    fn occluded_batch<const PACKED: bool, V: Lanes>(&self, rays: &[Ray], out: &mut [bool]) {
        for (rays, out) in rays.chunks(RAYS).zip(out.chunks_mut(RAYS)) {
            let m = self.occluded_packet::<PACKED, V>(rays);
            for (k, o) in out.iter_mut().enumerate() {
                *o = m & (1 << k) != 0;
            }
        }
    }

    /// Any-hit of up to 8 rays as a packet (a BVH without instances); the
    /// mask of the occluded ones.
    #[inline(always)]
    fn occluded_packet<const PACKED: bool, V: Lanes>(&self, rays: &[Ray]) -> u32 {
        let n = rays.len();
        let lanes = PacketRays::<V>::new(rays);
        let slabs = PacketSlabs::new(&lanes);
        let mut tmax = [-1.0f32; RAYS];
        for k in 0..n {
            tmax[k] = rays[k].tmax;
        }
        let tmax = V::from_array(tmax);
        let far = V::splat(super::FAR);
        let mut blocked = 0u32;
        let all = lanes_of(n);
        let min_rays = self.packet_min();
        count!(stats::OCCLUDED_PACKET, stats::RAYS, n);
        // The single-ray lanes of each ray, made when a leaf or a split
        // first needs them (the mask `made`).
        let mut rd: [MaybeUninit<RayData<V>>; RAYS] = [const { MaybeUninit::uninit() }; RAYS];
        let mut made = 0u32;
        // Pending nodes and the rays entering each; uninitialised (zeroing
        // its 2 KB cost a `memset` a packet).
        let mut stack: [MaybeUninit<(u32, u32)>; STACK] = [const { MaybeUninit::uninit() }; STACK];
        let mut sp = 0usize;
        let (mut cur, mut active) = (0u32, all);
        loop {
            if cur & (LEAF | DIRECT) == LEAF | DIRECT && splat_leaf(active, cur) {
                // Triangles alone, reached by at least half as many rays
                // as it holds: each triangle against all rays at once.
                blocked |= self.direct_leaf_occludes_rays::<PACKED, V>(cur, &lanes, tmax, active);
                if blocked == all {
                    return blocked;
                }
            } else if cur & LEAF != 0 || active.count_ones() < min_rays {
                // A leaf, or too few rays left for the packet to pay: each
                // ray goes on alone.
                if cur & LEAF == 0 {
                    count!(stats::OCCLUDED_PACKET, stats::SPLIT_OFF, active.count_ones());
                }
                let mut m = active;
                while m != 0 {
                    let k = m.trailing_zeros() as usize;
                    m &= m - 1;
                    if made & (1 << k) == 0 {
                        rd[k].write(RayData::<V>::new(&rays[k]));
                        made |= 1 << k;
                    }
                    // SAFETY: written just above or before (`made`).
                    let r = unsafe { rd[k].assume_init_ref() };
                    let hit = if cur & LEAF != 0 {
                        self.leaf_occludes::<false, PACKED, V>(cur, r, &rays[k], rays[k].tmax, stats::OCCLUDED_PACKET)
                    } else {
                        self.any_hit_from::<false, false, PACKED, V>(r, &rays[k], cur, stats::OCCLUDED_PACKET)
                    };
                    if hit {
                        blocked |= 1 << k;
                    }
                }
                if blocked == all {
                    return blocked;
                }
            } else {
                let node = &self.nodes[cur as usize];
                count!(stats::OCCLUDED_PACKET, stats::NODES, active.count_ones());
                let mut first = None;
                for c in 0..WIDTH {
                    let child = node.children[c];
                    // Empty slots hold an inverted box; skip the test.
                    if node.b[0][c] > node.b[3][c] {
                        continue;
                    }
                    count!(stats::OCCLUDED_PACKET, stats::BOXES, RAYS);
                    let (tnear, tfar) = slabs.child(node, c, tmax);
                    let enter = tnear.le(tfar * far).bitmask() & active;
                    if enter == 0 {
                        continue;
                    }
                    match first {
                        None => first = Some((child, enter)),
                        Some(_) => {
                            self.prefetch(child);
                            stack[sp].write((child, enter));
                            sp += 1;
                        }
                    }
                }
                if let Some((child, enter)) = first {
                    cur = child;
                    active = enter;
                    continue;
                }
            }
            // Pop a pending node some unoccluded ray still enters.
            loop {
                if sp == 0 {
                    return blocked;
                }
                sp -= 1;
                // SAFETY: entries below `sp` were written before.
                let (c, m) = unsafe { stack[sp].assume_init() };
                let m = m & !blocked;
                if m != 0 {
                    (cur, active) = (c, m);
                    break;
                }
            }
        }
    }
}

impl Accel {
    /// The rays of `active` (lanes of `rays`, each up to its lane of
    /// `tmax`) that something in `DIRECT` leaf `cur` occludes: its
    /// triangles one at a time, each over all the rays (one per lane), by
    /// the single-ray test's own expression (`moller_trumbore`), so each
    /// ray gets the answer `leaf_occludes` gives it. A leaf of n triangles
    /// costs n tests this way, k tests ray by ray (and k rays' lanes made):
    /// `splat_leaf` chooses.
    #[inline(always)]
    fn direct_leaf_occludes_rays<const PACKED: bool, V: Lanes>(&self, cur: u32, rays: &PacketRays<V>, tmax: V, active: u32) -> u32 {
        let (p, n) = self.direct_packet::<PACKED, V>(cur);
        count!(stats::OCCLUDED_PACKET, stats::LEAVES, active.count_ones());
        count!(stats::OCCLUDED_PACKET, stats::TRIS, n as u32 * active.count_ones());
        let f = lanes_by_triangle(&p);
        let mut hit = 0u32;
        for i in 0..n {
            let tri = triangle_over_lanes::<V>(&f, i);
            hit |= moller_trumbore::<false, V>(&rays.o, &rays.d, &tri, tmax).1 & active;
            if hit == active {
                break;
            }
        }
        hit
    }
}

impl Accel {
    /// The closest hits of the rays of `active` (lanes of `rays`) in
    /// `DIRECT` leaf `cur`, into their `best`; whether any changed. Its
    /// triangles one at a time, each over all the rays, by the single-ray
    /// test's expressions (`moller_trumbore`, the same division), each hit
    /// taken under the tie rule (`Closest::accepts`): what `leaf_closest`
    /// finds for each ray. (A lane's mask is made with its nearest hit so
    /// far, which may have come nearer since the leaf began; a triangle it
    /// then drops is rounded beyond that hit, so it could not win.)
    #[inline(always)]
    fn direct_leaf_closest_rays<const PACKED: bool, V: Lanes>(&self, cur: u32, rays: &PacketRays<V>, best: &mut [Closest; RAYS], active: u32) -> bool {
        let (p, n) = self.direct_packet::<PACKED, V>(cur);
        count!(stats::CLOSEST_PACKET, stats::LEAVES, active.count_ones());
        count!(stats::CLOSEST_PACKET, stats::TRIS, n as u32 * active.count_ones());
        let f = lanes_by_triangle(&p);
        let mut tmax = [0.0f32; RAYS];
        for k in 0..RAYS {
            tmax[k] = best[k].t;
        }
        let mut tmax_v = V::from_array(tmax);
        let mut changed = false;
        for i in 0..n {
            let tri = triangle_over_lanes::<V>(&f, i);
            let ([t, u, v, adet], mask) = moller_trumbore::<true, V>(&rays.o, &rays.d, &tri, tmax_v);
            let mut mask = mask & active;
            if mask == 0 {
                continue;
            }
            let inv = V::splat(1.0) / adet;
            let (t, u, v) = ((t * inv).to_array(), (u * inv).to_array(), (v * inv).to_array());
            let key = self.direct_key::<PACKED>(cur, i);
            let mut took = false;
            while mask != 0 {
                let k = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                if best[k].accepts(t[k], key) {
                    best[k].set(t[k], key, u[k], v[k]);
                    tmax[k] = t[k];
                    took = true;
                }
            }
            if took {
                tmax_v = V::from_array(tmax);
                changed = true;
            }
        }
        changed
    }
}

/// The twelve rows of a packet of triangles (v0, −e1, e2, the normal; x,
/// y, z each), lane by lane.
#[inline(always)]
fn lanes_by_triangle<V: Lanes>(p: &TriPacket<V>) -> [[f32; RAYS]; 12] {
    // (Loops, not closures: see `PacketSlabs`.)
    let rows = [p.v0[0], p.v0[1], p.v0[2], p.e1n[0], p.e1n[1], p.e1n[2], p.e2[0], p.e2[1], p.e2[2], p.ng[0], p.ng[1], p.ng[2]];
    let mut f = [[0.0f32; RAYS]; 12];
    for j in 0..12 {
        f[j] = rows[j].to_array();
    }
    f
}

/// Triangle `i` of `lanes_by_triangle`'s rows, in every lane.
#[inline(always)]
fn triangle_over_lanes<V: Lanes>(f: &[[f32; RAYS]; 12], i: usize) -> TriPacket<V> {
    TriPacket {
        v0: [V::splat(f[0][i]), V::splat(f[1][i]), V::splat(f[2][i])],
        e1n: [V::splat(f[3][i]), V::splat(f[4][i]), V::splat(f[5][i])],
        e2: [V::splat(f[6][i]), V::splat(f[7][i]), V::splat(f[8][i])],
        ng: [V::splat(f[9][i]), V::splat(f[10][i]), V::splat(f[11][i])],
    }
}

/// Whether the rays `active` of a packet test `DIRECT` leaf `cur` triangle
/// by triangle over all of them (else ray by ray): when 8 · rays ≥ q ·
/// triangles. q = 4 (at least half as many rays as triangles) measured
/// best of 0, 2, 4, 6 and never (callgrind, Cornell box and the 2 k
/// mesh, for both queries). `SNELL_LEAF_SPLAT=q` sets it (0: always, 65:
/// never; for measurements, the hits are the same).
#[inline(always)]
fn splat_leaf(active: u32, cur: u32) -> bool {
    static Q: OnceLock<u32> = OnceLock::new();
    let q = *Q.get_or_init(|| std::env::var("SNELL_LEAF_SPLAT").ok().and_then(|v| v.trim().parse().ok()).unwrap_or(4));
    8 * active.count_ones() >= q.saturating_mul(direct_count(cur) as u32)
}

/// The triangle count of a `DIRECT` leaf's child word.
#[inline(always)]
fn direct_count(cur: u32) -> usize {
    (cur & 7) as usize + 1
}

/// A packet's origins and directions, ray k in lane k (unused lanes zero:
/// no triangle meets a zero direction).
struct PacketRays<V> {
    o: [V; 3],
    d: [V; 3],
}

impl<V: Lanes> PacketRays<V> {
    #[inline(always)]
    fn new(rays: &[Ray]) -> Self {
        let (mut o, mut d) = ([[0.0f32; RAYS]; 3], [[0.0f32; RAYS]; 3]);
        for k in 0..rays.len() {
            for a in 0..3 {
                o[a][k] = rays[k].o[a];
                d[a][k] = rays[k].d[a];
            }
        }
        PacketRays { o: [V::from_array(o[0]), V::from_array(o[1]), V::from_array(o[2])], d: [V::from_array(d[0]), V::from_array(d[1]), V::from_array(d[2])] }
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

impl Accel {
    /// A packet that reaches a node with fewer rays than this still entering
    /// it hands them to the single-ray traversal below it: a packet tests
    /// each child box against all 8 lanes, a single ray all 8 boxes at once,
    /// so in a big BVH a packet only pays while most of its rays go the same
    /// way. In a BVH that fits in cache (the one that does not prefetch)
    /// whole packets cost less than the hand-over (Cornell box: +4 % CPU at
    /// 256², +8 % at 512² with the split), so there it is 0.
    /// `SNELL_PACKET_MIN` sets it for every BVH (0 keeps every packet whole,
    /// 9 traces every ray alone; for measurements, the hits are the same).
    fn packet_min(&self) -> u32 {
        static MIN: OnceLock<Option<u32>> = OnceLock::new();
        let set = *MIN.get_or_init(|| std::env::var("SNELL_PACKET_MIN").ok().and_then(|v| v.trim().parse().ok()));
        set.unwrap_or(if self.prefetches { DEFAULT_PACKET_MIN } else { 0 })
    }
}

const DEFAULT_PACKET_MIN: u32 = 4;

/// `SNELL_PACKETS=0` traces every closest hit as a single ray (for
/// measurements; the hits are the same).
fn packets_off() -> bool {
    static OFF: OnceLock<bool> = OnceLock::new();
    *OFF.get_or_init(|| std::env::var("SNELL_PACKETS").is_ok_and(|v| v == "0"))
}

#[cfg(test)]
mod tests {
    use super::super::tests::{prim_t, shape, triangle_soup};
    use super::super::{Accel, Closest, DIRECT, Hit, LEAF, NO_INSTANCE, RayData, SimdLevel};
    use super::super::simd::{Lanes, Portable};
    #[cfg(target_arch = "x86_64")]
    use super::super::simd::Avx;
    use super::super::stats;
    use super::{PacketRays, RAYS, lanes_by_triangle};
    use crate::geometry::mesh::Mesh;
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

    /// A grid of 2·n² triangles at height z over [−1, 1]² (n a power of
    /// two, so every coordinate is dyadic), each square cut along one of its
    /// diagonals (alternating), listed in order or reversed.
    fn grid(n: u32, z: f32, reverse: bool) -> Mesh {
        let s = 2.0 / n as f32;
        let mut positions = vec![];
        for j in 0..=n {
            for i in 0..=n {
                positions.push(Vec3::new(-1.0 + s * i as f32, -1.0 + s * j as f32, z));
            }
        }
        let v = |i: u32, j: u32| j * (n + 1) + i;
        let mut triangles = vec![];
        for j in 0..n {
            for i in 0..n {
                let (a, b, c, d) = (v(i, j), v(i + 1, j), v(i + 1, j + 1), v(i, j + 1));
                if (i + j) % 2 == 0 {
                    triangles.extend([[a, b, c], [a, c, d]]);
                } else {
                    triangles.extend([[a, b, d], [b, c, d]]);
                }
            }
        }
        if reverse {
            triangles.reverse();
        }
        Mesh::new(positions, None, None, triangles, false)
    }

    /// Rays onto points of `grid(8, 0, _)`'s edges, vertices and diagonals
    /// (dyadic, so the tests are exact and every triangle through the point
    /// reports the same t): straight down from above each point, and in
    /// bundles of 8 from common origins (coherent packets), slanted.
    fn edge_rays() -> Vec<Ray> {
        let mut points = vec![];
        for j in 0..=32 {
            for i in 0..=32 {
                let (x, y) = (-1.0 + 0.0625 * i as f32, -1.0 + 0.0625 * j as f32);
                // On a grid line, or on a square's diagonal.
                let on_line = i % 4 == 0 || j % 4 == 0;
                let (u, v) = (i % 4, j % 4);
                let cell_even = ((i / 4) + (j / 4)) % 2 == 0;
                let on_diag = if cell_even { u == v } else { u + v == 4 };
                if (on_line || on_diag) && i < 32 && j < 32 {
                    points.push(Vec3::new(x, y, 0.0));
                }
            }
        }
        let mut rays: Vec<Ray> = points.iter().map(|&p| Ray { o: p + Vec3::Z, d: -Vec3::Z, tmax: f32::INFINITY }).collect();
        let origins = [Vec3::new(0.0625, -0.3125, 2.0), Vec3::new(-1.5, 0.5, 1.25), Vec3::new(0.75, 1.5, 0.5)];
        for (k, chunk) in points.chunks(8).enumerate() {
            let o = origins[k % 3];
            rays.extend(chunk.iter().map(|&p| Ray { o, d: p - o, tmax: f32::INFINITY }));
        }
        rays
    }

    /// The tie rule: on shared edges and vertices, and against exact
    /// duplicates (shape 1 is shape 0 again, shape 2 the same triangles in
    /// reverse order), the hit is the lowest (shape, primitive): shape 0 and
    /// the lowest triangle through the point, for the single-ray and the
    /// stream (packet) traversal alike, at every level, with full,
    /// quantized and gathered nodes and leaves.
    #[test]
    fn ties_go_to_the_lowest_shape_and_primitive_whatever_the_order() {
        let shapes = vec![shape(ShapeGeometry::Mesh(grid(8, 0.0, false))), shape(ShapeGeometry::Mesh(grid(8, 0.0, false))), shape(ShapeGeometry::Mesh(grid(8, 0.0, true)))];
        let rays = edge_rays();
        // The triangles of shape 0 through each ray's point (scalar test).
        let expected: Vec<u32> = rays.iter().map(|ray| (0..128).find(|&p| prim_t(&shapes, 0, p, ray).is_finite()).expect("every ray meets the grid")).collect();
        let ties = rays.iter().filter(|ray| (0..128).filter(|&p| prim_t(&shapes, 0, p, ray).is_finite()).count() > 1).count();
        assert!(ties > 300, "{ties} rays on shared edges");
        for variant in 0..3 {
            let mut accel = Accel::build(&shapes);
            match variant {
                1 => accel.quantize_nodes(),
                2 => accel.gather_triangles(),
                _ => {}
            }
            for level in SimdLevel::ALL.into_iter().filter(|l| l.supported()) {
                accel.set_simd_level(level);
                let mut hits = vec![None; rays.len()];
                accel.intersect_stream(&rays, &mut hits);
                for (i, ray) in rays.iter().enumerate() {
                    let single = accel.intersect(ray).expect("hit");
                    let stream = hits[i].expect("hit");
                    assert_eq!((single.shape, single.prim, single.instance), (0, expected[i], NO_INSTANCE), "variant {variant} {level:?} ray {i} single");
                    assert_eq!((stream.shape, stream.prim, stream.t.to_bits()), (single.shape, single.prim, single.t.to_bits()), "variant {variant} {level:?} ray {i} stream");
                }
            }
        }
        // Instances: the group is the grid twice, placed three times (the
        // first two identical): instance 0, shape 0, lowest triangle.
        let identity = Transform::IDENTITY;
        let shifted = Transform::from_matrix(glam::Mat4::from_translation(Vec3::new(0.0, 0.0, -0.5))).expect("invertible");
        let accel = Accel::build_instanced(&shapes, &[], &[vec![0, 1]], &[(identity.clone(), 0), (identity, 0), (shifted, 0)]);
        let mut hits = vec![None; rays.len()];
        accel.intersect_stream(&rays, &mut hits);
        for (i, ray) in rays.iter().enumerate() {
            let h = accel.intersect(ray).expect("hit");
            assert_eq!((h.shape, h.prim, h.instance), (0, expected[i], 0), "instanced ray {i}");
            let s = hits[i].expect("hit");
            assert_eq!((s.shape, s.prim, s.instance, s.t.to_bits()), (0, expected[i], 0, h.t.to_bits()), "instanced ray {i} stream");
        }
    }

    /// Leaves of triangles tested triangle by triangle over a packet's rays
    /// give each ray, bit for bit, what the single-ray leaf tests give it:
    /// every `DIRECT` leaf (stored lanes, and gathered from a mesh in leaf
    /// order), 8 rays aimed at its triangles (inside, and on their edges
    /// and corners) from scattered origins, some cut short, starting from a
    /// nearest hit already found at their tmax, with every lane and with
    /// some lanes inactive; at every level.
    #[test]
    fn leaves_tested_over_rays_agree_with_rays_one_by_one() {
        fn check<const PACKED: bool, V: Lanes>(accel: &Accel, rng: &mut Pcg32) -> (usize, usize) {
            assert_eq!(PACKED, accel.keeps_packets());
            let (mut hits, mut blocked) = (0, 0);
            let leaves: Vec<u32> = accel.nodes.iter().flat_map(|n| n.children).filter(|c| c & (LEAF | DIRECT) == LEAF | DIRECT).collect();
            assert!(leaves.len() > 50, "{} direct leaves", leaves.len());
            for &cur in &leaves {
                let (p, n) = accel.direct_packet::<PACKED, Portable>(cur);
                let f = lanes_by_triangle(&p);
                let mut rays = vec![];
                for k in 0..RAYS {
                    let i = k % n;
                    let v0 = Vec3::new(f[0][i], f[1][i], f[2][i]);
                    let (e1, e2) = (-Vec3::new(f[3][i], f[4][i], f[5][i]), Vec3::new(f[6][i], f[7][i], f[8][i]));
                    let (a, b) = match k % 4 {
                        0 => (0.0, 0.0),
                        1 => (0.5, 0.0),
                        2 => (0.5, 0.5),
                        _ => (rng.next_f32() * 0.5, rng.next_f32() * 0.5),
                    };
                    let target = v0 + e1 * a + e2 * b;
                    let o = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 6.0 - 3.0;
                    let d = (target - o).normalize();
                    let tmax = match k % 3 {
                        0 => f32::INFINITY,
                        1 => (target - o).length() * (0.5 + rng.next_f32()),
                        _ => (target - o).length(),
                    };
                    rays.push(Ray { o, d, tmax });
                }
                let lanes = PacketRays::<V>::new(&rays);
                for active in [0xff, rng.next_u32() & 0xff | 1] {
                    let mut best = [Closest::new(-1.0, 0); RAYS];
                    for k in 0..RAYS {
                        best[k] = Closest::new(rays[k].tmax, 0);
                    }
                    let mut one_by_one = best;
                    accel.direct_leaf_closest_rays::<PACKED, V>(cur, &lanes, &mut best, active);
                    let tmax = V::from_array(std::array::from_fn(|k| rays[k].tmax));
                    let occluded = accel.direct_leaf_occludes_rays::<PACKED, V>(cur, &lanes, tmax, active);
                    for k in 0..RAYS {
                        let r = RayData::<V>::new(&rays[k]);
                        if active & (1 << k) == 0 {
                            assert!(!best[k].found && occluded & (1 << k) == 0);
                            continue;
                        }
                        accel.leaf_closest::<false, PACKED, V>(cur, &r, &rays[k], &mut one_by_one[k], stats::CLOSEST_PACKET);
                        let key = |c: &Closest| (c.found, c.t.to_bits(), c.key, c.b1.to_bits(), c.b2.to_bits());
                        assert_eq!(key(&best[k]), key(&one_by_one[k]), "leaf {cur:#x} ray {k}");
                        let single = accel.leaf_occludes::<false, PACKED, V>(cur, &r, &rays[k], rays[k].tmax, stats::OCCLUDED_PACKET);
                        assert_eq!(occluded & (1 << k) != 0, single, "leaf {cur:#x} ray {k}: occlusion");
                        hits += best[k].found as usize;
                        blocked += single as usize;
                    }
                }
            }
            (hits, blocked)
        }
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx2,fma")]
        fn check_avx<const PACKED: bool>(accel: &Accel, rng: &mut Pcg32) -> (usize, usize) {
            check::<PACKED, Avx>(accel, rng)
        }
        let mut rng = Pcg32::new(21, 4);
        let mut shapes = vec![shape(ShapeGeometry::Mesh(triangle_soup(&mut rng, 1500, 0.7)))];
        let stored = Accel::build(&shapes);
        let mut ordered = Accel::build(&shapes);
        ordered.gather_triangles();
        ordered.leaf_order(&mut shapes, true);
        for accel in [&stored, &ordered] {
            let packed = accel.keeps_packets();
            let (hits, blocked) = if packed { check::<true, Portable>(accel, &mut rng) } else { check::<false, Portable>(accel, &mut rng) };
            assert!(hits > 1000 && blocked > 1000, "{hits} hits, {blocked} blocked");
            #[cfg(target_arch = "x86_64")]
            if SimdLevel::Avx2.supported() {
                // SAFETY: the CPU has AVX2 and FMA.
                let (hits, blocked) = unsafe { if packed { check_avx::<true>(accel, &mut rng) } else { check_avx::<false>(accel, &mut rng) } };
                assert!(hits > 1000 && blocked > 1000, "{hits} hits, {blocked} blocked");
            }
        }
    }

    /// Coherent bundles (8 rays from one origin into a narrow cone, as
    /// camera rays of one pixel) through the random scenes: the packet
    /// traversal returns the single-ray hits bit for bit, at every level,
    /// with stored and gathered triangles, and for bundles cut short.
    #[test]
    fn coherent_packets_agree_with_single_rays() {
        for seed in [4, 5] {
            let (shapes, _) = scene(seed);
            let mut rng = Pcg32::new(seed, 17);
            let mut rays = vec![];
            for b in 0..400 {
                let o = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 5.0 - 2.5;
                let axis = square_to_uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32()));
                let spread = [0.002, 0.02, 0.1][b % 3];
                for _ in 0..8 {
                    let j = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5;
                    let d = (axis + j * spread).normalize();
                    rays.push(Ray { o, d, tmax: if b % 5 == 0 { rng.next_f32() * 3.0 } else { f32::INFINITY } });
                }
            }
            for gathered in [false, true] {
                let mut accel = Accel::build(&shapes);
                if gathered {
                    accel.gather_triangles();
                }
                for level in SimdLevel::ALL.into_iter().filter(|l| l.supported()) {
                    accel.set_simd_level(level);
                    for len in [rays.len(), rays.len() - 3] {
                        let mut hits = vec![None; len];
                        accel.intersect_stream(&rays[..len], &mut hits);
                        let mut n_hit = 0;
                        for (i, ray) in rays[..len].iter().enumerate() {
                            let key = |h: Option<Hit>| h.map(|h| (h.t.to_bits(), h.bary.0.to_bits(), h.bary.1.to_bits(), h.shape, h.prim));
                            assert_eq!(key(hits[i]), key(accel.intersect(ray)), "seed {seed} gathered {gathered} {level:?} ray {i}");
                            n_hit += hits[i].is_some() as usize;
                        }
                        assert!(n_hit > 1000 && n_hit < len - 300, "{n_hit}");
                    }
                }
            }
        }
    }
}
