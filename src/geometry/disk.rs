//! Mitsuba's `disk`: the unit disk in the z=0 plane of its `to_world`, normal
//! +z, uv = (r, φ/2π). An affine `to_world` makes it an ellipse, which the
//! concentric map still samples uniformly by area.

use super::mesh::PositionSample;
use crate::math::sampling::square_to_uniform_disk_concentric;
use crate::math::{INV_TWO_PI, PI, Transform};
use glam::{Vec2, Vec3};

#[derive(Clone, Debug)]
pub struct Disk {
    pub to_world: Transform,
    /// World-space geometric normal (flip applied).
    pub normal: Vec3,
    pub area: f32,
    pub flip_normals: bool,
}

impl Disk {
    pub fn new(to_world: Transform, flip_normals: bool) -> Disk {
        let n = to_world.normal(Vec3::Z).normalize_or_zero();
        let area = PI * to_world.vector(Vec3::X).cross(to_world.vector(Vec3::Y)).length();
        Disk { to_world, normal: if flip_normals { -n } else { n }, area, flip_normals }
    }

    /// Nearest t in (0, tmax) or infinity.
    #[inline]
    pub fn intersect(to_object: &Transform, o: Vec3, d: Vec3, tmax: f32) -> f32 {
        let lo = to_object.point(o);
        let ld = to_object.vector(d);
        if ld.z == 0.0 {
            return f32::INFINITY;
        }
        let t = -lo.z / ld.z;
        if !(t > 0.0 && t < tmax) {
            return f32::INFINITY;
        }
        let p = lo + ld * t;
        if p.x * p.x + p.y * p.y <= 1.0 { t } else { f32::INFINITY }
    }

    pub fn uv_at(&self, p: Vec3) -> Vec2 {
        let l = self.to_world.inverse_point(p);
        let r = (l.x * l.x + l.y * l.y).sqrt();
        let mut v = crate::math::trig::atan2(l.y, l.x) * INV_TWO_PI;
        if v < 0.0 {
            v += 1.0;
        }
        Vec2::new(r, v)
    }

    #[inline(always)]
    pub fn sample_position(&self, u: Vec2) -> PositionSample {
        let d = square_to_uniform_disk_concentric(u);
        let p = self.to_world.point(Vec3::new(d.x, d.y, 0.0));
        PositionSample { p, n: self.normal, sh_n: self.normal, pdf_area: 1.0 / self.area }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Mat4;

    #[test]
    fn scaled_disk_area_and_hits() {
        let t = Transform::from_matrix(Mat4::from_scale(Vec3::new(2.0, 0.5, 1.0))).unwrap();
        let d = Disk::new(t, false);
        assert!((d.area - PI).abs() < 1e-5);
        let hit = Disk::intersect(&Transform { matrix: t.inverse, inverse: t.matrix }, Vec3::new(1.9, 0.0, 1.0), -Vec3::Z, 10.0);
        assert!((hit - 1.0).abs() < 1e-6);
        let miss = Disk::intersect(&Transform { matrix: t.inverse, inverse: t.matrix }, Vec3::new(0.0, 0.6, 1.0), -Vec3::Z, 10.0);
        assert!(miss.is_infinite());
    }
}
