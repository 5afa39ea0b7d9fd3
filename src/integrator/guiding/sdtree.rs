//! The spatial part of the guide: a binary tree over the scene's bounding
//! box, split at the middle of the axis x, y, z in turn (Müller et al.
//! 2017, §3), each leaf holding a [`DirTree`] of the radiance arriving in
//! its region.
//!
//! A region is split while it holds more than
//! `SPATIAL_C · √(training samples per pixel)` records (the paper's
//! c · √(2^k), here counted on the iteration's own records). Leaves with
//! fewer than [`MIN_LEAF_RECORDS`] records, or none with energy, get no
//! directional distribution: vertices there sample the BSDF alone.
//!
//! Above the spatial tree, vertices are classed by the dominant axis (and
//! sign) of their normal on the path's side, one tree per class: the floor
//! and the wall meeting it in one region see different hemispheres (on the
//! Cornell box at 64², 64 spp, this took the guided relMSE from 1.86e-3 to
//! 1.38e-3).

use super::quadtree::{DirTree, dir_to_square};
use glam::{Vec2, Vec3};

/// Records a region may hold before it is split, per √spp of the training
/// iteration.
pub const SPATIAL_C: f32 = 4000.0;
/// Fewest records a leaf needs for a directional distribution.
pub const MIN_LEAF_RECORDS: usize = 64;
/// Deepest split.
const MAX_SPATIAL_DEPTH: u32 = 48;

/// One training sample of the incident radiance: at `p`, from the unit
/// direction `d`, radiance over the density it was sampled with.
#[derive(Clone, Copy, Debug)]
pub struct Record {
    pub p: Vec3,
    /// Which of the [`NORMAL_BINS`] the vertex's shading normal falls in.
    pub bin: u8,
    pub d: Vec3,
    pub value: f32,
}

/// Number of normal classes: the dominant axis of the normal and its sign.
pub const NORMAL_BINS: usize = 6;

/// The class of the unit normal `n` (surfaces facing apart in one region
/// of space have their own trees).
#[inline]
pub fn normal_bin(n: Vec3) -> u8 {
    let a = n.abs();
    let axis = if a.x >= a.y && a.x >= a.z { 0 } else if a.y >= a.z { 1 } else { 2 };
    (2 * axis + (n[axis] < 0.0) as usize) as u8
}

#[derive(Clone, Copy, Debug)]
enum SpatialNode {
    /// Children at `child` (below `split` on `axis`) and `child + 1`.
    Inner { axis: u8, split: f32, child: u32 },
    /// Index into `Guide::dirs`, or `u32::MAX` for no distribution.
    Leaf(u32),
}

/// A frozen spatial-directional tree.
#[derive(Clone, Debug, Default)]
pub struct SdTree {
    /// Root node of each normal class (all 0 when classes are not used).
    roots: [u32; NORMAL_BINS],
    nodes: Vec<SpatialNode>,
    dirs: Vec<DirTree>,
}

impl SdTree {
    /// The tree fitted to `records` over the box `lo`–`hi`; `spp`: the
    /// samples per pixel the records come from.
    pub fn build(records: &mut [Record], lo: Vec3, hi: Vec3, spp: u32, by_normal: bool) -> SdTree {
        let mut tree = SdTree { roots: [0; NORMAL_BINS], nodes: vec![SpatialNode::Leaf(u32::MAX)], dirs: vec![] };
        let threshold = ((SPATIAL_C * (spp.max(1) as f32).sqrt()) as usize).max(MIN_LEAF_RECORDS * 4);
        if !by_normal {
            tree.build_node(0, records, lo, hi, 0, threshold);
            return tree;
        }
        records.sort_by_key(|r| r.bin);
        let mut start = 0;
        for b in 0..NORMAL_BINS {
            let end = start + records[start..].iter().take_while(|r| r.bin as usize == b).count();
            let root = tree.nodes.len();
            tree.nodes.push(SpatialNode::Leaf(u32::MAX));
            tree.roots[b] = root as u32;
            tree.build_node(root, &mut records[start..end], lo, hi, 0, threshold);
            start = end;
        }
        tree
    }

    fn build_node(&mut self, index: usize, records: &mut [Record], lo: Vec3, hi: Vec3, depth: u32, threshold: usize) {
        if records.len() > threshold && depth < MAX_SPATIAL_DEPTH {
            let axis = (depth % 3) as usize;
            let split = 0.5 * (lo[axis] + hi[axis]);
            // Deterministic in-place partition (stable).
            records.sort_by_key(|r| r.p[axis] >= split);
            let n_low = records.iter().take_while(|r| r.p[axis] < split).count();
            let child = self.nodes.len();
            self.nodes.push(SpatialNode::Leaf(u32::MAX));
            self.nodes.push(SpatialNode::Leaf(u32::MAX));
            self.nodes[index] = SpatialNode::Inner { axis: axis as u8, split, child: child as u32 };
            let (low, high) = records.split_at_mut(n_low);
            let mut hi_low = hi;
            hi_low[axis] = split;
            let mut lo_high = lo;
            lo_high[axis] = split;
            self.build_node(child, low, lo, hi_low, depth + 1, threshold);
            self.build_node(child + 1, high, lo_high, hi, depth + 1, threshold);
            return;
        }
        if records.len() < MIN_LEAF_RECORDS {
            return;
        }
        let mut points: Vec<(Vec2, f32)> = records.iter().map(|r| (dir_to_square(r.d), r.value)).collect();
        let dir = DirTree::build(&mut points);
        if !dir.is_empty() {
            self.nodes[index] = SpatialNode::Leaf(self.dirs.len() as u32);
            self.dirs.push(dir);
        }
    }

    /// The directional distribution of the region holding `p`, if it has one.
    #[inline]
    pub fn lookup(&self, p: Vec3, n: Vec3) -> Option<&DirTree> {
        let mut i = self.roots[normal_bin(n) as usize] as usize;
        loop {
            match self.nodes[i] {
                SpatialNode::Inner { axis, split, child } => {
                    i = child as usize + (p[axis as usize] >= split) as usize;
                }
                SpatialNode::Leaf(d) => return self.dirs.get(d as usize),
            }
        }
    }

    /// (spatial leaves, leaves with a distribution, directional nodes).
    pub fn stats(&self) -> (usize, usize, usize) {
        let leaves = self.nodes.iter().filter(|n| matches!(n, SpatialNode::Leaf(_))).count();
        (leaves, self.dirs.len(), self.dirs.iter().map(DirTree::node_count).sum())
    }
}
