//! Triangle meshes in world space, and Mitsuba's built-in `rectangle` and
//! `cube` as meshes.
//!
//! Mitsuba's rectangle is the square [-1,1]² in the z=0 plane with normal +z
//! and uv = (x/2 + ½, y/2 + ½); its cube is [-1,1]³ with outward normals.
//! After an affine `to_world` a rectangle is a parallelogram, so two
//! triangles represent it exactly, including uniform area sampling.

use crate::math::Transform;
use crate::math::sampling::{DiscreteDistribution, square_to_uniform_triangle};
use super::mesh_io::Attribute;
use super::sphere::DirectionSample;
use std::sync::Arc;
use glam::{Vec2, Vec3};

/// An immutable array shared by reference count: the mesh and the BVH
/// (which reads triangles through it instead of copying them) hold the
/// same buffer. Reads like a slice.
#[derive(Debug)]
pub struct Shared<T>(Arc<[T]>);

impl<T> Clone for Shared<T> {
    fn clone(&self) -> Self {
        Shared(self.0.clone())
    }
}

impl<T> From<Vec<T>> for Shared<T> {
    fn from(v: Vec<T>) -> Self {
        Shared(v.into())
    }
}

impl<T> std::ops::Deref for Shared<T> {
    type Target = [T];
    #[inline(always)]
    fn deref(&self) -> &[T] {
        &self.0
    }
}

impl<'a, T> IntoIterator for &'a Shared<T> {
    type Item = &'a T;
    type IntoIter = std::slice::Iter<'a, T>;
    fn into_iter(self) -> Self::IntoIter {
        self.0.iter()
    }
}

#[derive(Clone, Debug)]
pub struct Mesh {
    pub positions: Shared<Vec3>,
    /// Per-vertex shading normals, unit length, already flipped if needed.
    pub normals: Option<Vec<Vec3>>,
    pub uvs: Option<Vec<Vec2>>,
    pub triangles: Shared<[u32; 3]>,
    /// Negate geometric and shading normals (Mitsuba's `flip_normals`).
    pub flip_normals: bool,
    /// Mesh attributes by name (`vertex_color`, `face_weight`, …); vertex
    /// attributes stored per triangle corner (see `Attribute::to_corners`).
    pub attributes: Vec<(String, Arc<Attribute>)>,
    /// Unit geometric normal per triangle (flip applied), kept only for
    /// meshes of at most [`STORED_NORMALS_MAX`] triangles (empty otherwise):
    /// a small mesh's normals cost little memory and save a normalisation
    /// per hit; a large mesh's are computed at the hit from the edges the
    /// hit already has (12 bytes per triangle saved).
    face_normals: Vec<Vec3>,
    /// Total surface area.
    area: f32,
    /// Triangles by area, for `sample_position`; made on first use (only
    /// emitters sample positions: other meshes save its 4 bytes per
    /// triangle).
    area_distribution: std::sync::OnceLock<DiscreteDistribution>,
}

/// A point drawn on a shape's surface.
#[derive(Clone, Copy, Debug)]
pub struct PositionSample {
    pub p: Vec3,
    /// Geometric normal at `p`.
    pub n: Vec3,
    /// Shading normal at `p` (decides which side emits).
    pub sh_n: Vec3,
    /// Density with respect to surface area.
    pub pdf_area: f32,
}

impl PositionSample {
    /// This point as a direction seen from `p`, its area density converted
    /// to solid angle by the Jacobian ‖x″ − x′‖² / |cos θ″|.
    #[inline(always)]
    pub fn towards(&self, p: Vec3) -> Option<DirectionSample> {
        let v = self.p - p;
        let dist2 = v.length_squared();
        let dist = dist2.sqrt();
        if !(dist > 0.0 && dist.is_finite()) {
            return None;
        }
        let d = v / dist;
        let cos = self.n.dot(d).abs();
        if cos <= 1e-7 {
            return None;
        }
        Some(DirectionSample { p: self.p, n: self.n, sh_n: self.sh_n, d, dist, pdf: self.pdf_area * dist2 / cos })
    }
}

/// Solid-angle density at `p` of a point `hit` (normal `n`) on a surface
/// sampled uniformly over `area`.
pub fn area_pdf_to_solid_angle(p: Vec3, hit: Vec3, n: Vec3, area: f32) -> f32 {
    let v = hit - p;
    let dist2 = v.length_squared();
    let cos = n.dot(v).abs() / dist2.sqrt();
    if cos <= 1e-7 || area <= 0.0 { 0.0 } else { dist2 / (cos * area) }
}

/// Meshes with at most this many triangles store their face normals
/// (at most 768 KiB each).
pub const STORED_NORMALS_MAX: usize = 1 << 16;

impl Mesh {
    /// Builds a mesh from world-space data. Indices must be in range (the
    /// loaders check this with a located error before calling).
    pub fn new(
        positions: Vec<Vec3>,
        normals: Option<Vec<Vec3>>,
        uvs: Option<Vec<Vec2>>,
        triangles: Vec<[u32; 3]>,
        flip_normals: bool,
    ) -> Mesh {
        let mut mesh = Mesh {
            positions: positions.into(),
            normals,
            uvs,
            triangles: triangles.into(),
            flip_normals,
            attributes: vec![],
            face_normals: vec![],
            area: 0.0,
            area_distribution: Default::default(),
        };
        if let Some(ns) = mesh.normals.take() {
            mesh.set_vertex_normals(ns);
        }
        if mesh.triangles.len() <= STORED_NORMALS_MAX {
            mesh.face_normals = (0..mesh.triangles.len()).map(|i| mesh.face_normal(i)).collect();
        }
        // Summed as `DiscreteDistribution` sums (in f64, in order), so that
        // `area()` equals the distribution's sum bit for bit.
        mesh.area = (0..mesh.triangles.len()).fold(0.0f64, |acc, i| acc + mesh.triangle_area(i).max(0.0) as f64) as f32;
        mesh
    }

    /// Sets the per-vertex shading normals (normalised, and flipped if
    /// the mesh flips its normals), as `new` does with the normals given.
    pub fn set_vertex_normals(&mut self, mut normals: Vec<Vec3>) {
        for n in normals.iter_mut() {
            *n = n.normalize_or_zero();
            if self.flip_normals {
                *n = -*n;
            }
        }
        self.normals = Some(normals);
    }

    fn area_distribution(&self) -> &DiscreteDistribution {
        self.area_distribution.get_or_init(|| DiscreteDistribution::new((0..self.triangles.len()).map(|i| self.triangle_area(i))))
    }

    /// The triangle [`Mesh::sample_position`] picks for `u` (by area) and
    /// `u` re-scaled within it (for the batched emitter sampling).
    #[inline]
    pub fn sample_triangle(&self, u: f32) -> (usize, f32) {
        self.area_distribution().sample_reuse(u)
    }

    /// The CDF [`Mesh::sample_triangle`] walks (triangles by area), for a
    /// copy kept next to the triangles' corners.
    pub fn triangle_cdf(&self) -> &[f32] {
        self.area_distribution().cdf()
    }

    pub fn vertices(&self, i: usize) -> [Vec3; 3] {
        let [a, b, c] = self.triangles[i];
        [self.positions[a as usize], self.positions[b as usize], self.positions[c as usize]]
    }

    /// Prefetches triangle `i`'s corner indices, the first of a hit's two
    /// dependent reads (see [`Mesh::prefetch_corners`]).
    #[inline(always)]
    pub fn prefetch_indices(&self, i: usize) {
        super::prefetch(self.triangles.get(i));
    }

    /// Prefetches triangle `i`'s corner positions and shading normals,
    /// reading its indices: call it once those have arrived.
    #[inline(always)]
    pub fn prefetch_corners(&self, i: usize) {
        let Some(&corners) = self.triangles.get(i) else { return };
        for v in corners.map(|v| v as usize) {
            super::prefetch(self.positions.get(v));
            if let Some(normals) = &self.normals {
                super::prefetch(normals.get(v));
            }
        }
    }

    pub fn triangle_area(&self, i: usize) -> f32 {
        let [a, b, c] = self.vertices(i);
        0.5 * (b - a).cross(c - a).length()
    }

    pub fn area(&self) -> f32 {
        self.area
    }

    /// Unit geometric normal of triangle `i` (orientation from the winding,
    /// flip applied). Computed on each call rather than stored: 12 bytes
    /// per triangle saved for a cross product and a normalisation per hit.
    #[inline]
    pub fn face_normal(&self, i: usize) -> Vec3 {
        let [a, b, c] = self.vertices(i);
        self.face_normal_from_edges(b - a, c - a)
    }

    /// [`Mesh::face_normal`] from the edges e1 = b − a and e2 = c − a that
    /// the caller already has (a hit, a position sample): no second read of
    /// the vertices; the same arithmetic, so the same bits.
    #[inline(always)]
    pub fn face_normal_from_edges(&self, e1: Vec3, e2: Vec3) -> Vec3 {
        let n = e1.cross(e2).normalize_or_zero();
        if self.flip_normals { -n } else { n }
    }

    /// The normal of triangle `i`, whose edges are `e1` and `e2`: the
    /// stored one of a small mesh, else computed from the edges (the same
    /// bits either way).
    #[inline(always)]
    pub fn face_normal_at(&self, i: usize, e1: Vec3, e2: Vec3) -> Vec3 {
        match self.face_normals.get(i) {
            Some(&n) => n,
            None => self.face_normal_from_edges(e1, e2),
        }
    }

    /// ∂p/∂u of triangle `i` from its texture coordinates; `None` without
    /// them or if they are degenerate.
    pub fn dp_du(&self, i: usize) -> Option<Vec3> {
        let uvs = self.uvs.as_ref()?;
        let [ia, ib, ic] = self.triangles[i];
        let [a, b, c] = self.vertices(i);
        let (duv1, duv2) = (uvs[ib as usize] - uvs[ia as usize], uvs[ic as usize] - uvs[ia as usize]);
        let det = duv1.x * duv2.y - duv1.y * duv2.x;
        if !(det.abs() > 1e-12) {
            return None;
        }
        // p(u, v) is affine on the triangle: solve for ∂p/∂u from its edges.
        Some(((b - a) * duv2.y - (c - a) * duv1.y) / det)
    }

    /// ∂p/∂u and ∂p/∂v of triangle `i` (`None` without texture coordinates
    /// or with degenerate ones).
    pub fn dp_duv(&self, i: usize) -> Option<(Vec3, Vec3)> {
        let uvs = self.uvs.as_ref()?;
        let [ia, ib, ic] = self.triangles[i];
        let [a, b, c] = self.vertices(i);
        let (duv1, duv2) = (uvs[ib as usize] - uvs[ia as usize], uvs[ic as usize] - uvs[ia as usize]);
        let det = duv1.x * duv2.y - duv1.y * duv2.x;
        if !(det.abs() > 1e-12) {
            return None;
        }
        let inv = 1.0 / det;
        let (e1, e2) = (b - a, c - a);
        Some(((e1 * duv2.y - e2 * duv1.y) * inv, (e2 * duv1.x - e1 * duv2.x) * inv))
    }

    /// Shading normal and uv at barycentrics (b1, b2) of triangle `i`.
    /// (Always inlined: called, its result came back through memory. A
    /// mesh without vertex normals and uvs needs neither its corners'
    /// indices nor any arithmetic.)
    #[inline(always)]
    pub fn shading(&self, i: usize, b1: f32, b2: f32, face_n: Vec3) -> (Vec3, Vec2) {
        if self.normals.is_none() && self.uvs.is_none() {
            return (face_n, Vec2::new(b1, b2));
        }
        let [ia, ib, ic] = self.triangles[i];
        let b0 = 1.0 - b1 - b2;
        let sh_n = match &self.normals {
            Some(ns) => {
                let n = (ns[ia as usize] * b0 + ns[ib as usize] * b1 + ns[ic as usize] * b2).normalize_or_zero();
                if n == Vec3::ZERO { face_n } else { n }
            }
            None => face_n,
        };
        let uv = match &self.uvs {
            Some(uvs) => uvs[ia as usize] * b0 + uvs[ib as usize] * b1 + uvs[ic as usize] * b2,
            None => Vec2::new(b1, b2),
        };
        (sh_n, uv)
    }

    /// Uniform by area over the whole mesh.
    #[inline(always)]
    pub fn sample_position(&self, u: Vec2) -> Option<PositionSample> {
        if self.triangles.is_empty() || self.area() <= 0.0 {
            return None;
        }
        let (i, ux) = self.area_distribution().sample_reuse(u.x);
        let b = square_to_uniform_triangle(Vec2::new(ux, u.y));
        let [a, bb, c] = self.vertices(i);
        let p = a * (1.0 - b.x - b.y) + bb * b.x + c * b.y;
        let n = self.face_normal_at(i, bb - a, c - a);
        let sh_n = match self.normals {
            Some(_) => self.shading(i, b.x, b.y, n).0,
            None => n,
        };
        Some(PositionSample { p, n, sh_n, pdf_area: 1.0 / self.area() })
    }

    /// Renumbers the triangles so that triangle `i` is the old triangle
    /// `order[i]` (`order` must be a permutation of the triangle indices),
    /// and the vertices by first use in that order (vertices no triangle
    /// uses keep their order, at the end). Each triangle keeps its corners
    /// in the same order and each vertex its position, normal and uv, so
    /// every hit and every shading value is the same bits as before under
    /// the new numbers; per-face attributes, stored face normals and
    /// per-corner (vertex) attributes move with their triangle. The total
    /// area is summed again in the new order and the area distribution
    /// (for emitters) is rebuilt on first use: uniform by area as before,
    /// over the triangles in the new order.
    ///
    /// The BVH calls this for big meshes (`Accel::store_meshes_in_leaf_order`) so that a
    /// leaf's triangles, and mostly their vertices, lie next to each other in memory.
    pub fn reorder(&mut self, order: &[u32]) {
        let n = self.triangles.len();
        assert_eq!(order.len(), n, "a triangle order must list every triangle");
        // Vertex renumbering by first use; `u32::MAX` = not yet used.
        // `old_of`, its inverse, grows as vertices are numbered. The new
        // buffers are collected straight into their shared arrays (one
        // allocation each, no copy), and each old one is freed as soon as
        // it is replaced: this runs after the BVH build, and must not raise
        // the load's peak memory.
        let n_verts = self.positions.len();
        let mut new_of = vec![u32::MAX; n_verts];
        let mut old_of = Vec::with_capacity(n_verts);
        let triangles: Arc<[[u32; 3]]> = order
            .iter()
            .map(|&t| {
                self.triangles[t as usize].map(|v| {
                    let slot = &mut new_of[v as usize];
                    if *slot == u32::MAX {
                        *slot = old_of.len() as u32;
                        old_of.push(v);
                    }
                    *slot
                })
            })
            .collect();
        self.triangles = Shared(triangles);
        // Unused vertices last, in their order.
        if old_of.len() < n_verts {
            old_of.extend((0..n_verts as u32).filter(|&v| new_of[v as usize] == u32::MAX));
        }
        drop(new_of);
        debug_assert_eq!(old_of.len(), n_verts);
        // The vertex gathers in parallel (each the same values as in order).
        use rayon::prelude::*;
        let positions = &self.positions;
        let (new_positions, (normals, uvs)) = rayon::join(
            || old_of.par_iter().map(|&o| positions[o as usize]).collect::<Arc<[Vec3]>>(),
            || {
                rayon::join(
                    || self.normals.as_ref().map(|ns| old_of.par_iter().map(|&o| ns[o as usize]).collect::<Vec<_>>()),
                    || self.uvs.as_ref().map(|uvs| old_of.par_iter().map(|&o| uvs[o as usize]).collect::<Vec<_>>()),
                )
            },
        );
        self.positions = Shared(new_positions);
        if normals.is_some() {
            self.normals = normals;
        }
        if uvs.is_some() {
            self.uvs = uvs;
        }
        drop(old_of);
        // Per-triangle data: rows of `row` floats or vectors, gathered in the new order.
        fn gather<T: Copy>(old: &[T], row: usize, order: &[u32]) -> Vec<T> {
            let mut out = Vec::with_capacity(old.len());
            for &t in order {
                out.extend_from_slice(&old[t as usize * row..(t as usize + 1) * row]);
            }
            out
        }
        if !self.face_normals.is_empty() {
            self.face_normals = gather(&self.face_normals, 1, order);
        }
        for (_, a) in &mut self.attributes {
            let row = if a.per_face { a.dims } else { 3 * a.dims };
            if row > 0 && a.data.len() == row * n {
                *a = Arc::new(Attribute { per_face: a.per_face, dims: a.dims, data: gather(&a.data, row, order) });
            }
        }
        self.area = (0..n).fold(0.0f64, |acc, i| acc + self.triangle_area(i).max(0.0) as f64) as f32;
        self.area_distribution = Default::default();
    }

    /// Mitsuba's `rectangle`.
    pub fn rectangle(to_world: &Transform, flip_normals: bool) -> Mesh {
        let local = [Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, -1.0, 0.0), Vec3::new(1.0, 1.0, 0.0), Vec3::new(-1.0, 1.0, 0.0)];
        let uvs = vec![Vec2::new(0.0, 0.0), Vec2::new(1.0, 0.0), Vec2::new(1.0, 1.0), Vec2::new(0.0, 1.0)];
        Self::from_local_quads(to_world, &local, uvs, &[[0, 1, 2, 3]], flip_normals)
    }

    /// Mitsuba's `cube`: [-1,1]³, four vertices and one uv square per face.
    pub fn cube(to_world: &Transform, flip_normals: bool) -> Mesh {
        let mut positions = vec![];
        let mut uvs = vec![];
        let mut quads = vec![];
        for axis in 0..3 {
            for sign in [-1.0f32, 1.0] {
                let mut n = Vec3::ZERO;
                n[axis] = sign;
                // Two tangents with t1 × t2 = n, so the quad winds counter-clockwise seen from outside.
                let mut t1 = Vec3::ZERO;
                t1[(axis + 1) % 3] = 1.0;
                let mut t2 = Vec3::ZERO;
                t2[(axis + 2) % 3] = 1.0;
                if sign < 0.0 {
                    std::mem::swap(&mut t1, &mut t2);
                }
                let base = positions.len() as u32;
                for (du, dv) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                    positions.push(n + t1 * du + t2 * dv);
                    uvs.push(Vec2::new((du + 1.0) * 0.5, (dv + 1.0) * 0.5));
                }
                quads.push([base, base + 1, base + 2, base + 3]);
            }
        }
        Self::from_local_quads(to_world, &positions, uvs, &quads, flip_normals)
    }

    fn from_local_quads(
        to_world: &Transform,
        local: &[Vec3],
        uvs: Vec<Vec2>,
        quads: &[[u32; 4]],
        flip_normals: bool,
    ) -> Mesh {
        let positions: Vec<Vec3> = local.iter().map(|&p| to_world.point(p)).collect();
        // A mirroring transform reverses the winding; keep the geometric
        // normal on the side of the transformed normal, as Mitsuba's analytic
        // shapes do.
        let mirrored = to_world.matrix.determinant() < 0.0;
        let mut triangles = vec![];
        for &[a, b, c, d] in quads {
            if mirrored {
                triangles.push([a, c, b]);
                triangles.push([a, d, c]);
            } else {
                triangles.push([a, b, c]);
                triangles.push([a, c, d]);
            }
        }
        // Flat faces: the geometric normal is the shading normal.
        Mesh::new(positions, None, Some(uvs), triangles, flip_normals)
    }

    /// Smooth vertex normals weighted by the angle each face makes at the
    /// vertex (Thürmer & Wüthrich 1998), as Mitsuba computes them for meshes
    /// that come without normals.
    pub fn compute_vertex_normals(positions: &[Vec3], triangles: &[[u32; 3]]) -> Vec<Vec3> {
        let mut normals = vec![Vec3::ZERO; positions.len()];
        for tri in triangles {
            let p = [positions[tri[0] as usize], positions[tri[1] as usize], positions[tri[2] as usize]];
            let n = (p[1] - p[0]).cross(p[2] - p[0]).normalize_or_zero();
            if n == Vec3::ZERO {
                continue;
            }
            for k in 0..3 {
                let e1 = (p[(k + 1) % 3] - p[k]).normalize_or_zero();
                let e2 = (p[(k + 2) % 3] - p[k]).normalize_or_zero();
                let angle = e1.dot(e2).clamp(-1.0, 1.0).acos();
                normals[tri[k] as usize] += n * angle;
            }
        }
        for n in &mut normals {
            *n = n.normalize_or_zero();
        }
        normals
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Mat4;

    #[test]
    fn rectangle_area_and_normal() {
        let t = Transform::from_matrix(Mat4::from_scale(Vec3::new(2.0, 3.0, 1.0))).unwrap();
        let m = Mesh::rectangle(&t, false);
        assert!((m.area() - 24.0).abs() < 1e-4);
        assert!((m.face_normal(0) - Vec3::Z).length() < 1e-6);
        let flipped = Mesh::rectangle(&t, true);
        assert!((flipped.face_normal(1) + Vec3::Z).length() < 1e-6);
    }

    #[test]
    fn cube_normals_point_outwards() {
        let m = Mesh::cube(&Transform::IDENTITY, false);
        assert_eq!(m.triangles.len(), 12);
        assert!((m.area() - 24.0).abs() < 1e-4);
        for i in 0..12 {
            let [a, b, c] = m.vertices(i);
            let centre = (a + b + c) / 3.0;
            assert!(m.face_normal(i).dot(centre) > 0.0, "face {i} points inwards");
        }
    }

    /// A large mesh computes its face normals at the hit, a small one
    /// stores them: the same bits, flipped or not.
    #[test]
    fn stored_and_computed_face_normals_agree() {
        let n = STORED_NORMALS_MAX / 2 + 1; // 2n triangles: past the limit
        let mut positions = vec![];
        let mut triangles = vec![];
        for k in 0..=n {
            let x = k as f32 * 0.37;
            positions.push(Vec3::new(x, (x * 1.3).sin(), 0.2 * x.cos()));
            positions.push(Vec3::new(x + 0.11, 1.0 + (x * 0.7).cos(), 0.5 + 0.1 * x.sin()));
        }
        for k in 0..n as u32 {
            triangles.push([2 * k, 2 * k + 2, 2 * k + 1]);
            triangles.push([2 * k + 1, 2 * k + 2, 2 * k + 3]);
        }
        for flip in [false, true] {
            let big = Mesh::new(positions.clone(), None, None, triangles.clone(), flip);
            assert!(big.triangles.len() > STORED_NORMALS_MAX && big.face_normals.is_empty());
            for i in (0..big.triangles.len()).step_by(997) {
                let small = Mesh::new(big.vertices(i).to_vec(), None, None, vec![[0, 1, 2]], flip);
                assert_eq!(small.face_normals.len(), 1);
                let [a, b, c] = big.vertices(i);
                let computed = big.face_normal_at(i, b - a, c - a);
                assert_eq!(computed.to_array().map(f32::to_bits), small.face_normal_at(0, Vec3::ZERO, Vec3::ZERO).to_array().map(f32::to_bits));
                assert!((computed.length() - 1.0).abs() < 1e-5);
                let p = big.sample_position(Vec2::new(0.3, 0.6)).map(|s| s.n.length());
                assert!(p.is_some_and(|l| (l - 1.0).abs() < 1e-5));
            }
        }
    }

    /// `reorder` renumbers triangles and vertices but keeps every
    /// triangle's corners, normals, uvs, attributes, face normal and area
    /// weight, and the vertices a triangle uses come first in first-use order.
    #[test]
    fn reorder_keeps_every_triangle_and_its_data() {
        let mut rng = crate::math::Pcg32::new(9, 2);
        let mut r = || rng.next_f32();
        let nv = 60usize;
        let positions: Vec<Vec3> = (0..nv).map(|_| Vec3::new(r(), r(), r())).collect();
        let normals: Vec<Vec3> = (0..nv).map(|_| Vec3::new(r() - 0.5, r() - 0.5, 1.0)).collect();
        let uvs: Vec<Vec2> = (0..nv).map(|_| Vec2::new(r(), r())).collect();
        // Vertex 59 is used by no triangle.
        let triangles: Vec<[u32; 3]> = (0..80).map(|_| [0, 1, 2].map(|_| ((r() * 59.0) as u32).min(58))).collect();
        let n = triangles.len();
        let mut old = Mesh::new(positions, Some(normals), Some(uvs), triangles.clone(), true);
        let face = Attribute { per_face: true, dims: 2, data: (0..2 * n).map(|k| k as f32).collect() };
        let vertex = Attribute { per_face: false, dims: 1, data: (0..nv).map(|k| 1000.0 + k as f32).collect() }.to_corners(&triangles);
        old.attributes = vec![("face_w".into(), Arc::new(face)), ("vertex_c".into(), Arc::new(vertex))];
        let order: Vec<u32> = (0..n as u32).map(|i| (i * 37 + 11) % n as u32).collect();
        let mut new = old.clone();
        new.reorder(&order);
        assert_eq!(new.triangles.len(), n);
        assert_eq!(new.positions.len(), nv);
        assert_eq!(new.positions[nv - 1], old.positions[nv - 1], "an unused vertex goes last");
        let bits = |v: Vec3| v.to_array().map(f32::to_bits);
        let mut seen = 0u32;
        for (i, &o) in order.iter().enumerate() {
            let o = o as usize;
            assert_eq!(new.vertices(i).map(bits), old.vertices(o).map(bits));
            assert_eq!(new.face_normal(i).to_array().map(f32::to_bits), old.face_normal(o).to_array().map(f32::to_bits));
            assert_eq!(new.face_normals[i], old.face_normals[o]);
            let (a, b) = (new.shading(i, 0.2, 0.3, Vec3::Z), old.shading(o, 0.2, 0.3, Vec3::Z));
            assert_eq!((bits(a.0), a.1.to_array().map(f32::to_bits)), (bits(b.0), b.1.to_array().map(f32::to_bits)));
            assert_eq!(new.attributes[0].1.data[2 * i..2 * i + 2], old.attributes[0].1.data[2 * o..2 * o + 2]);
            assert_eq!(new.attributes[1].1.data[3 * i..3 * i + 3], old.attributes[1].1.data[3 * o..3 * o + 3]);
            assert_eq!(new.triangle_area(i).to_bits(), old.triangle_area(o).to_bits());
            // The same weight (up to the rounding of the cumulative sums, summed in another order).
            let (pn, po) = (new.area_distribution().pmf(i), old.area_distribution().pmf(o));
            assert!((pn - po).abs() <= 1e-6, "{pn} vs {po}");
            // First use: a triangle's vertices are at most one past those seen so far.
            for v in new.triangles[i] {
                assert!(v <= seen, "vertex {v} numbered out of first-use order");
                seen = seen.max(v + 1);
            }
        }
        assert!((new.area() - old.area()).abs() <= 1e-5 * old.area());
        assert!(new.sample_position(Vec2::new(0.4, 0.7)).is_some());
    }

    #[test]
    fn mirrored_rectangle_keeps_its_normal() {
        let t = Transform::from_matrix(Mat4::from_scale(Vec3::new(-1.0, 1.0, 1.0))).unwrap();
        let m = Mesh::rectangle(&t, false);
        assert!((m.face_normal(0) - Vec3::Z).length() < 1e-6);
    }
}
