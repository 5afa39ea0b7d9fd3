//! An orthonormal frame. BSDFs work in the local frame of the shading normal,
//! where z is the normal and `cos_theta(v) = v.z`.

use glam::Vec3;

#[derive(Clone, Copy, Debug)]
pub struct Frame {
    pub s: Vec3,
    pub t: Vec3,
    pub n: Vec3,
}

impl Frame {
    /// A frame around `n` (unit length); tangents by Duff et al. 2017
    /// ("Building an orthonormal basis, revisited"), continuous except at one pole.
    #[inline]
    pub fn from_normal(n: Vec3) -> Frame {
        let sign = 1.0f32.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        let s = Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
        let t = Vec3::new(b, sign + n.y * n.y * a, -n.y);
        Frame { s, t, n }
    }

    /// The frame about `n` whose tangent s is `tangent` made perpendicular
    /// to n (the normal alone if that leaves nothing).
    pub fn from_normal_and_tangent(n: Vec3, tangent: Vec3) -> Frame {
        let s = (tangent - n * n.dot(tangent)).normalize_or_zero();
        if s == Vec3::ZERO || !s.is_finite() {
            return Frame::from_normal(n);
        }
        Frame { s, t: n.cross(s), n }
    }

    #[inline]
    pub fn to_local(&self, v: Vec3) -> Vec3 {
        Vec3::new(v.dot(self.s), v.dot(self.t), v.dot(self.n))
    }

    #[inline]
    pub fn to_world(&self, v: Vec3) -> Vec3 {
        self.s * v.x + self.t * v.y + self.n * v.z
    }
}

#[inline]
pub fn cos_theta(v: Vec3) -> f32 {
    v.z
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Pcg32;
    use crate::math::sampling::square_to_uniform_sphere;
    use glam::Vec2;

    #[test]
    fn frame_is_orthonormal_and_round_trips() {
        let mut rng = Pcg32::new(7, 1);
        for _ in 0..10_000 {
            let n = square_to_uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32()));
            let f = Frame::from_normal(n);
            assert!((f.s.length() - 1.0).abs() < 1e-4);
            assert!((f.t.length() - 1.0).abs() < 1e-4);
            assert!(f.s.dot(f.t).abs() < 1e-4 && f.s.dot(f.n).abs() < 1e-4 && f.t.dot(f.n).abs() < 1e-4);
            assert!(f.s.cross(f.t).dot(f.n) > 0.999, "right-handed");
            let v = Vec3::new(0.3, -0.2, 0.9).normalize();
            assert!((f.to_world(f.to_local(v)) - v).length() < 1e-4);
        }
    }
}
