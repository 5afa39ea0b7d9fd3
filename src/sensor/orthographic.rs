//! `orthographic` — parallel projection.
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `to_world` | transform | identity | placement; the view spans [-1,1] along x (scaled by `to_world`) |
//! | `near_clip`, `far_clip` | float | 0.01, 10000 | clip distances along the view axis |
//!
//! ```xml
//! <sensor type="orthographic">
//!     <transform name="to_world"><scale x="2" y="2"/><lookat origin="0,5,0" target="0,0,0" up="0,0,1"/></transform>
//! </sensor>
//! ```

use crate::geometry::Ray;
use crate::math::Transform;
use glam::{Vec2, Vec3};

#[derive(Clone, Debug)]
pub struct Orthographic {
    pub to_world: Transform,
    pub aspect: f32,
    pub near_clip: f32,
    pub far_clip: f32,
}

impl Orthographic {
    #[inline]
    pub fn generate_ray(&self, film: Vec2) -> Ray {
        let local = Vec3::new(1.0 - 2.0 * film.x, (1.0 - 2.0 * film.y) / self.aspect, self.near_clip);
        let o = self.to_world.point(local);
        let dz = self.to_world.vector(Vec3::Z);
        let len = dz.length();
        Ray { o, d: dz / len, tmax: (self.far_clip - self.near_clip) * len }
    }
}
