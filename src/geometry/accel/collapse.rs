//! The binary BVH (`build.rs`) collapsed into the 8-wide BVH that traversal
//! uses, with the least SAH cost the binary tree allows: the dynamic
//! programme of Ylitie, Karras and Laine, "Efficient incoherent ray
//! traversal on GPUs through compressed wide BVHs" (HPG 2017), section 3.
//!
//! Every binary node n is one of three things in the wide tree: a leaf
//! (all its primitives, at most `MAX_LEAF`), a wide node, or dissolved:
//! its subtree spread over several child slots of the wide node above.
//! `C(n, j)`, the least cost of n's subtree in at most j slots, is filled
//! bottom-up (children have higher indices than their parent):
//!
//! - `C(n, 1) = min(leaf(n), A(n)·COST_NODE + D(n, 8))`, with
//!   `leaf(n) = A(n)·COST_LEAF·units(n)` (∞ above `MAX_LEAF` primitives
//!   unless n is a binary leaf);
//! - `C(n, j) = min(C(n, j − 1), D(n, j))` for j > 1, where
//!   `D(n, j) = min over k of C(a, k) + C(b, j − k)` over n's children a, b.
//!
//! `A` is the half surface area (the SAH needs only ratios). The choice is
//! then read back from the root down: the root is always a wide node (one
//! with a single leaf when everything fits in one), and each slot takes
//! the option its cost came from. The greedy collapse this replaced opened
//! the largest child until a node was full and stopped at binary leaves,
//! which left nodes of 4.4 children on average on a 1 M-triangle mesh.
//!
//! Memory: 40 bytes per binary node while the wide tree is made.

use super::build::{Bvh2, OTHER, PACKET};
use super::{Accel, Leaf, Node, PrimGeom, PrimRef, TriRef, LEAF, MAX_LEAF, WIDTH};

/// Relative costs of a wide node visit (one slab test of its eight boxes)
/// and of a leaf unit (a packet of up to `PACKET` triangles, or one other
/// primitive), per unit of half area.
///
/// They are the binary build's (`build.rs`), so that the collapse does not
/// undo its splits: with them every binary leaf stays a leaf (a packet of
/// up to 8 triangles costs one unit, however full) and only the grouping
/// into wide nodes changes. Measured (2026-12-01, AVX-512 EPYC, 1 M and 4 M
/// triangle meshes): building the binary tree on to leaves of at most 4
/// and letting the collapse merge them (`COST_LEAF` 1, 2 or 4) gave 26 %
/// more smaller leaves and 10–15 % fewer triangle tests per ray, but no
/// render time gain beyond the noise, for 20 % more build time and 50 %
/// more peak memory at 4 M triangles.
const COST_NODE: f32 = 1.0;
const COST_LEAF: f32 = 1.0;

/// Leaf units of `tris` triangles and `others` other primitives.
fn units(tris: u32, others: u32) -> f32 {
    (tris.div_ceil(PACKET as u32) + others) as f32
}

/// The cost table of the binary tree.
struct Plan {
    /// `cost[n][j − 1]` = C(n, j).
    cost: Vec<[f32; WIDTH]>,
    /// Primitives under each binary node: (all, triangles).
    prims: Vec<(u32, u32)>,
}

impl Plan {
    fn new(bvh2: &Bvh2) -> Plan {
        let n = bvh2.nodes.len();
        let mut cost = vec![[0.0f32; WIDTH]; n];
        let mut prims = vec![(0u32, 0u32); n];
        for i in (0..n).rev() {
            let nd = &bvh2.nodes[i];
            let area = nd.bounds().half_area();
            if !nd.is_inner() {
                let items = &bvh2.order[nd.a as usize..(nd.a + nd.count) as usize];
                let tris = items.iter().filter(|&&id| id & OTHER == 0).count() as u32;
                prims[i] = (nd.count, tris);
                cost[i] = [area * COST_LEAF * units(tris, nd.count - tris); WIDTH];
                continue;
            }
            let (a, b) = (nd.a as usize, nd.b as usize);
            let (all, tris) = (prims[a].0 + prims[b].0, prims[a].1 + prims[b].1);
            prims[i] = (all, tris);
            let (ca, cb) = (&cost[a], &cost[b]);
            let dist = |j: usize| (1..j).map(|k| ca[k - 1] + cb[j - k - 1]).fold(f32::INFINITY, f32::min);
            let leaf = if all as usize <= MAX_LEAF { area * COST_LEAF * units(tris, all - tris) } else { f32::INFINITY };
            let mut c = [0.0f32; WIDTH];
            c[0] = leaf.min(area * COST_NODE + dist(WIDTH));
            for j in 2..=WIDTH {
                c[j - 1] = c[j - 2].min(dist(j));
            }
            cost[i] = c;
        }
        Plan { cost, prims }
    }

    /// The split of inner node `n`'s `j` slots between its children that
    /// `D(n, j)` takes: the slots of the left child.
    fn split(&self, bvh2: &Bvh2, n: usize, j: usize) -> (f32, usize) {
        let nd = &bvh2.nodes[n];
        let (ca, cb) = (&self.cost[nd.a as usize], &self.cost[nd.b as usize]);
        let mut best = (f32::INFINITY, 1);
        for k in 1..j {
            let c = ca[k - 1] + cb[j - k - 1];
            if c < best.0 {
                best = (c, k);
            }
        }
        best
    }

    /// Appends to `out` the binary nodes that fill the (at most) `j` slots
    /// given to node `n`, each one slot (a leaf or a wide node).
    fn slots(&self, bvh2: &Bvh2, n: usize, j: usize, out: &mut Vec<usize>) {
        let nd = &bvh2.nodes[n];
        if j == 1 || !nd.is_inner() {
            out.push(n);
            return;
        }
        let (d, k) = self.split(bvh2, n, j);
        if d < self.cost[n][j - 2] {
            self.slots(bvh2, nd.a as usize, k, out);
            self.slots(bvh2, nd.b as usize, j - k, out);
        } else {
            self.slots(bvh2, n, j - 1, out);
        }
    }

    /// The binary nodes that become the children of the wide node made
    /// for `n` (`D(n, 8)`; `n` itself when it is a binary leaf).
    fn children(&self, bvh2: &Bvh2, n: usize) -> Vec<usize> {
        let nd = &bvh2.nodes[n];
        let mut kids = Vec::with_capacity(WIDTH);
        if nd.is_inner() {
            let (_, k) = self.split(bvh2, n, WIDTH);
            self.slots(bvh2, nd.a as usize, k, &mut kids);
            self.slots(bvh2, nd.b as usize, WIDTH - k, &mut kids);
        } else {
            kids.push(n);
        }
        kids
    }

    /// Whether node `n`, given one slot, is a leaf (else a wide node).
    fn is_leaf(&self, bvh2: &Bvh2, n: usize) -> bool {
        let nd = &bvh2.nodes[n];
        if !nd.is_inner() {
            return true;
        }
        let (all, _) = self.prims[n];
        // The same comparison as `C(n, 1)`'s minimum: a leaf when it is at
        // most the cost of the wide node.
        all as usize <= MAX_LEAF && {
            let (d, _) = self.split(bvh2, n, WIDTH);
            let tris = self.prims[n].1;
            let area = nd.bounds().half_area();
            area * COST_LEAF * units(tris, all - tris) <= area * COST_NODE + d
        }
    }
}

/// Collapses the binary BVH into `Accel`'s wide one.
pub(super) struct Collapse<'a> {
    bvh2: &'a Bvh2,
    /// First triangle id of each mesh.
    mesh_first: &'a [u32],
    others: &'a [PrimGeom],
    other_refs: &'a [PrimRef],
    accel: &'a mut Accel,
    max_depth: u32,
    /// Σ area × cost over the nodes and leaves emitted, a node and a leaf
    /// unit costing 1 (`Accel::sah`).
    sah: f64,
    plan: Plan,
}

impl<'a> Collapse<'a> {
    pub fn new(bvh2: &'a Bvh2, mesh_first: &'a [u32], others: &'a [PrimGeom], other_refs: &'a [PrimRef], accel: &'a mut Accel) -> Self {
        Collapse { bvh2, mesh_first, others, other_refs, accel, max_depth: 0, sah: 0.0, plan: Plan::new(bvh2) }
    }

    /// Emits the wide tree, root first; returns its depth in wide nodes
    /// and its SAH cost (unnormalised).
    pub fn run(mut self) -> (u32, f64) {
        self.node(0, 1);
        (self.max_depth, self.sah)
    }

    /// Emits a leaf of every primitive under binary node `n2`; returns its
    /// child code.
    fn leaf(&mut self, n2: usize) -> u32 {
        // The items of a subtree are one range of `order`, from its leftmost leaf's.
        let mut first = n2;
        while self.bvh2.nodes[first].is_inner() {
            first = self.bvh2.nodes[first].a as usize;
        }
        let start = self.bvh2.nodes[first].a as usize;
        let items = &self.bvh2.order[start..start + self.plan.prims[n2].0 as usize];
        let a = &mut *self.accel;
        let tri_start = a.tris.len() as u32;
        let other_start = a.others.len() as u32;
        for &id in items.iter().filter(|&&id| id & OTHER == 0) {
            let mesh = self.mesh_first.partition_point(|&f| f <= id) - 1;
            a.tris.push(TriRef { mesh: mesh as u32, prim: id - self.mesh_first[mesh] });
        }
        for &id in items.iter().filter(|&&id| id & OTHER != 0) {
            let i = (id & !OTHER) as usize;
            a.others.push(self.others[i].clone());
            a.other_refs.push(self.other_refs[i]);
        }
        a.leaves.push(Leaf { tri_start, tri_end: a.tris.len() as u32, other_start, other_end: a.others.len() as u32 });
        let units = (a.tris.len() - tri_start as usize).div_ceil(PACKET) + (a.others.len() - other_start as usize);
        self.sah += self.bvh2.nodes[n2].bounds().half_area() as f64 * units as f64;
        LEAF | (a.leaves.len() as u32 - 1)
    }

    /// Emits a wide node for binary node `n2` (a root that is a leaf gets a
    /// node with that one child); returns its index.
    fn node(&mut self, n2: usize, depth: u32) -> u32 {
        self.max_depth = self.max_depth.max(depth);
        self.sah += self.bvh2.nodes[n2].bounds().half_area() as f64;
        let id = self.accel.nodes.len();
        let (inf, ninf) = ([f32::INFINITY; WIDTH], [f32::NEG_INFINITY; WIDTH]);
        self.accel.nodes.push(Node { b: [inf, inf, inf, ninf, ninf, ninf], children: [0; WIDTH] });
        let kids = self.plan.children(self.bvh2, n2);
        let mut bounds = [inf, inf, inf, ninf, ninf, ninf];
        let mut children = [0u32; WIDTH];
        for (slot, &k) in kids.iter().enumerate() {
            children[slot] = if self.plan.is_leaf(self.bvh2, k) { self.leaf(k) } else { self.node(k, depth + 1) };
            let b = self.bvh2.nodes[k].bounds();
            for a in 0..3 {
                bounds[a][slot] = b.lo[a];
                bounds[a + 3][slot] = b.hi[a];
            }
        }
        self.accel.nodes[id] = Node { b: bounds, children };
        id as u32
    }
}

#[cfg(test)]
mod tests {
    use super::super::build::{self, Aabb, Item};
    use super::*;
    use crate::math::Pcg32;
    use glam::Vec3A;

    /// The cost of the wide tree read back from `n` (made a wide node), its
    /// wide nodes and their children, and the primitives of its leaves.
    fn read_back(plan: &Plan, bvh2: &Bvh2, n: usize, prims: &mut Vec<u32>) -> (f32, usize, usize) {
        let area = |k: usize| bvh2.nodes[k].bounds().half_area();
        let kids = plan.children(bvh2, n);
        let (mut cost, mut nodes, mut children) = (area(n) * COST_NODE, 1, kids.len());
        for &k in &kids {
            if plan.is_leaf(bvh2, k) {
                let (all, tris) = plan.prims[k];
                assert!(all as usize <= MAX_LEAF, "a leaf of {all}");
                cost += area(k) * COST_LEAF * units(tris, all - tris);
                let mut first = k;
                while bvh2.nodes[first].is_inner() {
                    first = bvh2.nodes[first].a as usize;
                }
                let start = bvh2.nodes[first].a as usize;
                prims.extend_from_slice(&bvh2.order[start..start + all as usize]);
            } else {
                let (c, n2, ch) = read_back(plan, bvh2, k, prims);
                (cost, nodes, children) = (cost + c, nodes + n2, children + ch);
            }
        }
        (cost, nodes, children)
    }

    /// Random small boxes (triangles' and, one in ten, other primitives').
    fn items(rng: &mut Pcg32, n: u32) -> Vec<Item> {
        (0..n)
            .map(|i| {
                let c = Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 10.0;
                let h = Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 0.2;
                let id = if i % 10 == 0 { OTHER | i } else { i };
                Item::new(Aabb { lo: c - h, hi: c + h }, id)
            })
            .collect()
    }

    /// The tree read back costs what the programme computed for it, holds
    /// every primitive once, and fills its nodes better than opening the
    /// largest child did (4.4 children a node on the 1 M mesh; 5.1 here,
    /// where one primitive in ten is a leaf unit of its own).
    #[test]
    fn read_back_tree_has_the_planned_cost() {
        let mut rng = Pcg32::new(7, 3);
        for n in [1u32, 2, 9, 100, 5000] {
            let bvh2 = build::build(items(&mut rng, n), MAX_LEAF);
            let plan = Plan::new(&bvh2);
            let mut prims = vec![];
            let (cost, nodes, children) = read_back(&plan, &bvh2, 0, &mut prims);
            let planned = if bvh2.nodes[0].is_inner() {
                bvh2.nodes[0].bounds().half_area() * COST_NODE + plan.split(&bvh2, 0, WIDTH).0
            } else {
                cost
            };
            assert!((cost - planned).abs() <= 1e-5 * planned, "{n}: read back {cost}, planned {planned}");
            prims.sort_unstable();
            let mut want: Vec<u32> = (0..n).map(|i| if i % 10 == 0 { OTHER | i } else { i }).collect();
            want.sort_unstable();
            assert_eq!(prims, want, "{n} primitives");
            if n == 5000 {
                let fill = children as f32 / nodes as f32;
                assert!(fill > 5.0, "{fill} children a node");
            }
        }
    }
}
