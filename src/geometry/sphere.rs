//! Mitsuba's `sphere`: an analytic sphere (`center`, `radius`, and a
//! similarity `to_world`). Seen from outside, area lights on it are sampled by
//! the solid angle of the cone it subtends, which has far less variance than
//! sampling its area.

use super::mesh::{PositionSample, area_pdf_to_solid_angle};
use crate::math::sampling::{square_to_uniform_cone, square_to_uniform_sphere};
use crate::math::{Frame, INV_PI, INV_TWO_PI, PI, Transform};
use glam::{Vec2, Vec3};

#[derive(Clone, Debug)]
pub struct Sphere {
    pub center: Vec3,
    pub radius: f32,
    /// World → object, for uv (object space is the unit sphere).
    pub to_object: Transform,
    pub flip_normals: bool,
}

/// A direction towards a shape, with the point it reaches.
#[derive(Clone, Copy, Debug)]
pub struct DirectionSample {
    pub p: Vec3,
    pub n: Vec3,
    pub sh_n: Vec3,
    /// Unit direction from the reference point to `p`.
    pub d: Vec3,
    pub dist: f32,
    /// Density with respect to solid angle at the reference point.
    pub pdf: f32,
}

impl Sphere {
    pub fn area(&self) -> f32 {
        4.0 * PI * self.radius * self.radius
    }

    /// Nearest t in (0, tmax) or infinity. Double precision keeps grazing
    /// hits and large spheres stable.
    #[inline]
    pub fn intersect(center: Vec3, radius: f32, o: Vec3, d: Vec3, tmax: f32) -> f32 {
        let oc = (o - center).as_dvec3();
        let d = d.as_dvec3();
        let r = radius as f64;
        let a = d.length_squared();
        let b = oc.dot(d);
        // Hearn & Baker: the discriminant through the closest-approach vector.
        let l = oc - d * (b / a);
        let disc = r * r - l.length_squared();
        if disc < 0.0 {
            return f32::INFINITY;
        }
        let c = oc.length_squared() - r * r;
        let sign_b = if b >= 0.0 { 1.0 } else { -1.0 };
        let q = -(b + sign_b * (a * disc).sqrt());
        let (t0, t1) = {
            let x0 = c / q;
            let x1 = q / a;
            if x0 < x1 { (x0, x1) } else { (x1, x0) }
        };
        let tmax = tmax as f64;
        if t0 > 0.0 && t0 < tmax {
            t0 as f32
        } else if t1 > 0.0 && t1 < tmax {
            t1 as f32
        } else {
            f32::INFINITY
        }
    }

    pub fn normal_at(&self, p: Vec3) -> Vec3 {
        let n = (p - self.center).normalize_or_zero();
        if self.flip_normals { -n } else { n }
    }

    /// Mitsuba's sphere parameterisation: u = φ/2π, v = θ/π in object space.
    pub fn uv_at(&self, p: Vec3) -> Vec2 {
        let l = self.to_object.point(p).normalize_or_zero();
        let mut phi = l.y.atan2(l.x);
        if phi < 0.0 {
            phi += 2.0 * PI;
        }
        let theta = l.z.clamp(-1.0, 1.0).acos();
        Vec2::new(phi * INV_TWO_PI, theta * INV_PI)
    }

    #[inline(always)]
    pub fn sample_position(&self, u: Vec2) -> PositionSample {
        let local = square_to_uniform_sphere(u);
        let p = self.center + local * self.radius;
        let n = if self.flip_normals { -local } else { local };
        PositionSample { p, n, sh_n: n, pdf_area: 1.0 / self.area() }
    }

    /// Cosine of the cone's half angle seen from `p`, and 1 − that cosine
    /// (computed without cancellation); `None` from inside the sphere.
    fn cone(&self, p: Vec3) -> Option<(f32, f32)> {
        let dc2 = (self.center - p).length_squared();
        let r2 = self.radius * self.radius;
        if dc2 <= r2 * (1.0 + 1e-4) {
            return None;
        }
        let sin2 = r2 / dc2;
        let cos_max = (1.0 - sin2).max(0.0).sqrt();
        Some((cos_max, sin2 / (1.0 + cos_max)))
    }

    #[inline(always)]
    pub fn sample_direction(&self, p: Vec3, u: Vec2) -> Option<DirectionSample> {
        match self.cone(p) {
            Some((cos_max, one_minus)) => {
                let to_c = self.center - p;
                let dc = to_c.length();
                let frame = Frame::from_normal(to_c / dc);
                let local = square_to_uniform_cone(u, cos_max);
                let d = frame.to_world(local).normalize();
                // Where that direction meets the sphere (near side); at the
                // rim numerical error can miss it, so clamp to the tangent.
                let cos_t = local.z;
                let disc = (self.radius * self.radius - dc * dc * (1.0 - cos_t * cos_t)).max(0.0);
                let t = dc * cos_t - disc.sqrt();
                let hit = p + d * t;
                let n = self.normal_at(hit);
                Some(DirectionSample { p: hit, n, sh_n: n, d, dist: t, pdf: 1.0 / (2.0 * PI * one_minus) })
            }
            None => self.sample_position(u).towards(p),
        }
    }

    /// Solid-angle density of `sample_direction` from `p` towards `hit` (a point on the sphere).
    pub fn pdf_direction(&self, p: Vec3, hit: Vec3, n: Vec3) -> f32 {
        match self.cone(p) {
            Some((_, one_minus)) => 1.0 / (2.0 * PI * one_minus),
            None => area_pdf_to_solid_angle(p, hit, n, self.area()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn intersects_from_outside_and_inside() {
        let t = Sphere::intersect(Vec3::ZERO, 1.0, Vec3::new(0.0, 0.0, -5.0), Vec3::Z, f32::INFINITY);
        assert!((t - 4.0).abs() < 1e-5);
        let t = Sphere::intersect(Vec3::ZERO, 1.0, Vec3::ZERO, Vec3::Z, f32::INFINITY);
        assert!((t - 1.0).abs() < 1e-5);
        let t = Sphere::intersect(Vec3::ZERO, 1.0, Vec3::new(0.0, 2.0, -5.0), Vec3::Z, f32::INFINITY);
        assert!(t.is_infinite());
    }

    #[test]
    fn cone_samples_land_on_the_sphere_and_pdf_agrees() {
        let s = Sphere { center: Vec3::new(0.0, 0.0, 3.0), radius: 0.5, to_object: Transform::IDENTITY, flip_normals: false };
        let mut rng = crate::math::Pcg32::new(1, 1);
        for _ in 0..1000 {
            let ds = s.sample_direction(Vec3::ZERO, Vec2::new(rng.next_f32(), rng.next_f32())).unwrap();
            assert!(((ds.p - s.center).length() - 0.5).abs() < 1e-3);
            assert!(ds.n.dot(ds.d) <= 1e-3, "the sampled point faces the reference point");
            assert!((s.pdf_direction(Vec3::ZERO, ds.p, ds.n) - ds.pdf).abs() < 1e-3 * ds.pdf);
        }
    }
}
