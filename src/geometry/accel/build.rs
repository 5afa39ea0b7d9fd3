//! Binary BVH construction by the surface area heuristic: an exact sweep
//! over sorted centroids for small nodes, binning for large ones; the two
//! halves of large nodes are built in parallel (rayon). The result is
//! collapsed into the 8-wide BVH that traversal uses (see `accel.rs`).
//!
//! Memory: a primitive is a 28-byte `Item` (its box and an id) while the
//! tree is built, and a node 32 bytes; the items are dropped before the
//! wide BVH is made.

use glam::Vec3A;

/// Relative cost of one BVH2 node visit, against one leaf "unit" (a packet
/// of up to `PACKET` triangles, or one other primitive).
const COST_TRAVERSE: f32 = 1.0;
const COST_UNIT: f32 = 1.0;
/// Nodes at most this size use the exact SAH sweep (three sorts per node:
/// worth it only near the leaves).
const SWEEP_MAX: usize = 24;
const BINS: usize = 32;
/// Past this depth, nodes split at the object median: depth stays bounded
/// (and with it the traversal stack) whatever the input.
const MAX_SAH_DEPTH: u32 = 48;
/// Nodes with more items than this, above `PAR_DEPTH`, build their two
/// halves on two threads.
const PAR_MIN: usize = 8192;
const PAR_DEPTH: u32 = 6;
#[cfg(test)]
pub const PAR_MIN_FOR_TESTS: usize = PAR_MIN;

#[derive(Clone, Copy, Debug)]
pub struct Aabb {
    pub lo: Vec3A,
    pub hi: Vec3A,
}

impl Aabb {
    pub const EMPTY: Aabb = Aabb { lo: Vec3A::splat(f32::INFINITY), hi: Vec3A::splat(f32::NEG_INFINITY) };

    #[inline]
    pub fn union(self, o: Aabb) -> Aabb {
        Aabb { lo: self.lo.min(o.lo), hi: self.hi.max(o.hi) }
    }

    #[inline]
    pub fn grow(self, p: Vec3A) -> Aabb {
        Aabb { lo: self.lo.min(p), hi: self.hi.max(p) }
    }

    /// Half the surface area (the SAH only needs ratios); zero when empty.
    #[inline]
    pub fn half_area(self) -> f32 {
        let d = (self.hi - self.lo).max(Vec3A::ZERO);
        d.x * d.y + d.y * d.z + d.z * d.x
    }

    #[inline]
    pub fn centroid(self) -> Vec3A {
        (self.lo + self.hi) * 0.5
    }
}

/// A node of the binary BVH: its box, and either two children (`count`
/// is `INNER`, `a` and `b` their indices) or a leaf (`count` items of
/// `order` from `a`).
#[derive(Clone, Copy, Debug)]
pub struct Node2 {
    lo: [f32; 3],
    hi: [f32; 3],
    pub a: u32,
    pub b: u32,
    pub count: u32,
}

pub const INNER: u32 = u32::MAX;

impl Node2 {
    pub fn bounds(&self) -> Aabb {
        Aabb { lo: self.lo.into(), hi: self.hi.into() }
    }

    pub fn is_inner(&self) -> bool {
        self.count == INNER
    }

    fn new(b: Aabb, a: u32, bb: u32, count: u32) -> Node2 {
        Node2 { lo: b.lo.into(), hi: b.hi.into(), a, b: bb, count }
    }
}

pub struct Bvh2 {
    /// Root first.
    pub nodes: Vec<Node2>,
    /// Primitive ids in leaf order; leaves index ranges of this.
    pub order: Vec<u32>,
}

/// A primitive to build over: its box and id. Ids with the `OTHER` bit
/// are non-triangles (one leaf unit each); the others are triangles
/// (packed `PACKET` to a unit).
#[derive(Clone, Copy, Debug)]
pub struct Item {
    lo: [f32; 3],
    hi: [f32; 3],
    pub id: u32,
}

pub const OTHER: u32 = 1 << 31;

impl Item {
    pub fn new(b: Aabb, id: u32) -> Item {
        Item { lo: b.lo.into(), hi: b.hi.into(), id }
    }

    #[inline(always)]
    fn bounds(&self) -> Aabb {
        Aabb { lo: self.lo.into(), hi: self.hi.into() }
    }

    #[inline(always)]
    fn centroid(&self) -> Vec3A {
        self.bounds().centroid()
    }

    #[inline(always)]
    fn tri(&self) -> bool {
        self.id & OTHER == 0
    }
}

/// Triangles per SIMD test.
pub const PACKET: usize = 8;

/// Leaf cost of `tris` triangles (tested `PACKET` at a time) and `others` other primitives.
#[inline]
fn units(tris: usize, others: usize) -> f32 {
    (tris.div_ceil(PACKET) + others) as f32
}

/// A BVH over `items`; leaves hold at most `max_leaf` primitives.
pub fn build(mut items: Vec<Item>, max_leaf: usize) -> Bvh2 {
    // At most 2n − 1 nodes: reserved (untouched pages cost no memory) so
    // that the vector never doubles and copies itself.
    let mut nodes = Vec::with_capacity((2 * items.len()).saturating_sub(1));
    if !items.is_empty() {
        let root = Summary::of(&items);
        build_rec(&mut items, root, 0, 0, max_leaf.max(1), &mut nodes);
    }
    nodes.shrink_to_fit();
    let order = items.iter().map(|it| it.id).collect();
    drop(items);
    Bvh2 { nodes, order }
}

struct Split {
    cost: f32,
    /// Items (in the partitioned order) that go left.
    left: usize,
    /// The two sides' summaries when the split gathered them (the binned
    /// split does, in its partition pass: no extra pass over the items).
    sides: Option<[Summary; 2]>,
}

/// What a node needs of its items: their bounds, the bounds of their
/// centroids and how many are triangles.
#[derive(Clone, Copy)]
struct Summary {
    bounds: Aabb,
    cbounds: Aabb,
    tris: usize,
}

impl Summary {
    const EMPTY: Summary = Summary { bounds: Aabb::EMPTY, cbounds: Aabb::EMPTY, tris: 0 };

    #[inline(always)]
    fn add(&mut self, it: &Item) {
        let ib = it.bounds();
        self.bounds = self.bounds.union(ib);
        self.cbounds = self.cbounds.grow(ib.centroid());
        self.tris += it.tri() as usize;
    }

    fn of(items: &[Item]) -> Summary {
        let mut s = Summary::EMPTY;
        for it in items {
            s.add(it);
        }
        s
    }
}

/// Builds the node of `items`, whose summary is `sum` (min and max are
/// exact, so a summary gathered in any order is the same bits).
fn build_rec(items: &mut [Item], sum: Summary, offset: usize, depth: u32, max_leaf: usize, nodes: &mut Vec<Node2>) -> u32 {
    let id = nodes.len() as u32;
    let Summary { bounds, cbounds, tris } = sum;
    let n = items.len();
    nodes.push(Node2::new(bounds, offset as u32, 0, n as u32));
    if n <= 1 {
        return id;
    }
    let leaf_cost = COST_UNIT * units(tris, n - tris);
    let degenerate = (cbounds.hi - cbounds.lo).max_element() <= 0.0;
    let split = if degenerate || depth >= MAX_SAH_DEPTH {
        None
    } else if n <= SWEEP_MAX {
        sweep_split(items, bounds.half_area())
    } else {
        binned_split(items, bounds.half_area(), cbounds)
    };
    let mut sides = None;
    let left = match split {
        Some(s) if n > max_leaf || s.cost < leaf_cost => {
            sides = s.sides;
            s.left
        }
        Some(_) => return id,
        None if n <= max_leaf => return id,
        None => {
            // Object median along the longest centroid axis.
            let ext = cbounds.hi - cbounds.lo;
            let axis = if ext.x >= ext.y && ext.x >= ext.z { 0 } else if ext.y >= ext.z { 1 } else { 2 };
            let mid = n / 2;
            items.select_nth_unstable_by(mid, |a, b| a.centroid()[axis].total_cmp(&b.centroid()[axis]));
            mid
        }
    };
    let (l, r) = items.split_at_mut(left);
    let [ls, rs] = sides.unwrap_or_else(|| [Summary::of(l), Summary::of(r)]);
    let (li, ri) = if n > PAR_MIN && depth < PAR_DEPTH {
        // Each half into its own list, then appended with indices shifted:
        // the same tree as the serial order gives.
        let sub = |items: &mut [Item], sum: Summary, offset: usize| {
            let mut v = Vec::with_capacity(2 * items.len() - 1);
            build_rec(items, sum, offset, depth + 1, max_leaf, &mut v);
            v
        };
        let (lv, rv) = rayon::join(|| sub(l, ls, offset), || sub(r, rs, offset + left));
        let mut append = |v: Vec<Node2>| {
            let base = nodes.len() as u32;
            nodes.extend(v.into_iter().map(|mut nd| {
                if nd.is_inner() {
                    nd.a += base;
                    nd.b += base;
                }
                nd
            }));
            base
        };
        (append(lv), append(rv))
    } else {
        (build_rec(l, ls, offset, depth + 1, max_leaf, nodes), build_rec(r, rs, offset + left, depth + 1, max_leaf, nodes))
    };
    nodes[id as usize] = Node2::new(bounds, li, ri, INNER);
    id
}

/// Exact SAH: sort by centroid on each axis and sweep. Leaves `items`
/// (at most `SWEEP_MAX`) sorted along the axis of the best split found.
fn sweep_split(items: &mut [Item], parent_area: f32) -> Option<Split> {
    let n = items.len();
    let inv_area = 1.0 / parent_area.max(f32::MIN_POSITIVE);
    let mut best: Option<(f32, usize, usize)> = None; // cost, axis, items left of the split
    let mut right_cost = [0.0f32; SWEEP_MAX];
    // Per axis, the items' positions in centroid order: indices sorted by
    // a key, not the 28-byte items by a comparison.
    let mut order = [[0u8; SWEEP_MAX]; 3];
    for (axis, order) in order.iter_mut().enumerate() {
        let mut keys = [0u64; SWEEP_MAX];
        for (key, it) in keys.iter_mut().zip(items.iter()) {
            *key = sweep_key(it, axis);
        }
        let order = &mut order[..n];
        for (i, o) in order.iter_mut().enumerate() {
            *o = i as u8;
        }
        order.sort_unstable_by_key(|&i| keys[i as usize]);
        let item = |i: usize| &items[order[i] as usize];
        // right_cost[i]: area × units of the items from the i-th on.
        let (mut b, mut t) = (Aabb::EMPTY, 0);
        for i in (1..n).rev() {
            b = b.union(item(i).bounds());
            t += item(i).tri() as usize;
            right_cost[i] = b.half_area() * units(t, n - i - t);
        }
        let (mut b, mut t) = (Aabb::EMPTY, 0);
        for i in 1..n {
            b = b.union(item(i - 1).bounds());
            t += item(i - 1).tri() as usize;
            let cost = COST_TRAVERSE + COST_UNIT * (b.half_area() * units(t, i - t) + right_cost[i]) * inv_area;
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, axis, i));
            }
        }
    }
    let (cost, axis, left) = best?;
    let mut sorted = [items[0]; SWEEP_MAX];
    for (s, &o) in sorted.iter_mut().zip(&order[axis][..n]) {
        *s = items[o as usize];
    }
    items.copy_from_slice(&sorted[..n]);
    Some(Split { cost, left, sides: None })
}

/// An item's place along `axis` as one integer: its centroid (the sum of
/// its bounds, as `f32::total_cmp` orders it), then its id (unique), so
/// that the order is total and independent of the items' input order.
#[inline(always)]
fn sweep_key(it: &Item, axis: usize) -> u64 {
    let bits = (it.lo[axis] + it.hi[axis]).to_bits() as i32;
    // total_cmp's map to a signed order, then to an unsigned one.
    let ordered = (bits ^ (((bits >> 31) as u32) >> 1) as i32) as u32 ^ 0x8000_0000;
    (ordered as u64) << 32 | it.id as u64
}

/// The bins of the three axes: boxes, triangles and items.
#[derive(Clone, Copy)]
struct Bins {
    bb: [[Aabb; BINS]; 3],
    tri: [[usize; BINS]; 3],
    cnt: [[usize; BINS]; 3],
}

impl Bins {
    const EMPTY: Bins = Bins { bb: [[Aabb::EMPTY; BINS]; 3], tri: [[0; BINS]; 3], cnt: [[0; BINS]; 3] };
}

/// The bin of a centroid at `x` bins from the low end (an `i32`
/// conversion: fewer instructions than to `usize`, same bins).
#[inline(always)]
fn bin_index(x: f32) -> usize {
    (x as i32).clamp(0, BINS as i32 - 1) as usize
}

/// Binned SAH over the centroid bounds; partitions `items` by the best split.
fn binned_split(items: &mut [Item], parent_area: f32, cbounds: Aabb) -> Option<Split> {
    let inv_area = 1.0 / parent_area.max(f32::MIN_POSITIVE);
    let ext = cbounds.hi - cbounds.lo;
    let mut best: Option<(f32, usize, usize)> = None; // cost, axis, bins left of the split
    // One pass over the items fills the bins of all three axes.
    let scale = Vec3A::select(ext.cmpgt(Vec3A::ZERO), Vec3A::splat(BINS as f32) / ext, Vec3A::ZERO);
    // Two sets of bins, for the even and the odd items: neighbours in a
    // coherent input mostly fall into the same bins, and each update would
    // wait on the one before. Merged after (unions and counts: exact, so
    // the same bits as one set).
    let mut sets = [Bins::EMPTY; 2];
    let add = |bins: &mut Bins, it: &Item| {
        let b = it.bounds();
        let k = ((b.centroid() - cbounds.lo) * scale).to_array();
        for axis in 0..3 {
            let k = bin_index(k[axis]);
            bins.bb[axis][k] = bins.bb[axis][k].union(b);
            bins.cnt[axis][k] += 1;
            bins.tri[axis][k] += it.tri() as usize;
        }
    };
    let [even, odd] = &mut sets;
    let mut pairs = items.chunks_exact(2);
    for pair in &mut pairs {
        add(even, &pair[0]);
        add(odd, &pair[1]);
    }
    if let [last] = pairs.remainder() {
        add(even, last);
    }
    let (bb, tri, cnt) = (&mut even.bb, &mut even.tri, &mut even.cnt);
    for axis in 0..3 {
        for k in 0..BINS {
            bb[axis][k] = bb[axis][k].union(odd.bb[axis][k]);
            tri[axis][k] += odd.tri[axis][k];
            cnt[axis][k] += odd.cnt[axis][k];
        }
    }
    for axis in 0..3 {
        if ext[axis] <= 0.0 {
            continue;
        }
        let (bb, tri, cnt) = (&bb[axis], &tri[axis], &cnt[axis]);
        let mut right_cost = [0.0f32; BINS];
        let (mut b, mut t, mut c) = (Aabb::EMPTY, 0, 0);
        for k in (1..BINS).rev() {
            b = b.union(bb[k]);
            t += tri[k];
            c += cnt[k];
            right_cost[k] = if c == 0 { f32::INFINITY } else { b.half_area() * units(t, c - t) };
        }
        let (mut b, mut t, mut c) = (Aabb::EMPTY, 0, 0);
        for k in 1..BINS {
            b = b.union(bb[k - 1]);
            t += tri[k - 1];
            c += cnt[k - 1];
            if c == 0 {
                continue;
            }
            let cost = COST_TRAVERSE + COST_UNIT * (b.half_area() * units(t, c - t) + right_cost[k]) * inv_area;
            if cost.is_finite() && best.is_none_or(|(bc, _, _)| cost < bc) {
                best = Some((cost, axis, k));
            }
        }
    }
    let (cost, axis, k) = best?;
    let scale = BINS as f32 / ext[axis];
    let bin_of = |c: f32| bin_index((c - cbounds.lo[axis]) * scale);
    // In-place partition from both ends, gathering the two sides'
    // summaries on the way: only the items on the wrong side move (in
    // coherent input most are already on theirs).
    let goes_left = |it: &Item| bin_of(it.centroid()[axis]) < k;
    let (mut left, mut right) = (0, items.len());
    let (mut ls, mut rs) = (Summary::EMPTY, Summary::EMPTY);
    loop {
        while left < right && goes_left(&items[left]) {
            ls.add(&items[left]);
            left += 1;
        }
        while left < right && !goes_left(&items[right - 1]) {
            rs.add(&items[right - 1]);
            right -= 1;
        }
        if left >= right {
            break;
        }
        // items[left] goes right and items[right - 1] left.
        items.swap(left, right - 1);
        ls.add(&items[left]);
        rs.add(&items[right - 1]);
        left += 1;
        right -= 1;
    }
    if left == 0 || left == items.len() {
        return None;
    }
    Some(Split { cost, left, sides: Some([ls, rs]) })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The sweep's integer keys order items as the comparison they stand
    /// for: centroid sums by `total_cmp` (negative, ±0, ties), then id.
    #[test]
    fn sweep_keys_order_as_total_cmp_then_id() {
        let values = [-3.5f32, -1.0, -0.0, 0.0, 1e-30, 0.25, 0.25, 2.0, f32::MAX, -f32::MAX, 7.0];
        let mut items = vec![];
        for (i, &v) in values.iter().enumerate() {
            for (j, &w) in values.iter().enumerate().step_by(3) {
                let id = (i * values.len() + j) as u32 ^ 0x55;
                items.push(Item::new(Aabb { lo: Vec3A::new(v, w, 0.0), hi: Vec3A::new(v, w, 0.0) }, id));
            }
        }
        for axis in 0..3 {
            let mut by_cmp = items.clone();
            by_cmp.sort_by(|a, b| (a.lo[axis] + a.hi[axis]).total_cmp(&(b.lo[axis] + b.hi[axis])).then(a.id.cmp(&b.id)));
            let mut by_key = items.clone();
            by_key.sort_by_key(|it| sweep_key(it, axis));
            let ids = |v: &[Item]| v.iter().map(|it| it.id).collect::<Vec<_>>();
            assert_eq!(ids(&by_cmp), ids(&by_key), "axis {axis}");
        }
    }
}
