//! `irradiancemeter` — the irradiance over a shape: Mitsuba's irradiance
//! meter, the power per unit area arriving at the surface of the shape it
//! is nested in, averaged over that surface. It measures
//! E = (1/A) ∫_A ∫_{H²(n)} L(x, ω) cos θ dω dx: each sample starts at a
//! point drawn uniformly by area, leaves in a cosine-distributed direction
//! about the normal, and weighs the radiance it brings back by π (the
//! cosine's integral, which the sampling density cancels with all but this
//! constant).
//!
//! It has no parameters and takes no `to_world`: it sits on its shape.
//! Every pixel of its film measures the same quantity (Mitsuba intends a
//! 1 × 1 film; a larger one is allowed, as in Mitsuba). The shape stays in
//! the scene as any other (it shadows and reflects); the rays start
//! `RAY_EPSILON` off it, as Mitsuba's do, on the side its normals point to.
//!
//! ```xml
//! <shape type="rectangle">
//!     <sensor type="irradiancemeter">
//!         <film type="hdrfilm"><integer name="width" value="1"/><integer name="height" value="1"/></film>
//!     </sensor>
//! </shape>
//! ```

use crate::geometry::{Ray, Shape};
use crate::math::sampling::square_to_cosine_hemisphere;
use crate::math::{Frame, RAY_EPSILON};
use glam::{Vec2, Vec3};
use std::f32::consts::PI;
use std::sync::Arc;

#[derive(Clone)]
pub struct IrradianceMeter {
    /// The shape it measures (a copy of the scene's, in world space).
    pub shape: Arc<Shape>,
}

/// Brief: the scene's fingerprint prints the camera, and a mesh's every
/// vertex (and its lazily built caches) do not belong there.
impl std::fmt::Debug for IrradianceMeter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("IrradianceMeter").field("area", &self.shape.area()).field("bsdf", &self.shape.bsdf).finish()
    }
}

impl IrradianceMeter {
    /// What each sample's radiance is multiplied by.
    pub const WEIGHT: f32 = PI;

    /// The ray of the sample whose position on the surface is drawn with
    /// `u_pos` and direction with `u_dir`.
    #[inline]
    pub fn sample_ray(&self, u_pos: Vec2, u_dir: Vec2) -> Ray {
        let Some(ps) = self.shape.sample_position(u_pos) else {
            // The loader only places a meter on a shape it can sample.
            return Ray::new(Vec3::ZERO, Vec3::Z);
        };
        let n = if ps.sh_n.is_finite() && ps.sh_n != Vec3::ZERO { ps.sh_n } else { ps.n };
        let d = Frame::from_normal(n).to_world(square_to_cosine_hemisphere(u_dir));
        Ray::new(ps.p + d * RAY_EPSILON, d)
    }

    /// The camera's up direction for Stokes vectors: the surface frame's
    /// first tangent at the shape's first sample point.
    pub fn up(&self) -> Vec3 {
        self.shape.sample_position(Vec2::splat(0.5)).map_or(Vec3::Y, |ps| Frame::from_normal(ps.n).s)
    }
}
