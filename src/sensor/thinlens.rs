//! `thinlens` — a perspective camera with a finite aperture: depth of field.
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `aperture_radius` | float | — (required) | radius of the lens aperture (scene units); 0 is taken as a tiny radius, as Mitsuba does |
//! | `focus_distance` | float | `far_clip` | distance along the view axis of the plane in focus |
//! | `fov`, `fov_axis` | float, string | —, `x` | field of view in degrees along `fov_axis` (`x`, `y`, `smaller`, `larger`, `diagonal`) |
//! | `focal_length` | string | `50mm` | instead of `fov`: 35 mm film equivalent focal length, measured on the diagonal |
//! | `principal_point_offset_x/y` | float | 0 | shift of the image centre, in fractions of the film (a Snell extension here; Mitsuba 3.9 reads it on `perspective` only) |
//! | `to_world` | transform | identity | camera placement (no scale) |
//! | `near_clip`, `far_clip` | float | 0.01, 10000 | clip distances along the view axis |
//!
//! A ray leaves a point of the aperture disk (at the camera origin, in its
//! x-y plane; uniform in area by the concentric map, as Mitsuba samples it)
//! towards the point of the focus plane `z = focus_distance` that the
//! pinhole ray through the same film position hits, so points at the focus
//! distance are sharp and others blur into a circle of confusion of
//! diameter 2·r·|z − f|/f at unit depth. Every ray has weight 1.
//!
//! ```xml
//! <sensor type="thinlens">
//!     <float name="aperture_radius" value="0.1"/>
//!     <float name="focus_distance" value="4"/>
//!     <float name="fov" value="40"/>
//!     <transform name="to_world"><lookat origin="0,0,4" target="0,0,0" up="0,1,0"/></transform>
//! </sensor>
//! ```

use crate::geometry::Ray;
use crate::math::Transform;
use crate::math::sampling::square_to_uniform_disk_concentric;
use glam::{Vec2, Vec3};

#[derive(Clone, Debug)]
pub struct ThinLens {
    pub to_world: Transform,
    /// tan(fov_x / 2).
    pub tan_half_x: f32,
    /// width / height.
    pub aspect: f32,
    pub near_clip: f32,
    pub far_clip: f32,
    pub aperture_radius: f32,
    pub focus_distance: f32,
    /// Added to the film position (fractions of the film).
    pub principal_offset: Vec2,
}

impl ThinLens {
    /// The ray through film position `film` ∈ [0,1]² (top left (0,0)) from
    /// the aperture point chosen by `aperture` ∈ [0,1]².
    #[inline]
    pub fn generate_ray(&self, film: Vec2, aperture: Vec2) -> Ray {
        let film = film + self.principal_offset;
        let (sx, sy) = (1.0 - 2.0 * film.x, 1.0 - 2.0 * film.y);
        // The pinhole ray's point at depth 1, scaled onto the focus plane.
        let focus = Vec3::new(sx * self.tan_half_x, sy * self.tan_half_x / self.aspect, 1.0) * self.focus_distance;
        let a = self.aperture_radius * square_to_uniform_disk_concentric(aperture);
        let lens = Vec3::new(a.x, a.y, 0.0);
        let local = (focus - lens).normalize();
        let d = self.to_world.vector(local).normalize();
        let o = self.to_world.point(lens);
        // Clip distances are along the view axis.
        let (t_near, t_far) = (self.near_clip / local.z, self.far_clip / local.z);
        Ray { o: o + d * t_near, d, tmax: t_far - t_near }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera(radius: f32, focus: f32) -> ThinLens {
        let to_world = Transform::look_at(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, Vec3::Y).unwrap();
        ThinLens {
            to_world,
            tan_half_x: 0.5,
            aspect: 1.5,
            near_clip: 0.01,
            far_clip: 100.0,
            aperture_radius: radius,
            focus_distance: focus,
            principal_offset: Vec2::ZERO,
        }
    }

    #[test]
    fn rays_of_one_film_point_meet_on_the_focus_plane() {
        let cam = camera(0.3, 4.0);
        let film = Vec2::new(0.2, 0.7);
        let mut hits = vec![];
        for &u in &[Vec2::new(0.1, 0.2), Vec2::new(0.9, 0.5), Vec2::new(0.5, 0.5), Vec2::new(0.3, 0.95)] {
            let r = cam.generate_ray(film, u);
            // The focus plane is world z = 5 − 4 = 1 (the camera looks down −z).
            let t = (1.0 - r.o.z) / r.d.z;
            hits.push(r.o + r.d * t);
        }
        for h in &hits[1..] {
            assert!((*h - hits[0]).length() < 1e-4, "{hits:?}");
        }
        // The centre of the aperture gives the pinhole ray.
        let pinhole = crate::sensor::Perspective::new(cam.to_world, 0.5, 1.5, 0.01, 100.0).generate_ray(film);
        let centre = cam.generate_ray(film, Vec2::splat(0.5));
        assert!((pinhole.d - centre.d).length() < 1e-5 && (pinhole.o - centre.o).length() < 1e-4);
    }

    #[test]
    fn ray_origins_cover_the_aperture_disk() {
        let cam = camera(0.25, 3.0);
        let mut max_r = 0.0f32;
        let n = 64;
        for j in 0..n {
            for i in 0..n {
                let u = Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
                let r = cam.generate_ray(Vec2::splat(0.5), u);
                // Back to the lens plane (world z = 5) along the ray.
                let t = (5.0 - r.o.z) / r.d.z;
                let p = r.o + r.d * t;
                max_r = max_r.max(Vec2::new(p.x, p.y).length());
            }
        }
        assert!(max_r <= 0.25 + 1e-4 && max_r > 0.24, "{max_r}");
    }
}
