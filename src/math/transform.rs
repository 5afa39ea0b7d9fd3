//! Affine transforms with their inverse, as Mitsuba's `to_world` builds them.

use glam::{Mat3, Mat4, Vec3};

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transform {
    pub matrix: Mat4,
    pub inverse: Mat4,
}

impl Default for Transform {
    fn default() -> Self {
        Transform::IDENTITY
    }
}

impl Transform {
    pub const IDENTITY: Transform = Transform { matrix: Mat4::IDENTITY, inverse: Mat4::IDENTITY };

    /// `None` when the matrix cannot be inverted (a degenerate scale, say).
    pub fn from_matrix(matrix: Mat4) -> Option<Transform> {
        let det = matrix.determinant();
        if !det.is_finite() || det.abs() < 1e-30 {
            return None;
        }
        let inverse = matrix.inverse();
        inverse.is_finite().then_some(Transform { matrix, inverse })
    }

    /// Mitsuba's `look_at`: columns (left, up, dir, origin), where
    /// left = up × dir, so the camera looks along +z with +x to its left.
    pub fn look_at(origin: Vec3, target: Vec3, up: Vec3) -> Option<Transform> {
        let dir = (target - origin).normalize_or_zero();
        let left = up.normalize_or_zero().cross(dir).normalize_or_zero();
        if dir == Vec3::ZERO || left == Vec3::ZERO {
            return None;
        }
        let new_up = dir.cross(left);
        Transform::from_matrix(Mat4::from_cols(
            left.extend(0.0),
            new_up.extend(0.0),
            dir.extend(0.0),
            origin.extend(1.0),
        ))
    }

    /// Rotation by `angle_deg` degrees about `axis` (right-handed), by
    /// Rodrigues' formula R = cos·I + (1 − cos)·a aᵀ + sin·[a]×.
    ///
    /// As in Mitsuba, `axis` is used as given, not normalised: for a unit
    /// axis this is a rotation; for any other length it also scales and
    /// shears, and Snell reproduces that so scenes render as in Mitsuba.
    pub fn rotate(axis: Vec3, angle_deg: f32) -> Option<Transform> {
        if axis == Vec3::ZERO {
            return None;
        }
        let (s, c) = angle_deg.to_radians().sin_cos();
        let a = axis;
        let m = Mat3::from_cols(
            Vec3::new(c + (1.0 - c) * a.x * a.x, (1.0 - c) * a.y * a.x + s * a.z, (1.0 - c) * a.z * a.x - s * a.y),
            Vec3::new((1.0 - c) * a.x * a.y - s * a.z, c + (1.0 - c) * a.y * a.y, (1.0 - c) * a.z * a.y + s * a.x),
            Vec3::new((1.0 - c) * a.x * a.z + s * a.y, (1.0 - c) * a.y * a.z - s * a.x, c + (1.0 - c) * a.z * a.z),
        );
        Transform::from_matrix(Mat4::from_mat3(m))
    }

    /// `self` applied after `first`.
    pub fn compose(&self, first: &Transform) -> Transform {
        Transform { matrix: self.matrix * first.matrix, inverse: first.inverse * self.inverse }
    }

    /// World-space axis-aligned bounds (lo, hi) of the unit cube [0, 1]³
    /// placed by this transform (a volume's or an SDF grid's box).
    pub fn unit_cube_bounds(&self) -> (Vec3, Vec3) {
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for i in 0..8 {
            let p = self.point(Vec3::new((i & 1) as f32, ((i >> 1) & 1) as f32, (i >> 2) as f32));
            lo = lo.min(p);
            hi = hi.max(p);
        }
        (lo, hi)
    }

    #[inline]
    pub fn point(&self, p: Vec3) -> Vec3 {
        self.matrix.transform_point3(p)
    }

    #[inline]
    pub fn vector(&self, v: Vec3) -> Vec3 {
        self.matrix.transform_vector3(v)
    }

    /// Normals transform by the inverse transpose.
    #[inline]
    pub fn normal(&self, n: Vec3) -> Vec3 {
        Mat3::from_mat4(self.inverse).transpose() * n
    }

    #[inline]
    pub fn inverse_point(&self, p: Vec3) -> Vec3 {
        self.inverse.transform_point3(p)
    }

    #[inline]
    pub fn inverse_vector(&self, v: Vec3) -> Vec3 {
        self.inverse.transform_vector3(v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn look_at_matches_mitsuba_convention() {
        let t = Transform::look_at(Vec3::new(0.0, 0.0, 3.9), Vec3::ZERO, Vec3::Y).unwrap();
        // Camera +z maps to the viewing direction, +x to the camera's left (world +x
        // when looking down -z with y up: up × dir = y × (-z) = -x... so left is -x).
        assert!((t.vector(Vec3::Z) - Vec3::new(0.0, 0.0, -1.0)).length() < 1e-6);
        assert!((t.vector(Vec3::X) - Vec3::new(-1.0, 0.0, 0.0)).length() < 1e-6);
        assert!((t.point(Vec3::ZERO) - Vec3::new(0.0, 0.0, 3.9)).length() < 1e-6);
    }

    #[test]
    fn rotate_is_right_handed() {
        let r = Transform::rotate(Vec3::Z, 90.0).unwrap();
        assert!((r.vector(Vec3::X) - Vec3::Y).length() < 1e-6);
        let axis = Vec3::new(1.0, 2.0, -0.5).normalize();
        let r = Transform::rotate(axis, 37.0).unwrap();
        let q = Mat4::from_axis_angle(axis, 37f32.to_radians());
        assert!(r.matrix.abs_diff_eq(q, 1e-6));
        // Mitsuba's matrix for a non-unit axis (1, 1, 0.3) and 35°: not a rotation.
        let m = Transform::rotate(Vec3::new(1.0, 1.0, 0.3), 35.0).unwrap().matrix;
        assert!((m.x_axis.y - 0.3529).abs() < 1e-4 && (m.z_axis.x - 0.6278).abs() < 1e-4);
        assert!((m.determinant() - 1.6264).abs() < 1e-3);
    }

    #[test]
    fn normals_stay_perpendicular_under_nonuniform_scale() {
        let t = Transform::from_matrix(Mat4::from_scale(Vec3::new(2.0, 1.0, 0.5))).unwrap();
        let tangent = t.vector(Vec3::new(1.0, 1.0, 0.0));
        let n = t.normal(Vec3::new(1.0, -1.0, 0.0));
        assert!(tangent.dot(n).abs() < 1e-6);
        assert!(Transform::from_matrix(Mat4::from_scale(Vec3::new(1.0, 0.0, 1.0))).is_none());
    }
}
