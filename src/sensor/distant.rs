//! `distant` — Mitsuba's distant radiance meter: the radiance leaving the
//! scene in one direction, averaged over a target. Every sample's ray runs
//! along the sensor's direction from outside the scene's bounding sphere;
//! where it starts depends on the target:
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `to_world` | transform | identity | the rays run along to_world's +z |
//! | `direction` | vector | — | instead of `to_world` (not both): the rays' direction |
//! | `target` | point, or a nested `<shape name="target">` | none | rays aimed at this point, or at points drawn uniformly by area on this shape; with none, at points drawn uniformly on the cross-section of the scene's bounding sphere (spanned by to_world's x and y) |
//!
//! The film must be 1 × 1 pixels (as Mitsuba). A target shape only aims the
//! rays: it is not part of the scene. The rays start two bounding-sphere
//! radii before the target point (one radius before the cross-section), as
//! Mitsuba's do, so the measured value is that of the first surface along
//! each ray, or the environment where the ray misses.
//!
//! ```xml
//! <sensor type="distant">
//!     <vector name="direction" x="0" y="0" z="-1"/>
//!     <shape type="rectangle" name="target"/>
//!     <film type="hdrfilm"><integer name="width" value="1"/><integer name="height" value="1"/></film>
//! </sensor>
//! ```

use crate::geometry::{Ray, Shape};
use crate::math::sampling::square_to_uniform_disk_concentric;
use glam::{Vec2, Vec3};
use std::sync::Arc;

#[derive(Clone)]
pub enum DistantTarget {
    /// The cross-section of the scene's bounding sphere.
    BoundingDisk,
    Point(Vec3),
    Shape(Arc<Shape>),
}

#[derive(Clone)]
pub struct Distant {
    /// Unit direction of the rays.
    pub direction: Vec3,
    /// to_world's x and y axes: they span the cross-section.
    pub x_axis: Vec3,
    pub y_axis: Vec3,
    pub target: DistantTarget,
    /// The scene's bounding sphere (set once the scene is built).
    pub center: Vec3,
    pub radius: f32,
}

/// Brief: the scene's fingerprint prints the camera, and a target mesh's
/// vertices do not belong there.
impl std::fmt::Debug for Distant {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let target = match &self.target {
            DistantTarget::BoundingDisk => "bounding disk".to_string(),
            DistantTarget::Point(p) => format!("point {p:?}"),
            DistantTarget::Shape(s) => format!("shape of area {}", s.area()),
        };
        f.debug_struct("Distant")
            .field("direction", &self.direction)
            .field("x_axis", &self.x_axis)
            .field("y_axis", &self.y_axis)
            .field("target", &target)
            .field("center", &self.center)
            .field("radius", &self.radius)
            .finish()
    }
}

impl Distant {
    /// Sets the scene's bounding box (lo, hi): the rays start outside it.
    pub fn set_bounds(&mut self, lo: Vec3, hi: Vec3) {
        let eps = crate::math::RAY_EPSILON;
        self.center = 0.5 * (lo + hi);
        self.radius = (0.5 * (hi - lo).length() * (1.0 + eps)).max(eps);
    }

    /// The ray of the sample whose target point is drawn with `u`.
    #[inline]
    pub fn sample_ray(&self, u: Vec2) -> Ray {
        let d = self.direction;
        let o = match &self.target {
            DistantTarget::BoundingDisk => {
                let offset = square_to_uniform_disk_concentric(u);
                self.center + (self.x_axis * offset.x + self.y_axis * offset.y) * self.radius - d * self.radius
            }
            DistantTarget::Point(p) => *p - 2.0 * d * self.radius,
            DistantTarget::Shape(s) => match s.sample_position(u) {
                Some(ps) => ps.p - 2.0 * d * self.radius,
                None => self.center - 2.0 * d * self.radius,
            },
        };
        Ray::new(o, d)
    }

    /// The up direction for Stokes vectors: to_world's y, made
    /// perpendicular to the direction.
    pub fn up(&self) -> Vec3 {
        let up = (self.y_axis - self.direction * self.direction.dot(self.y_axis)).normalize_or_zero();
        if up == Vec3::ZERO { crate::math::Frame::from_normal(self.direction).s } else { up }
    }
}
