//! `radiancemeter` — the radiance arriving along one ray: Mitsuba's radiance
//! meter, the limit of a perspective camera whose field of view tends to
//! zero. A virtual experiment's probe: every sample measures the same ray,
//! so a path tracer's estimate converges to L(o, −d) itself.
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `to_world` | transform | identity | the ray starts at to_world's origin and runs along its +z |
//! | `origin` | point | — | with `direction`, instead of `to_world`: where the ray starts |
//! | `direction` | vector | — | with `origin`: where the ray points |
//!
//! The film is a single pixel (as Mitsuba, a film with neither side 1 is
//! refused). Where both `to_world` and `origin`/`direction` are given,
//! `to_world` wins, as in Mitsuba. The ray starts `RAY_EPSILON` along its
//! direction, as Mitsuba's does; the camera's up direction (for Stokes
//! vectors) is to_world's +y, or for `origin`/`direction` the first tangent
//! of the direction's frame (Mitsuba's `coordinate_system`).
//!
//! ```xml
//! <sensor type="radiancemeter">
//!     <point name="origin" x="0" y="2" z="0"/>
//!     <vector name="direction" x="0" y="-1" z="0"/>
//!     <film type="hdrfilm"><integer name="width" value="1"/><integer name="height" value="1"/></film>
//! </sensor>
//! ```

use crate::geometry::Ray;
use crate::math::{Frame, Transform, RAY_EPSILON};
use glam::Vec3;

#[derive(Clone, Debug)]
pub struct RadianceMeter {
    pub origin: Vec3,
    /// Unit length.
    pub direction: Vec3,
    /// The camera's up direction, perpendicular to `direction`.
    pub up: Vec3,
}

impl RadianceMeter {
    /// The meter at to_world's origin looking along its +z; `None` if that
    /// direction has no length.
    pub fn from_transform(to_world: &Transform) -> Option<RadianceMeter> {
        let direction = to_world.vector(Vec3::Z).normalize_or_zero();
        if direction == Vec3::ZERO || !direction.is_finite() {
            return None;
        }
        let up = to_world.vector(Vec3::Y);
        let up = (up - direction * direction.dot(up)).normalize_or_zero();
        let up = if up == Vec3::ZERO { Frame::from_normal(direction).s } else { up };
        Some(RadianceMeter { origin: to_world.point(Vec3::ZERO), direction, up })
    }

    /// The meter at `origin` looking along `direction`; `None` if the
    /// direction has no length.
    pub fn from_ray(origin: Vec3, direction: Vec3) -> Option<RadianceMeter> {
        let direction = direction.normalize_or_zero();
        if direction == Vec3::ZERO || !direction.is_finite() || !origin.is_finite() {
            return None;
        }
        Some(RadianceMeter { origin, direction, up: Frame::from_normal(direction).s })
    }

    /// The one ray it measures (whatever the film position).
    #[inline]
    pub fn generate_ray(&self) -> Ray {
        Ray::new(self.origin + self.direction * RAY_EPSILON, self.direction)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn looks_along_to_world_z_or_the_given_direction() {
        let t = Transform::look_at(Vec3::new(1.0, 2.0, 3.0), Vec3::new(1.0, 1.0, 3.0), Vec3::Z).expect("a frame");
        let m = RadianceMeter::from_transform(&t).expect("a direction");
        let ray = m.generate_ray();
        assert!((ray.d - Vec3::new(0.0, -1.0, 0.0)).length() < 1e-6, "{:?}", ray.d);
        assert!((ray.o - Vec3::new(1.0, 2.0, 3.0) - ray.d * RAY_EPSILON).length() < 1e-6, "{:?}", ray.o);
        // to_world's +y: the look-at's up.
        assert!((m.up - Vec3::Z).length() < 1e-6, "{:?}", m.up);

        let m = RadianceMeter::from_ray(Vec3::new(0.0, 1.0, 0.0), Vec3::new(0.0, -2.0, 0.0)).expect("a direction");
        assert_eq!(m.generate_ray().d, Vec3::new(0.0, -1.0, 0.0));
        assert!(m.up.dot(m.direction).abs() < 1e-6 && (m.up.length() - 1.0).abs() < 1e-6);
        assert!(RadianceMeter::from_ray(Vec3::ZERO, Vec3::ZERO).is_none());
    }
}
