//! The directional part of the guide: a quadtree over the square of
//! cylindrical coordinates (u = (cos θ + 1)/2, v = φ/2π), an equal-area map
//! of the sphere, so a density on the square is the density on the sphere
//! times 4π (Müller et al. 2017, §4).
//!
//! Each node keeps the energy (sum of recorded radiance/pdf) of its four
//! quadrants; a quadrant is subdivided where it holds more than
//! [`SUBDIVIDE_FRACTION`] of the tree's energy (down to [`MAX_DEPTH`]
//! levels) and at least [`MIN_RECORDS`] records. Sampling descends by the
//! quadrants' energies, reusing the rescaled 2-D sample, and is uniform
//! within a leaf; [`DirTree::pdf`] is the same density in closed form.

use glam::{Vec2, Vec3};
use std::f32::consts::PI;

/// A quadrant holding more than this fraction of the tree's energy is split
/// (Müller et al.'s ρ = 0.01).
pub const SUBDIVIDE_FRACTION: f32 = 0.01;
/// Deepest level of the tree (Müller et al.'s 20).
pub const MAX_DEPTH: u32 = 20;
/// Fewest records a quadrant needs to be split (fewer: its energy is noise).
pub const MIN_RECORDS: usize = 8;

#[derive(Clone, Copy, Debug)]
struct Node {
    /// Child node of each quadrant (index 0 = x low, y low; 1 = x high;
    /// 2 = y high; 3 = both high); 0 for a leaf quadrant.
    child: [u32; 4],
    energy: [f32; 4],
}

/// A directional distribution over the sphere.
#[derive(Clone, Debug, Default)]
pub struct DirTree {
    nodes: Vec<Node>,
}

/// The point of the square for the unit direction `d`.
#[inline]
pub fn dir_to_square(d: Vec3) -> Vec2 {
    let u = ((d.z.clamp(-1.0, 1.0) + 1.0) * 0.5).min(1.0 - f32::EPSILON);
    let mut phi = d.y.atan2(d.x);
    if phi < 0.0 {
        phi += 2.0 * PI;
    }
    let v = (phi * (0.5 / PI)).clamp(0.0, 1.0 - f32::EPSILON);
    Vec2::new(u, v)
}

/// The unit direction at the point `p` of the square.
#[inline]
pub fn square_to_dir(p: Vec2) -> Vec3 {
    let cos_t = 2.0 * p.x - 1.0;
    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
    let (s, c) = (2.0 * PI * p.y).sin_cos();
    Vec3::new(sin_t * c, sin_t * s, cos_t)
}

#[inline]
fn quadrant(p: Vec2) -> usize {
    (p.x >= 0.5) as usize + 2 * (p.y >= 0.5) as usize
}

#[inline]
fn to_child(p: Vec2, q: usize) -> Vec2 {
    let o = Vec2::new((q & 1) as f32, (q >> 1) as f32);
    (p * 2.0 - o).clamp(Vec2::ZERO, Vec2::splat(1.0 - f32::EPSILON))
}

impl DirTree {
    /// The tree fitted to `records` (points of the square, non-negative
    /// energies); records are reordered. Empty (no density) if their
    /// energy is zero.
    pub fn build(records: &mut [(Vec2, f32)]) -> DirTree {
        let total: f64 = records.iter().map(|r| r.1 as f64).sum();
        let mut tree = DirTree { nodes: vec![] };
        if !(total > 0.0) || !total.is_finite() {
            return tree;
        }
        tree.build_node(records, total as f32, 1);
        tree
    }

    /// Appends the node for `records` (in the node's own coordinates) and
    /// returns its index.
    fn build_node(&mut self, records: &mut [(Vec2, f32)], total: f32, depth: u32) -> u32 {
        let index = self.nodes.len();
        self.nodes.push(Node { child: [0; 4], energy: [0.0; 4] });
        // Group the records by quadrant (a stable sort: deterministic).
        records.sort_by_key(|r| quadrant(r.0));
        let mut start = 0;
        for q in 0..4 {
            let end = start + records[start..].iter().take_while(|r| quadrant(r.0) == q).count();
            let part = &mut records[start..end];
            let energy: f64 = part.iter().map(|r| r.1 as f64).sum();
            self.nodes[index].energy[q] = energy as f32;
            if depth < MAX_DEPTH && part.len() >= MIN_RECORDS && energy as f32 > SUBDIVIDE_FRACTION * total {
                for r in part.iter_mut() {
                    r.0 = to_child(r.0, q);
                }
                let child = self.build_node(part, total, depth + 1);
                self.nodes[index].child[q] = child;
            }
            start = end;
        }
        index as u32
    }

    /// Whether the tree has a density (recorded energy).
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// Number of nodes.
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// Density on the square at `p` (0 for an empty tree).
    pub fn pdf_square(&self, mut p: Vec2) -> f32 {
        if self.nodes.is_empty() {
            return 0.0;
        }
        let mut pdf = 1.0f32;
        let mut node = &self.nodes[0];
        loop {
            let total: f32 = node.energy.iter().sum();
            if !(total > 0.0) {
                return 0.0;
            }
            let q = quadrant(p);
            pdf *= 4.0 * node.energy[q] / total;
            if node.child[q] == 0 || pdf == 0.0 {
                return pdf;
            }
            p = to_child(p, q);
            node = &self.nodes[node.child[q] as usize];
        }
    }

    /// Solid-angle density of the unit direction `d`.
    #[inline]
    pub fn pdf(&self, d: Vec3) -> f32 {
        self.pdf_square(dir_to_square(d)) * (0.25 / PI)
    }

    /// A point of the square distributed by [`DirTree::pdf_square`], from a
    /// uniform `u` (the tree must not be empty).
    pub fn sample_square(&self, mut u: Vec2) -> Vec2 {
        let mut origin = Vec2::ZERO;
        let mut scale = 1.0f32;
        let mut node = &self.nodes[0];
        let below_one = 1.0 - f32::EPSILON;
        loop {
            let e = node.energy;
            let left = e[0] + e[2];
            let total = left + e[1] + e[3];
            let p_left = if total > 0.0 { left / total } else { 0.5 };
            let ix = if u.x < p_left {
                u.x /= p_left;
                0
            } else {
                u.x = (u.x - p_left) / (1.0 - p_left);
                1
            };
            let column = e[ix] + e[ix + 2];
            let p_low = if column > 0.0 { e[ix] / column } else { 0.5 };
            let iy = if u.y < p_low {
                u.y /= p_low;
                0
            } else {
                u.y = (u.y - p_low) / (1.0 - p_low);
                1
            };
            u = u.clamp(Vec2::ZERO, Vec2::splat(below_one));
            let q = ix + 2 * iy;
            scale *= 0.5;
            origin += Vec2::new(ix as f32, iy as f32) * scale;
            if node.child[q] == 0 {
                return (origin + u * scale).clamp(Vec2::ZERO, Vec2::splat(below_one));
            }
            node = &self.nodes[node.child[q] as usize];
        }
    }

    /// A unit direction distributed by [`DirTree::pdf`] (the tree must not
    /// be empty).
    #[inline]
    pub fn sample(&self, u: Vec2) -> Vec3 {
        square_to_dir(self.sample_square(u))
    }
}

