//! `perspective` — a pinhole camera.
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `fov` | float | — | field of view in degrees, along `fov_axis` |
//! | `fov_axis` | string | `x` | `x`, `y`, `smaller`, `larger` or `diagonal` |
//! | `to_world` | transform | identity | camera placement (usually a `lookat`) |
//! | `near_clip`, `far_clip` | float | 0.01, 10000 | clip distances along the view axis |
//!
//! ```xml
//! <sensor type="perspective">
//!     <float name="fov" value="39.3"/>
//!     <transform name="to_world"><lookat origin="0,0,4" target="0,0,0" up="0,1,0"/></transform>
//!     <film type="hdrfilm"><integer name="width" value="256"/><integer name="height" value="256"/></film>
//! </sensor>
//! ```

use crate::geometry::Ray;
use crate::math::Transform;
use glam::{Vec2, Vec3};

#[derive(Clone, Debug)]
pub struct Perspective {
    pub to_world: Transform,
    /// tan(fov_x / 2).
    pub tan_half_x: f32,
    /// width / height.
    pub aspect: f32,
    pub near_clip: f32,
    pub far_clip: f32,
    /// Precomputed so a camera ray costs two multiply-adds and one
    /// normalisation: the world-space origin, and the world-space images of
    /// the camera's x and y half-extents at depth 1 and of its axis.
    origin: Vec3,
    half_x: Vec3,
    half_y: Vec3,
    axis: Vec3,
}
/// The horizontal field of view (degrees) for a `fov` given along `axis`.
pub fn horizontal_fov(fov: f32, axis: &str, aspect: f32) -> f32 {
    let axis = match axis {
        "smaller" => if aspect > 1.0 { "y" } else { "x" },
        "larger" => if aspect > 1.0 { "x" } else { "y" },
        a => a,
    };
    let half = (fov.to_radians() * 0.5).tan();
    match axis {
        "y" => 2.0 * (half * aspect).atan().to_degrees(),
        "diagonal" => {
            let diagonal = 2.0 * half;
            let width = diagonal / (1.0 + 1.0 / (aspect * aspect)).sqrt();
            2.0 * (width * 0.5).atan().to_degrees()
        }
        _ => fov,
    }
}

impl Perspective {
    pub fn new(to_world: Transform, tan_half_x: f32, aspect: f32, near_clip: f32, far_clip: f32) -> Perspective {
        let tan_half_y = tan_half_x / aspect;
        Perspective {
            origin: to_world.point(Vec3::ZERO),
            half_x: to_world.vector(Vec3::new(tan_half_x, 0.0, 0.0)),
            half_y: to_world.vector(Vec3::new(0.0, tan_half_y, 0.0)),
            axis: to_world.vector(Vec3::Z),
            to_world,
            tan_half_x,
            aspect,
            near_clip,
            far_clip,
        }
    }

    /// The ray through film position `film` ∈ [0,1]² (top left (0,0)),
    /// starting at the near clip plane and ending at the far one.
    #[inline]
    pub fn generate_ray(&self, film: Vec2) -> Ray {
        // Camera space: (x, y, 1) through the film point; its length converts
        // clip depths along the axis into distances along the ray.
        let (sx, sy) = (1.0 - 2.0 * film.x, 1.0 - 2.0 * film.y);
        let local_len = (sx * sx * self.tan_half_x * self.tan_half_x
            + sy * sy * (self.tan_half_x / self.aspect) * (self.tan_half_x / self.aspect)
            + 1.0)
            .sqrt();
        let d = (self.half_x * sx + self.half_y * sy + self.axis).normalize();
        let t_near = self.near_clip * local_len;
        let t_far = self.far_clip * local_len;
        Ray { o: self.origin + d * t_near, d, tmax: t_far - t_near }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fov_axis_conversions() {
        assert!((horizontal_fov(40.0, "x", 2.0) - 40.0).abs() < 1e-4);
        // fov along y on a 2:1 film: tan(x/2) = 2 tan(y/2).
        let x = horizontal_fov(40.0, "y", 2.0);
        assert!(((x.to_radians() / 2.0).tan() - 2.0 * (20.0f32.to_radians()).tan()).abs() < 1e-5);
        assert_eq!(horizontal_fov(40.0, "smaller", 2.0), x);
        assert_eq!(horizontal_fov(40.0, "larger", 0.5), x.min(horizontal_fov(40.0, "y", 0.5)));
        let d = horizontal_fov(60.0, "diagonal", 1.0);
        assert!(((d.to_radians() / 2.0).tan() * 2f32.sqrt() - (30.0f32.to_radians()).tan()).abs() < 1e-5);
    }

    #[test]
    fn image_corners_follow_mitsuba() {
        let to_world = Transform::look_at(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, Vec3::Y).unwrap();
        let cam = Perspective::new(to_world, 1.0, 1.0, 0.0, 100.0);
        let top_left = cam.generate_ray(Vec2::new(0.0, 0.0));
        // Looking down -z with +y up, the image's left is world -x and its top world +y.
        assert!(top_left.d.x < 0.0 && top_left.d.y > 0.0 && top_left.d.z < 0.0);
        let centre = cam.generate_ray(Vec2::splat(0.5));
        assert!((centre.d - Vec3::new(0.0, 0.0, -1.0)).length() < 1e-6);
    }
}
