//! The acceleration structure: one compressed wide BVH (obvhs' CWBVH, 8-wide
//! with SIMD node tests) over every primitive of every shape. Primitive data
//! are stored in the BVH's leaf order so traversal reads them contiguously.

use super::disk::Disk;
use super::shape::{Shape, ShapeGeometry};
use super::sphere::Sphere;
use super::Ray;
use crate::math::Transform;
use glam::{Vec3, Vec3A};
use obvhs::aabb::Aabb;
use obvhs::cwbvh::CwBvh;
use obvhs::{Boundable, BvhBuildParams};
use std::time::Duration;

/// Intersection data of one primitive, as compact as traversal wants it.
#[derive(Clone, Debug)]
enum PrimGeom {
    Triangle { v0: Vec3A, e1: Vec3A, e2: Vec3A },
    Sphere { center: Vec3, radius: f32 },
    Disk { to_object: Box<Transform> },
}

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
}

pub struct Accel {
    bvh: Option<CwBvh>,
    geoms: Vec<PrimGeom>,
    refs: Vec<PrimRef>,
}

struct Bounded(Aabb);

impl Boundable for Bounded {
    fn aabb(&self) -> Aabb {
        self.0
    }
}

fn prim_geom(shape: &Shape, prim: usize) -> (PrimGeom, Aabb) {
    match &shape.geometry {
        ShapeGeometry::Mesh(m) => {
            let [a, b, c] = m.vertices(prim);
            let mut aabb = Aabb::empty();
            aabb.extend(a.into()).extend(b.into()).extend(c.into());
            (PrimGeom::Triangle { v0: a.into(), e1: (b - a).into(), e2: (c - a).into() }, aabb)
        }
        ShapeGeometry::Sphere(s) => {
            let r = Vec3A::splat(s.radius);
            let c: Vec3A = s.center.into();
            (PrimGeom::Sphere { center: s.center, radius: s.radius }, Aabb::new(c - r, c + r))
        }
        ShapeGeometry::Disk(d) => {
            let mut aabb = Aabb::empty();
            // The disk lies inside the transformed square [-1,1]² × {0}.
            for (x, y) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                aabb.extend(d.to_world.point(Vec3::new(x, y, 0.0)).into());
            }
            let to_object = Transform { matrix: d.to_world.inverse, inverse: d.to_world.matrix };
            (PrimGeom::Disk { to_object: Box::new(to_object) }, aabb)
        }
    }
}

impl Accel {
    pub fn build(shapes: &[Shape]) -> Accel {
        let mut geoms = vec![];
        let mut refs = vec![];
        let mut boxes = vec![];
        for (si, shape) in shapes.iter().enumerate() {
            for p in 0..shape.primitive_count() {
                let (g, mut aabb) = prim_geom(shape, p);
                // Flat primitives have zero-thickness boxes; pad them so the
                // slab test never rejects a hit on an axis-aligned face.
                let pad = Vec3A::splat(1e-6) * (1.0 + aabb.max.abs().max(aabb.min.abs()).max_element());
                aabb.min -= pad;
                aabb.max += pad;
                geoms.push(g);
                refs.push(PrimRef { shape: si as u32, prim: p as u32 });
                boxes.push(Bounded(aabb));
            }
        }
        if boxes.is_empty() {
            return Accel { bvh: None, geoms, refs };
        }
        let bvh = obvhs::cwbvh::builder::build_cwbvh(&boxes, BvhBuildParams::medium_build(), &mut Duration::default());
        let order = &bvh.primitive_indices;
        let geoms = order.iter().map(|&i| geoms[i as usize].clone()).collect();
        let refs = order.iter().map(|&i| refs[i as usize]).collect();
        Accel { bvh: Some(bvh), geoms, refs }
    }

    #[inline(always)]
    fn intersect_prim(&self, slot: usize, o: Vec3A, d: Vec3A, tmax: f32) -> f32 {
        self.intersect_prim_bary(slot, o, d, tmax).0
    }

    /// Hit distance (infinite on a miss) and, for triangles, barycentrics.
    #[inline(always)]
    fn intersect_prim_bary(&self, slot: usize, o: Vec3A, d: Vec3A, tmax: f32) -> (f32, f32, f32) {
        const MISS: (f32, f32, f32) = (f32::INFINITY, 0.0, 0.0);
        match &self.geoms[slot] {
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
        }
    }

    /// The closest hit along the ray before `ray.tmax`.
    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<Hit> {
        let bvh = self.bvh.as_ref()?;
        let r = obvhs::ray::Ray::new(ray.o.into(), ray.d.into(), 0.0, ray.tmax);
        let mut hit = obvhs::ray::RayHit::none();
        let mut bary = (0.0, 0.0);
        let found = bvh.ray_traverse(r, &mut hit, |r, slot| {
            let (t, b1, b2) = self.intersect_prim_bary(slot, r.origin, r.direction, r.tmax);
            if t < r.tmax {
                bary = (b1, b2);
            }
            t
        });
        if !found {
            return None;
        }
        let pref = self.refs[hit.primitive_id as usize];
        Some(Hit { t: hit.t, bary, shape: pref.shape, prim: pref.prim })
    }

    /// Whether anything lies on the ray before `ray.tmax`.
    #[inline]
    pub fn occluded(&self, ray: &Ray) -> bool {
        let Some(bvh) = self.bvh.as_ref() else { return false };
        let r = obvhs::ray::Ray::new(ray.o.into(), ray.d.into(), 0.0, ray.tmax);
        !bvh.ray_traverse_miss(r, |r, slot| self.intersect_prim(slot, r.origin, r.direction, r.tmax))
    }

    /// Bounding box of everything (min, max); a unit box around the origin when empty.
    pub fn bounds(&self, shapes: &[Shape]) -> (Vec3, Vec3) {
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for s in shapes {
            for p in 0..s.primitive_count() {
                let (_, b) = prim_geom(s, p);
                lo = lo.min(b.min.into());
                hi = hi.max(b.max.into());
            }
        }
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

    fn brute_force(shapes: &[Shape], ray: &Ray) -> f32 {
        let mut best = f32::INFINITY;
        for s in shapes {
            for p in 0..s.primitive_count() {
                let (g, _) = prim_geom(s, p);
                let a = Accel { bvh: None, geoms: vec![g], refs: vec![] };
                best = best.min(a.intersect_prim(0, ray.o.into(), ray.d.into(), ray.tmax));
            }
        }
        best
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
            shapes.push(Shape { geometry, bsdf: 0, emitter: None });
        }
        let accel = Accel::build(&shapes);
        let mut rng = Pcg32::new(9, 9);
        let mut hits = 0;
        for _ in 0..5000 {
            let o = Vec3::new(rng.next_f32() * 8.0 - 4.0, rng.next_f32() * 4.0 - 1.0, rng.next_f32() * 6.0 - 3.0);
            let d = square_to_uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32()));
            let ray = Ray::new(o, d);
            let expected = brute_force(&shapes, &ray);
            let got = accel.intersect(&ray).map_or(f32::INFINITY, |h| h.t);
            if expected.is_finite() {
                hits += 1;
                assert!((expected - got).abs() < 1e-4 * (1.0 + expected), "{expected} vs {got}");
                assert!(accel.occluded(&Ray { tmax: expected * 1.001, ..ray }));
            } else {
                assert!(got.is_infinite());
                assert!(!accel.occluded(&ray));
            }
        }
        assert!(hits > 500, "the test should exercise hits ({hits})");
    }
}
