//! Mitsuba's `sphere`: an analytic sphere (`center`, `radius`, and a
//! similarity `to_world`). Seen from outside, area lights on it are sampled by
//! the solid angle of the cone it subtends, which has far less variance than
//! sampling its area.

use super::mesh::{PositionSample, area_pdf_to_solid_angle};
use crate::math::sampling::{square_to_uniform_cone, square_to_uniform_sphere};
use crate::math::trig::atan2;
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
        // The discriminant through the ray's distance from the centre, as
        // Hearn & Baker's closest-approach vector l = oc − d·b/a, but
        // without that division on the way to the square root: a·|l|² =
        // |oc × d|² (Lagrange's identity), so a·disc = a·r² − |oc × d|².
        let a_disc = a * (r * r) - oc.cross(d).length_squared();
        if a_disc < 0.0 {
            return f32::INFINITY;
        }
        let c = oc.length_squared() - r * r;
        let sign_b = if b >= 0.0 { 1.0 } else { -1.0 };
        let q = -(b + sign_b * a_disc.sqrt());
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
        // The polynomial arc tangent (math/trig.rs), not the C library's:
        // this runs at every hit of a sphere. θ = acos z as the angle of
        // (ρ, z), ρ = √(x² + y²): no arc cosine, and exact near the poles.
        let mut phi = atan2(l.y, l.x);
        if phi < 0.0 {
            phi += 2.0 * PI;
        }
        let theta = atan2((l.x * l.x + l.y * l.y).sqrt(), l.z);
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

    /// The hits of rays from all around (near, far, grazing, from inside and
    /// from points on the surface) against the roots of the quadratic
    /// solved in f64 the textbook way with the points re-checked on the
    /// sphere: the same answer to f32 rounding, misses where it misses.
    #[test]
    fn hits_match_the_quadratic_solved_in_double_precision() {
        let mut rng = crate::math::Pcg32::new(7, 3);
        let mut f = || rng.next_f32();
        let (mut hits, mut grazing) = (0, 0);
        for case in 0..20000 {
            let center = Vec3::new(f() - 0.5, f() - 0.5, f() - 0.5) * 4.0;
            let radius = 0.05 + 2.0 * f();
            let d = square_to_uniform_sphere(Vec2::new(f(), f()));
            // Origins: far outside, inside, or on the surface (a ray leaving it).
            let o = match case % 3 {
                0 => center + square_to_uniform_sphere(Vec2::new(f(), f())) * radius * (1.5 + 10.0 * f()),
                1 => center + square_to_uniform_sphere(Vec2::new(f(), f())) * radius * 0.99 * f(),
                _ => center + square_to_uniform_sphere(Vec2::new(f(), f())) * radius,
            };
            let t = Sphere::intersect(center, radius, o, d, f32::INFINITY);
            let (oc, dd, r) = ((o - center).as_dvec3(), d.as_dvec3(), radius as f64);
            let (a, b, c) = (dd.length_squared(), 2.0 * oc.dot(dd), oc.length_squared() - r * r);
            let disc = b * b - 4.0 * a * c;
            // A hit must lie on the sphere.
            if t.is_finite() {
                hits += 1;
                let p = oc + dd * t as f64;
                assert!((p.length() - r).abs() < 2e-6 * (r + oc.length()), "case {case}: hit off the sphere");
            }
            if disc < -1e-9 * (b * b).max(1e-12) {
                assert!(t.is_infinite(), "case {case}: a miss reported as {t}");
                continue;
            }
            if disc.abs() < 1e-6 * b * b {
                grazing += 1;
                continue; // grazing: either answer is a rounding away
            }
            let s = disc.sqrt();
            let (t0, t1) = ((-b - s) / (2.0 * a), (-b + s) / (2.0 * a));
            // Roots within rounding of the origin are the surface it left.
            let tol = 1e-5 * (r + oc.length());
            let want = [t0, t1].into_iter().find(|&x| x > tol);
            // A hit within rounding of the origin is the surface the ray
            // leaves (the renderer's ray offsets step past it), whichever
            // root lies beyond.
            if (t as f64) <= tol {
                continue;
            }
            match want {
                Some(x) => assert!((t as f64 - x).abs() <= 1e-5 * x.max(tol), "case {case}: {t} against {x}"),
                None => assert!(t.is_infinite() || (t as f64) <= tol, "case {case}: {t} where none lies ahead"),
            }
        }
        assert!(hits > 10000 && grazing < 100, "{hits} hits, {grazing} grazing");
    }

    /// Mitsuba's (u, v) = (φ/2π, θ/π) against f64 trigonometry, poles and
    /// the seam included.
    #[test]
    fn uv_matches_double_precision_angles() {
        let s = Sphere { center: Vec3::new(0.5, -1.0, 2.0), radius: 1.5, to_object: Transform::IDENTITY, flip_normals: false };
        let to_object = glam::Mat4::from_scale(Vec3::splat(1.0 / s.radius)) * glam::Mat4::from_translation(-s.center);
        let s = Sphere { to_object: Transform::from_matrix(to_object).unwrap(), ..s };
        let mut rng = crate::math::Pcg32::new(5, 9);
        let mut dirs: Vec<Vec3> = (0..20000).map(|_| square_to_uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32()))).collect();
        dirs.extend([Vec3::Z, -Vec3::Z, Vec3::X, -Vec3::X, Vec3::new(1.0, -1e-7, 0.0).normalize(), Vec3::new(1e-4, 0.0, 1.0).normalize()]);
        for l in dirs {
            let uv = s.uv_at(s.center + l * s.radius);
            let l = s.to_object.point(s.center + l * s.radius).normalize().as_dvec3();
            let phi = l.y.atan2(l.x).rem_euclid(std::f64::consts::TAU);
            // θ of the vector itself (acos of its f32-rounded z is off by
            // up to 3·10⁻⁴ rad near the poles).
            let theta = (l.x * l.x + l.y * l.y).sqrt().atan2(l.z);
            let (u, v) = (phi / std::f64::consts::TAU, theta / std::f64::consts::PI);
            // u wraps at the seam: compare on the circle.
            let du = (uv.x as f64 - u).abs();
            assert!(du.min(1.0 - du) < 2e-6, "u {} against {u} at {l:?}", uv.x);
            assert!((uv.y as f64 - v).abs() < 2e-6, "v {} against {v} at {l:?}", uv.y);
        }
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
