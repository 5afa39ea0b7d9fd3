//! Mitsuba's `cylinder`: an open tube (no end caps) around the segment
//! from `p0` to `p1`, its normals pointing outwards.
//!
//! | parameter      | type      | default   | meaning                                        |
//! |----------------|-----------|-----------|------------------------------------------------|
//! | `p0`           | point     | (0, 0, 0) | object-space start of the centre line          |
//! | `p1`           | point     | (0, 0, 1) | object-space end of the centre line            |
//! | `radius`       | float     | 1         | object-space radius                            |
//! | `flip_normals` | boolean   | false     | normals point inwards (the inside is the front) |
//! | `to_world`     | transform | identity  | object-to-world (rotation, translation, a scale that is uniform across the axis) |
//!
//! ```xml
//! <shape type="cylinder">
//!     <point name="p0" x="0" y="0" z="-1"/>
//!     <point name="p1" x="0" y="0" z="1"/>
//!     <float name="radius" value="0.3"/>
//!     <bsdf type="twosided"><bsdf type="diffuse"/></bsdf>
//! </shape>
//! ```
//!
//! As in Mitsuba, the local frame has its z axis along p1 − p0 (x and y from
//! the same orthonormal basis construction, which fixes where u = 0 is), the
//! tube spans z ∈ [0, length]; uv = (φ/2π, z/length), ∂p/∂u = 2π(−y, x, 0).
//! Positions are sampled uniformly by area (u.x along the axis, u.y around
//! it), so a cylinder can carry an `area` emitter.

use super::mesh::PositionSample;
use crate::math::{Frame, INV_TWO_PI, PI, Transform};
use glam::{Mat4, Vec2, Vec3};

#[derive(Clone, Debug)]
pub struct Cylinder {
    /// Object (unit scale: rotation and translation only) → world.
    pub to_world: Transform,
    pub radius: f32,
    pub length: f32,
    pub flip_normals: bool,
}

impl Cylinder {
    /// The cylinder of radius `radius` from `p0` to `p1`, placed by
    /// `to_world`; `None` if the axis has zero length or `to_world` does not
    /// keep the tube circular (a different scale across the axis, shear or
    /// a mirror; a scale along the axis is allowed).
    pub fn new(to_world: &Transform, p0: Vec3, p1: Vec3, radius: f32, flip_normals: bool) -> Option<Cylinder> {
        let d = p1 - p0;
        let length = d.length();
        if !(length > 0.0 && radius > 0.0 && length.is_finite()) {
            return None;
        }
        let f = Frame::from_normal(d / length);
        let local = Mat4::from_cols(f.s.extend(0.0), f.t.extend(0.0), f.n.extend(0.0), p0.extend(1.0));
        let m = to_world.matrix * local;
        let (x, y, z) = (m.x_axis.truncate(), m.y_axis.truncate(), m.z_axis.truncate());
        // As Mitsuba: the axes stay perpendicular and the cross-section a
        // circle (equal scale across the axis); the scale along the axis
        // may differ (it stretches the length).
        let (s, sz) = (x.length(), z.length());
        let circular = (y.length() - s).abs() <= 1e-4 * s
            && x.dot(y).abs() <= 1e-4 * s * s
            && y.dot(z).abs() <= 1e-4 * s * sz
            && x.dot(z).abs() <= 1e-4 * s * sz
            && x.cross(y).dot(z) > 0.0;
        if !circular || !(s > 0.0 && sz > 0.0) {
            return None;
        }
        let rigid = Mat4::from_cols((x / s).extend(0.0), (y / s).extend(0.0), (z / sz).extend(0.0), m.w_axis);
        Some(Cylinder { to_world: Transform::from_matrix(rigid)?, radius: radius * s, length: length * sz, flip_normals })
    }

    pub fn area(&self) -> f32 {
        2.0 * PI * self.radius * self.length
    }

    /// Nearest t in (0, tmax) where the ray meets the tube, or infinity.
    /// `to_object` is the inverse of `to_world` (rigid, so t is preserved).
    #[inline]
    pub fn intersect(to_object: &Transform, radius: f32, length: f32, o: Vec3, d: Vec3, tmax: f32) -> f32 {
        let o = to_object.point(o).as_dvec3();
        let d = to_object.vector(d).as_dvec3();
        let r = radius as f64;
        let a = d.x * d.x + d.y * d.y;
        if a == 0.0 {
            return f32::INFINITY; // parallel to the axis: never meets the wall
        }
        let b = 2.0 * (d.x * o.x + d.y * o.y);
        let c = o.x * o.x + o.y * o.y - r * r;
        let disc = b * b - 4.0 * a * c;
        if disc < 0.0 {
            return f32::INFINITY;
        }
        // Numerically stable roots.
        let q = -0.5 * (b + disc.sqrt().copysign(b));
        let (mut t0, mut t1) = (q / a, if q != 0.0 { c / q } else { q / a });
        if t0 > t1 {
            std::mem::swap(&mut t0, &mut t1);
        }
        for t in [t0, t1] {
            let z = o.z + d.z * t;
            if t > 0.0 && t < tmax as f64 && (0.0..=length as f64).contains(&z) {
                return t as f32;
            }
        }
        f32::INFINITY
    }

    /// World-space box of the tube: the box of its two end circles.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        let x1 = self.to_world.vector(Vec3::X * self.radius);
        let x2 = self.to_world.vector(Vec3::Y * self.radius);
        let ext = (x1 * x1 + x2 * x2).powf(0.5);
        let p0 = self.to_world.point(Vec3::ZERO);
        let p1 = self.to_world.point(Vec3::Z * self.length);
        (p0.min(p1) - ext, p0.max(p1) + ext)
    }

    /// Point projected onto the surface, geometric normal, uv and ∂p/∂u at a hit `p`.
    /// (Not inlined: it would grow `Shape::interaction`, which meshes use.)
    #[inline(never)]
    pub fn surface(&self, p: Vec3) -> (Vec3, Vec3, Vec2, Vec3) {
        let l = self.to_world.inverse_point(p);
        let radial = Vec3::new(l.x, l.y, 0.0);
        let rl = radial.length();
        let (radial, l) = if rl > 0.0 {
            // Remove the error of o + t·d: back onto the wall.
            let unit = radial / rl;
            (unit, Vec3::new(unit.x * self.radius, unit.y * self.radius, l.z))
        } else {
            (Vec3::X, l)
        };
        let mut phi = crate::math::trig::atan2(l.y, l.x);
        if phi < 0.0 {
            phi += 2.0 * PI;
        }
        let uv = Vec2::new(phi * INV_TWO_PI, l.z / self.length);
        let n = self.to_world.vector(radial).normalize_or_zero();
        let dp_du = self.to_world.vector(Vec3::new(-l.y, l.x, 0.0) * (2.0 * PI));
        (self.to_world.point(l), if self.flip_normals { -n } else { n }, uv, dp_du)
    }

    /// Uniform by area.
    #[inline(always)]
    pub fn sample_position(&self, u: Vec2) -> PositionSample {
        let (s, c) = crate::math::trig::sin_cos_turn(u.y);
        let p = self.to_world.point(Vec3::new(c * self.radius, s * self.radius, u.x * self.length));
        let n = self.to_world.vector(Vec3::new(c, s, 0.0)).normalize_or_zero();
        let n = if self.flip_normals { -n } else { n };
        PositionSample { p, n, sh_n: n, pdf_area: 1.0 / self.area() }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn inv(t: &Transform) -> Transform {
        Transform { matrix: t.inverse, inverse: t.matrix }
    }

    #[test]
    fn axis_radius_and_scale() {
        let t = Transform::from_matrix(Mat4::from_translation(Vec3::new(1.0, 2.0, 3.0)) * Mat4::from_scale(Vec3::splat(2.0))).unwrap();
        let c = Cylinder::new(&t, Vec3::new(0.0, 0.0, -1.0), Vec3::new(0.0, 0.0, 1.0), 0.5, false).unwrap();
        assert!((c.radius - 1.0).abs() < 1e-6 && (c.length - 4.0).abs() < 1e-6);
        assert!((c.area() - 8.0 * PI).abs() < 1e-4);
        // A ray along x through the axis at the middle hits the wall at x = 0.
        let hit = Cylinder::intersect(&inv(&c.to_world), c.radius, c.length, Vec3::new(-5.0, 2.0, 3.0), Vec3::X, f32::INFINITY);
        assert!((hit - 5.0).abs() < 1e-5, "{hit}");
        let (p, n, uv, _) = c.surface(Vec3::new(-5.0, 2.0, 3.0) + Vec3::X * hit);
        assert!((p - Vec3::new(0.0, 2.0, 3.0)).length() < 1e-5);
        assert!((n + Vec3::X).length() < 1e-5, "outward normal {n}");
        assert!((uv.y - 0.5).abs() < 1e-5);
        // From inside, the far wall; beyond the ends, nothing; tmax respected.
        let inside = Cylinder::intersect(&inv(&c.to_world), c.radius, c.length, Vec3::new(1.0, 2.0, 3.0), Vec3::Y, f32::INFINITY);
        assert!((inside - 1.0).abs() < 1e-5);
        let beyond = Cylinder::intersect(&inv(&c.to_world), c.radius, c.length, Vec3::new(-5.0, 2.0, 5.5), Vec3::X, f32::INFINITY);
        assert!(beyond.is_infinite());
        let short = Cylinder::intersect(&inv(&c.to_world), c.radius, c.length, Vec3::new(-5.0, 2.0, 3.0), Vec3::X, 3.0);
        assert!(short.is_infinite());
        // A ray entering through the open end meets the inside of the wall.
        let d = Vec3::new(0.3, 0.0, 1.0).normalize();
        let t = Cylinder::intersect(&inv(&c.to_world), c.radius, c.length, Vec3::new(1.0, 2.0, 0.0), d, f32::INFINITY);
        assert!((t * d.x - 1.0).abs() < 1e-4, "{t}");
        assert!(Cylinder::new(&Transform::from_matrix(Mat4::from_scale(Vec3::new(1.0, 2.0, 1.0))).unwrap(), Vec3::ZERO, Vec3::Z, 1.0, false).is_none());
    }

    /// A scale along the axis stretches the tube (Mitsuba's
    /// tests/scenes/various_shapes scales a cylinder by (1.5, 1.5, 2)); a
    /// scale across it that is not uniform, a shear or a mirror is refused.
    #[test]
    fn a_stretch_along_the_axis_changes_the_length_only() {
        let scale = Mat4::from_scale(Vec3::new(1.5, 1.5, 2.0));
        let rotate = Mat4::from_axis_angle(Vec3::new(0.3, -0.5, 0.8).normalize(), 0.7);
        let t = Transform::from_matrix(Mat4::from_translation(Vec3::new(0.0, -2.0, -2.0)) * rotate * scale).unwrap();
        let c = Cylinder::new(&t, Vec3::ZERO, Vec3::Z, 1.0, false).unwrap();
        assert!((c.radius - 1.5).abs() < 1e-5 && (c.length - 2.0).abs() < 1e-5, "radius {} length {}", c.radius, c.length);
        // Points of the object-space tube map onto the world-space one.
        let mut rng = crate::math::Pcg32::new(9, 1);
        for _ in 0..100 {
            let (phi, z) = (rng.next_f32() * 2.0 * PI, rng.next_f32());
            let world = t.point(Vec3::new(phi.cos(), phi.sin(), z));
            let l = c.to_world.inverse_point(world);
            assert!(((l.x * l.x + l.y * l.y).sqrt() - 1.5).abs() < 1e-4 && (l.z - 2.0 * z).abs() < 1e-4, "{l}");
        }
        let shear = Mat4::from_cols(Vec3::X.extend(0.0), Vec3::new(0.3, 1.0, 0.0).extend(0.0), Vec3::Z.extend(0.0), Vec3::ZERO.extend(1.0));
        let mirror = Mat4::from_scale(Vec3::new(1.0, 1.0, -2.0));
        for m in [shear, mirror] {
            assert!(Cylinder::new(&Transform::from_matrix(m).unwrap(), Vec3::ZERO, Vec3::Z, 1.0, false).is_none());
        }
    }

    #[test]
    fn samples_lie_on_the_wall_with_outward_normals_and_uv_matches() {
        let t = Transform::rotate(Vec3::new(1.0, 1.0, 0.0).normalize(), 40.0).unwrap();
        let c = Cylinder::new(&t, Vec3::new(0.5, 0.0, 0.0), Vec3::new(0.5, 2.0, 1.0), 0.7, false).unwrap();
        let mut rng = crate::math::Pcg32::new(4, 2);
        for _ in 0..500 {
            let u = Vec2::new(rng.next_f32(), rng.next_f32());
            let ps = c.sample_position(u);
            let l = c.to_world.inverse_point(ps.p);
            assert!(((l.x * l.x + l.y * l.y).sqrt() - c.radius).abs() < 1e-4);
            assert!(l.z >= -1e-4 && l.z <= c.length + 1e-4);
            let (_, n, uv, dp_du) = c.surface(ps.p);
            assert!((n - ps.n).length() < 1e-4);
            assert!((uv - Vec2::new(u.y, u.x)).length() < 1e-3 || (uv.x - u.y).abs() > 0.999, "{uv} vs {u}");
            assert!(dp_du.dot(n).abs() < 1e-3 && (dp_du.length() - 2.0 * PI * c.radius).abs() < 1e-3);
        }
    }
}
